//! End-to-end runs of `cellist run` with `model = "vortex"` and `dimension = 3`
//! (issue 44): the columns and files, a ring's speed against the thin-ring
//! formula with every solver, the ABC flow's order of convergence, thread
//! independence, restarts, bad input and `cellist bench vortex --dim 3`.

use std::f64::consts::PI;

mod common;
use common::{cellist, csv_columns as columns, ok_run, run_scenario as run, text};

/// A single ring (radius 1, circulation 1, core `core`) at spacing `h` with the
/// velocity solver `velocity`, `steps` steps of `dt` with rk2.
fn ring(core: f64, h: f64, velocity: &str, steps: u64, dt: f64) -> String {
    format!(
        "model = \"vortex\"\ndimension = 3\n[system]\n\
         initial = {{ kind = \"ring\", radius = 1.0, circulation = 1.0, core = {core}, spacing = {h} }}\n\
         velocity = {velocity}\n\
         [run]\nsteps = {steps}\ndt = {dt}\nintegrator = \"rk2\"\n\
         [output]\nthermo_every = 1\npicture_size = 64\n"
    )
}

/// The thin-ring speed of a Gaussian core `s` widened by blobs of `sigma`.
fn thin_ring_speed(core: f64, sigma: f64) -> f64 {
    let effective = (core * core + 2.0 * sigma * sigma).sqrt();
    1.0 / (4.0 * PI) * ((8.0 / effective).ln() - 0.558)
}

#[test]
fn a_ring_run_writes_its_columns_fields_pictures_and_trajectories() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = format!(
        "{}field = {{ every = 2, file = \"w.csv\" }}\ngif = {{ every = 1 }}\nvtk = {{ every = 2, file = \"t.pvd\" }}\ngsd = {{ every = 2, file = \"t.gsd\" }}\n",
        ring(0.3, 0.15, "{ kind = \"mesh\", grid = 32 }", 2, 0.05)
    );
    let out = ok_run(dir.path(), "ring", &scenario, &[]);
    let (header, t) = columns(&out.join("thermo.csv"));
    assert_eq!(
        header,
        "step,time,total_vorticity_x,total_vorticity_y,total_vorticity_z,impulse_x,impulse_y,impulse_z,\
         energy,enstrophy,helicity,ring_z,ring_radius,ring_speed"
    );
    // the impulse of a ring is pi R^2 G along its axis (to the core's width)
    let iz = t["impulse_z"][0];
    assert!((iz - PI).abs() < 0.1 * PI, "impulse {iz}");
    assert!(t["ring_speed"][0] > 0.0 && (t["ring_radius"][0] - 1.0).abs() < 0.05);
    let csv = std::fs::read_to_string(out.join("w_2.csv")).unwrap();
    assert!(csv.starts_with("x,y,z,ax,ay,az,u,v,w\n"), "{}", &csv[..60]);
    for file in [
        "vorticity_0.png",
        "vorticity_2.png",
        "vorticity.gif",
        "ring.png",
        "t.pvd",
        "t.gsd",
    ] {
        assert!(out.join(file).is_file(), "{file} is missing");
    }
}

#[test]
fn strengths_that_overflow_stop_the_run_as_a_blow_up_with_its_last_good_state() {
    // strengths of 1e50 stay finite for a step whose squares overflow (the
    // rings' weighted position, which moves the pictures' view, is then not
    // finite); the picture of that step is drawn and the next step blows up
    let dir = tempfile::tempdir().unwrap();
    let scenario = format!(
        "{}gif = {{ every = 1 }}\n",
        ring(0.3, 0.15, "{ kind = \"mesh\", grid = 16 }", 4, 0.05)
            .replace("circulation = 1.0", "circulation = 1e50")
    );
    let (out, o) = run(dir.path(), "overflow", &scenario, &[]);
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("last good state (step"), "{err}");
    assert!(out.join("last.csv").is_file() && out.join("vorticity.gif").is_file());
}

