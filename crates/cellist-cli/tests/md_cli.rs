//! End-to-end runs of `cellist run` with `model = "md"` against LAMMPS's numbers
//! (../shared/testdata/lammps and this crate's tests/data/lammps2d), and its
//! outputs, thread independence and errors.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod common;
use common::{cellist, shared_testdata};

fn text(bytes: &[u8]) -> String {
    String::from_utf8(bytes.to_vec()).unwrap()
}

fn lammps_data() -> Option<PathBuf> {
    shared_testdata("lammps")
}

fn data_2d() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/lammps2d")
}

/// Runs a scenario text (written to `dir/s.toml`) with extra flags; returns the output folder.
fn run_scenario(dir: &Path, scenario: &str, extra: &[&str]) -> PathBuf {
    let (out, o) = common::run_scenario(dir, "s", scenario, extra);
    assert!(
        o.status.success(),
        "cellist failed: {}\n{}",
        text(&o.stderr),
        text(&o.stdout)
    );
    out
}

/// One dump frame: step, box bounds and per-atom columns by id.
struct DumpFrame {
    step: u64,
    box_lo_hi: Vec<(f64, f64)>,
    atoms: BTreeMap<u64, BTreeMap<String, f64>>,
}

fn read_dump(path: &Path) -> Vec<DumpFrame> {
    let content = std::fs::read_to_string(path).unwrap();
    let lines: Vec<&str> = content.lines().collect();
    let mut frames = Vec::new();
    let mut k = 0;
    while k < lines.len() {
        assert_eq!(lines[k], "ITEM: TIMESTEP");
        let step = lines[k + 1].trim().parse().unwrap();
        let n: usize = lines[k + 3].trim().parse().unwrap();
        let box_lo_hi = (0..3)
            .map(|a| {
                let v: Vec<f64> = lines[k + 5 + a]
                    .split_whitespace()
                    .map(|x| x.parse().unwrap())
                    .collect();
                (v[0], v[1])
            })
            .collect();
        let columns: Vec<String> = lines[k + 8]
            .split_whitespace()
            .skip(2)
            .map(String::from)
            .collect();
        let mut atoms = BTreeMap::new();
        for line in &lines[k + 9..k + 9 + n] {
            let values: Vec<f64> = line
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            let row: BTreeMap<String, f64> = columns.iter().cloned().zip(values).collect();
            atoms.insert(row["id"] as u64, row);
        }
        frames.push(DumpFrame {
            step,
            box_lo_hi,
            atoms,
        });
        k += 9 + n;
    }
    frames
}

/// The rows of a whitespace table with a `# name name ...` header.
fn read_table(path: &Path) -> Vec<BTreeMap<String, f64>> {
    let content = std::fs::read_to_string(path).unwrap();
    let mut lines = content.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .trim_start_matches('#')
        .split_whitespace()
        .map(String::from)
        .collect();
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split_whitespace().map(|x| x.parse().unwrap()))
                .collect()
        })
        .collect()
}

/// cellist's thermo.csv rows.
fn read_thermo_csv(path: &Path) -> Vec<BTreeMap<String, f64>> {
    let content = std::fs::read_to_string(path).unwrap();
    let mut lines = content.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    assert_eq!(header, ["step", "temp", "pe", "ke", "etotal", "press"]);
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(|x| x.parse().unwrap()))
                .collect()
        })
        .collect()
}

