//! `cellist_sim::billiards::check`, the course's grader, against its own
//! script `check_traj.py`: trajectories with the mistakes it must catch fail at
//! the step the script names.

use cellist::models::billiards::{ContactGrid, Separation, Table};
use cellist::Threads;
use cellist_sim::billiards::{check, Verdict};
use std::path::{Path, PathBuf};
use std::process::Command;

/// `../shared/testdata/<name>`, or `None` with a message when it is absent.
fn shared_testdata(name: &str) -> Option<PathBuf> {
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

/// A Python 3 with numpy, for the benchmark's own scripts.
fn python() -> Option<String> {
    let candidates = [
        std::env::var("CELLIST_PYTHON").unwrap_or_default(),
        "python3".into(),
        "/usr/bin/python3".into(),
    ];
    let found = candidates.into_iter().filter(|c| !c.is_empty()).find(|c| {
        Command::new(c)
            .args(["-c", "import numpy"])
            .output()
            .is_ok_and(|o| o.status.success())
    });
    if found.is_none() {
        eprintln!("skipped: no python3 with numpy (.ci/run installs python3-numpy)");
    }
    found
}

/// The mistakes the course's grader must catch.
#[derive(Clone, Copy, Debug)]
enum Mistake {
    NoResolution,
    OneSweep,
    ResolveBeforeMove,
    ExtraEnergy,
}

/// Writes a trajectory of `steps` steps made with `mistake`, in the 8-decimal form.
fn broken_trajectory(input: &cellist_io::BilliardsInput, steps: u64, mistake: Mistake, out: &Path) {
    let table = Table {
        side: input.side,
        radius: input.radius,
    };
    let (mut x, mut y, mut v) = (input.x.clone(), input.y.clone(), input.v.clone());
    let mut text = Vec::new();
    let mut grid = ContactGrid::default();
    let mut contacts = Vec::new();
    // one canonical sweep, or sweeps until settled, at the current positions
    let mut resolve = |x: &[f64], y: &[f64], v: &mut Vec<[f64; 2]>, sweeps: usize| {
        grid.find(x, y, table.contact(), &Threads::single(), &mut contacts);
        for _ in 0..sweeps {
            let mut changed = false;
            for k in 0..x.len() {
                let w = table.walls_at(x[k], y[k]);
                if w.collides(&v[k]) {
                    w.resolve(&mut v[k]);
                    changed = true;
                }
            }
            for c in &contacts {
                let (a, b) = (c.a as usize, c.b as usize);
                let sep = Separation::between([x[a], y[a]], [x[b], y[b]]);
                let (head, tail) = v.split_at_mut(b);
                changed |= sep.collide(&mut head[a], &mut tail[0]);
            }
            if !changed {
                break;
            }
        }
    };
    for step in 1..=steps {
        let moves = |x: &mut Vec<f64>, y: &mut Vec<f64>, v: &[[f64; 2]]| {
            for k in 0..x.len() {
                x[k] += v[k][0];
                y[k] += v[k][1];
            }
        };
        match mistake {
            Mistake::NoResolution => moves(&mut x, &mut y, &v),
            Mistake::OneSweep => {
                moves(&mut x, &mut y, &v);
                resolve(&x, &y, &mut v, 1);
            }
            Mistake::ResolveBeforeMove => {
                resolve(&x, &y, &mut v, usize::MAX);
                moves(&mut x, &mut y, &v);
            }
            Mistake::ExtraEnergy => {
                moves(&mut x, &mut y, &v);
                resolve(&x, &y, &mut v, usize::MAX);
                if step == 1 {
                    for w in v.iter_mut() {
                        *w = [w[0] * 1.01f64.sqrt(), w[1] * 1.01f64.sqrt()];
                    }
                }
            }
        }
        cellist_io::write_state(
            &mut text,
            cellist_io::StateFormat::Fixed8,
            step,
            &input.ids,
            &x,
            &y,
            &v,
        )
        .unwrap();
    }
    std::fs::write(out, text).unwrap();
}

/// The step a verdict line names: `FAIL at step k: ...`.
fn failing_step(verdict: &str) -> Option<u64> {
    verdict
        .strip_prefix("FAIL at step ")?
        .split(':')
        .next()?
        .parse()
        .ok()
}

#[test]
fn the_checker_rejects_broken_runs_where_check_traj_py_does() {
    let Some(data) = shared_testdata("billiards") else {
        return;
    };
    let python = python();
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("small/random80.in", 3, Mistake::NoResolution, 1),
        ("small/random80.in", 3, Mistake::OneSweep, 1),
        ("small/random80.in", 3, Mistake::ResolveBeforeMove, 1),
        ("small/random80.in", 3, Mistake::ExtraEnergy, 1),
        ("standard/10k_density_0.7.in", 2, Mistake::NoResolution, 1),
        ("standard/10k_density_0.7.in", 2, Mistake::OneSweep, 1),
        ("correctness/cradle.in", 300, Mistake::NoResolution, 201),
    ];
    for (name, steps, mistake, expected) in cases {
        let path = data.join("inputs").join(name);
        let input = cellist_io::read_billiards_input(&path).unwrap();
        let traj = dir.path().join("broken.viz");
        broken_trajectory(&input, steps, mistake, &traj);
        let verdict = match check(&path, &traj, &Threads::single()).unwrap() {
            Verdict::Fail(verdict) => verdict,
            pass => panic!("{name} {mistake:?}: {pass:?}"),
        };
        assert_eq!(
            failing_step(&verdict),
            Some(expected),
            "{name} {mistake:?}: {verdict}"
        );
        if let Some(python) = &python {
            let theirs = Command::new(python)
                .arg(data.join("check_traj.py"))
                .args([path.to_str().unwrap(), traj.to_str().unwrap()])
                .output()
                .unwrap();
            assert_eq!(theirs.status.code(), Some(1), "{name} {mistake:?}");
            assert_eq!(
                failing_step(&String::from_utf8_lossy(&theirs.stdout)),
                Some(expected),
                "check_traj.py on {name} {mistake:?}"
            );
        }
    }
}
