//! `summary.json` (issue 43): every `cellist run` writes it into its output
//! folder, for every model, with the contract's keys; a restart counts its
//! steps from the checkpoint, and a blow-up writes it too, saying so.

mod common;

use common::{cellist, ok, run_scenario, text, HOT_MELT};
use serde_json::Value;
use std::path::Path;

/// Every key of the contract, in the file's order.
const KEYS: [&str; 17] = [
    "cellist_version",
    "model",
    "scenario",
    "outcome",
    "first_step",
    "last_step",
    "steps",
    "particles",
    "threads",
    "ranks",
    "wall_seconds",
    "loop_seconds",
    "stage_seconds",
    "communication_seconds",
    "imbalance_particles",
    "imbalance_busy",
    "peak_rss_bytes",
];

/// `out/summary.json`, its keys checked against the contract.
fn summary(out: &Path) -> Value {
    let path = out.join("summary.json");
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let json: Value = serde_json::from_slice(&bytes).expect("summary.json is JSON");
    let keys: Vec<&str> = json
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    let mut expected = KEYS.to_vec();
    expected.sort_unstable();
    assert_eq!(keys, expected, "{json}");
    json
}

/// The figures every run has, and the MPI ones null in one process.
fn check_run(json: &Value, model: &str, scenario: &Path, steps: u64, particles: u64) {
    assert_eq!(json["cellist_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(json["model"], model);
    assert_eq!(json["scenario"], scenario.display().to_string());
    assert_eq!(json["outcome"], "completed");
    assert_eq!(json["first_step"], 0);
    assert_eq!(json["last_step"], steps);
    assert_eq!(json["steps"], steps, "{json}");
    assert_eq!(json["particles"], particles, "{json}");
    assert_eq!(json["threads"], 1);
    assert_eq!(json["ranks"], 1);
    let loop_seconds = json["loop_seconds"].as_f64().unwrap();
    assert!(loop_seconds > 0.0, "{json}");
    assert!(
        json["wall_seconds"].as_f64().unwrap() >= loop_seconds,
        "{json}"
    );
    let stages = json["stage_seconds"].as_object().unwrap();
    let names: Vec<&str> = stages.keys().map(String::as_str).collect();
    assert!(
        names.contains(&"Output") && names.contains(&"Other"),
        "{json}"
    );
    let sum: f64 = stages.values().map(|s| s.as_f64().unwrap()).sum();
    assert!(
        (sum - loop_seconds).abs() <= 1e-6 * loop_seconds.max(1.0),
        "{json}"
    );
    for key in [
        "communication_seconds",
        "imbalance_particles",
        "imbalance_busy",
    ] {
        assert!(json[key].is_null(), "{key} in one process: {json}");
    }
    assert!(json["peak_rss_bytes"].as_u64().unwrap() > 0, "{json}");
}

const MD: &str =
    "model = \"md\"\n[system]\nlattice = { kind = \"fcc\", density = 0.8442, cells = [4, 4, 4] }\n\
velocity = { temperature = 3.0, seed = 87287 }\n[run]\nsteps = 20\n[output]\nthermo_every = 10\n\
checkpoint = { every = 10, file = \"state.ckpt\" }\n";

const PSE: &str = "model = \"pse\"\ndimension = 2\n[system]\nlattice = { n = 24 }\nnu = 1.0\n\
epsilon = 0.05\ncutoff_factor = 5.0\nmethod = \"cell-list\"\n\
initial = { kind = \"gaussian\", center = [0.5, 0.5], width = 0.1 }\n[run]\nsteps = 6\ndt = 1e-4\n\
[output]\nthermo_every = 3\n";

const GRAVITY: &str =
    "model = \"gravity\"\n[system]\ninitial = { kind = \"plummer\", n = 50, seed = 1 }\n\
softening = 0.1\n[run]\nsteps = 5\ndt = 0.01\n[output]\nthermo_every = 5\n";

const VORTEX: &str = "model = \"vortex\"\ndimension = 2\n[system]\n\
initial = { kind = \"gaussian\", circulation = 1.0, core = 0.2, spacing = 0.1, extent = 0.8 }\n\
nu = 0.0\nvelocity = { kind = \"direct\" }\n[run]\nsteps = 4\ndt = 0.02\n[output]\nthermo_every = 2\n\
field = { every = 4, file = \"w.csv\" }\npicture_size = 32\n";

#[test]
fn every_model_writes_its_summary() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("discs.in");
    let gen = [
        "billiards",
        "gen",
        "200",
        "100",
        "1",
        "10",
        "-1",
        "1",
        "--output",
    ];
    let mut args = gen.to_vec();
    args.push(input.to_str().unwrap());
    ok(&cellist(&args));
    let billiards = format!(
        "model = \"billiards\"\ninput = \"{}\"\n[run]\nsteps = 10\n[output]\nthermo_every = 5\n",
        input.display()
    );
    for (name, scenario, steps, particles) in [
        ("md", MD, 20, 256),
        ("pse", PSE, 6, 24 * 24),
        ("gravity", GRAVITY, 5, 50),
        ("vortex", VORTEX, 4, 0),
        ("billiards", billiards.as_str(), 10, 200),
    ] {
        let (out, run) = run_scenario(dir.path(), name, scenario, &["--threads", "1"]);
        ok(&run);
        let json = summary(&out);
        // the vortex particles: the rows of the last field file
        let particles = if name == "vortex" {
            let field = std::fs::read_to_string(out.join("w_4.csv")).unwrap();
            field.lines().count() as u64 - 1
        } else {
            particles
        };
        let scenario = dir.path().join(format!("{name}.toml"));
        check_run(&json, name, &scenario, steps, particles);
    }
}

#[test]
fn the_md_stages_are_those_of_the_speed_line() {
    let dir = tempfile::tempdir().unwrap();
    let (out, run) = run_scenario(dir.path(), "md", MD, &[]);
    ok(&run);
    let json = summary(&out);
    let names: Vec<&str> = json["stage_seconds"]
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    // serde_json's map sorts its keys; the file keeps the table's order
    let file = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let at = |name: &str| file.find(&format!("\"{name}\":")).unwrap();
    for name in &names {
        assert!(
            text(&run.stdout).contains(&format!("\n{name:<10} |")),
            "{name}"
        );
    }
    assert!(at("Neighbor") < at("Force") && at("Force") < at("Integrate"));
    assert!(at("Integrate") < at("Output") && at("Output") < at("Other"));
}

#[test]
fn a_restart_counts_its_steps_from_the_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let (out, run) = run_scenario(dir.path(), "md", MD, &["--set", "run.steps=10"]);
    ok(&run);
    let ckpt = out.join("state.ckpt");
    let (_, run) = run_scenario(dir.path(), "md", MD, &["--restart", ckpt.to_str().unwrap()]);
    ok(&run);
    let json = summary(&out);
    assert_eq!(json["first_step"], 10, "{json}");
    assert_eq!(json["last_step"], 20, "{json}");
    assert_eq!(json["steps"], 10, "{json}");
    assert_eq!(json["outcome"], "completed");
}

