//! The scenario keys several models share: checkpoints and trajectories under
//! `[output]`, `[decomposition]`, each with its check.

use cellist::decomposition::Balance;
use std::path::PathBuf;

/// `[output] checkpoint = { every = K, file = "state.ckpt" }`.
#[derive(Clone, Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CheckpointKeys {
    /// Steps between checkpoints (the last step is always one).
    pub every: u64,
    /// File name in the output folder.
    #[serde(default = "default_checkpoint_file")]
    pub file: PathBuf,
}

fn default_checkpoint_file() -> PathBuf {
    "state.ckpt".into()
}

impl CheckpointKeys {
    /// Refuses `every = 0`.
    pub fn check(&self, key: &str) -> Result<(), String> {
        check_every(self.every, key)
    }
}

/// `[decomposition]` of the models that run by domain decomposition on
/// several MPI ranks (md, pse): `balance = "rcb"` (the default: planes placed
/// by the particles, never worse than equal ones for an even system) or
/// `"uniform"` (equal subdomains).
#[derive(Clone, Debug, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DecompositionKeys {
    /// `"rcb"` or `"uniform"`.
    pub balance: String,
}

impl Default for DecompositionKeys {
    fn default() -> Self {
        DecompositionKeys {
            balance: "rcb".into(),
        }
    }
}

impl DecompositionKeys {
    /// The placement the keys name.
    pub fn balance(&self) -> Result<Balance, String> {
        choice(
            "decomposition.balance",
            &self.balance,
            &[("rcb", Balance::Rcb), ("uniform", Balance::Uniform)],
        )
    }
}

/// Refuses `key.every = 0`: outputs every `every >= 1` steps.
pub fn check_every(every: u64, key: &str) -> Result<(), String> {
    if every == 0 {
        Err(format!("{key}.every must be >= 1"))
    } else {
        Ok(())
    }
}

/// `[output] gsd = { every = K, file = "traj.gsd" }` and the same for `vtk`.
#[derive(Clone, Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SeriesKeys {
    /// Steps between frames (step 0 is one).
    pub every: u64,
    /// File name in the output folder.
    pub file: PathBuf,
}

impl SeriesKeys {
    /// Refuses `every = 0`.
    pub fn check(&self, key: &str) -> Result<(), String> {
        check_every(self.every, key)
    }
}

/// The trajectories a scenario asks for under `[output]`.
#[derive(Clone, Debug, Default)]
pub struct TrajectoryKeys {
    /// `gsd = { every, file }`.
    pub gsd: Option<SeriesKeys>,
    /// `vtk = { every, file }` (the `.pvd` index).
    pub vtk: Option<SeriesKeys>,
}

impl TrajectoryKeys {
    /// The keys `gsd` and `vtk`, checked (`every >= 1`, a `.gsd` and a `.pvd`
    /// file name without a folder).
    pub fn checked(gsd: Option<SeriesKeys>, vtk: Option<SeriesKeys>) -> Result<Self, String> {
        for (keys, key, extension) in [(&gsd, "output.gsd", "gsd"), (&vtk, "output.vtk", "pvd")] {
            if let Some(k) = keys {
                k.check(key)?;
                if k.file.components().count() != 1 {
                    return Err(format!(
                        "{key}.file must be a file name in the output folder, got {}",
                        k.file.display()
                    ));
                }
                if k.file.extension().and_then(|e| e.to_str()) != Some(extension) {
                    return Err(format!(
                        "{key}.file must end in .{extension}, got {}",
                        k.file.display()
                    ));
                }
            }
        }
        Ok(TrajectoryKeys { gsd, vtk })
    }
}

/// The value that the option `key = "name"` stands for among `options` (each a
/// name and its value): where a scenario's option strings become enums. An
/// unknown name gives `key 'name' is unknown; expected "a", "b" or "c"`.
pub fn choice<T: Copy>(key: &str, name: &str, options: &[(&str, T)]) -> Result<T, String> {
    if let Some(&(_, value)) = options.iter().find(|(n, _)| *n == name) {
        return Ok(value);
    }
    let quoted: Vec<String> = options.iter().map(|(n, _)| format!("\"{n}\"")).collect();
    let expected = match quoted.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => "nothing".into(),
    };
    Err(format!("{key} '{name}' is unknown; expected {expected}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn balance_defaults_to_rcb_and_names_its_options() {
        assert_eq!(DecompositionKeys::default().balance(), Ok(Balance::Rcb));
        let named = |name: &str| {
            DecompositionKeys {
                balance: name.into(),
            }
            .balance()
        };
        assert_eq!(named("uniform"), Ok(Balance::Uniform));
        assert_eq!(
            named("even"),
            Err("decomposition.balance 'even' is unknown; expected \"rcb\" or \"uniform\"".into())
        );
    }

    #[test]
    fn a_choice_is_found_or_the_options_are_named() {
        let options = [("square", 4), ("hex", 6), ("round", 0)];
        assert_eq!(choice("run.cells", "hex", &options), Ok(6));
        assert_eq!(
            choice("run.cells", "oval", &options),
            Err("run.cells 'oval' is unknown; expected \"square\", \"hex\" or \"round\"".into())
        );
        assert_eq!(
            choice("run.cells", "oval", &options[..2]),
            Err("run.cells 'oval' is unknown; expected \"square\" or \"hex\"".into())
        );
        assert_eq!(
            choice("pair.style", "lj", &[("lj/cut", ())]),
            Err("pair.style 'lj' is unknown; expected \"lj/cut\"".into())
        );
    }
}
