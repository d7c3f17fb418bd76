//! MPI test of the command line (feature `mpi`; its own binary, run directly,
//! not under mpirun: it starts `mpirun` itself). `cellist run` on one rank is
//! the plain run; md on 2, 3 and 4 ranks gives the dumps (with per-atom
//! energies) and the thermo of the plain run within 1e-10 after 100 steps (and
//! with `[run] reproducible = true`, as pse always, the same bytes on 2, 3 and
//! 4 ranks), an uneven md system (a slab
//! in a third of the box) with balanced planes likewise, a 4-rank
//! checkpoint continues in one process and on 2 ranks like the uninterrupted
//! run; gravity's direct sum with its bodies divided among 1 to 4 ranks gives
//! the plain run's dumps within 1e-10, also with ranks that own no body (2
//! bodies) and with more bodies than one block of rank 0's pulls; the
//! Barnes-Hut trees of gravity and of the vortex model on 1 to 4 ranks give
//! the bytes of the plain run; gravity's PM and P3M and the vortex-in-cell
//! velocity on a slab-decomposed mesh on 1 to 4 ranks give the plain run's
//! dumps and fields within 1e-10; the 3D vortex model's vortex-in-cell and
//! tree on 1 to 4 ranks give the bytes of the plain run's fields, its direct
//! sum (block pairs dealt out) the fields within 1e-10; md, pse and gravity (ring and tree) on 2
//! ranks write `summary.json` with the MPI figures; bad input, a thin
//! subdomain, more ranks than mesh planes and a blow-up (md's, gravity's
//! with its bodies divided among the ranks, and the 3D vortex model's with
//! every particle on every rank) stop every rank with one message
//! from rank 0 and a non-zero status, never a hang. Ends with `N passed, N
//! failed`.
//!
//! ```text
//! cargo test --release -p cellist-cli --features mpi --test mpi_cli
//! ```

use std::path::{Path, PathBuf};

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

/// A small LJ melt (2048 atoms, 100 steps) whose dump at steps 50 and 100
/// holds positions, velocities, forces and per-atom energies (thermo every 20
/// steps: steps that observe the thermo alone, and steps that also observe
/// the energies), written as `dir/melt.toml`.
fn melt_scenario(dir: &Path) -> String {
    let path = dir.join("melt.toml");
    std::fs::write(
        &path,
        r#"model = "md"
[system]
lattice = { kind = "fcc", density = 0.8442, cells = [8, 8, 8] }
velocity = { temperature = 3.0, seed = 87287 }
[pair]
cutoff = 2.5
shift = true
[run]
steps = 100
[output]
thermo_every = 20
dump = { every = 50, file = "melt.dump", columns = ["id", "x", "y", "z", "vx", "vy", "vz", "fx", "fy", "fz", "pe"] }
checkpoint = { every = 50 }
"#,
    )
    .expect("write the scenario");
    path.display().to_string()
}

/// A small PSE run (128^2 particles, 100 RK4 steps) whose field at step 100
/// is `field_100.csv`, written as `dir/pse.toml`.
fn pse_scenario(dir: &Path) -> String {
    let path = dir.join("pse.toml");
    std::fs::write(
        &path,
        r#"model = "pse"
dimension = 2
[system]
lattice = { n = 128 }
nu = 1.0
epsilon = 0.01171875
cutoff_factor = 5.0
method = "cell-list"
initial = { kind = "gaussian", center = [0.5, 0.5], width = 0.05 }
[run]
steps = 100
dt = 8e-6
integrator = "rk4"
[output]
thermo_every = 20
field = { every = 50, file = "field.csv" }
checkpoint = { every = 50 }
"#,
    )
    .expect("write the scenario");
    path.display().to_string()
}

/// An uneven md system: an fcc slab of 8 x 8 x 8 cells (2048 atoms) filling
/// the lower third of a box three times longer along x
/// (`scripts/lj-slab-data.py`), heated to T = 3 so that it spreads into the
/// vacuum, with `[decomposition] balance = "rcb"`; written as
/// `dir/slab/slab.toml` beside its data file, its dump at step 100
/// `slab.dump`.
fn slab_scenario(dir: &Path) -> Result<String, String> {
    let folder = dir.join("slab");
    std::fs::create_dir_all(&folder).map_err(|e| e.to_string())?;
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/lj-slab-data.py");
    let data = Command::new("python3")
        .arg(&script)
        .args(["--cells", "8", "8", "8", "--stretch", "3"])
        .output()
        .map_err(|e| format!("python3 {}: {e}", script.display()))?;
    if !data.status.success() {
        return Err(String::from_utf8_lossy(&data.stderr).into_owned());
    }
    std::fs::write(folder.join("slab.data"), &data.stdout).map_err(|e| e.to_string())?;
    let path = folder.join("slab.toml");
    std::fs::write(
        &path,
        r#"model = "md"
[system]
read_data = "slab.data"
velocity = { temperature = 3.0, seed = 87287 }
[pair]
cutoff = 2.5
shift = true
[run]
steps = 100
[decomposition]
balance = "rcb"
[output]
thermo_every = 20
dump = { every = 100, file = "slab.dump", columns = ["id", "x", "y", "z", "vx", "vy", "vz", "fx", "fy", "fz"] }
"#,
    )
    .map_err(|e| e.to_string())?;
    Ok(path.display().to_string())
}

