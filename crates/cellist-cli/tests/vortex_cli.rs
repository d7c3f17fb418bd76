//! End-to-end runs of `cellist run` with `model = "vortex"` (issue 15): the
//! invariants, the Lamb-Oseen vortex (order of the vorticity error, velocity of
//! each solver against the exact regularised field), the co-rotating pair's
//! period, the ellipse's effective viscosity, thread independence, outputs,
//! restarts and `cellist bench vortex`.

use std::f64::consts::PI;
use std::path::Path;

mod common;
use common::{cellist, csv_columns as columns, ok_run, run_scenario as run, text};

/// A Lamb-Oseen scenario: circulation 1, t0 = 1, nu = 0.01 (core 0.2), on
/// `[-0.9, 0.9]^2` at spacing `h`.
fn lamb_oseen(h: f64, velocity: &str, remesh: u64, steps: u64) -> String {
    format!(
        "model = \"vortex\"\ndimension = 2\n[system]\n\
         initial = {{ kind = \"lamb-oseen\", circulation = 1.0, t0 = 1.0, spacing = {h}, extent = 0.9 }}\n\
         nu = 0.01\nsigma_over_h = 1.5\nvelocity = {velocity}\nremesh_every = {remesh}\n\
         [run]\nsteps = {steps}\ndt = 0.02\nintegrator = \"rk4\"\n\
         [output]\nthermo_every = 5\nfield = {{ every = 5, file = \"w.csv\" }}\npicture_size = 64\n"
    )
}

#[test]
fn circulation_and_impulse_are_kept_and_angular_impulse_grows_at_4_nu_gamma() {
    let dir = tempfile::tempdir().unwrap();
    // inviscid, off-centre, no remeshing: circulation to 1e-12, impulse to 1e-8
    let inviscid = "model = \"vortex\"\n[system]\n\
        initial = { kind = \"gaussian\", circulation = 2.0, core = 0.2, spacing = 0.05, extent = 0.8, center = [0.3, -0.2] }\n\
        nu = 0.0\nvelocity = { kind = \"direct\" }\n[run]\nsteps = 20\ndt = 0.02\n[output]\nthermo_every = 5\npicture_size = 32\n";
    for (name, remesh, circulation_tolerance) in [("keep", 0, 1e-12), ("remesh", 3, 1e-10)] {
        let out = ok_run(
            dir.path(),
            name,
            inviscid,
            &["--set", &format!("system.remesh_every={remesh}")],
        );
        let (header, t) = columns(&out.join("thermo.csv"));
        assert_eq!(
            header,
            "step,time,circulation,impulse_x,impulse_y,angular_impulse,energy,enstrophy"
        );
        let g0 = t["circulation"][0];
        assert!((g0 - 2.0).abs() < 1e-6, "{g0}");
        let (ix, iy) = (t["impulse_x"][0], t["impulse_y"][0]);
        // the impulse of a vortex at (0.3, -0.2): (Gamma y, -Gamma x)
        assert!(
            (ix + 0.4).abs() < 1e-6 && (iy + 0.6).abs() < 1e-6,
            "{ix} {iy}"
        );
        let size = ix.hypot(iy);
        for (k, &g) in t["circulation"].iter().enumerate() {
            assert!(
                (g - g0).abs() <= circulation_tolerance * g0.abs(),
                "{name}: {g} vs {g0}"
            );
            let d = (t["impulse_x"][k] - ix).hypot(t["impulse_y"][k] - iy);
            assert!(d <= 1e-8 * size, "{name}: impulse moved by {d}");
        }
    }
    // viscous: d(angular impulse)/dt = 4 nu Gamma
    let out = ok_run(
        dir.path(),
        "viscous",
        &lamb_oseen(0.05, "{ kind = \"direct\" }", 5, 25),
        &[],
    );
    let (_, t) = columns(&out.join("thermo.csv"));
    let last = t["step"].len() - 1;
    let rate = (t["angular_impulse"][last] - t["angular_impulse"][0]) / t["time"][last];
    let expected = 4.0 * 0.01 * t["circulation"][0];
    assert!(
        (rate - expected).abs() < 0.01 * expected,
        "dA/dt = {rate}, 4 nu Gamma = {expected}"
    );
}