#[test]
fn threads_do_not_change_the_files_and_a_restart_is_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    // viscous, remeshed and relaxed, on the mesh, on all pairs and by the fmm
    for (name, velocity) in [
        ("mesh", "{ kind = \"mesh\", grid = 32 }"),
        ("direct", "{ kind = \"direct\" }"),
        ("fmm", "{ kind = \"fmm\", tolerance = 1e-6 }"),
    ] {
        let scenario = format!(
            "{}field = {{ every = 2, file = \"w.csv\" }}\npng = {{ every = 2 }}\ncheckpoint = {{ every = 2, file = \"state.ckpt\" }}\n",
            ring(0.4, 0.2, velocity, 4, 0.05)
                .replace("[run]", "nu = 0.001\npse_cutoff_factor = 2.0\nremesh_every = 2\nremesh_threshold = 1e-6\nrelaxation = { factor = 0.3, every = 3 }\n[run]")
        );
        let one = ok_run(
            dir.path(),
            &format!("{name}-1"),
            &scenario,
            &["--threads", "1"],
        );
        let two = ok_run(
            dir.path(),
            &format!("{name}-2"),
            &scenario,
            &["--threads", "2"],
        );
        let split = ok_run(
            dir.path(),
            &format!("{name}-split"),
            &scenario,
            &["--set", "run.steps=2"],
        );
        let ckpt = split.join("state.ckpt");
        let (_, o) = run(
            dir.path(),
            &format!("{name}-split"),
            &scenario,
            &["--restart", ckpt.to_str().unwrap()],
        );
        assert!(o.status.success(), "{}", text(&o.stderr));
        let a = common::outputs(&one);
        for other in [&two, &split] {
            let b = common::outputs(other);
            assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>());
            for (file, bytes) in &a {
                assert!(
                    b[file] == *bytes,
                    "{name}: {} differs in {}",
                    file.display(),
                    other.display()
                );
            }
        }
    }
}

#[test]
fn the_abc_flow_error_falls_at_second_order_with_the_spacing() {
    let dir = tempfile::tempdir().unwrap();
    let mut errors = Vec::new();
    for n in [16, 32] {
        let h = 2.0 * PI / n as f64;
        let scenario = format!(
            "model = \"vortex\"\ndimension = 3\n[system]\n\
             initial = {{ kind = \"abc\", spacing = {h} }}\nnu = 0.05\n\
             velocity = {{ kind = \"mesh\", boundary = \"periodic\", box = {}, grid = {n} }}\n\
             [run]\nsteps = {}\ndt = {}\n[output]\nthermo_every = 100\npicture_size = 32\n",
            2.0 * PI,
            n / 4,
            2.0 / n as f64
        );
        let out = ok_run(dir.path(), &format!("abc{n}"), &scenario, &[]);
        let (header, t) = columns(&out.join("thermo.csv"));
        assert!(
            header.ends_with(",helicity,omega_l2_error,omega_max_error"),
            "{header}"
        );
        assert!(t["omega_l2_error"][0] < 1e-15);
        // half a time unit at either spacing
        assert!((t["time"].last().unwrap() - 0.5).abs() < 1e-12);
        errors.push(*t["omega_l2_error"].last().unwrap());
    }
    let order = (errors[0] / errors[1]).log2();
    assert!(order > 1.6, "errors {errors:?}: order {order}");
    assert!(errors[1] < 1e-2, "{errors:?}");
}

#[test]
fn a_ring_moves_at_the_thin_ring_speed_with_every_solver() {
    let dir = tempfile::tempdir().unwrap();
    // core 0.2 at 2 spacings per core: the coarsest the model takes
    let (core, h) = (0.2, 0.1);
    let expected = thin_ring_speed(core, 1.5 * h);
    for (name, velocity) in [
        ("direct", "{ kind = \"direct\" }"),
        ("tree", "{ kind = \"barnes-hut\" }"),
        ("mesh", "{ kind = \"mesh\", grid = 32 }"),
        ("fmm", "{ kind = \"fmm\", tolerance = 1e-4 }"),
    ] {
        let out = ok_run(dir.path(), name, &ring(core, h, velocity, 2, 0.1), &[]);
        let (_, t) = columns(&out.join("thermo.csv"));
        let speed = (t["ring_z"][2] - t["ring_z"][0]) / t["time"][2];
        assert!(
            (speed - expected).abs() < 0.06 * expected,
            "{name}: {speed} against the thin-ring {expected}"
        );
        let rate = t["ring_speed"][0];
        assert!(
            (rate - speed).abs() < 0.02 * speed,
            "{name}: dz/dt {rate} against {speed}"
        );
    }
}