/// The slab of [`slab_scenario`] with balanced planes: on 1 to 4 ranks the
/// dumps of the plain run within 1e-10, reproducible the same bytes on 2, 3
/// and 4 ranks, and on 4 ranks the planes were placed again during the run
/// (the atoms spread out of the balanced subdomains).
fn balanced_slab(dir: &Path) -> Result<(), String> {
    let scenario = slab_scenario(dir)?;
    let folder = dir.join("slab");
    for same_bytes in [false, true] {
        distributed_runs_match_the_plain_run(&folder, "md", &scenario, "slab.dump", same_bytes)?;
    }
    let out = folder.join("np4-speed");
    let o = mpirun(4, &["run", &scenario, "--out", out.to_str().unwrap()])?;
    let said = String::from_utf8_lossy(&o.stdout);
    if !o.status.success() || !said.contains("planes placed again") {
        return Err(format!("-np 4 said no `planes placed again`:\n{said}"));
    }
    if said.contains("planes placed again 0 times") {
        return Err(format!("-np 4 never placed its planes again:\n{said}"));
    }
    Ok(())
}

/// A Plummer sphere of 1000 bodies under `solver`, 100 leapfrog steps,
/// written as `dir/NAME.toml`.
fn gravity_scenario(dir: &Path, name: &str, solver: &str) -> String {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            r#"model = "gravity"
[system]
initial = {{ kind = "plummer", n = 1000, seed = 1 }}
softening = 0.01
solver = {solver}
[run]
steps = 100
dt = 0.01
integrator = "leapfrog"
[output]
thermo_every = 20
dump = {{ every = 50, file = "stars.dump", columns = ["id", "x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az", "phi"] }}
checkpoint = {{ every = 50 }}
"#
        ),
    )
    .expect("write the scenario");
    path.display().to_string()
}

/// The direct-sum gravity `scenario` with its Plummer sphere's 1000 bodies
/// replaced by `initial`, 10 steps, a dump at the last: `dir/NAME.toml`.
fn gravity_variant(dir: &Path, name: &str, scenario: &str, initial: &str) -> String {
    let text = std::fs::read_to_string(scenario).expect("the gravity scenario");
    let path = dir.join(format!("{name}.toml"));
    let text = text
        .replace(
            r#"initial = { kind = "plummer", n = 1000, seed = 1 }"#,
            &format!("initial = {initial}"),
        )
        .replace("steps = 100", "steps = 10")
        .replace("every = 50, file", "every = 10, file")
        .replace("checkpoint = { every = 50 }", "");
    std::fs::write(&path, text).expect("write the scenario");
    path.display().to_string()
}

/// A body file of 2000 bodies in the plane z = 0 (`m x y z vx vy vz`, all
/// points apart), with `change(i, line)` applied to each: `dir/NAME.txt`.
fn body_file(dir: &Path, name: &str, change: impl Fn(usize, String) -> String) -> String {
    let path = dir.join(format!("{name}.txt"));
    let text: String = (0..2000)
        .map(|i| {
            let (t, r) = (i as f64 * 2.399_963, (1.0 + i as f64).sqrt() / 10.0);
            let line = format!(
                "0.0005 {} {} 0 {} {} 0\n",
                r * t.cos(),
                r * t.sin(),
                -0.1 * t.sin(),
                0.1 * t.cos()
            );
            change(i, line)
        })
        .collect();
    std::fs::write(&path, text).expect("write the body file");
    path.display().to_string()
}

/// A vortex pair under the `velocity` solver, remeshed, 20 RK4 steps, written
/// as `dir/NAME.toml`.
fn vortex_scenario(dir: &Path, name: &str, velocity: &str) -> String {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            r#"model = "vortex"
dimension = 2
[system]
initial = {{ kind = "pair", circulation = 1.0, separation = 0.3, core = 0.06, spacing = 0.025, extent = 0.4 }}
nu = 0.0002
velocity = {velocity}
remesh_every = 5
[run]
steps = 20
dt = 0.01
integrator = "rk4"
[output]
thermo_every = 10
field = {{ every = 20, file = "vorticity.csv" }}
"#
        ),
    )
    .expect("write the scenario");
    path.display().to_string()
}

/// A small viscous 3D vortex ring under the `velocity` solver, remeshed, 3
/// RK2 steps, written as `dir/NAME.toml`.
fn vortex3_scenario(dir: &Path, name: &str, velocity: &str) -> String {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            r#"model = "vortex"
dimension = 3
[system]
initial = {{ kind = "ring", radius = 0.5, circulation = 1.0, core = 0.2, spacing = 0.1, center = [0.0, 0.0, 0.0], axis = [0.0, 0.0, 1.0] }}
nu = 0.001
velocity = {velocity}
remesh_every = 2
[run]
steps = 3
dt = 0.05
integrator = "rk2"
[output]
thermo_every = 1
field = {{ every = 3, file = "vorticity.csv" }}
"#
        ),
    )
    .expect("write the scenario");
    path.display().to_string()
}

/// The scenario file `path` with each `(from, to)` of `changes` made (each
/// `from` must be in it), written back; its path.
fn with_replaced(path: &str, changes: &[(&str, &str)]) -> String {
    let mut text = std::fs::read_to_string(path).expect("read the scenario");
    for (from, to) in changes {
        assert!(text.contains(from), "{path} has no {from}");
        text = text.replace(from, to);
    }
    std::fs::write(path, text).expect("write the scenario");
    path.to_string()
}

/// `cellist run ARGS` in one process.
fn plain(args: &[&str]) -> Result<(), String> {
    let o = Command::new(env!("CARGO_BIN_EXE_cellist"))
        .args(args)
        .output()
        .map_err(|e| e.to_string())?;
    if o.status.success() {
        Ok(())
    } else {
        Err(format!(
            "the plain run {args:?} failed: {}",
            String::from_utf8_lossy(&o.stderr)
        ))
    }
}