/// The L2 error of the particles' vorticity against Lamb-Oseen after 25 steps
/// without remeshing (remeshing adds the M4' error: see docs/models.md).
fn final_l2_error(dir: &Path, h: f64) -> f64 {
    let name = format!("h{}", (1.0 / h).round());
    let out = ok_run(
        dir,
        &name,
        &lamb_oseen(h, "{ kind = \"direct\" }", 0, 25),
        &[],
    );
    let (header, t) = columns(&out.join("thermo.csv"));
    assert!(
        header.ends_with(",omega_l2_error,omega_max_error"),
        "{header}"
    );
    // at step 0 the particles carry the exact vorticity (up to round-off)
    assert!(t["omega_l2_error"][0] < 1e-12, "{}", t["omega_l2_error"][0]);
    *t["omega_l2_error"].last().unwrap()
}

#[test]
fn the_lamb_oseen_vorticity_error_falls_at_second_order() {
    let dir = tempfile::tempdir().unwrap();
    let errors: Vec<f64> = [0.1, 0.05, 0.025]
        .iter()
        .map(|&h| final_l2_error(dir.path(), h))
        .collect();
    for w in errors.windows(2) {
        let order = (w[0] / w[1]).log2();
        assert!(
            (1.7..2.5).contains(&order),
            "observed order {order} from errors {errors:?}"
        );
    }
}

/// The largest difference between a field file's velocities and the exact
/// velocity of the blob-regularised Lamb-Oseen vortex (age `t0 + sigma^2 / (2 nu)`),
/// relative to the peak speed.
fn velocity_error(csv: &Path, h: f64) -> f64 {
    let (header, f) = columns(csv);
    assert_eq!(header, "x,y,omega,gamma,u,v");
    let (nu, sigma) = (0.01, 1.5 * h);
    let age = 1.0 + sigma * sigma / (2.0 * nu);
    let speed = |r: f64| -> f64 {
        if r == 0.0 {
            0.0
        } else {
            -(-(r * r) / (4.0 * nu * age)).exp_m1() / (2.0 * PI * r)
        }
    };
    let (mut worst, mut peak) = (0.0f64, 0.0f64);
    for (k, (&x, &y)) in f["x"].iter().zip(&f["y"]).enumerate() {
        let r = x.hypot(y);
        let s = speed(r);
        let exact = if r == 0.0 {
            [0.0, 0.0]
        } else {
            [-s * y / r, s * x / r]
        };
        worst = worst.max((f["u"][k] - exact[0]).hypot(f["v"][k] - exact[1]));
        peak = peak.max(s);
    }
    worst / peak
}

#[test]
fn each_solver_gives_the_lamb_oseen_velocity_within_1e_3_of_its_peak() {
    let dir = tempfile::tempdir().unwrap();
    let h = 0.025;
    for (name, velocity) in [
        ("direct", "{ kind = \"direct\" }"),
        ("tree", "{ kind = \"barnes-hut\", theta = 0.3 }"),
        ("mesh", "{ kind = \"mesh\", grid = 128 }"),
        ("fmm", "{ kind = \"fmm\", tolerance = 1e-8 }"),
    ] {
        let out = ok_run(dir.path(), name, &lamb_oseen(h, velocity, 0, 0), &[]);
        let error = velocity_error(&out.join("w_0.csv"), h);
        assert!(error < 1e-3, "{name}: {error:.3e} of the peak speed");
    }
}

