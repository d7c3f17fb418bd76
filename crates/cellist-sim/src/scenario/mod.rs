//! Scenario files (TOML): reading, `--set key=value` overrides, and the model they
//! name. Each model deserialises its own keys, refusing unknown ones with the line;
//! the keys every model shares are in [`keys`].

pub mod keys;
mod registry;

pub use registry::ModelKind;

use crate::error::{SimError, SimResult};
use std::path::{Path, PathBuf};

/// The scenario that `cellist run` runs without a file: the LJ melt.
pub const DEFAULT_SCENARIO: &str = include_str!("../../../../examples/lj-melt.toml");

/// A scenario's text and where it came from.
pub struct Scenario {
    /// The TOML text with every `--set` applied.
    pub text: String,
    /// Name for messages (the file path, or the built-in name).
    pub origin: String,
    /// The file it was read from (`None` for the built-in melt or a text).
    pub path: Option<PathBuf>,
    /// Folder that relative input paths start from.
    pub base_dir: PathBuf,
    /// Default output folder name, `out/<name>/`.
    pub name: String,
}

impl Scenario {
    /// Reads `path` (or the built-in melt) and applies the overrides.
    pub fn load(path: Option<&Path>, sets: &[String]) -> SimResult<Self> {
        let (text, origin, base_dir, name) = match path {
            Some(p) => {
                let text = std::fs::read_to_string(p)
                    .map_err(|e| SimError::Input(format!("{}: cannot read: {e}", p.display())))?;
                let name = p
                    .file_stem()
                    .map_or_else(|| "scenario".into(), |s| s.to_string_lossy().into_owned());
                let base = p.parent().map_or_else(PathBuf::new, Path::to_path_buf);
                (text, p.display().to_string(), base, name)
            }
            None => (
                DEFAULT_SCENARIO.to_string(),
                "built-in lj-melt".to_string(),
                PathBuf::new(),
                "lj-melt".to_string(),
            ),
        };
        let text = apply_sets(&text, &origin, sets)?;
        Ok(Scenario {
            text,
            origin,
            path: path.map(Path::to_path_buf),
            base_dir,
            name,
        })
    }

    /// A scenario given as text (not read from a file), called `origin` in
    /// messages; relative input paths start from the working folder and its
    /// default output folder is `out/<name>/`.
    pub fn from_text(text: &str, origin: &str, name: &str) -> Self {
        Scenario {
            text: text.to_string(),
            origin: origin.to_string(),
            path: None,
            base_dir: PathBuf::new(),
            name: name.to_string(),
        }
    }

    /// The same scenario with more `--set key=value` overrides applied.
    pub fn with_sets(&self, sets: &[String]) -> SimResult<Self> {
        Ok(Scenario {
            text: apply_sets(&self.text, &self.origin, sets)?,
            origin: self.origin.clone(),
            path: self.path.clone(),
            base_dir: self.base_dir.clone(),
            name: self.name.clone(),
        })
    }

    /// The model the `model` key names.
    pub fn model(&self) -> SimResult<ModelKind> {
        let table: toml::Table = toml::from_str(&self.text).map_err(|e| self.error(e))?;
        match table.get("model") {
            Some(toml::Value::String(m)) => ModelKind::from_name(m).ok_or_else(|| {
                self.error(format!(
                    "model '{m}' is unknown; this build runs: {}",
                    ModelKind::list()
                ))
            }),
            Some(other) => Err(SimError::Input(format!(
                "{}: model must be a string such as \"md\", got {other}",
                self.origin
            ))),
            None => Err(SimError::Input(format!(
                "{}: no `model` key; expected e.g. model = \"md\"",
                self.origin
            ))),
        }
    }

    /// Deserialises the model's keys.
    pub fn parse<T: serde::de::DeserializeOwned>(&self) -> SimResult<T> {
        toml::from_str(&self.text).map_err(|e| self.error(e))
    }

    /// An input error about this scenario.
    pub fn error(&self, e: impl std::fmt::Display) -> SimError {
        SimError::Input(format!("{}: {e}", self.origin))
    }