/// `mpirun -np RANKS cellist ARGS`, which must succeed.
fn distributed(ranks: usize, args: &[&str]) -> Result<(), String> {
    let o = mpirun(ranks, args)?;
    if o.status.success() {
        Ok(())
    } else {
        Err(format!(
            "-np {ranks} {args:?} failed: {}",
            String::from_utf8_lossy(&o.stderr)
        ))
    }
}

/// The largest difference between the numbers of two dumps, which must have
/// the same lines with the same words where they are not numbers.
fn dump_difference(a: &Path, b: &Path) -> Result<f64, String> {
    let read = |p: &Path| std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()));
    let (a, b) = (read(a)?, read(b)?);
    if a.lines().count() != b.lines().count() {
        return Err("the dumps have different numbers of lines".into());
    }
    let words = |line: &str| -> Vec<String> {
        line.split([' ', ','])
            .filter(|w| !w.is_empty())
            .map(String::from)
            .collect()
    };
    let mut most = 0.0f64;
    for (x, y) in a.lines().zip(b.lines()) {
        let (wx, wy) = (words(x), words(y));
        if wx.len() != wy.len() {
            return Err(format!("lines differ: `{x}` and `{y}`"));
        }
        for (u, v) in wx.iter().zip(&wy) {
            match (u.parse::<f64>(), v.parse::<f64>()) {
                (Ok(p), Ok(q)) if p == q => {}
                // a NaN on either side counts as an infinite difference
                (Ok(p), Ok(q)) => {
                    most = most.max((p - q).abs()).max(if (p - q).is_nan() {
                        f64::INFINITY
                    } else {
                        0.0
                    })
                }
                _ if u == v => {}
                _ => return Err(format!("lines differ: `{x}` and `{y}`")),
            }
        }
    }
    Ok(most)
}

/// `scenario` (of `model`, writing `file`) on 1 to 4 ranks against the plain
/// run: `file` and `thermo.csv` within 1e-10; with `same_bytes` (the sums in
/// id order: md with `[run] reproducible = true`, pse) the same bytes on 2, 3
/// and 4 ranks.
fn distributed_runs_match_the_plain_run(
    dir: &Path,
    model: &str,
    scenario: &str,
    file: &str,
    same_bytes: bool,
) -> Result<(), String> {
    let out = |name: &str| run_folder(dir, model, same_bytes, name);
    let text = |p: PathBuf| p.display().to_string();
    let sets: &[&str] = if same_bytes && model == "md" {
        &["--set", "run.reproducible=true"]
    } else {
        &[]
    };
    let args = |folder: PathBuf| {
        let mut args = vec![
            "run".to_string(),
            scenario.to_string(),
            "--out".into(),
            text(folder),
        ];
        args.extend(sets.iter().map(|s| s.to_string()));
        args
    };
    plain(&strs(&args(out("plain"))))?;
    for ranks in [1, 2, 3, 4] {
        let name = format!("np{ranks}");
        distributed(ranks, &strs(&args(out(&name))))?;
        for file in [file, "thermo.csv"] {
            let d = dump_difference(&out("plain").join(file), &out(&name).join(file))?;
            if d > 1e-10 {
                return Err(format!(
                    "-np {ranks}: {file} differs from the plain run by {d:e}"
                ));
            }
        }
    }
    for file in [file, "thermo.csv"] {
        let read = |ranks: usize| std::fs::read(out(&format!("np{ranks}")).join(file));
        let two = read(2).map_err(|e| e.to_string())?;
        for ranks in [3, 4] {
            if same_bytes && read(ranks).map_err(|e| e.to_string())? != two {
                return Err(format!(
                    "{file} of 2 and {ranks} ranks are not the same bytes"
                ));
            }
        }
    }
    Ok(())
}

/// The folder of the run `name` (`plain`, `np2`, ...) of
/// [`distributed_runs_match_the_plain_run`].
fn run_folder(dir: &Path, model: &str, same_bytes: bool, name: &str) -> PathBuf {
    let mode = if same_bytes { "same" } else { "near" };
    dir.join(format!("{model}-{mode}-{name}"))
}

/// `scenario` of `model` on 1 to 4 ranks against the plain run (in a folder
/// of its own): within 1e-10, and each of `files` the same bytes as the plain
/// run's on every rank count (the vortex runs' thermo too: in 2D its energy
/// and enstrophy rows are dealt out among the ranks and added in row order,
/// and in both the PSE rates are shared). Barnes-Hut trees: each particle's tree sum runs as in
/// one process, whichever rank computes it. Gravity's divided meshes: each
/// node sums its bodies in their order, and each P3M short-range sum runs
/// over the same cells in the same order, as in one process.
fn runs_have_the_plain_bytes(
    dir: &Path,
    model: &str,
    scenario: &str,
    files: &[&str],
) -> Result<(), String> {
    let stem = Path::new(scenario)
        .file_stem()
        .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
    let folder = dir.join(format!("{model}-{stem}-bytes"));
    std::fs::create_dir_all(&folder).map_err(|e| e.to_string())?;
    distributed_runs_match_the_plain_run(&folder, model, scenario, files[0], false)?;
    for file in files {
        let read = |name: &str| {
            let path = run_folder(&folder, model, false, name).join(file);
            std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))
        };
        let plain = read("plain")?;
        for ranks in [1, 2, 3, 4] {
            if read(&format!("np{ranks}"))? != plain {
                return Err(format!(
                    "-np {ranks}: {file} is not the bytes of the plain run"
                ));
            }
        }
    }
    Ok(())
}