fn relative(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

fn static_scenario(data: &Path, dim: usize, shift: bool) -> String {
    format!(
        "model = \"md\"\ndimension = {dim}\n[system]\nread_data = \"{}\"\n[pair]\nstyle = \"lj/cut\"\ncutoff = 2.5\nshift = {shift}\n\
         [run]\nsteps = 0\n[output]\ndump = {{ every = 1, file = \"d.lammpstrj\", columns = [\"id\", \"type\", \"x\", \"y\", \"z\", \"fx\", \"fy\", \"fz\", \"pe\"] }}\n",
        data.display()
    )
}

/// Forces (max per-atom norm of the difference), per-atom energies, pe and
/// pressure of one static configuration against LAMMPS.
fn check_static(
    data: &Path,
    reference_dump: &Path,
    reference_thermo: &Path,
    dim: usize,
    shift: bool,
) {
    let dir = tempfile::tempdir().unwrap();
    let out = run_scenario(dir.path(), &static_scenario(data, dim, shift), &[]);
    let ours = &read_dump(&out.join("d.lammpstrj"))[0];
    let theirs = &read_dump(reference_dump)[0];
    assert_eq!(ours.atoms.len(), theirs.atoms.len());
    let mut worst_force: f64 = 0.0;
    let mut worst_pe: f64 = 0.0;
    for (id, t) in &theirs.atoms {
        let o = &ours.atoms[id];
        let d2: f64 = ["fx", "fy", "fz"]
            .iter()
            .map(|c| (o[*c] - t[*c]).powi(2))
            .sum();
        worst_force = worst_force.max(d2.sqrt());
        worst_pe = worst_pe.max((o["pe"] - t["c_peatom"]).abs());
        for c in ["x", "y", "z"] {
            assert!((o[c] - t[c]).abs() < 1e-12, "atom {id} {c}");
        }
    }
    eprintln!(
        "{}: forces within {worst_force:e}, per-atom pe within {worst_pe:e}",
        reference_dump.display()
    );
    assert!(worst_force < 1e-10, "forces differ by {worst_force}");
    assert!(worst_pe < 1e-12, "per-atom energies differ by {worst_pe}");
    let ours = &read_thermo_csv(&out.join("thermo.csv"))[0];
    let theirs = &read_table(reference_thermo)[0];
    assert!(
        relative(ours["pe"], theirs["pe_per_atom"]) < 1e-12,
        "pe {} vs {}",
        ours["pe"],
        theirs["pe_per_atom"]
    );
    assert!(
        relative(ours["press"], theirs["press"]) < 1e-12,
        "press {} vs {}",
        ours["press"],
        theirs["press"]
    );
}

#[test]
fn static_forces_energy_and_pressure_match_lammps_3d() {
    let Some(dir) = lammps_data() else { return };
    for shift in ["no", "yes"] {
        check_static(
            &dir.join("lj500.data"),
            &dir.join(format!("lj500_shift{shift}.dump")),
            &dir.join(format!("lj500_shift{shift}.thermo")),
            3,
            shift == "yes",
        );
    }
}

#[test]
fn static_forces_energy_and_pressure_match_lammps_2d() {
    let dir = data_2d();
    for shift in ["no", "yes"] {
        check_static(
            &dir.join("lj2d512.data"),
            &dir.join(format!("lj2d512_shift{shift}.dump")),
            &dir.join(format!("lj2d512_shift{shift}.thermo")),
            2,
            shift == "yes",
        );
    }
}

/// A data file with the positions and velocities of a reference dump's first frame.
fn data_from_dump(frame: &DumpFrame, dim: usize, path: &Path) {
    let mut s = format!(
        "from a LAMMPS dump\n\n{} atoms\n1 atom types\n\n",
        frame.atoms.len()
    );
    for (a, (lo, hi)) in frame.box_lo_hi.iter().enumerate() {
        let axis = ["x", "y", "z"][a];
        s += &format!("{lo:?} {hi:?} {axis}lo {axis}hi\n");
    }
    s += "\nMasses\n\n1 1\n\nAtoms # atomic\n\n";
    for (id, r) in &frame.atoms {
        s += &format!("{id} 1 {:?} {:?} {:?}\n", r["x"], r["y"], r["z"]);
    }
    s += "\nVelocities\n\n";
    for (id, r) in &frame.atoms {
        let vz = if dim == 3 { r["vz"] } else { 0.0 };
        s += &format!("{id} {:?} {:?} {vz:?}\n", r["vx"], r["vy"]);
    }
    std::fs::write(path, s).unwrap();
}

/// 100 velocity-Verlet steps from the reference's step 0: positions (nearest image)
/// and velocities at step 100 within 1e-8, thermo lines close to LAMMPS's.
fn check_trajectory(reference_dump: &Path, reference_thermo: &Path, dim: usize, shift: bool) {
    let dir = tempfile::tempdir().unwrap();
    let frames = read_dump(reference_dump);
    let data = dir.path().join("start.data");
    data_from_dump(&frames[0], dim, &data);
    let scenario = format!(
        "model = \"md\"\ndimension = {dim}\n[system]\nread_data = \"start.data\"\n[pair]\nstyle = \"lj/cut\"\ncutoff = 2.5\nshift = {shift}\n\
         [neighbor]\nskin = 0.3\n[run]\nsteps = 100\ndt = 0.005\nintegrator = \"velocity-verlet\"\n\
         [output]\nthermo_every = 10\ndump = {{ every = 100, file = \"t.lammpstrj\", columns = [\"id\", \"type\", \"x\", \"y\", \"z\", \"vx\", \"vy\", \"vz\"] }}\n"
    );
    let out = run_scenario(dir.path(), &scenario, &[]);
    let ours = read_dump(&out.join("t.lammpstrj"));
    assert_eq!(ours.len(), 2);
    let (o, t) = (&ours[1], &frames[1]);
    assert_eq!((o.step, t.step), (100, 100));
    let lengths: Vec<f64> = t.box_lo_hi.iter().map(|(lo, hi)| hi - lo).collect();
    let mut worst: f64 = 0.0;
    for (id, tr) in &t.atoms {
        let or = &o.atoms[id];
        for (a, c) in ["x", "y", "z"].iter().enumerate().take(dim) {
            let d = or[*c] - tr[*c];
            worst = worst.max((d - lengths[a] * (d / lengths[a]).round()).abs());
        }
        for c in ["vx", "vy", "vz"].iter().take(dim) {
            worst = worst.max((or[*c] - tr[*c]).abs());
        }
    }
    eprintln!(
        "{}: step-100 state within {worst:e}",
        reference_dump.display()
    );
    assert!(worst < 1e-8, "step-100 state differs by {worst}");
    let n = frames[0].atoms.len() as f64;
    let ours = read_thermo_csv(&out.join("thermo.csv"));
    let theirs = read_table(reference_thermo);
    assert_eq!(ours.len(), theirs.len());
    for (o, t) in ours.iter().zip(&theirs) {
        assert_eq!(o["step"], t["step"]);
        assert!(
            relative(o["temp"], t["temp"]) < 1e-9,
            "temp at step {}",
            t["step"]
        );
        assert!(
            (o["pe"] - t["pe_total"] / n).abs() < 1e-9,
            "pe at step {}",
            t["step"]
        );
        assert!(
            (o["etotal"] - t["etotal_total"] / n).abs() < 1e-9,
            "etotal at step {}",
            t["step"]
        );
        assert!(
            (o["press"] - t["press"]).abs() < 1e-8,
            "press at step {}",
            t["step"]
        );
    }
}

#[test]
fn trajectory_of_100_steps_matches_lammps_3d() {
    let Some(dir) = lammps_data() else { return };
    for shift in ["no", "yes"] {
        check_trajectory(
            &dir.join(format!("traj500_shift{shift}.dump")),
            &dir.join(format!("traj500_shift{shift}.thermo")),
            3,
            shift == "yes",
        );
    }
}

#[test]
fn trajectory_of_100_steps_matches_lammps_2d() {
    let dir = data_2d();
    for shift in ["no", "yes"] {
        check_trajectory(
            &dir.join("traj2d512_shiftno.dump"),
            &dir.join(format!("traj2d512_shift{shift}.thermo")),
            2,
            shift == "yes",
        );
    }
}

/// The 32000-atom melt from LAMMPS's own start: thermo every 100 steps against
/// LAMMPS's, and energy conservation after the melt.
fn check_melt(steps: u64) {
    let Some(dir) = lammps_data() else { return };
    let work = tempfile::tempdir().unwrap();
    let scenario = format!(
        "model = \"md\"\n[system]\nread_data = \"{}\"\n[pair]\nstyle = \"lj/cut\"\ncutoff = 2.5\nshift = true\n\
         [neighbor]\nskin = 0.3\n[run]\nsteps = {steps}\ndt = 0.005\n[output]\nthermo_every = 100\n",
        dir.join("melt32000_init.data.gz").display()
    );
    let out = run_scenario(work.path(), &scenario, &["--threads", "2"]);
    let ours = read_thermo_csv(&out.join("thermo.csv"));
    let theirs = read_table(&dir.join("nve_safe_shiftyes.thermo"));
    assert_eq!(ours.len() as u64, steps / 100 + 1);
    for (o, t) in ours.iter().zip(&theirs) {
        assert_eq!(o["step"], t["step"]);
        // chaos amplifies round-off differences; the averages stay close
        assert!(
            (o["etotal"] - t["etotal/atom"]).abs() < 1e-4,
            "etotal at step {}: {} vs {}",
            t["step"],
            o["etotal"],
            t["etotal/atom"]
        );
        assert!(
            (o["temp"] - t["temp"]).abs() < 1e-2,
            "temp at step {}",
            t["step"]
        );
    }
    let e200 = ours[2]["etotal"];
    let drift = ours[2..]
        .iter()
        .map(|o| (o["etotal"] - e200).abs())
        .fold(0.0, f64::max);
    eprintln!("melt: max |E(t) - E(200)| = {drift:e} per atom over {steps} steps");
    for o in &ours[2..] {
        assert!(
            (o["etotal"] - e200).abs() < 1e-4,
            "|E(t) - E(200)| at step {}",
            o["step"]
        );
    }
}

#[test]
fn melt_of_32000_atoms_follows_lammps_for_200_steps() {
    check_melt(200);
}

/// The whole 1000-step melt (about 20 s on 2 cores):
/// `cargo test --release -p cellist-cli --test md_cli -- --ignored`
#[test]
#[ignore]
fn melt_of_32000_atoms_conserves_energy_over_1000_steps_like_lammps() {
    check_melt(1000);
}

#[test]
fn dumps_do_not_depend_on_the_thread_count() {
    let scenario = "model = \"md\"\ndimension = 3\n[system]\nlattice = { kind = \"fcc\", density = 0.8442, cells = [6, 6, 7] }\n\
        velocity = { temperature = 3.0, seed = 5 }\n[pair]\nstyle = \"lj/cut\"\ncutoff = 2.5\n[run]\nsteps = 200\n\
        [output]\nthermo_every = 50\ndump = { every = 100, file = \"d.lammpstrj\", columns = [\"id\", \"type\", \"x\", \"y\", \"z\", \"vx\", \"vy\", \"vz\", \"fx\", \"fy\", \"fz\", \"pe\"] }\n\
        xyz = { every = 100, file = \"d.xyz\" }\n";
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let dir = tempfile::tempdir().unwrap();
        let out = run_scenario(dir.path(), scenario, &["--threads", threads]);
        let files: Vec<Vec<u8>> = ["d.lammpstrj", "d.xyz", "thermo.csv"]
            .iter()
            .map(|f| std::fs::read(out.join(f)).unwrap())
            .collect();
        assert!(out.join("energy.png").is_file());
        outputs.push(files);
    }
    assert!(
        outputs[0] == outputs[1],
        "outputs differ between 1 and 2 threads"
    );
}

