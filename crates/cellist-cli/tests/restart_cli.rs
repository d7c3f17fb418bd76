//! Checkpoints and restarts (issue 14): a run of 2K steps and a run of K steps
//! restarted to 2K write the same bytes, for every model; also after the first run
//! was killed between two checkpoints. Bad checkpoints are refused with exit
//! status 2 and nothing is overwritten; a blow-up exits with 3 and leaves its last
//! good state.

mod common;

use common::{cellist, files, ok, outputs, run_scenario, text, HOT_MELT};
use std::path::{Path, PathBuf};
use std::process::Output;

/// The two folders hold the same files with the same bytes (but their
/// `summary.json`, whose times differ).
fn same_files(a: &Path, b: &Path) {
    let (fa, fb) = (outputs(a), outputs(b));
    assert_eq!(
        fa.keys().collect::<Vec<_>>(),
        fb.keys().collect::<Vec<_>>(),
        "file lists differ"
    );
    for (name, bytes) in &fa {
        assert!(bytes == &fb[name], "{} differs", name.display());
    }
}

/// Runs `scenario` for `2k` steps in one go and for `k` steps then restarted to
/// `2k`; asserts both output folders are identical byte for byte.
fn restart_matches(name: &str, scenario: &str, k: u64) {
    let dir = tempfile::tempdir().unwrap();
    let steps = |n: u64| format!("run.steps={n}");
    let (whole, run) = run_scenario(dir.path(), name, scenario, &["--set", &steps(2 * k)]);
    ok(&run);
    let split_name = format!("{name}-split");
    let (split, run) = run_scenario(dir.path(), &split_name, scenario, &["--set", &steps(k)]);
    ok(&run);
    let ckpt = split.join("state.ckpt");
    assert!(ckpt.is_file(), "no checkpoint at step {k}");
    let (_, run) = run_scenario(
        dir.path(),
        &split_name,
        scenario,
        &["--set", &steps(2 * k), "--restart", ckpt.to_str().unwrap()],
    );
    ok(&run);
    assert!(text(&run.stdout).contains(&format!("restart: from step {k}")));
    same_files(&whole, &split);
}

const MD_3D: &str = "model = \"md\"\n[system]\nlattice = { kind = \"fcc\", density = 0.8442, cells = [4, 4, 4] }\n\
velocity = { temperature = 3.0, seed = 87287 }\n[run]\nsteps = 40\ndt = 0.005\n\
[output]\nthermo_every = 5\ncheckpoint = { every = 10, file = \"state.ckpt\" }\n\
dump = { every = 5, file = \"d.lammpstrj\", columns = [\"id\", \"type\", \"x\", \"y\", \"z\", \"vx\", \"vy\", \"vz\", \"fx\", \"fy\", \"fz\", \"pe\"] }\n\
xyz = { every = 10, file = \"d.xyz\" }\n";

#[test]
fn md_velocity_verlet_restarts_bit_for_bit() {
    restart_matches("md3", MD_3D, 30);
}

#[test]
fn md_with_its_list_rebuilt_every_n_steps_restarts_bit_for_bit() {
    // the checkpoint at step 30 falls 2 steps after a build (every 7): the
    // restart must rebuild on steps 35, 42, ... as the whole run does
    let scenario = format!("{MD_3D}[neighbor]\nevery = 7\ncheck = false\n");
    restart_matches("md3-every", &scenario, 30);
}

#[test]
fn md_langevin_in_2d_restarts_bit_for_bit() {
    let scenario = "model = \"md\"\ndimension = 2\n[system]\nlattice = { kind = \"hex\", density = 0.7, cells = [12, 7] }\n\
        velocity = { temperature = 0.8, seed = 1 }\n[pair]\nstyle = \"lj/cut\"\ncutoff = 2.5\nshift = true\n\
        [run]\nsteps = 40\ndt = 0.005\nintegrator = \"langevin\"\nlangevin = { temperature = 0.8, damping = 1.0, seed = 7 }\n\
        [output]\nthermo_every = 4\nxyz = { every = 8, file = \"fluid.xyz\" }\ncheckpoint = { every = 16, file = \"state.ckpt\" }\n";
    restart_matches("md2", scenario, 24);
}