/// An fcc crystal of 14^3 cells (10976 atoms) read from a data file whose
/// ids jump from 5488 to 1000001: rank 0 pulls its frames by id ranges, and
/// the middle ones hold no atom. Its step-0 GSD and VTK frames (written a
/// block at a time, the empty blocks skipped) on 2 and 3 ranks in the
/// reproducible mode: the same bytes.
fn gapped_ids_give_the_same_frames(dir: &Path) -> Result<(), String> {
    let folder = dir.join("gapped");
    std::fs::create_dir_all(&folder).map_err(|e| e.to_string())?;
    let (cells, a) = (14, (4.0f64 / 0.8442).cbrt());
    let side = cells as f64 * a;
    let mut atoms = String::new();
    let mut velocities = String::new();
    let basis = [
        [0.0, 0.0, 0.0],
        [0.5, 0.5, 0.0],
        [0.5, 0.0, 0.5],
        [0.0, 0.5, 0.5],
    ];
    let n = 4 * cells * cells * cells;
    let mut k = 0;
    for i in 0..cells {
        for j in 0..cells {
            for l in 0..cells {
                for b in basis {
                    let id = if k < n / 2 { k + 1 } else { 1_000_001 + k };
                    let x = [i as f64 + b[0], j as f64 + b[1], l as f64 + b[2]].map(|c| c * a);
                    atoms += &format!("{id} 1 {} {} {}\n", x[0], x[1], x[2]);
                    let v = (k % 7) as f64 * 0.1 - 0.3;
                    velocities += &format!("{id} {v} {} {}\n", -v, 0.5 * v);
                    k += 1;
                }
            }
        }
    }
    let data = format!(
        "gapped ids\n\n{n} atoms\n1 atom types\n\n0 {side} xlo xhi\n0 {side} ylo yhi\n0 {side} zlo zhi\n\n\
         Masses\n\n1 1.0\n\nAtoms # atomic\n\n{atoms}\nVelocities\n\n{velocities}"
    );
    std::fs::write(folder.join("gapped.data"), data).map_err(|e| e.to_string())?;
    let scenario = folder.join("gapped.toml");
    std::fs::write(
        &scenario,
        "model = \"md\"\n[system]\nread_data = \"gapped.data\"\n[pair]\ncutoff = 2.5\n\
         [run]\nsteps = 0\nreproducible = true\n[output]\n\
         gsd = { every = 1, file = \"t.gsd\" }\nvtk = { every = 1, file = \"t.pvd\" }\n",
    )
    .map_err(|e| e.to_string())?;
    let scenario = scenario.display().to_string();
    let mut frames = Vec::new();
    for ranks in [2, 3] {
        let out = folder.join(format!("np{ranks}"));
        let out = out.display().to_string();
        distributed(ranks, &["run", &scenario, "--out", &out])?;
        let read = |file: &str| {
            let path = Path::new(&out).join(file);
            std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))
        };
        frames.push((read("t.gsd")?, read("t_00000000.vtp")?));
    }
    if frames[0] != frames[1] {
        return Err("the GSD or VTK frame of 2 and 3 ranks are not the same bytes".into());
    }
    Ok(())
}

/// The md `scenario` with `[neighbor] every = 10, check = false`, distributed
/// and plain (in a folder of its own): the ranks rebuild on the steps the plain
/// run does. The skin (1.5) is wide enough that no build is late: a late build
/// may miss pairs, and lists of different shape (the plain run's clusters, the
/// ranks' atom rows) then miss different ones.
fn every_ten_without_check(dir: &Path, scenario: &str) -> Result<(), String> {
    let folder = dir.join("every-ten");
    std::fs::create_dir_all(&folder).map_err(|e| e.to_string())?;
    let text = std::fs::read_to_string(scenario).map_err(|e| e.to_string())?;
    let path = folder.join("melt.toml");
    std::fs::write(
        &path,
        format!("{text}[neighbor]\nevery = 10\ncheck = false\nskin = 1.5\n"),
    )
    .map_err(|e| e.to_string())?;
    let path = path.display().to_string();
    distributed_runs_match_the_plain_run(&folder, "md", &path, "melt.dump", false)
}

/// A checkpoint of `scenario` written at step 50 of 100 on 4 ranks, continued
/// in one process and on 2 ranks: `file` within 1e-10 of the uninterrupted run.
fn four_rank_checkpoint_continues(
    dir: &Path,
    model: &str,
    scenario: &str,
    file: &str,
) -> Result<(), String> {
    let out = |name: &str| dir.join(format!("{model}-{name}"));
    let text = |p: PathBuf| p.display().to_string();
    plain(&["run", scenario, "--out", &text(out("whole"))])?;
    for (ranks, name) in [(1usize, "restart-plain"), (2, "restart-np2")] {
        let folder = text(out(name));
        distributed(
            4,
            &["run", scenario, "--set", "run.steps=50", "--out", &folder],
        )?;
        let checkpoint = text(out(name).join("state.ckpt"));
        let args = ["run", scenario, "--restart", &checkpoint, "--out", &folder];
        if ranks == 1 {
            plain(&args)?;
        } else {
            distributed(ranks, &args)?;
        }
        let d = dump_difference(&out("whole").join(file), &out(name).join(file))?;
        if d > 1e-10 {
            return Err(format!(
                "restarted on {ranks} rank(s) from 4: {file} differs from the uninterrupted run by {d:e}"
            ));
        }
    }
    Ok(())
}