#[test]
fn the_default_run_is_the_melt_and_writes_its_results() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("melt");
    let o = cellist(&[
        "run",
        "--out",
        out.to_str().unwrap(),
        "--set",
        "system.lattice.cells=[5,5,5]",
        "--set",
        "run.steps=20",
        "--set",
        "output.thermo_every=10",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let stdout = text(&o.stdout);
    assert!(stdout.contains("md: 500 atoms in 3D"), "{stdout}");
    assert!(stdout.contains("Loop time of"), "{stdout}");
    for f in ["thermo.csv", "energy.png", "melt.lammpstrj", "melt.xyz"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let rows = read_thermo_csv(&out.join("thermo.csv"));
    assert_eq!(rows.len(), 3);
    assert!((rows[0]["temp"] - 3.0).abs() < 1e-12);
}

#[test]
fn bench_lj_reports_json() {
    let o = cellist(&[
        "bench",
        "lj",
        "--atoms-per-side",
        "5",
        "--steps",
        "10",
        "--repeat",
        "1",
        "--json",
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["atoms"], 500);
    assert_eq!(v["steps"], 10);
    assert!(v["us_per_atom_step"].as_f64().unwrap() > 0.0);
}

const GOOD_DATA: &str = "title\n\n2 atoms\n1 atom types\n\n0 10 xlo xhi\n0 10 ylo yhi\n0 10 zlo zhi\n\nMasses\n\n1 1\n\nAtoms # atomic\n\n1 1 1 1 1\n2 1 2 2 2\n";

fn failure(dir: &Path, scenario: &str, data: Option<&str>, extra: &[&str]) -> (i32, String) {
    std::fs::write(dir.join("s.toml"), scenario).unwrap();
    if let Some(d) = data {
        std::fs::write(dir.join("start.data"), d).unwrap();
    }
    let s = dir.join("s.toml");
    let out = dir.join("out");
    let mut args = vec!["run", s.to_str().unwrap(), "--out", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    let o = cellist(&args);
    (o.status.code().unwrap_or(-1), text(&o.stderr))
}

#[test]
fn bad_input_is_refused_with_a_clear_message() {
    let base = "model = \"md\"\n[system]\nread_data = \"start.data\"\n[pair]\nstyle = \"lj/cut\"\ncutoff = 2.5\n[run]\nsteps = 1\nintegrator = \"velocity-verlet\"\n";
    let cases: Vec<(String, Option<String>, &str)> = vec![
        (
            base.into(),
            Some(GOOD_DATA.replace("2 1 2 2 2", "2 1 2 x 2")),
            "start.data:17: y is 'x'; expected a number",
        ),
        (
            base.into(),
            Some(GOOD_DATA.replace("2 1 2 2 2", "2 1 1 1 1")),
            "atoms 1 and 2 are at the same position",
        ),
        (
            base.into(),
            Some(GOOD_DATA.replace("0 10 ylo", "0 4 ylo")),
            "box side along y is 4, smaller than twice the cutoff (5)",
        ),
        (
            base.replace("lj/cut", "lj/long"),
            Some(GOOD_DATA.into()),
            "pair.style 'lj/long' is unknown; expected \"lj/cut\"",
        ),
        (
            base.replace("\"velocity-verlet\"", "\"rk4\""),
            Some(GOOD_DATA.into()),
            "run.integrator 'rk4' is unknown",
        ),
        (
            base.replace("cutoff = 2.5", "cutoff = 2.5\ncutof = 3"),
            Some(GOOD_DATA.into()),
            "line 7",
        ),
        (
            base.replace("[run]", "[run]\ntemperature = 1"),
            Some(GOOD_DATA.into()),
            "unknown field `temperature`",
        ),
        (
            base.replace("model = \"md\"", "model = \"plasma\""),
            None,
            "model 'plasma' is unknown",
        ),
        (
            base.into(),
            Some(GOOD_DATA.replace("Masses\n\n1 1\n\n", "")),
            "has no Masses section; add one or set system.mass",
        ),
        (
            base.replace(
                "read_data = \"start.data\"",
                "lattice = { kind = \"fcc\", density = 0.8442, cells = [2, 2, 2] }",
            ),
            None,
            "smaller than twice the cutoff",
        ),
        (
            base.replace(
                "read_data = \"start.data\"",
                "lattice = { kind = \"hcp\", density = 0.8442, cells = [5, 5, 5] }",
            ),
            None,
            "system.lattice.kind 'hcp' is unknown",
        ),
        (
            base.replace("read_data = \"start.data\"", "read_data = \"missing.data\""),
            None,
            "missing.data: cannot read",
        ),
        (
            base.replace("model = \"md\"", "model = \"md\"\ndimension = 2"),
            Some(GOOD_DATA.into()),
            "a 2D system needs z = 0 and vz = 0 (is this a 3D data file? set dimension = 3)",
        ),
    ];
    for (scenario, data, want) in cases {
        let dir = tempfile::tempdir().unwrap();
        let (code, err) = failure(dir.path(), &scenario, data.as_deref(), &[]);
        assert_eq!(code, 2, "{want}: {err}");
        assert!(err.contains(want), "expected '{want}' in: {err}");
    }
    let dir = tempfile::tempdir().unwrap();
    let (code, err) = failure(dir.path(), base, Some(GOOD_DATA), &["--set", "run"]);
    assert_eq!(code, 2);
    assert!(err.contains("--set run: expected KEY=VALUE"), "{err}");
}

#[test]
fn a_blow_up_names_the_step_and_the_atom_and_keeps_the_last_state() {
    // two atoms far inside the repulsive core, a huge dt and a fixed z boundary
    let data = GOOD_DATA.replace("2 1 2 2 2", "2 1 1.3 1.3 1.3");
    let scenario = "model = \"md\"\n[system]\nread_data = \"start.data\"\nboundary = [\"p\", \"p\", \"f\"]\n[pair]\nstyle = \"lj/cut\"\ncutoff = 2.5\n\
        [run]\nsteps = 100\ndt = 0.05\n[output]\ndump = { every = 1000, file = \"d.lammpstrj\" }\n";
    let dir = tempfile::tempdir().unwrap();
    let (code, err) = failure(dir.path(), scenario, Some(&data), &[]);
    assert_eq!(code, 3, "{err}");
    assert!(
        err.contains("step 1: atom 1 left the box through the non-periodic z boundary"),
        "{err}"
    );
    // the dump keeps its regular frames; the last good state (step 0) is a frame
    // and a checkpoint of its own
    let frames = read_dump(&dir.path().join("out/d.lammpstrj"));
    assert_eq!(frames.iter().map(|f| f.step).collect::<Vec<_>>(), [0]);
    let last = read_dump(&dir.path().join("out/last.lammpstrj"));
    assert_eq!(last.iter().map(|f| f.step).collect::<Vec<_>>(), [0]);
    assert!(err.contains("the last good state (step 0) is in"), "{err}");
    assert!(dir.path().join("out/last.ckpt").is_file());
}