#[test]
fn pse_restarts_bit_for_bit_with_its_field_files_and_animation() {
    let scenario = "model = \"pse\"\n[system]\nlattice = { n = 24 }\nepsilon = 0.0625\ninitial = { kind = \"sine\", k = [1, 1] }\n\
        [run]\nsteps = 40\ndt = 2e-5\nintegrator = \"rk2\"\n\
        [output]\nthermo_every = 5\nfield = { every = 10, file = \"f.csv\" }\npng = { every = 10 }\ngif = { every = 5 }\npicture_size = 64\n\
        checkpoint = { every = 10, file = \"state.ckpt\" }\n";
    restart_matches("pse", scenario, 30);
}

#[test]
fn gravity_barnes_hut_restarts_bit_for_bit() {
    let scenario = "model = \"gravity\"\n[system]\ninitial = { kind = \"plummer\", n = 300, seed = 3 }\nsoftening = 0.05\n\
        solver = { kind = \"barnes-hut\", theta = 0.6 }\n[run]\nsteps = 40\ndt = 0.01\n\
        [output]\nthermo_every = 5\ndump = { every = 10, file = \"b.dump\" }\ncheckpoint = { every = 10, file = \"state.ckpt\" }\n";
    restart_matches("grav", scenario, 20);
}

fn billiards_input() -> Option<PathBuf> {
    common::shared_testdata("billiards").map(|d| d.join("inputs/sample.in"))
}