#[test]
fn a_blow_up_writes_what_was_done_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let (out, run) = run_scenario(dir.path(), "hot", HOT_MELT, &[]);
    assert_eq!(run.status.code(), Some(3), "{}", text(&run.stderr));
    let err = text(&run.stderr);
    let step: u64 = err
        .split("step ")
        .nth(1)
        .and_then(|s| s.split(':').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no step in: {err}"));
    let json = summary(&out);
    assert_eq!(json["outcome"], "blow-up", "{json}");
    assert_eq!(json["first_step"], 0);
    assert_eq!(json["last_step"], step, "{json}");
    assert_eq!(json["steps"], step, "{json}");
    assert_eq!(json["particles"], 256);
    assert!(json["loop_seconds"].as_f64().unwrap() > 0.0);
    assert!(json["peak_rss_bytes"].as_u64().unwrap() > 0);
}

const VORTEX3: &str = "model = \"vortex\"\ndimension = 3\n[system]\n\
initial = { kind = \"ring\", radius = 1.0, circulation = 1.0, core = 0.4, spacing = 0.2 }\n\
velocity = { kind = \"direct\" }\nremesh_every = 1\n[run]\nsteps = 2\ndt = 0.05\n\
integrator = \"rk2\"\n[output]\nthermo_every = 1\npicture_size = 32\n";

/// The seconds of every stage of `json`.
fn stage_seconds(json: &Value) -> Vec<(String, f64)> {
    let stages = json["stage_seconds"].as_object().unwrap();
    stages
        .iter()
        .map(|(name, s)| (name.clone(), s.as_f64().unwrap()))
        .collect()
}

#[test]
fn the_vortex_stages_count_the_steps_only() {
    // the rate of the set-up (and of a restored state) is not a step's: a
    // run of no steps spent nothing in them, and a run's stages add up to
    // its loop (before, the set-up's velocity evaluation was counted in)
    let dir = tempfile::tempdir().unwrap();
    for (name, scenario) in [("vortex2", VORTEX), ("vortex3", VORTEX3)] {
        let (out, run) = run_scenario(dir.path(), name, scenario, &["--set", "run.steps=0"]);
        ok(&run);
        let json = summary(&out);
        for (stage, seconds) in stage_seconds(&json) {
            if stage != "Other" {
                assert_eq!(seconds, 0.0, "{name}: {stage}: {json}");
            }
        }
        let (out, run) = run_scenario(dir.path(), name, scenario, &[]);
        ok(&run);
        let json = summary(&out);
        let loop_seconds = json["loop_seconds"].as_f64().unwrap();
        let stages = stage_seconds(&json);
        let sum: f64 = stages.iter().map(|(_, s)| s).sum();
        let known = sum - stages.iter().find(|(n, _)| n == "Other").unwrap().1;
        assert!(known <= loop_seconds, "{name}: {json}");
        assert!((sum - loop_seconds).abs() <= 1e-6, "{name}: {json}");
    }
}