#[test]
fn solvers_agree_and_threads_do_not_change_a_byte() {
    let dir = tempfile::tempdir().unwrap();
    let mut fields = Vec::new();
    for (name, velocity) in [
        ("direct", "{ kind = \"direct\" }"),
        ("tree", "{ kind = \"barnes-hut\", theta = 0.4 }"),
        ("mesh", "{ kind = \"mesh\", grid = 64 }"),
        ("fmm", "{ kind = \"fmm\", order = 12 }"),
    ] {
        let scenario = lamb_oseen(0.05, velocity, 5, 10);
        let one = ok_run(
            dir.path(),
            &format!("{name}1"),
            &scenario,
            &["--threads", "1"],
        );
        let two = ok_run(
            dir.path(),
            &format!("{name}2"),
            &scenario,
            &["--threads", "2"],
        );
        for file in [
            "thermo.csv",
            "w_00.csv",
            "w_05.csv",
            "w_10.csv",
            "vorticity.gif",
        ] {
            let a = std::fs::read(one.join(file)).unwrap();
            let b = std::fs::read(two.join(file)).unwrap();
            assert!(a == b, "{name}: {file} differs between 1 and 2 threads");
        }
        for picture in ["vorticity_00.png", "vorticity_10.png", "error.png"] {
            assert!(one.join(picture).is_file(), "{name}: {picture}");
        }
        fields.push(columns(&one.join("w_00.csv")).1);
    }
    // at step 0 the particles are the same; the velocities differ by the solvers' errors
    let peak = fields[0]["u"]
        .iter()
        .zip(&fields[0]["v"])
        .fold(0.0f64, |m, (u, v)| m.max(u.hypot(*v)));
    for (k, name, within) in [(1, "tree", 1e-3), (2, "mesh", 1e-3), (3, "fmm", 1e-5)] {
        let worst = (0..fields[0]["u"].len())
            .map(|i| {
                (fields[k]["u"][i] - fields[0]["u"][i]).hypot(fields[k]["v"][i] - fields[0]["v"][i])
            })
            .fold(0.0f64, f64::max);
        assert!(
            worst < within * peak,
            "{name}: {worst} against a peak of {peak}"
        );
    }
}

#[test]
fn a_co_rotating_pair_turns_with_period_2_pi2_b2_over_gamma() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = "model = \"vortex\"\n[system]\n\
        initial = { kind = \"pair\", circulation = 1.0, separation = 0.3, core = 0.04, spacing = 0.015, extent = 0.3 }\n\
        nu = 0.0\nvelocity = { kind = \"direct\" }\nremesh_every = 5\n\
        [run]\nsteps = 40\ndt = 0.01\n[output]\nthermo_every = 5\npicture_size = 32\n";
    let out = ok_run(dir.path(), "pair", scenario, &[]);
    let (header, t) = columns(&out.join("thermo.csv"));
    assert!(header.ends_with(",axis_angle"), "{header}");
    let last = t["step"].len() - 1;
    let omega = (t["axis_angle"][last] - t["axis_angle"][0]) / t["time"][last];
    let period = 2.0 * PI / omega;
    let expected = 2.0 * PI * PI * 0.09 / 1.0;
    assert!(
        (period - expected).abs() < 0.03 * expected,
        "period {period}, 2 pi^2 b^2 / Gamma = {expected}"
    );
}

#[test]
fn an_inviscid_ellipse_shows_little_effective_viscosity() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = "model = \"vortex\"\n[system]\n\
        initial = { kind = \"ellipse\", spacing = 0.05, extent = 1.4 }\n\
        nu = 0.0\nvelocity = { kind = \"barnes-hut\", theta = 0.4 }\nremesh_every = 5\n\
        [run]\nsteps = 20\ndt = 0.01\n[output]\nthermo_every = 10\npicture_size = 32\n";
    let out = ok_run(dir.path(), "ellipse", scenario, &[]);
    let (header, t) = columns(&out.join("thermo.csv"));
    assert!(
        header.ends_with(",aspect_ratio,effective_viscosity"),
        "{header}"
    );
    assert!(
        (t["aspect_ratio"][0] - 2.0).abs() < 0.05,
        "{}",
        t["aspect_ratio"][0]
    );
    let nu_eff = *t["effective_viscosity"].last().unwrap();
    assert!(nu_eff.abs() < 1e-4, "effective viscosity {nu_eff}");
}

