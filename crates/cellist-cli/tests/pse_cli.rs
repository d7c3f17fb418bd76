//! End-to-end runs of `cellist run` with `model = "pse"` and of `cellist bench pse`:
//! outputs, thread independence, conservation, restart from a field file, and
//! errors.

use std::path::Path;

mod common;
use common::{cellist, run_scenario as run};

fn text(bytes: &[u8]) -> String {
    String::from_utf8(bytes.to_vec()).unwrap()
}

const SCENARIO: &str = r#"
model = "pse"
dimension = 2
[system]
lattice = { n = 24, jitter = 0.3, seed = 5 }
nu = 1.0
epsilon = 0.05
cutoff_factor = 5.0
method = "cell-list"
initial = { kind = "gaussian", center = [0.3, 0.6], width = 0.1 }
[run]
steps = 40
dt = 1e-4
integrator = "rk4"
[output]
thermo_every = 10
field = { every = 20, file = "field.csv" }
gif = { every = 10 }
"#;

fn thermo(out: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(out.join("thermo.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("step,time,total,l2_error,max_error"));
    lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

#[test]
fn a_run_writes_its_files_conserves_the_total_and_ignores_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut outs = Vec::new();
    for threads in ["1", "2"] {
        let (out, o) = run(
            dir.path(),
            &format!("t{threads}"),
            SCENARIO,
            &["--threads", threads],
        );
        assert!(o.status.success(), "{}", text(&o.stderr));
        outs.push(out);
    }
    for name in ["field_00.csv", "field_20.csv", "field_40.csv", "thermo.csv"] {
        let a = std::fs::read(outs[0].join(name)).unwrap();
        let b = std::fs::read(outs[1].join(name)).unwrap();
        assert!(a == b, "{name} differs between 1 and 2 threads");
    }
    for picture in ["field.gif", "field_00.png", "field_40.png", "error.png"] {
        assert!(outs[0].join(picture).exists(), "{picture}");
    }
    let rows = thermo(&outs[0]);
    assert_eq!(
        rows.iter().map(|r| r[0]).collect::<Vec<_>>(),
        [0.0, 10.0, 20.0, 30.0, 40.0]
    );
    let total = rows[0][2];
    for r in &rows {
        assert!(
            (r[2] - total).abs() <= 1e-12 * total.abs(),
            "{} vs {total}",
            r[2]
        );
    }
    // the error against the exact solution grows from zero but stays small
    assert_eq!(rows[0][3], 0.0);
    assert!(rows[4][3] > 0.0 && rows[4][3] < 1e-2, "{}", rows[4][3]);
    let field = std::fs::read_to_string(outs[0].join("field_40.csv")).unwrap();
    assert_eq!(field.lines().next(), Some("x,y,phi"));
    assert_eq!(field.lines().count(), 1 + 24 * 24);
}

#[test]
fn a_field_file_restarts_a_run() {
    let dir = tempfile::tempdir().unwrap();
    let (first, o) = run(dir.path(), "first", SCENARIO, &["--threads", "1"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let restart = SCENARIO
        .replace(
            "lattice = { n = 24, jitter = 0.3, seed = 5 }",
            &format!("particles = {:?}", first.join("field_40.csv")),
        )
        .replace(
            "initial = { kind = \"gaussian\", center = [0.3, 0.6], width = 0.1 }\n",
            "",
        );
    let (second, o) = run(
        dir.path(),
        "second",
        &restart,
        &["--threads", "1", "--set", "run.steps=0"],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    // the field read back is the field written, to the bit
    let a = std::fs::read(first.join("field_40.csv")).unwrap();
    let b = std::fs::read(second.join("field_0.csv")).unwrap();
    assert!(a == b);
    // no exact solution: the error columns are empty (nan)
    assert!(thermo(&second)[0][3].is_nan());
}

fn fails_with(scenario: &str, set: &str, expected: &str) {
    let dir = tempfile::tempdir().unwrap();
    let (_, o) = run(dir.path(), "bad", scenario, &["--set", set]);
    assert_eq!(o.status.code(), Some(2), "{set}: {}", text(&o.stderr));
    let err = text(&o.stderr);
    assert!(err.contains(expected), "{set}: {err}");
}

#[test]
fn bad_parameters_are_refused_with_exit_status_2() {
    fails_with(SCENARIO, "system.epsilon=0", "system.epsilon must be > 0");
    fails_with(SCENARIO, "system.epsilon=-1", "system.epsilon must be > 0");
    fails_with(SCENARIO, "system.nu=-0.5", "system.nu must be >= 0");
    fails_with(
        SCENARIO,
        "system.lattice.n=1",
        "at least 2 particles per side",
    );
    fails_with(
        SCENARIO,
        "system.cutoff_factor=1.5",
        "cutoff_factor must be >= 2",
    );
    fails_with(
        SCENARIO,
        "system.initial.kind=square",
        "initial.kind 'square' is unknown",
    );
    fails_with(SCENARIO, "system.method=tree", "method 'tree' is unknown");
    fails_with(
        SCENARIO,
        "run.integrator=rk3",
        "integrator 'rk3' is unknown",
    );
    fails_with(SCENARIO, "system.epsilon=0.2", "cutoff");
    fails_with(SCENARIO, "run.dt=0.01", "exceeds the stability limit");
}

#[test]
fn an_unstable_run_needs_the_override_and_stops_at_the_step_that_blows_up() {
    let dir = tempfile::tempdir().unwrap();
    let (out, o) = run(
        dir.path(),
        "unstable",
        SCENARIO,
        &[
            "--set",
            "run.dt=0.01",
            "--set",
            "run.allow_unstable=true",
            "--set",
            "run.steps=2000",
        ],
    );
    assert_eq!(o.status.code(), Some(3));
    let err = text(&o.stderr);
    assert!(
        err.contains("warning: run.dt = 0.01 exceeds the stability limit"),
        "{err}"
    );
    assert!(
        err.contains(": the field of particle") && err.contains("is not finite"),
        "{err}"
    );
    let step: u64 = err
        .split("step ")
        .nth(1)
        .unwrap()
        .split(':')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!(step > 1 && step < 2000, "{err}");
    assert!(out.join("last.csv").exists());
    assert!(out.join("thermo.csv").exists());
}

#[test]
fn bench_pse_reports_pairs_per_second() {
    for method in ["direct", "cell-list"] {
        let o = cellist(&[
            "bench",
            "pse",
            "--n-per-side",
            "20",
            "--dim",
            "2",
            "--method",
            method,
            "--repeat",
            "1",
            "--steps",
            "2",
            "--json",
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["particles"], 400);
        assert!(v["pair_kernels_per_second"].as_f64().unwrap() > 0.0);
        if method == "direct" {
            assert_eq!(v["pairs_per_step"], 400 * 399 / 2);
        }
    }
}