    /// The physics keys: every key but those under `[output]` and
    /// `[decomposition]` (where the ranks cut the box) and `run.steps`, as
    /// dotted names with their TOML values, sorted by name. A checkpoint records
    /// them; a restart refuses a scenario whose physics keys differ.
    pub fn physics_keys(&self) -> SimResult<Vec<(String, String)>> {
        let table: toml::Table = toml::from_str(&self.text).map_err(|e| self.error(e))?;
        let mut keys = Vec::new();
        flatten("", &table, &mut keys);
        keys.retain(|(k, _)| {
            !(k.starts_with("output.") || k.starts_with("decomposition.") || k == "run.steps")
        });
        keys.sort();
        Ok(keys)
    }

    /// An input path relative to the scenario file.
    pub fn input_path(&self, p: &Path) -> PathBuf {
        self.base_dir.join(p)
    }
}

/// Appends `prefix.key = value` for every value under `table`, tables flattened.
fn flatten(prefix: &str, table: &toml::Table, out: &mut Vec<(String, String)>) {
    for (key, value) in table {
        let name = if prefix.is_empty() {
            key.clone()
        } else {
            format!("{prefix}.{key}")
        };
        match value {
            toml::Value::Table(t) => flatten(&name, t, out),
            other => out.push((name, other.to_string())),
        }
    }
}

/// Applies `key.path=value` overrides; the value is read as TOML (a number, a
/// boolean, an array, an inline table, a quoted string) or else taken as a string.
fn apply_sets(text: &str, origin: &str, sets: &[String]) -> SimResult<String> {
    if sets.is_empty() {
        return Ok(text.to_string());
    }
    let mut doc: toml_edit::DocumentMut = text
        .parse()
        .map_err(|e| SimError::Input(format!("{origin}: {e}")))?;
    for set in sets {
        let bad = |why: &str| SimError::Input(format!("--set {set}: {why}"));
        let (key, value) = set
            .split_once('=')
            .ok_or_else(|| bad("expected KEY=VALUE, e.g. run.steps=200"))?;
        let keys: Vec<&str> = key.trim().split('.').map(str::trim).collect();
        if keys.iter().any(|k| k.is_empty()) {
            return Err(bad("empty key"));
        }
        let value = value.trim();
        let parsed: toml_edit::Value = value
            .parse()
            .unwrap_or_else(|_| toml_edit::Value::from(value));
        let mut item = doc.as_item_mut();
        for (depth, k) in keys.iter().enumerate() {
            if !(item.is_table_like() || item.is_none()) {
                return Err(bad(&format!(
                    "{} is a value, not a table",
                    keys[..depth].join(".")
                )));
            }
            item = &mut item[*k];
        }
        *item = toml_edit::Item::Value(parsed);
    }
    Ok(doc.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sets_replace_and_add_keys_at_any_depth() {
        let text = "model = \"md\"\n[run]\nsteps = 10\n[system]\nlattice = { kind = \"fcc\", cells = [2, 2, 2] }\n";
        let sets = [
            "run.steps=200".to_string(),
            "system.lattice.cells=[3,3,3]".to_string(),
            "pair.style=lj/cut".to_string(),
        ];
        let out = apply_sets(text, "t", &sets).unwrap();
        let v: toml::Table = toml::from_str(&out).unwrap();
        assert_eq!(v["run"]["steps"].as_integer(), Some(200));
        assert_eq!(v["system"]["lattice"]["cells"].as_array().unwrap().len(), 3);
        assert_eq!(v["pair"]["style"].as_str(), Some("lj/cut"));
        assert!(apply_sets(text, "t", &["run.steps".into()]).is_err());
        assert!(apply_sets(text, "t", &["model.x=1".into()]).is_err());
    }

    #[test]
    fn physics_keys_leave_out_the_outputs_the_cuts_and_the_step_count() {
        let text = "model = \"md\"\n[run]\nsteps = 10\ndt = 0.005\n[system]\nlattice = { kind = \"fcc\", cells = [2, 2, 2] }\n[output]\nthermo_every = 5\n[decomposition]\nbalance = \"uniform\"\n";
        let scenario = Scenario {
            text: text.into(),
            origin: "t".into(),
            path: None,
            base_dir: PathBuf::new(),
            name: "t".into(),
        };
        let keys = scenario.physics_keys().unwrap();
        let names: Vec<&str> = keys.iter().map(|(k, _)| k.as_str()).collect();
        assert_eq!(
            names,
            [
                "model",
                "run.dt",
                "system.lattice.cells",
                "system.lattice.kind"
            ]
        );
        assert_eq!(keys[1].1, "0.005");
        assert_eq!(keys[2].1, "[2, 2, 2]");
    }
}