/// A blow-up on some rank stops every rank: status 3, one message, the last
/// good frame and `summary.json` written by rank 0.
fn blowup_stops_every_rank(dir: &Path) -> Result<(), String> {
    let scenario = melt_scenario(dir);
    let out = dir.join("blowup");
    let o = mpirun(
        4,
        &[
            "run",
            &scenario,
            "--set",
            "run.dt=0.5",
            "--out",
            out.to_str().unwrap(),
        ],
    )?;
    let err = String::from_utf8_lossy(&o.stderr);
    let lines = err.lines().filter(|l| l.starts_with("error: ")).count();
    if o.status.success() || lines != 1 || !err.contains("last good state") {
        return Err(format!(
            "expected one `error: ... last good state ...` line:\n{err}"
        ));
    }
    // the last good state, put together from the 4 ranks' parts, is the
    // plain run's: its frame within 1e-10, its checkpoint the same size
    let alone = dir.join("blowup-plain");
    let o = Command::new(env!("CARGO_BIN_EXE_cellist"))
        .args(["run", &scenario, "--set", "run.dt=0.5", "--out"])
        .arg(&alone)
        .output()
        .map_err(|e| e.to_string())?;
    if o.status.success() {
        return Err("the plain run with dt = 0.5 did not blow up".into());
    }
    let d = dump_difference(&alone.join("last.lammpstrj"), &out.join("last.lammpstrj"))?;
    if d > 1e-10 {
        return Err(format!(
            "the last frame differs from the plain run's by {d:e}"
        ));
    }
    let size = |p: PathBuf| {
        std::fs::metadata(&p)
            .map(|m| m.len())
            .map_err(|e| format!("{}: {e}", p.display()))
    };
    let (a, b) = (
        size(alone.join("state.ckpt"))?,
        size(out.join("state.ckpt"))?,
    );
    if a != b {
        return Err(format!(
            "last.ckpt has {b} bytes on 4 ranks, {a} in one process"
        ));
    }
    let summary = std::fs::read_to_string(out.join("summary.json")).map_err(|e| e.to_string())?;
    if !summary.contains("\"outcome\": \"blow-up\"") || !summary.contains("\"ranks\": 4") {
        return Err(format!("summary.json of the blow-up:\n{summary}"));
    }
    Ok(())
}

/// Two bodies of mass 0.5 at rest at x = -0.5 and 0.5, unsoftened, one per
/// rank of 2: after one Euler step of dt 1 they meet at x = 0 and the second
/// step's field is not finite. Every rank stops with status 3 and one
/// message naming body 0, and rank 0 writes the last good state (step 1) put
/// together from the ranks' parts: the plain run's frame and checkpoint, the
/// same bytes (each body's field is one pair's, the same on any rank).
fn gravity_blowup_on_two_ranks(dir: &Path) -> Result<(), String> {
    let folder = dir.join("gravity-blowup");
    std::fs::create_dir_all(&folder).map_err(|e| e.to_string())?;
    std::fs::write(
        folder.join("two.txt"),
        "0.5 -0.5 0 0 0 0 0\n0.5 0.5 0 0 0 0 0\n",
    )
    .map_err(|e| e.to_string())?;
    let scenario = folder.join("crash.toml");
    std::fs::write(
        &scenario,
        "model = \"gravity\"\n[system]\ninitial = { file = \"two.txt\" }\nsoftening = 0.0\n\
         [run]\nsteps = 10\ndt = 1.0\nintegrator = \"euler\"\n\
         [output]\nthermo_every = 1\ncheckpoint = { every = 1 }\n",
    )
    .map_err(|e| e.to_string())?;
    let scenario = scenario.display().to_string();
    let (alone, spread) = (folder.join("plain"), folder.join("np2"));
    let o = Command::new(env!("CARGO_BIN_EXE_cellist"))
        .args(["run", &scenario, "--out"])
        .arg(&alone)
        .output()
        .map_err(|e| e.to_string())?;
    if o.status.code() != Some(3) {
        return Err(format!("the plain run did not blow up: {o:?}"));
    }
    let o = mpirun(2, &["run", &scenario, "--out", spread.to_str().unwrap()])?;
    let err = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("error: ")).collect();
    if o.status.code() != Some(3)
        || lines.len() != 1
        || !lines[0].contains("step 2: the state of body 0 is not finite")
        || !lines[0].contains("last good state (step 1)")
    {
        return Err(format!(
            "expected status 3 and one `error: step 2: the state of body 0 ...` line:\n{err}"
        ));
    }
    for file in ["last.dump", "state.ckpt", "thermo.csv"] {
        let read = |d: &Path| std::fs::read(d.join(file)).map_err(|e| format!("{file}: {e}"));
        if read(&alone)? != read(&spread)? {
            return Err(format!("{file} of 2 ranks is not the plain run's"));
        }
    }
    Ok(())
}

/// `scenario` of `model` on 2 ranks writes one `summary.json` (rank 0's) with
/// 2 ranks, the run's steps and particles, and the MPI figures: the
/// communication time and the two imbalances (at least 1).
fn summary_on_two_ranks(
    dir: &Path,
    model: &str,
    scenario: &str,
    steps: u64,
    particles: u64,
) -> Result<(), String> {
    let name = Path::new(scenario).file_stem().map(|s| s.to_string_lossy());
    let out = dir.join(format!("{}-summary", name.unwrap_or_default()));
    distributed(2, &["run", scenario, "--out", out.to_str().unwrap()])?;
    let text = std::fs::read_to_string(out.join("summary.json")).map_err(|e| e.to_string())?;
    let json: serde_json::Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
    let number = |key: &str| json[key].as_f64().ok_or(format!("no {key} in:\n{text}"));
    let expected = [
        ("model", serde_json::json!(model)),
        ("outcome", serde_json::json!("completed")),
        ("ranks", serde_json::json!(2)),
        ("steps", serde_json::json!(steps)),
        ("particles", serde_json::json!(particles)),
    ];
    for (key, value) in expected {
        if json[key] != value {
            return Err(format!("{key} is not {value} in:\n{text}"));
        }
    }
    let at_least = [
        ("loop_seconds", f64::MIN_POSITIVE),
        ("communication_seconds", 0.0),
        ("imbalance_particles", 1.0),
        ("imbalance_busy", 1.0),
        ("peak_rss_bytes", 1.0),
    ];
    for (key, least) in at_least {
        if number(key)? < least {
            return Err(format!("{key} is below {least} in:\n{text}"));
        }
    }
    Ok(())
}