#[test]
fn bad_input_is_refused_with_one_message() {
    let dir = tempfile::tempdir().unwrap();
    let nan = dir.path().join("nan.csv");
    std::fs::write(&nan, "x,y,z,ax,ay,az\n0,0,0,1,0,0\n0,1,0,nan,0,0\n").unwrap();
    let base = ring(0.3, 0.1, "{ kind = \"direct\" }", 1, 0.1);
    let cases = [
        (
            base.replace("spacing = 0.1", "spacing = 0.2"),
            "core needs at least 2",
        ),
        (
            base.replace("spacing = 0.1 }", "spacing = 0.1, extent = 2.0 }"),
            "system.initial.extent is a key of 2D initial conditions",
        ),
        (
            base.replace(
                "kind = \"ring\", radius = 1.0, circulation = 1.0, core = 0.3,",
                "kind = \"lamb-oseen\",",
            ),
            "2D initial conditions",
        ),
        (
            base.replace(
                "kind = \"ring\", radius = 1.0, circulation = 1.0, core = 0.3, spacing = 0.1",
                "kind = \"abc\", spacing = 0.39269908169872414",
            ),
            "the abc initial condition needs the periodic mesh solver",
        ),
        (
            base.replace(
                "kind = \"ring\", radius = 1.0, circulation = 1.0, core = 0.3, spacing = 0.1",
                &format!(
                    "kind = \"file\", spacing = 0.1, path = \"{}\"",
                    nan.display()
                ),
            ),
            "nan.csv:3: ax is NaN",
        ),
        (
            base.replace("dimension = 3", "dimension = 4"),
            "dimension must be 2 or 3",
        ),
        (
            base.replace("[run]", "stretching = \"sideways\"\n[run]"),
            "system.stretching",
        ),
        (
            base.replace(
                "{ kind = \"direct\" }",
                "{ kind = \"fmm\", tolerance = 0.5 }",
            ),
            "system.velocity: tolerance must be in (1e-15, 1e-1), got 0.5",
        ),
    ];
    for (k, (scenario, expected)) in cases.iter().enumerate() {
        let (_, o) = run(dir.path(), &format!("bad{k}"), scenario, &[]);
        let err = text(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "case {k}: {err}");
        assert!(
            err.contains(expected),
            "case {k}: expected '{expected}' in: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

#[test]
fn bench_vortex_3d_reports_time_and_errors() {
    for solver in ["direct", "barnes-hut", "mesh", "fmm"] {
        let o = cellist(&[
            "bench",
            "vortex",
            "--dim",
            "3",
            "--n",
            "3000",
            "--solver",
            solver,
            "--repeat",
            "1",
            "--sample",
            "300",
            "--json",
            "--tolerance",
            "1e-5",
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let v: serde_json::Value = serde_json::from_str(text(&o.stdout).trim()).unwrap();
        assert_eq!(v["dimension"], 3);
        assert!(v["seconds_per_velocity_and_gradient"].as_f64().unwrap() > 0.0);
        let (u, g) = (
            v["rms_relative_velocity_error"].as_f64().unwrap(),
            v["rms_relative_gradient_error"].as_f64().unwrap(),
        );
        let bound = match solver {
            "direct" => 1e-13,
            "fmm" => 1e-5,
            _ => 2e-2,
        };
        assert!(u < bound && g < 10.0 * bound, "{solver}: {u} {g}");
    }
}