#[test]
fn billiards_restarts_bit_for_bit_with_its_trajectory_and_animation() {
    let Some(input) = billiards_input() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let run = |folder: &str, steps: u64, extra: &[&str]| {
        let d = dir.path().join(folder);
        std::fs::create_dir_all(&d).unwrap();
        let p = |f: &str| d.join(f).to_str().unwrap().to_string();
        let mut args: Vec<String> = [
            "billiards",
            "run",
            input.to_str().unwrap(),
            "--format",
            "bits",
            "--steps",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        args.push(steps.to_string());
        for (flag, file) in [
            ("--viz", "v.out"),
            ("--gif", "r.gif"),
            ("--png", "last.png"),
            ("--output", "final.out"),
            ("--checkpoint", "state.ckpt"),
        ] {
            args.push(flag.into());
            args.push(p(file));
        }
        args.extend(["--checkpoint-every".to_string(), "4".to_string()]);
        args.extend(extra.iter().map(|s| s.to_string()));
        let refs: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = cellist(&refs);
        ok(&out);
        d
    };
    let whole = run("whole", 24, &[]);
    let split = run("split", 12, &[]);
    let ckpt = split.join("state.ckpt");
    run("split", 24, &["--restart", ckpt.to_str().unwrap()]);
    // the checkpoints name the output files by the paths given, which differ
    // between the two folders: compare their steps and states, the rest byte for byte
    for name in ["state.ckpt", "state.ckpt.prev"] {
        let a = cellist_sim::checkpoint::read_checkpoint(&whole.join(name)).unwrap();
        let b = cellist_sim::checkpoint::read_checkpoint(&split.join(name)).unwrap();
        assert_eq!((a.step, &a.state), (b.step, &b.state), "{name}");
        std::fs::remove_file(whole.join(name)).unwrap();
        std::fs::remove_file(split.join(name)).unwrap();
    }
    same_files(&whole, &split);
}

#[test]
fn a_run_killed_between_checkpoints_restarts_to_the_same_bytes() {
    let scenario = MD_3D.replace("cells = [4, 4, 4]", "cells = [6, 6, 6]");
    let dir = tempfile::tempdir().unwrap();
    let steps = ["--set", "run.steps=4000", "--threads", "1"];
    let (whole, run) = run_scenario(dir.path(), "whole", &scenario, &steps);
    ok(&run);
    // the same run, killed (SIGKILL) once some checkpoints exist
    let path = dir.path().join("killed.toml");
    std::fs::write(&path, &scenario).unwrap();
    let out = dir.path().join("killed");
    let mut args = vec![
        "run",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(&steps);
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_cellist"))
        .args(&args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let ckpt = out.join("state.ckpt");
    let prev = out.join("state.ckpt.prev");
    let started = std::time::Instant::now();
    while !prev.exists() && started.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    std::thread::sleep(std::time::Duration::from_millis(37));
    child.kill().unwrap();
    let status = child.wait().unwrap();
    assert!(!status.success(), "the run finished before it was killed");
    let from = if ckpt.exists() { ckpt } else { prev };
    let mut args = vec![
        "run",
        path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(&steps);
    args.extend_from_slice(&["--restart", from.to_str().unwrap()]);
    ok(&cellist(&args));
    same_files(&whole, &out);
}

fn refused(run: &Output, message: &str) {
    assert_eq!(run.status.code(), Some(2), "{}", text(&run.stderr));
    let err = text(&run.stderr);
    assert!(err.contains(message), "expected '{message}' in: {err}");
}

#[test]
fn bad_checkpoints_are_refused_and_nothing_is_overwritten() {
    let dir = tempfile::tempdir().unwrap();
    let (out, run) = run_scenario(dir.path(), "md", MD_3D, &["--set", "run.steps=20"]);
    ok(&run);
    let ckpt = out.join("state.ckpt");
    let bytes = std::fs::read(&ckpt).unwrap();
    let before = files(&out);
    let restart = |file: &Path, extra: &[&str]| {
        let mut args = vec!["--set", "run.steps=40", "--restart", file.to_str().unwrap()];
        args.extend_from_slice(extra);
        run_scenario(dir.path(), "md", MD_3D, &args).1
    };
    let bad = dir.path().join("bad.ckpt");
    // a flipped byte in the middle, and in the last section's data
    for at in [bytes.len() / 2, bytes.len() - 40] {
        let mut flipped = bytes.clone();
        flipped[at] ^= 0x01;
        std::fs::write(&bad, &flipped).unwrap();
        refused(
            &restart(&bad, &[]),
            "the checkpoint is corrupt (its CRC-32 does not match)",
        );
    }
    std::fs::write(&bad, &bytes[..bytes.len() / 3]).unwrap();
    refused(&restart(&bad, &[]), "the checkpoint is truncated");
    std::fs::write(&bad, b"model = \"md\"\n").unwrap();
    refused(&restart(&bad, &[]), "not a cellist checkpoint");
    let mut newer = bytes.clone();
    newer[8] = 2;
    std::fs::write(&bad, &newer).unwrap();
    refused(
        &restart(&bad, &[]),
        "checkpoint format version 2; this cellist reads version 1",
    );
    refused(
        &restart(&ckpt, &["--set", "run.dt=0.002"]),
        "the physics key `run.dt` is 0.002 in the scenario but was 0.005 in the checkpoint's run",
    );
    refused(
        &restart(&ckpt, &["--set", "pair.cutoff=2.0"]),
        "the physics key `pair.cutoff` = 2.0 is set in the scenario but was not in the checkpoint's run",
    );
    refused(
        &restart(&ckpt, &["--set", "run.steps=10"]),
        "the checkpoint is at step 20, beyond the run's last step 10",
    );
    // another model's checkpoint
    let gravity = "model = \"gravity\"\n[system]\ninitial = { kind = \"plummer\", n = 50, seed = 1 }\nsoftening = 0.1\n\
        [run]\nsteps = 2\ndt = 0.01\n[output]\ncheckpoint = { every = 2, file = \"g.ckpt\" }\n";
    let (gout, run) = run_scenario(dir.path(), "g", gravity, &[]);
    ok(&run);
    refused(
        &restart(&gout.join("g.ckpt"), &[]),
        "a checkpoint of model 'gravity'; this run is model 'md'",
    );
    assert!(
        files(&out) == before,
        "a refused restart changed the output folder"
    );
}

#[test]
fn a_blow_up_exits_with_3_and_leaves_its_last_good_frame_and_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let (out, run) = run_scenario(dir.path(), "hot", HOT_MELT, &[]);
    assert_eq!(run.status.code(), Some(3), "{}", text(&run.stderr));
    let err = text(&run.stderr);
    assert!(
        err.contains("left the box through the non-periodic z boundary (z = "),
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
    assert!(
        err.contains(&format!("the last good state (step {})", step - 1)),
        "{err}"
    );
    let frame = std::fs::read_to_string(out.join("last.lammpstrj")).unwrap();
    assert!(
        frame.starts_with(&format!("ITEM: TIMESTEP\n{}\n", step - 1)),
        "{frame}"
    );
    // the checkpoint holds that state: restarted, the run blows up at the same step
    let (_, again) = run_scenario(
        dir.path(),
        "hot",
        HOT_MELT,
        &["--restart", out.join("last.ckpt").to_str().unwrap()],
    );
    assert_eq!(again.status.code(), Some(3));
    assert!(text(&again.stderr).contains(&format!("step {step}: ")));
}
