//! End-to-end runs of `cellist run` with `model = "gravity"` and of `cellist bench
//! gravity`: the outputs, the shared reference states through a body file,
//! thread independence of the dumps for every solver, and errors.

use std::path::Path;

mod common;
use common::{cellist, run_scenario, shared_testdata};

fn text(bytes: &[u8]) -> String {
    String::from_utf8(bytes.to_vec()).unwrap()
}

/// A gravity scenario of a small Plummer sphere with `solver` and `extra` lines
/// appended to `[system]`.
fn plummer_scenario(solver: &str, extra: &str) -> String {
    format!(
        r#"
model = "gravity"
[system]
initial = {{ kind = "plummer", n = 600, seed = 3 }}
G = 1.0
softening = 0.01
solver = {solver}
{extra}
[run]
steps = 20
dt = 0.01
integrator = "leapfrog"
[output]
thermo_every = 5
dump = {{ every = 10, file = "stars.dump" }}
"#
    )
}

const THERMO_HEADER: &str = "step,time,ke,pe,etotal,rel_energy_error,px,py,pz,lx,ly,lz";

fn thermo(out: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(out.join("thermo.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(THERMO_HEADER));
    lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

/// The rows of the frames of a LAMMPS dump, `(step, rows)`.
fn dump_frames(path: &Path) -> Vec<(u64, Vec<Vec<f64>>)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let mut frames = Vec::new();
    while let Some(l) = lines.next() {
        assert_eq!(l, "ITEM: TIMESTEP");
        let step = lines.next().unwrap().parse().unwrap();
        assert_eq!(lines.next(), Some("ITEM: NUMBER OF ATOMS"));
        let n: usize = lines.next().unwrap().parse().unwrap();
        for _ in 0..4 {
            lines.next();
        }
        assert!(lines.next().unwrap().starts_with("ITEM: ATOMS "));
        let rows = (0..n)
            .map(|_| {
                lines
                    .next()
                    .unwrap()
                    .split(' ')
                    .map(|v| v.parse().unwrap())
                    .collect()
            })
            .collect();
        frames.push((step, rows));
    }
    frames
}

#[test]
fn a_run_writes_thermo_dumps_and_plot_and_ignores_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    for (name, solver) in [
        ("direct", r#""direct""#),
        (
            "tree",
            r#"{ kind = "barnes-hut", theta = 0.6, quadrupole = true }"#,
        ),
        ("pm", r#"{ kind = "pm", grid = 16 }"#),
        ("p3m", r#"{ kind = "p3m", grid = 16 }"#),
        (
            "periodic",
            r#"{ kind = "p3m", grid = 16, boundary = "periodic", box = 100.0 }"#,
        ),
        ("fmm", r#"{ kind = "fmm", tolerance = 1e-8 }"#),
    ] {
        let scenario = plummer_scenario(solver, "");
        let (one, run1) = run_scenario(
            dir.path(),
            &format!("{name}1"),
            &scenario,
            &["--threads", "1"],
        );
        assert!(run1.status.success(), "{name}: {}", text(&run1.stderr));
        let (two, run2) = run_scenario(
            dir.path(),
            &format!("{name}2"),
            &scenario,
            &["--threads", "2"],
        );
        assert!(run2.status.success(), "{name}: {}", text(&run2.stderr));
        for file in ["stars.dump", "thermo.csv"] {
            assert_eq!(
                std::fs::read(one.join(file)).unwrap(),
                std::fs::read(two.join(file)).unwrap(),
                "{name}: {file} differs between 1 and 2 threads"
            );
        }
        assert!(one.join("energy.png").is_file());
        let rows = thermo(&one);
        assert_eq!(
            rows.iter().map(|r| r[0] as u64).collect::<Vec<_>>(),
            vec![0, 5, 10, 15, 20]
        );
        for r in &rows {
            assert!((r[4] - (r[2] + r[3])).abs() <= 1e-15, "etotal = ke + pe");
            // all pairs conserve momentum to round-off; the others only approximately
            let (energy, momentum) = match name {
                "direct" => (1e-4, 1e-12),
                "fmm" => (1e-4, 1e-8),
                "tree" => (1e-4, 1e-5),
                _ => (1e-2, 1e-3),
            };
            assert!(r[5].abs() < energy, "{name}: energy error {}", r[5]);
            assert!(
                r[6..9].iter().all(|p| p.abs() < momentum),
                "{name}: momentum {:?}",
                &r[6..9]
            );
        }
        let frames = dump_frames(&one.join("stars.dump"));
        assert_eq!(
            frames.iter().map(|f| f.0).collect::<Vec<_>>(),
            vec![0, 10, 20]
        );
        assert_eq!(frames[0].1.len(), 600);
        assert_eq!(
            frames[0].1[0].len(),
            12,
            "id mass x y z vx vy vz ax ay az phi"
        );
    }
}

#[test]
fn a_body_file_run_reproduces_the_shared_leapfrog_and_euler_states() {
    let Some(dir) = shared_testdata("gravity") else {
        return;
    };
    let start = dir.join("plummer_n1000_eps0.01.txt");
    let tmp = tempfile::tempdir().unwrap();
    for (integrator, reference) in [("leapfrog", "kdk10"), ("euler", "euler10")] {
        let scenario = format!(
            r#"
model = "gravity"
[system]
initial = {{ file = "{}" }}
softening = 0.01
[run]
steps = 10
dt = 0.01
integrator = "{integrator}"
[output]
dump = {{ every = 10, columns = ["x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az"] }}
"#,
            start.display()
        );
        let (out, run) = run_scenario(tmp.path(), integrator, &scenario, &[]);
        assert!(run.status.success(), "{}", text(&run.stderr));
        assert!(
            text(&run.stderr).contains("columns after the 7th"),
            "the extra columns are named"
        );
        let frames = dump_frames(&out.join("bodies.dump"));
        let got = &frames.last().unwrap().1;
        let want: Vec<Vec<f64>> =
            std::fs::read_to_string(dir.join(format!("plummer_n1000_eps0.01_{reference}.txt")))
                .unwrap()
                .lines()
                .filter(|l| !l.starts_with('#'))
                .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
                .collect();
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            for k in (0..9).step_by(3) {
                let norm = |v: &[f64]| v.iter().map(|c| c * c).sum::<f64>().sqrt();
                let diff: Vec<f64> = (k..k + 3).map(|a| g[a] - w[a]).collect();
                assert!(
                    norm(&diff) <= 1e-10 * norm(&w[k..k + 3]),
                    "{integrator}: {g:?} vs {w:?}"
                );
            }
        }
    }
}

#[test]
fn bad_input_exits_with_status_2_and_names_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let bodies = dir.path().join("bodies.txt");
    std::fs::write(&bodies, "1 0 0 0 0 0 0\n-2 1 0 0 0 0 0\n").unwrap();
    let same = dir.path().join("same.txt");
    std::fs::write(&same, "1 0 0 0 0 0 0\n1 0.5 0 0 0 0 0\n1 0 0 0 1 0 0\n").unwrap();
    let file_scenario = |path: &Path, softening: f64| {
        format!(
            "model = \"gravity\"\n[system]\ninitial = {{ file = \"{}\" }}\nsoftening = {softening}\n[run]\nsteps = 1\ndt = 0.01\n",
            path.display()
        )
    };
    let cases = [
        (
            file_scenario(&bodies, 0.0),
            "bodies.txt:2: mass -2 must be > 0",
        ),
        (
            file_scenario(&same, 0.0),
            "particles 0 and 2 are at the same point",
        ),
        (
            plummer_scenario(r#""direct""#, "").replace("softening = 0.01", "softening = -0.1"),
            "softening",
        ),
        (
            plummer_scenario(r#"{ kind = "barnes-hut", theta = 1.5 }"#, ""),
            "theta must be in (0, 1.2]",
        ),
        (
            plummer_scenario(r#"{ kind = "barnes-hut", theta = 0.0 }"#, ""),
            "theta must be in (0, 1.2]",
        ),
        (
            plummer_scenario(r#"{ kind = "octree" }"#, ""),
            "solver kind 'octree' is unknown",
        ),
        (
            plummer_scenario(r#""direct""#, "").replace("leapfrog", "rk4"),
            "run.integrator 'rk4' is unknown",
        ),
        (plummer_scenario(r#""direct""#, "colour = 1"), "colour"),
        (
            plummer_scenario(r#"{ kind = "pm", grid = 100 }"#, ""),
            "grid must be a power of two >= 8, got 100",
        ),
        (
            plummer_scenario(r#"{ kind = "p3m", grid = 48 }"#, ""),
            "grid must be a power of two >= 8, got 48",
        ),
        (
            plummer_scenario(r#"{ kind = "pm", grid = 4096 }"#, ""),
            "grid must be at most",
        ),
        (
            plummer_scenario(r#"{ kind = "pm", grid = 16 }"#, "repulsion_radius = 0.1"),
            "repulsion_radius",
        ),
        (
            plummer_scenario(r#"{ kind = "pm", boundary = "periodic" }"#, ""),
            "needs box = L",
        ),
        (
            plummer_scenario(r#"{ kind = "direct", grid = 16 }"#, ""),
            "system.solver.grid applies to kind",
        ),
        (
            plummer_scenario(r#""direct""#, "").replace("G = 1.0", "G = 0.0"),
            "G must be finite and > 0",
        ),
        (
            plummer_scenario(r#""direct""#, "") + "picture_size = 8\n",
            "output.picture_size must be between 16 and 4096 pixels, got 8",
        ),
        (
            plummer_scenario(r#""direct""#, "") + "plane = \"zx\"\n",
            "output.plane 'zx' is unknown",
        ),
        (
            plummer_scenario(r#""direct""#, "")
                .replace("model = \"gravity\"", "model = \"gravity\"\ndimension = 2")
                + "plane = \"xz\"\n",
            "output.plane = \"xz\" shows a line of a 2D run",
        ),
        (
            plummer_scenario(r#""direct""#, "") + "gif = { every = 5, name = \"b.gif\" }\n",
            "unknown field `name`",
        ),
    ];
    for (k, (scenario, expected)) in cases.iter().enumerate() {
        let (_, run) = run_scenario(dir.path(), &format!("bad{k}"), scenario, &[]);
        assert_eq!(
            run.status.code(),
            Some(2),
            "case {k}: {}",
            text(&run.stderr)
        );
        assert!(
            text(&run.stderr).contains(expected),
            "case {k}: expected '{expected}' in {}",
            text(&run.stderr)
        );
    }
    // two bodies at the same point are fine with softening
    let (_, run) = run_scenario(dir.path(), "soft", &file_scenario(&same, 0.1), &[]);
    assert!(run.status.success(), "{}", text(&run.stderr));
}

/// Decodes every frame of a GIF; returns the frame count and the frames' size
/// (all frames of one size).
fn gif_frames(path: &Path) -> (usize, [u32; 2]) {
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options
        .read_info(std::fs::File::open(path).unwrap())
        .unwrap();
    let size = [decoder.width() as u32, decoder.height() as u32];
    let mut frames = 0;
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        assert_eq!([frame.width as u32, frame.height as u32], size);
        assert_eq!(frame.buffer.len(), 4 * (size[0] * size[1]) as usize);
        frames += 1;
    }
    (frames, size)
}

/// Decodes a PNG; returns its size.
fn png_size(path: &Path) -> [u32; 2] {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    [info.width, info.height]
}

#[test]
fn a_run_draws_its_bodies_and_a_restart_continues_the_animation() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = plummer_scenario(r#""direct""#, "").replace("n = 600", "n = 300")
        + "checkpoint = { every = 10, file = \"state.ckpt\" }\n";
    // by default: bodies.png of the last step, no animation
    let (out, run) = run_scenario(dir.path(), "default", &scenario, &[]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    assert_eq!(png_size(&out.join("bodies.png")), [640, 512]);
    assert!(!out.join("bodies.gif").exists());

    // an animation every 5 steps (0, 5, ..., 20), in one go and restarted at 10
    let gif = scenario.clone() + "gif = { every = 5 }\npng = { every = 10, file = \"b.png\" }\n";
    let (whole, run) = run_scenario(dir.path(), "whole", &gif, &[]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    assert_eq!(gif_frames(&whole.join("bodies.gif")), (5, [640, 512]));
    for name in ["b_00.png", "b_10.png", "b_20.png"] {
        assert_eq!(png_size(&whole.join(name)), [640, 512], "{name}");
    }
    assert!(!whole.join("bodies.png").exists());
    let (split, run) = run_scenario(dir.path(), "split", &gif, &["--set", "run.steps=10"]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    assert_eq!(gif_frames(&split.join("bodies.gif")).0, 3);
    let ckpt = split.join("state.ckpt");
    let (_, run) = run_scenario(
        dir.path(),
        "split",
        &gif,
        &["--restart", ckpt.to_str().unwrap()],
    );
    assert!(run.status.success(), "{}", text(&run.stderr));
    assert_eq!(gif_frames(&split.join("bodies.gif")), (5, [640, 512]));
    for name in ["bodies.gif", "b_00.png", "b_10.png", "b_20.png"] {
        assert_eq!(
            std::fs::read(whole.join(name)).unwrap(),
            std::fs::read(split.join(name)).unwrap(),
            "{name} differs after a restart"
        );
    }

    // wider pictures, another plane; every = 0 turns them off
    let wide = scenario.clone()
        + "picture_size = 800\nplane = \"yz\"\ngif = { every = 10, file = \"yz.gif\" }\n";
    let (out, run) = run_scenario(dir.path(), "wide", &wide, &[]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    let size = png_size(&out.join("bodies.png"));
    assert_eq!(size[0], 800);
    assert_eq!(gif_frames(&out.join("yz.gif")), (3, size));
    let off = scenario + "png = { every = 0 }\n";
    let (out, run) = run_scenario(dir.path(), "off", &off, &[]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    assert!(!out.join("bodies.png").exists());
}

#[test]
fn a_state_that_overflows_stops_the_run_naming_the_step_and_body() {
    let dir = tempfile::tempdir().unwrap();
    let bodies = dir.path().join("fast.txt");
    std::fs::write(&bodies, "1 0 0 0 0 0 0\n1 10 0 0 1e300 0 0\n").unwrap();
    let scenario = format!(
        "model = \"gravity\"\n[system]\ninitial = {{ file = \"{}\" }}\n[run]\nsteps = 5\ndt = 1e10\nintegrator = \"euler\"\n",
        bodies.display()
    );
    let (out, run) = run_scenario(dir.path(), "nan", &scenario, &[]);
    assert_eq!(run.status.code(), Some(3), "{}", text(&run.stderr));
    let err = text(&run.stderr);
    assert!(err.contains("step 1: the state of body "), "{err}");
    assert!(out.join("last.dump").is_file());
    assert!(out.join("thermo.csv").is_file());
}

/// A Plummer sphere without softening (the law the expansions hold
/// everywhere) run by the fmm at 1e-8 and by the direct sum: every thermo
/// column agrees within 1e-7 of its scale after 20 steps.
#[test]
fn the_fmm_run_follows_the_direct_run() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = |solver: &str| {
        plummer_scenario(solver, "")
            .replace("n = 600", "n = 4000")
            .replace("softening = 0.01", "softening = 0.0")
    };
    let (direct, run) = run_scenario(dir.path(), "direct", &scenario(r#""direct""#), &[]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    let fmm_solver = r#"{ kind = "fmm", tolerance = 1e-8 }"#;
    let (fmm, run) = run_scenario(dir.path(), "fmm", &scenario(fmm_solver), &[]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    assert!(text(&run.stdout).contains("fmm (order 22, tolerance 1e-8)"));
    let (want, got) = (thermo(&direct), thermo(&fmm));
    assert_eq!(want.len(), got.len());
    for (w, g) in want.iter().zip(&got) {
        // energies against the total energy's size, momenta against 1
        let scale = w[2].abs() + w[3].abs();
        for column in 2..5 {
            assert!(
                (w[column] - g[column]).abs() < 1e-7 * scale,
                "{w:?} vs {g:?}"
            );
        }
        for column in 6..12 {
            assert!((w[column] - g[column]).abs() < 1e-7, "{w:?} vs {g:?}");
        }
    }
}

/// The fmm with the examples' softening (0.01, at 1e-6 the law is `1/r`
/// only beyond 12.2) on a Plummer sphere, whose pairs nearly all lie closer:
/// the run warns that it sums them directly and names the faster choices;
/// with a softening of 1e-6 (reach 1.2e-3) it does not warn.
#[test]
fn the_fmm_warns_when_the_softening_leaves_it_a_direct_sum() {
    let dir = tempfile::tempdir().unwrap();
    let fmm = r#"{ kind = "fmm", tolerance = 1e-6 }"#;
    let scenario = plummer_scenario(fmm, "").replace("steps = 20", "steps = 1");
    let (_, run) = run_scenario(dir.path(), "wide", &scenario, &[]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    let err = text(&run.stderr);
    assert!(
        err.contains(
            "warning: system.solver: the fmm sums directly every pair of bodies closer than 12.2"
        ),
        "{err}"
    );
    assert!(err.contains("the softening (0.01) keeps"), "{err}");
    assert!(
        err.contains("% of the pairs here, so it may cost more"),
        "{err}"
    );
    assert!(err.contains("a larger tolerance is faster"), "{err}");
    assert!(err.contains("\"barnes-hut\""), "{err}");
    let narrow = scenario.replace("softening = 0.01", "softening = 1e-6");
    let (_, run) = run_scenario(dir.path(), "narrow", &narrow, &[]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    assert!(
        !text(&run.stderr).contains("warning"),
        "{}",
        text(&run.stderr)
    );
}

/// `bench gravity --solver fmm` on a file of bodies and on a uniform cube:
/// the RMS field error against the direct sum stays below the tolerance.
#[test]
fn bench_gravity_fmm_reads_bodies_and_meets_its_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let bodies = dir.path().join("bodies.txt");
    let mut lines = String::new();
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..3000 {
        lines += &format!("{} {} {} {}\n", next(), next(), next(), next());
    }
    std::fs::write(&bodies, lines).unwrap();
    let path = bodies.to_str().unwrap();
    for (source, tolerance) in [(["--input", path], "1e-6"), (["--n", "3000"], "1e-9")] {
        let mut args = vec!["bench", "gravity", "--solver", "fmm", "--softening", "0"];
        args.extend(source);
        if source[0] == "--n" {
            args.extend(["--distribution", "uniform"]);
        }
        args.extend([
            "--tolerance",
            tolerance,
            "--repeat",
            "1",
            "--sample",
            "500",
            "--json",
        ]);
        let run = cellist(&args);
        assert!(run.status.success(), "{}", text(&run.stderr));
        let v: serde_json::Value = serde_json::from_str(text(&run.stdout).trim()).unwrap();
        assert_eq!(v["n"], 3000);
        assert_eq!(v["error_targets"], 500);
        let rms = v["rms_field_error"].as_f64().unwrap();
        let t: f64 = tolerance.parse().unwrap();
        assert!(rms > 0.0 && rms < t, "{source:?}: {rms} at {t}");
        assert!(v["max_relative_error"].as_f64().unwrap() >= rms / 10.0);
        assert!(v["description"]
            .as_str()
            .unwrap()
            .starts_with("fmm (order "));
    }
}

#[test]
fn bench_gravity_reports_time_and_error_as_json() {
    for solver in ["direct", "barnes-hut", "pm", "p3m"] {
        let run = cellist(&[
            "bench", "gravity", "--solver", solver, "--n", "500", "--grid", "16", "--repeat", "1",
            "--json",
        ]);
        assert!(run.status.success(), "{}", text(&run.stderr));
        let v: serde_json::Value = serde_json::from_str(text(&run.stdout).trim()).unwrap();
        assert_eq!(v["n"], 500);
        assert!(v["seconds_per_force"].as_f64().unwrap() > 0.0);
        if solver == "direct" {
            assert!(v["ns_per_pair"].as_f64().unwrap() > 0.0);
        } else {
            let e = v["rms_relative_force_error"].as_f64().unwrap();
            let bound = if solver == "pm" { 1.0 } else { 1e-2 };
            assert!(e > 0.0 && e < bound, "{solver}: {e}");
        }
    }
}