/// The ellipse with the fmm at 1e-8 follows the direct sum's run: every
/// thermo value within 1e-7 relative after 20 steps (the differences are the
/// FMM's errors carried through RK4 and remeshing).
#[test]
fn the_fmm_ellipse_follows_the_direct_one() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = |velocity: &str| {
        format!(
            "model = \"vortex\"\n[system]\n\
             initial = {{ kind = \"ellipse\", spacing = 0.05, extent = 1.4 }}\n\
             nu = 0.0\nvelocity = {velocity}\nremesh_every = 5\n\
             [run]\nsteps = 20\ndt = 0.01\n[output]\nthermo_every = 10\npicture_size = 32\n"
        )
    };
    let direct = ok_run(
        dir.path(),
        "direct",
        &scenario("{ kind = \"direct\" }"),
        &[],
    );
    let fmm = ok_run(
        dir.path(),
        "fmm",
        &scenario("{ kind = \"fmm\", tolerance = 1e-8 }"),
        &[],
    );
    let ((header, a), (_, b)) = (
        columns(&direct.join("thermo.csv")),
        columns(&fmm.join("thermo.csv")),
    );
    for name in header.split(',').filter(|n| *n != "step" && *n != "time") {
        // the column's size, at least 1e-3: quantities zero by symmetry (the
        // impulse, about 1e-12 here) are compared with that
        let scale = a[name].iter().fold(1e-3f64, |m, x| m.max(x.abs()));
        for (x, y) in a[name].iter().zip(&b[name]) {
            assert!((x - y).abs() <= 1e-7 * scale, "{name}: {x} against {y}");
        }
    }
}