/// A 3D vortex ring (`scenario`, every rank holding every particle) whose
/// strengths overflow in the first step (or in the second, after an observed
/// step that only rank 0 writes), on 2 ranks: every rank stops with
/// one message naming the last good state, whose field file rank 0 writes
/// with the plain run's bytes (the ranks restore it together: its velocity
/// is a shared sum).
fn vortex3_blowup_on_two_ranks(dir: &Path, scenario: &str) -> Result<(), String> {
    // strengths of 1e150 blow up in step 1; of 1e30 in step 2, after a thermo
    // row of step 1, which only rank 0 writes but every rank keeps as the last
    // good state (they restore it together: the PSE rates are shared)
    for (circulation, good) in [("1e150", 0), ("1e30", 1)] {
        let huge = format!("system.initial.circulation={circulation}");
        let name = format!("vortex3-blowup-{circulation}");
        let (out, alone) = (dir.join(&name), dir.join(format!("{name}-plain")));
        let args = [
            "run",
            scenario,
            "--out",
            out.to_str().unwrap(),
            "--set",
            &huge,
        ];
        let o = mpirun(2, &args)?;
        let err = String::from_utf8_lossy(&o.stderr);
        let lines = err.lines().filter(|l| l.starts_with("error: ")).count();
        let expected = format!("last good state (step {good})");
        if o.status.success() || lines != 1 || !err.contains(&expected) {
            return Err(format!(
                "strengths of {circulation}: expected one `error: ... {expected} ...` line:\n{err}"
            ));
        }
        let o = Command::new(env!("CARGO_BIN_EXE_cellist"))
            .args(["run", scenario, "--out"])
            .arg(&alone)
            .args(["--set", &huge])
            .output()
            .map_err(|e| e.to_string())?;
        if o.status.success() {
            return Err(format!(
                "the plain run with strengths of {circulation} did not blow up"
            ));
        }
        let read = |d: &Path| std::fs::read(d.join("last.csv")).map_err(|e| e.to_string());
        if read(&out)? != read(&alone)? {
            return Err(format!(
                "strengths of {circulation}: last.csv of 2 ranks is not the plain run's"
            ));
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
    let melt = melt_scenario(dir.path());
    let pse = pse_scenario(dir.path());
    let gravity = gravity_scenario(dir.path(), "gravity", r#"{ kind = "direct" }"#);
    let two_bodies = gravity_variant(
        dir.path(),
        "gravity-two",
        &gravity,
        r#"{ kind = "two-body-seed004" }"#,
    );
    let five_thousand = gravity_variant(
        dir.path(),
        "gravity-5000",
        &gravity,
        r#"{ kind = "plummer", n = 5000, seed = 2 }"#,
    );
    let pm = gravity_scenario(dir.path(), "pm", r#"{ kind = "pm", grid = 16 }"#);
    // the potentials of a divided mesh agree to rounding: a dump without them
    let pm_motion = dir.path().join("pm-motion.toml");
    std::fs::write(
        &pm_motion,
        std::fs::read_to_string(&pm)
            .expect("the pm scenario")
            .replace(r#", "phi"]"#, "]"),
    )
    .expect("write the scenario");
    let pm_motion = pm_motion.display().to_string();
    let pm_two = gravity_variant(
        dir.path(),
        "pm-two",
        &pm,
        r#"{ kind = "two-body-seed004" }"#,
    );
    let p3m = gravity_scenario(
        dir.path(),
        "p3m",
        r#"{ kind = "p3m", grid = 16, boundary = "periodic", box = 40.0 }"#,
    );
    let gravity_tree = gravity_scenario(
        dir.path(),
        "gravity-tree",
        r#"{ kind = "barnes-hut", theta = 0.6 }"#,
    );
    let gravity_fmm = gravity_scenario(
        dir.path(),
        "gravity-fmm",
        r#"{ kind = "fmm", tolerance = 1e-6 }"#,
    );
    // each rank draws its block of a sphere beyond the exact virial's 20000
    let pm_drawn = gravity_variant(
        dir.path(),
        "pm-30000",
        &pm_motion,
        r#"{ kind = "plummer", n = 30000, seed = 3 }"#,
    );
    let bodies = body_file(dir.path(), "bodies", |_, line| line);
    let pm_read = gravity_variant(
        dir.path(),
        "pm-read",
        &pm_motion,
        &format!("{{ file = {bodies:?} }}"),
    );
    let shared = body_file(dir.path(), "shared", |i, line| {
        if i == 1500 {
            "0.0005 5 5 -0 0 0 0\n".into()
        } else if i == 3 {
            "0.0005 5 5 0 1 1 0\n".into()
        } else {
            line
        }
    });
    let shared = gravity_variant(
        dir.path(),
        "shared",
        &gravity,
        &format!("{{ file = {shared:?} }}"),
    );
    let off_plane = body_file(dir.path(), "off-plane", |i, line| {
        if i == 1700 {
            line.replacen(" 0 ", " 0.5 ", 1)
        } else {
            line
        }
    });
    let off_plane = gravity_variant(
        dir.path(),
        "off-plane",
        &gravity,
        &format!("{{ file = {off_plane:?} }}"),
    );
    let vortex = vortex_scenario(dir.path(), "vortex", r#"{ kind = "direct" }"#);
    let vic = vortex_scenario(dir.path(), "vic", r#"{ kind = "mesh", grid = 32 }"#);
    let vortex_tree = vortex_scenario(
        dir.path(),
        "vortex-tree",
        r#"{ kind = "barnes-hut", theta = 0.5 }"#,
    );
    let vic3 = vortex3_scenario(dir.path(), "vic3", r#"{ kind = "mesh", grid = 16 }"#);
    let vortex3_tree = vortex3_scenario(
        dir.path(),
        "vortex3-tree",
        r#"{ kind = "barnes-hut", theta = 0.5 }"#,
    );
    // not remeshed: its 6384 particles grow to 51514 by step 3, whose direct
    // sums took 50 s of one core, near the hang check's minute
    let vortex3 = with_replaced(
        &vortex3_scenario(dir.path(), "vortex3", r#"{ kind = "direct" }"#),
        &[("remesh_every = 2", "remesh_every = 1000")],
    );
    // several of the fmm's target groups (at most 4096 particles each in 2D,
    // 8192 in 3D): about 10^4 particles (in 3D not remeshed, which would
    // make five times as many)
    let vortex_fmm = with_replaced(
        &vortex_scenario(
            dir.path(),
            "vortex-fmm",
            r#"{ kind = "fmm", tolerance = 1e-8 }"#,
        ),
        &[("spacing = 0.025", "spacing = 0.008")],
    );
    let vortex3_fmm = with_replaced(
        &vortex3_scenario(
            dir.path(),
            "vortex3-fmm",
            r#"{ kind = "fmm", tolerance = 1e-4 }"#,
        ),
        &[
            ("spacing = 0.1", "spacing = 0.085"),
            ("remesh_every = 2", "remesh_every = 1000"),
        ],
    );
    let cases: Vec<(&str, Result<(), String>)> = vec![
        (
            "-np 1 writes the bytes of the plain run",
            one_rank_is_the_plain_run(dir.path()),
        ),
        (
            "md on 1 to 4 ranks: the dumps of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "md", &melt, "melt.dump", false),
        ),
        (
            "md reproducible on 1 to 4 ranks: within 1e-10 of the plain run, the same bytes on 2, 3 and 4 ranks",
            distributed_runs_match_the_plain_run(dir.path(), "md", &melt, "melt.dump", true),
        ),
        (
            "md, its list rebuilt every 10 steps without the check, on 1 to 4 ranks: the dumps of the plain run within 1e-10",
            every_ten_without_check(dir.path(), &melt),
        ),
        (
            "md, an fcc slab in a third of the box, balanced planes, on 1 to 4 ranks: within 1e-10 of the plain run, reproducible the same bytes on 2, 3 and 4 ranks, the planes placed again on 4",
            balanced_slab(dir.path()),
        ),
        (
            "pse on 1 to 4 ranks: the fields of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "pse", &pse, "field_100.csv", true),
        ),
        (
            "gravity direct by the ring on 1 to 4 ranks: the dumps of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "gravity", &gravity, "stars.dump", false),
        ),
        (
            "gravity direct, 2 bodies on 1 to 4 ranks (ranks with no body): the dumps of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "gravity-two", &two_bodies, "stars.dump", false),
        ),
        (
            "gravity direct, 5000 bodies on 1 to 4 ranks (rank 0 pulls two blocks): the dumps of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "gravity-5000", &five_thousand, "stars.dump", false),
        ),
        (
            "vortex direct with its block pairs dealt out on 1 to 4 ranks: the fields of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "vortex", &vortex, "vorticity_20.csv", false),
        ),
        (
            "gravity pm (isolated), the bodies divided, on a slab-decomposed mesh on 1 to 4 ranks: the dumps of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "gravity-pm", &pm, "stars.dump", false),
        ),
        (
            "gravity pm, the bodies divided: on 1 to 4 ranks the bytes of the plain run's positions, velocities and accelerations",
            runs_have_the_plain_bytes(dir.path(), "gravity", &pm_motion, &["stars.dump"]),
        ),
        (
            "gravity pm, 2 bodies on 1 to 4 ranks (ranks with no body): the dumps of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "gravity-pm-two", &pm_two, "stars.dump", false),
        ),
        (
            "gravity pm, a Plummer sphere of 30000 bodies (each rank draws its own block): on 1 to 4 ranks the bytes of the plain run's dump and picture",
            runs_have_the_plain_bytes(dir.path(), "gravity", &pm_drawn, &["stars.dump", "bodies.png"]),
        ),
        (
            "gravity pm, 2000 bodies from a file (each rank reads its own block): on 1 to 4 ranks the bytes of the plain run's dump and picture",
            runs_have_the_plain_bytes(dir.path(), "gravity", &pm_read, &["stars.dump", "bodies.png"]),
        ),
        (
            "gravity p3m (periodic), the bodies divided: on 1 to 4 ranks the bytes of the plain run's dumps",
            runs_have_the_plain_bytes(dir.path(), "gravity", &p3m, &["stars.dump"]),
        ),
        (
            "gravity p3m (periodic) on a slab-decomposed mesh on 1 to 4 ranks: the dumps of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "gravity-p3m", &p3m, "stars.dump", false),
        ),
        (
            "vortex mesh (vortex-in-cell) on a slab-decomposed mesh on 1 to 4 ranks: the fields of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "vortex-mesh", &vic, "vorticity_20.csv", false),
        ),
        (
            "gravity barnes-hut on 1 to 4 ranks: the bytes of the plain run's dumps",
            runs_have_the_plain_bytes(dir.path(), "gravity", &gravity_tree, &["stars.dump"]),
        ),
        (
            "gravity fmm on 1 to 4 ranks (every body gathered, the target groups dealt out): the bytes of the plain run's dumps",
            runs_have_the_plain_bytes(dir.path(), "gravity", &gravity_fmm, &["stars.dump"]),
        ),
        (
            "vortex barnes-hut on 1 to 4 ranks: the bytes of the plain run's fields and thermo",
            runs_have_the_plain_bytes(dir.path(), "vortex", &vortex_tree, &["vorticity_20.csv", "thermo.csv"]),
        ),
        (
            "3D vortex mesh (vortex-in-cell) on a slab-decomposed mesh on 1 to 4 ranks: the bytes of the plain run's fields and thermo",
            runs_have_the_plain_bytes(dir.path(), "vortex3", &vic3, &["vorticity_3.csv", "thermo.csv"]),
        ),
        (
            "3D vortex direct with its block pairs dealt out on 1 to 4 ranks: the fields of the plain run within 1e-10",
            distributed_runs_match_the_plain_run(dir.path(), "vortex3-direct", &vortex3, "vorticity_3.csv", false),
        ),
        (
            "3D vortex barnes-hut on 1 to 4 ranks: the bytes of the plain run's fields and thermo",
            runs_have_the_plain_bytes(dir.path(), "vortex3", &vortex3_tree, &["vorticity_3.csv", "thermo.csv"]),
        ),
        (
            "vortex fmm on 1 to 4 ranks (its target groups dealt out): the bytes of the plain run's fields and thermo",
            runs_have_the_plain_bytes(dir.path(), "vortex", &vortex_fmm, &["vorticity_20.csv", "thermo.csv"]),
        ),
        (
            "3D vortex fmm on 1 to 4 ranks (its target groups and blob rest's cell layers dealt out): the bytes of the plain run's fields and thermo",
            runs_have_the_plain_bytes(dir.path(), "vortex3", &vortex3_fmm, &["vorticity_3.csv", "thermo.csv"]),
        ),
        (
            "md with gapped ids (empty id ranges) on 2 and 3 ranks: the same GSD and VTK frames",
            gapped_ids_give_the_same_frames(dir.path()),
        ),
        (
            "gravity: a 4-rank checkpoint continues in one process and on 2 ranks",
            four_rank_checkpoint_continues(dir.path(), "gravity", &gravity, "stars.dump"),
        ),
        (
            "md: a 4-rank checkpoint continues in one process and on 2 ranks",
            four_rank_checkpoint_continues(dir.path(), "md", &melt, "melt.dump"),
        ),
        (
            "pse: a 4-rank checkpoint continues in one process and on 2 ranks",
            four_rank_checkpoint_continues(dir.path(), "pse", &pse, "field_100.csv"),
        ),
        (
            "md on 2 ranks: summary.json with the MPI figures",
            summary_on_two_ranks(dir.path(), "md", &melt, 100, 2048),
        ),
        (
            "pse on 2 ranks: summary.json with the MPI figures",
            summary_on_two_ranks(dir.path(), "pse", &pse, 100, 128 * 128),
        ),
        (
            "gravity by the ring on 2 ranks: summary.json with the MPI figures",
            summary_on_two_ranks(dir.path(), "gravity", &gravity, 100, 1000),
        ),
        (
            "gravity barnes-hut on 2 ranks: summary.json with the MPI figures",
            summary_on_two_ranks(dir.path(), "gravity", &gravity_tree, 100, 1000),
        ),
        (
            "-np 4: a blow-up stops every rank with one message",
            blowup_stops_every_rank(dir.path()),
        ),
        (
            "-np 2: gravity's bodies meet, every rank stops with one message, the plain run's last state",
            gravity_blowup_on_two_ranks(dir.path()),
        ),
        (
            "-np 2: a 3D vortex blow-up (the mesh shared) stops every rank with one message, the plain run's last state",
            vortex3_blowup_on_two_ranks(dir.path(), &vic3),
        ),
        (
            "-np 3: a subdomain thinner than cutoff + skin, one message",
            refused_once(
                3,
                &["run", &melt, "--set", "pair.cutoff=4.5"],
                "thinner than the cutoff + skin",
            ),
        ),
        (
            "-np 9: a mesh of 8 planes for 9 ranks, one message",
            refused_once(
                9,
                &["run", &pm, "--set", "system.solver.grid=8"],
                "9 ranks share a mesh of only 8 planes",
            ),
        ),
        (
            "-np 9: a vortex mesh of 16 rows for 9 ranks, one message",
            refused_once(
                9,
                &["run", &vic, "--set", "system.velocity.grid=16"],
                "9 ranks share a mesh of only 16 planes (grid 16): its slabs need at least 2",
            ),
        ),
        (
            "-np 9: a 3D vortex mesh of 16 planes for 9 ranks, one message",
            refused_once(
                9,
                &["run", &vic3],
                "9 ranks share a mesh of only 16 planes (grid 16): its slabs need at least 2",
            ),
        ),
        (
            "-np 3: bodies 3 and 1500 (on ranks 0 and 2) at one point, softening 0: one message, the plain run's",
            refused_once(
                3,
                &["run", &shared, "--set", "system.softening=0.0"],
                "particles 3 and 1500 are at the same point [5.0, 5.0, 0.0] and the softening is 0",
            ),
        ),
        (
            "-np 4: body 1700 (on rank 3) off the plane of a 2D run: one message, the plain run's",
            refused_once(
                4,
                &["run", &off_plane, "--set", "dimension=2"],
                "body 1700 has z = 0.5, vz = 0",
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

/// The arguments as `&str`s.
fn strs(args: &[String]) -> Vec<&str> {
    args.iter().map(String::as_str).collect()
}
