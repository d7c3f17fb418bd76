//! End-to-end runs of the studies (issue 16): `cellist convergence` on seed 004's
//! two bodies and on the PSE sine mode (the observed orders of the integrators),
//! `cellist scaling` (its table and picture), `cellist sweep` over two keys (a CSV
//! row per combination and a picture), and bad input that runs nothing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod common;
use common::{cellist, example};

fn text(bytes: &[u8]) -> String {
    String::from_utf8(bytes.to_vec()).unwrap()
}

/// Runs `cellist args`, asserting success; returns standard output.
fn ok(args: &[&str]) -> String {
    let o = cellist(args);
    assert!(
        o.status.success(),
        "cellist {}: {}\n{}",
        args.join(" "),
        text(&o.stdout),
        text(&o.stderr)
    );
    text(&o.stdout)
}

/// A CSV file as its header and its columns by name (text cells).
fn csv(path: &Path) -> (Vec<String>, BTreeMap<String, Vec<String>>) {
    let body = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = body.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut cols: BTreeMap<String, Vec<String>> =
        header.iter().map(|n| (n.clone(), Vec::new())).collect();
    for line in lines {
        // quoted fields (lists) hold commas
        let mut fields = Vec::new();
        let (mut cur, mut quoted) = (String::new(), false);
        for c in line.chars() {
            match c {
                '"' => quoted = !quoted,
                ',' if !quoted => fields.push(std::mem::take(&mut cur)),
                c => cur.push(c),
            }
        }
        fields.push(cur);
        assert_eq!(fields.len(), header.len(), "{line}");
        for (n, v) in header.iter().zip(fields) {
            cols.get_mut(n).unwrap().push(v);
        }
    }
    (header, cols)
}

fn is_png(path: &Path) -> bool {
    std::fs::read(path).is_ok_and(|b| b.len() > 8 && &b[1..4] == b"PNG")
}

/// The observed order of the finest pair in `convergence.csv`, from the
/// differences or the errors.
fn finest_order(dir: &Path, column: &str) -> f64 {
    let (_, cols) = csv(&dir.join("convergence.csv"));
    cols[column]
        .iter()
        .filter_map(|v| v.parse::<f64>().ok())
        .rfind(|v| !v.is_nan())
        .unwrap_or_else(|| panic!("no {column} in {}", dir.display()))
}

fn convergence(dir: &Path, name: &str, scenario: &str, flags: &[&str]) -> PathBuf {
    let out = dir.join(name);
    let mut args = vec!["convergence", scenario, "--out", out.to_str().unwrap()];
    args.extend_from_slice(flags);
    let stdout = ok(&args);
    assert!(
        stdout.contains("observed order from successive differences"),
        "{stdout}"
    );
    assert!(is_png(&out.join("convergence.png")));
    out
}

#[test]
fn seed_004_two_bodies_converge_at_order_one_for_euler_and_two_for_leapfrog() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = example("gravity-two-body.toml");
    let flags = [
        "--dt",
        "0.004",
        "--halvings",
        "3",
        "--observable",
        "velocity",
    ];
    let euler = convergence(dir.path(), "euler", &scenario, &flags);
    let p = finest_order(&euler, "order_difference");
    assert!((p - 1.0).abs() <= 0.1, "explicit Euler: order {p}");
    let mut leapfrog_flags = flags.to_vec();
    leapfrog_flags.extend(["--set", "run.integrator=leapfrog"]);
    let leapfrog = convergence(dir.path(), "leapfrog", &scenario, &leapfrog_flags);
    let p = finest_order(&leapfrog, "order_difference");
    assert!((p - 2.0).abs() <= 0.1, "leapfrog: order {p}");
    // 4 runs at dt/2^k to t = 15
    let (_, cols) = csv(&euler.join("convergence.csv"));
    assert_eq!(cols["steps"], ["3750", "7500", "15000", "30000"]);
}

#[test]
fn pse_sine_mode_converges_at_order_four_for_rk4_and_two_for_rk2() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = example("pse-sine.toml");
    for (integrator, order, tolerance) in [("rk4", 4.0, 0.2), ("rk2", 2.0, 0.1)] {
        let set = format!("run.integrator={integrator}");
        let flags = [
            "--dt",
            "1e-3",
            "--end-time",
            "0.01",
            "--halvings",
            "3",
            "--observable",
            "field",
            "--exact",
            "--set",
            "system.lattice.n=16",
            "--set",
            "system.epsilon=0.0625",
            "--set",
            &set,
        ];
        let out = convergence(dir.path(), integrator, &scenario, &flags);
        let p = finest_order(&out, "order_difference");
        assert!((p - order).abs() <= tolerance, "{integrator}: order {p}");
        // the errors against the exact solution are there (dominated by the
        // fixed spatial error: eps = h = 1/16)
        let (_, cols) = csv(&out.join("convergence.csv"));
        let errors: Vec<f64> = cols["error"].iter().map(|v| v.parse().unwrap()).collect();
        assert!(errors.iter().all(|e| *e > 0.0 && *e < 0.1), "{errors:?}");
    }
}

