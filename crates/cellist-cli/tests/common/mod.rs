//! Helpers shared by the end-to-end tests.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the built `cellist` binary.
pub fn cellist(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cellist"))
        .args(args)
        .output()
        .expect("cellist runs")
}

/// `../shared/testdata/<name>`, or `None` with a message when it is absent (not
/// every test crate reads shared data).
#[allow(dead_code)]
pub fn shared_testdata(name: &str) -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/testdata")
        .join(name);
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "skipped: {} is absent (the shared test data sits beside the project)",
            dir.display()
        );
        None
    }
}

/// Writes `scenario` to `dir/<name>.toml` and runs it with `--out dir/<name>` and
/// the `extra` flags; returns the output folder and the run.
#[allow(dead_code)]
pub fn run_scenario(dir: &Path, name: &str, scenario: &str, extra: &[&str]) -> (PathBuf, Output) {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, scenario).unwrap();
    let out = dir.join(name);
    let mut args = vec![
        "run",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    (out.clone(), cellist(&args))
}

/// Every file below `dir` (relative name -> bytes).
#[allow(dead_code)]
pub fn files(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let name = path.strip_prefix(dir).unwrap().to_path_buf();
                out.insert(name, std::fs::read(&path).unwrap());
            }
        }
    }
    out
}

/// Every file below `dir` but `summary.json`, whose times differ from run to
/// run: the files that two runs of the same steps write with the same bytes.
#[allow(dead_code)]
pub fn outputs(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = files(dir);
    out.remove(Path::new("summary.json"));
    out
}

/// `examples/<name>` of the repository.
#[allow(dead_code)]
pub fn example(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(name)
        .display()
        .to_string()
}

/// Standard output or error as text.
#[allow(dead_code)]
pub fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Asserts that a run succeeded, showing its status and standard error if not.
#[allow(dead_code)]
pub fn ok(run: &Output) {
    assert!(
        run.status.success(),
        "status {:?}\n{}",
        run.status.code(),
        text(&run.stderr)
    );
}

/// Runs `scenario` (with `extra` flags) in `dir/name`, asserting success, and
/// returns its output folder.
#[allow(dead_code)]
pub fn ok_run(dir: &Path, name: &str, scenario: &str, extra: &[&str]) -> PathBuf {
    let (out, o) = run_scenario(dir, name, scenario, extra);
    assert!(
        o.status.success(),
        "{name}: {}\n{}",
        text(&o.stdout),
        text(&o.stderr)
    );
    out
}

/// A CSV file as its header and columns by name.
#[allow(dead_code)]
pub fn csv_columns(path: &Path) -> (String, BTreeMap<String, Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let names: Vec<String> = header.split(',').map(str::to_string).collect();
    let mut cols: BTreeMap<String, Vec<f64>> = names.iter().map(|n| (n.clone(), vec![])).collect();
    for line in lines {
        for (name, v) in names.iter().zip(line.split(',')) {
            cols.get_mut(name).unwrap().push(v.parse().unwrap());
        }
    }
    (header, cols)
}

/// An md scenario whose atoms start far too hot for its step: the run blows
/// up within a few steps (an atom leaves through the fixed z boundary).
#[allow(dead_code)]
pub const HOT_MELT: &str = "model = \"md\"\n[system]\nlattice = { kind = \"fcc\", density = 1.2, cells = [4, 4, 4] }\n\
    velocity = { temperature = 1e6, seed = 5 }\nboundary = [\"p\", \"p\", \"f\"]\n[run]\nsteps = 50\ndt = 0.05\n\
    [output]\nthermo_every = 1\n";