#[test]
fn a_checkpointed_vortex_run_restarts_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = format!(
        "{}checkpoint = {{ every = 10, file = \"state.ckpt\" }}\ngif = {{ every = 5 }}\npng = {{ every = 10 }}\n",
        lamb_oseen(0.1, "{ kind = \"barnes-hut\", theta = 0.5 }", 3, 20)
    );
    let whole = ok_run(dir.path(), "whole", &scenario, &[]);
    let split = ok_run(dir.path(), "split", &scenario, &["--set", "run.steps=10"]);
    let ckpt = split.join("state.ckpt");
    let (_, o) = run(
        dir.path(),
        "split",
        &scenario,
        &["--restart", ckpt.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let (a, b) = (common::outputs(&whole), common::outputs(&split));
    assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
    for (name, bytes) in &a {
        assert!(
            b[name] == *bytes,
            "{} differs after the restart",
            name.display()
        );
    }
}

#[test]
fn bench_vortex_reports_time_and_error() {
    for solver in ["direct", "barnes-hut", "mesh", "fmm"] {
        let o = cellist(&[
            "bench", "vortex", "--n", "2000", "--solver", solver, "--repeat", "1", "--json",
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let line = text(&o.stdout);
        let v: serde_json::Value = serde_json::from_str(line.trim()).unwrap();
        assert!(v["seconds_per_velocity"].as_f64().unwrap() > 0.0);
        let error = v["rms_relative_velocity_error"].as_f64().unwrap();
        if solver == "direct" {
            assert!(error < 1e-13, "{error}");
        } else {
            assert!(error < 1e-3, "{solver}: {error}");
        }
    }
}

#[test]
fn a_non_finite_state_stops_the_run_with_status_3_and_its_last_good_state() {
    let dir = tempfile::tempdir().unwrap();
    // circulations near the largest float: the first step overflows
    std::fs::write(
        dir.path().join("huge.txt"),
        "x y gamma\n0 0 1e308\n0.1 0 1e308\n0 0.1 1e308\n",
    )
    .unwrap();
    let scenario = "model = \"vortex\"\n[system]\n\
        initial = { kind = \"file\", file = \"huge.txt\", spacing = 0.1 }\n\
        velocity = { kind = \"direct\" }\n[run]\nsteps = 5\ndt = 10.0\n[output]\npicture_size = 32\n";
    let (out, o) = run(dir.path(), "huge", scenario, &[]);
    assert_eq!(o.status.code(), Some(3), "{}", text(&o.stderr));
    let message = text(&o.stderr);
    assert!(
        message.contains("step 1: ") && message.contains("particle 0"),
        "{message}"
    );
    assert!(out.join("last.csv").is_file() && out.join("last.ckpt").is_file());
}

#[test]
fn a_periodic_taylor_green_field_decays_at_2_nu_k2_on_the_periodic_mesh() {
    // w = sin(k x) sin(k y), k = 2 pi: a steady Euler flow in the unit periodic box
    // whose vorticity decays as exp(-2 nu k^2 t)
    let dir = tempfile::tempdir().unwrap();
    let (n, k) = (32, 2.0 * PI);
    let h = 1.0 / n as f64;
    let mut lines = String::from("x y gamma\n");
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (-0.5 + i as f64 * h, -0.5 + j as f64 * h);
            lines += &format!("{x} {y} {}\n", (k * x).sin() * (k * y).sin() * h * h);
        }
    }
    std::fs::write(dir.path().join("tg.txt"), lines).unwrap();
    let scenario = format!(
        "model = \"vortex\"\n[system]\ninitial = {{ kind = \"file\", file = \"tg.txt\", spacing = {h} }}\n\
         nu = 0.01\nvelocity = {{ kind = \"mesh\", grid = 32, boundary = \"periodic\", box = 1.0 }}\nremesh_every = 5\n\
         [run]\nsteps = 10\ndt = 0.01\n[output]\nthermo_every = 5\nfield = {{ every = 10, file = \"w.csv\" }}\npicture_size = 32\n"
    );
    let mut outs = Vec::new();
    for threads in ["1", "2"] {
        outs.push(ok_run(
            dir.path(),
            &format!("tg{threads}"),
            &scenario,
            &["--threads", threads],
        ));
    }
    for file in ["thermo.csv", "w_10.csv"] {
        let (a, b) = (
            std::fs::read(outs[0].join(file)).unwrap(),
            std::fs::read(outs[1].join(file)).unwrap(),
        );
        assert!(a == b, "{file} differs between 1 and 2 threads");
    }
    let (_, f) = columns(&outs[0].join("w_10.csv"));
    let decay = (-2.0 * 0.01 * k * k * 0.1f64).exp();
    let mut worst = 0.0f64;
    for (i, w) in f["omega"].iter().enumerate() {
        let (x, y) = (f["x"][i], f["y"][i]);
        assert!(
            (-0.5..0.5).contains(&x) && (-0.5..0.5).contains(&y),
            "{x} {y}"
        );
        worst = worst.max((w - (k * x).sin() * (k * y).sin() * decay).abs());
    }
    assert!(
        worst < 5e-3,
        "largest vorticity error {worst} (amplitude {decay})"
    );
}

/// `bench vortex --solver fmm --input FILE`: point vortices (lines `x y
/// gamma`, as the FMM2D peer script reads them) and blobs with `--sigma`,
/// the RMS error and the largest error over the peak speed below the
/// tolerance asked, the JSON keys of the other solvers plus
/// `max_relative_error`.
#[test]
fn bench_vortex_fmm_reads_points_and_meets_its_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("points.txt");
    // pseudo-random points in the unit square (a 64-bit LCG's top bits)
    let mut state = 12345u64;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let lines: String = (0..5000)
        .map(|_| {
            let (x, y, g) = (uniform(), uniform(), uniform() - 0.3);
            format!("{x} {y} {g}\n")
        })
        .collect();
    std::fs::write(&path, lines).unwrap();
    for (tolerance, sigma) in [("1e-4", None), ("1e-9", None), ("1e-6", Some("0.01"))] {
        let mut args = vec![
            "bench",
            "vortex",
            "--solver",
            "fmm",
            "--tolerance",
            tolerance,
            "--input",
            path.to_str().unwrap(),
            "--repeat",
            "1",
            "--sample",
            "5000",
            "--json",
        ];
        if let Some(s) = sigma {
            args.extend(["--sigma", s]);
        }
        let o = cellist(&args);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let v: serde_json::Value = serde_json::from_str(text(&o.stdout).trim()).unwrap();
        let asked: f64 = tolerance.parse().unwrap();
        for key in ["rms_relative_velocity_error", "max_error_over_peak_speed"] {
            let error = v[key].as_f64().unwrap();
            assert!(
                error > 0.0 && error < asked,
                "{tolerance} {sigma:?}: {key} {error:e}"
            );
        }
        // per target: larger where the velocity nearly cancels
        let largest = v["max_relative_error"].as_f64().unwrap();
        assert!(largest.is_finite() && largest > 0.0, "{largest}");
        assert_eq!(v["n"], 5000);
        assert_eq!(v["sigma"].as_f64(), sigma.map(|s| s.parse().unwrap()));
    }
}