#[test]
fn scaling_prints_speed_up_efficiency_and_serial_fraction_and_draws_them() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scaling");
    let stdout = ok(&[
        "scaling",
        &example("lj-melt.toml"),
        "--threads",
        "1,2,3",
        "--repeat",
        "1",
        "--set",
        "system.lattice.cells=[5,5,5]",
        "--set",
        "run.steps=20",
        "--out",
        out.to_str().unwrap(),
    ]);
    for words in [
        "speed-up",
        "efficiency",
        "serial fraction",
        "Force",
        "Neighbor",
    ] {
        assert!(stdout.contains(words), "{words}: {stdout}");
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if cores < 3 {
        assert!(stdout.contains("oversubscribed"), "{stdout}");
    }
    assert!(is_png(&out.join("scaling.png")));
    let (header, cols) = csv(&out.join("scaling.csv"));
    assert_eq!(
        header,
        [
            "section",
            "threads",
            "median_s",
            "min_s",
            "max_s",
            "speedup",
            "efficiency",
            "serial_fraction"
        ]
    );
    let loop_rows: Vec<usize> = (0..cols["section"].len())
        .filter(|&k| cols["section"][k] == "loop")
        .collect();
    assert_eq!(loop_rows.len(), 3);
    let first = loop_rows[0];
    assert_eq!(cols["speedup"][first], "1");
    let f: f64 = cols["serial_fraction"][first].parse().unwrap();
    assert!((0.0..=1.0).contains(&f), "{f}");
}

#[test]
fn sweep_over_two_keys_writes_a_row_per_combination_and_a_picture() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sweep");
    let stdout = ok(&[
        "sweep",
        &example("pse-sine.toml"),
        "--set",
        "system.lattice.n=16,32",
        "--set",
        "system.method=direct,cell-list",
        "--set",
        "run.steps=3",
        "--threads",
        "1,2",
        "--metric",
        "time",
        "--metric",
        "error",
        "--metric",
        "total.drift",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(stdout.contains("system.lattice.n"), "{stdout}");
    let (header, cols) = csv(&out.join("sweep.csv"));
    assert_eq!(
        header,
        [
            "system.lattice.n",
            "system.method",
            "run.steps",
            "threads",
            "time",
            "error",
            "total.drift"
        ]
    );
    assert_eq!(
        cols["system.lattice.n"],
        ["16", "16", "16", "16", "32", "32", "32", "32"]
    );
    assert_eq!(
        cols["system.method"],
        [
            "direct",
            "direct",
            "cell-list",
            "cell-list",
            "direct",
            "direct",
            "cell-list",
            "cell-list"
        ]
    );
    assert_eq!(cols["threads"], ["1", "2", "1", "2", "1", "2", "1", "2"]);
    let value = |name: &str, k: usize| cols[name][k].parse::<f64>().unwrap();
    for k in 0..8 {
        assert!(value("time", k) > 0.0);
        assert!(value("error", k) > 0.0 && value("error", k) < 0.1);
        // PSE conserves the total to rounding
        assert!(value("total.drift", k) < 1e-9);
    }
    // the thread count changes no bit of the error
    for k in (0..8).step_by(2) {
        assert_eq!(cols["error"][k], cols["error"][k + 1]);
    }
    for png in ["sweep.png", "sweep-error.png", "sweep-total.drift.png"] {
        assert!(is_png(&out.join(png)), "{png}");
    }
    assert!(out.join("runs/008/thermo.csv").is_file());
}

#[test]
fn bad_study_input_runs_nothing_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = example("pse-sine.toml");
    let out = dir.path().join("study");
    let o = out.to_str().unwrap();
    let cases: Vec<Vec<&str>> = vec![
        vec!["sweep", &scenario, "--set", "system.nope=1,2", "--out", o],
        vec!["sweep", &scenario, "--set", "run.dt=1e-6,abc", "--out", o],
        vec!["sweep", &scenario, "--set", "run.dt=", "--out", o],
        // the probe sees the values given, run.steps too
        vec!["sweep", &scenario, "--set", "run.steps=3,-1", "--out", o],
        vec![
            "sweep",
            &scenario,
            "--set",
            "run.dt=1e-6,2e-6",
            "--set",
            "run.dt=3e-6",
            "--out",
            o,
        ],
        vec![
            "sweep",
            &scenario,
            "--set",
            "run.dt=1e-6,2e-6",
            "--metric",
            "etotal",
            "--out",
            o,
        ],
        vec!["sweep", &scenario, "--threads", "0,1", "--out", o],
        vec![
            "convergence",
            &scenario,
            "--dt",
            "1e-6",
            "--halvings",
            "0",
            "--observable",
            "field",
            "--out",
            o,
        ],
        vec![
            "convergence",
            &scenario,
            "--dt",
            "1e-6",
            "--halvings",
            "2",
            "--observable",
            "etotal",
            "--out",
            o,
        ],
        vec!["scaling", &scenario, "--threads", "1,0", "--out", o],
    ];
    for args in cases {
        let result = cellist(&args);
        assert_eq!(
            result.status.code(),
            Some(2),
            "{args:?}: {}",
            text(&result.stderr)
        );
        let err = text(&result.stderr);
        assert!(err.starts_with("error: --"), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
}

#[test]
fn scaling_takes_a_collision_benchmark_input() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("discs.in");
    ok(&[
        "billiards",
        "gen",
        "2000",
        "3000",
        "5",
        "10",
        "2",
        "5",
        "--overlaps",
        "--output",
        input.to_str().unwrap(),
    ]);
    let out = dir.path().join("scaling");
    let stdout = ok(&[
        "scaling",
        input.to_str().unwrap(),
        "--threads",
        "1,2",
        "--repeat",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        stdout.contains("billiards") && stdout.contains("Step"),
        "{stdout}"
    );
    assert!(is_png(&out.join("scaling.png")));
    // the runs leave the energy at the first and last step
    let thermo = std::fs::read_to_string(out.join("runs/001/thermo.csv")).unwrap();
    assert_eq!(thermo.lines().count(), 3, "{thermo}");
    let bad = cellist(&[
        "scaling",
        input.to_str().unwrap(),
        "--threads",
        "1,2",
        "--set",
        "run.steps=3",
    ]);
    assert_eq!(bad.status.code(), Some(2));
}
