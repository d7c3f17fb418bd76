//! MPI test of the command line (feature `mpi`; its own binary, run directly,
//! not under mpirun: it starts `mpirun` itself). `cellist run` on one rank is
//! the plain run; on several ranks it stops with one message from rank 0 and a
//! non-zero status on every rank, never a hang. Ends with `N passed, N failed`.
//!
//! ```text
//! cargo test --release -p cellist-cli --features mpi --test mpi_cli
//! ```

use std::path::Path;

mod common;
use common::example;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// `mpirun -np RANKS cellist ARGS`, killed after a minute (a hang fails).
fn mpirun(ranks: usize, args: &[&str]) -> Result<Output, String> {
    let mut child = Command::new("mpirun")
        .args([
            "--allow-run-as-root",
            "--oversubscribe",
            "-np",
            &ranks.to_string(),
        ])
        .arg(env!("CARGO_BIN_EXE_cellist"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("mpirun does not start: {e}"))?;
    let start = Instant::now();
    while child.try_wait().map_err(|e| e.to_string())?.is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            return Err(format!("mpirun -np {ranks} {args:?} hung for a minute"));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    child.wait_with_output().map_err(|e| e.to_string())
}

fn one_rank_is_the_plain_run(dir: &Path) -> Result<(), String> {
    let (one, plain) = (dir.join("one"), dir.join("plain"));
    let scenario = example("gravity-two-body.toml");
    let o = mpirun(1, &["run", &scenario, "--out", one.to_str().unwrap()])?;
    if !o.status.success() {
        return Err(format!("-np 1: {}", String::from_utf8_lossy(&o.stderr)));
    }
    let p = Command::new(env!("CARGO_BIN_EXE_cellist"))
        .args(["run", &scenario, "--out", plain.to_str().unwrap()])
        .output()
        .map_err(|e| e.to_string())?;
    if !p.status.success() {
        return Err("the plain run failed".into());
    }
    for file in ["thermo.csv", "two-body.dump"] {
        let a = std::fs::read(one.join(file)).map_err(|e| e.to_string())?;
        let b = std::fs::read(plain.join(file)).map_err(|e| e.to_string())?;
        if a != b {
            return Err(format!("{file} differs between -np 1 and the plain run"));
        }
    }
    Ok(())
}

/// Several ranks: a non-zero status and `expected` once on standard error.
fn refused_once(ranks: usize, args: &[&str], expected: &str) -> Result<(), String> {
    let o = mpirun(ranks, args)?;
    let err = String::from_utf8_lossy(&o.stderr);
    let lines = err.lines().filter(|l| l.starts_with("error: ")).count();
    if o.status.success() {
        return Err(format!("-np {ranks} {args:?} succeeded"));
    }
    if lines != 1 || !err.contains(expected) {
        return Err(format!(
            "-np {ranks} {args:?}: expected one `error: ...{expected}...` line, got:\n{err}"
        ));
    }
    Ok(())
}

fn main() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let scenario = example("lj-melt.toml");
    let cases: Vec<(&str, Result<(), String>)> = vec![
        (
            "-np 1 writes the bytes of the plain run",
            one_rank_is_the_plain_run(dir.path()),
        ),
        (
            "-np 2: a model not distributed yet, one message",
            refused_once(
                2,
                &["run", &scenario, "--set", "run.steps=5"],
                "does not run on 2 MPI ranks yet",
            ),
        ),
        (
            "-np 4: a missing scenario, one message",
            refused_once(
                4,
                &["run", "no-such-scenario.toml"],
                "no-such-scenario.toml: cannot read",
            ),
        ),
        (
            "-np 2: a command other than run, one message",
            refused_once(
                2,
                &["bench", "lj", "--steps", "1"],
                "only `cellist run` runs on several MPI ranks",
            ),
        ),
    ];
    let (mut passed, mut failed) = (0, 0);
    for (name, result) in cases {
        match result {
            Ok(()) => {
                passed += 1;
                println!("ok   {name}");
            }
            Err(why) => {
                failed += 1;
                println!("FAIL {name}: {why}");
            }
        }
    }
    println!("{passed} passed, {failed} failed");
    if failed > 0 {
        std::process::exit(1);
    }
}
