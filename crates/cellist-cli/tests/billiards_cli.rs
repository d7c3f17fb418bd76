//! End-to-end runs of `cellist billiards` and `cellist bench billiards` against the
//! benchmark's golden files, its reference simulator and its validator.

mod common;

use common::{cellist, shared_testdata};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The 15 public inputs, as `(dir__name, path)`.
fn public_inputs(data: &Path) -> Vec<(String, PathBuf)> {
    let mut inputs = Vec::new();
    for dir in ["", "correctness", "small", "standard"] {
        let folder = data.join("inputs").join(dir);
        let mut names: Vec<PathBuf> = std::fs::read_dir(&folder)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "in"))
            .collect();
        names.sort();
        for path in names {
            let stem = path.file_stem().unwrap().to_string_lossy().to_string();
            let key = if dir.is_empty() {
                stem
            } else {
                format!("{dir}__{stem}")
            };
            inputs.push((key, path));
        }
    }
    inputs
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn final_states_equal_the_golden_bits_with_1_and_2_threads_and_both_cell_shapes() {
    let Some(data) = shared_testdata("billiards") else {
        return;
    };
    let inputs = public_inputs(&data);
    assert_eq!(inputs.len(), 15, "the 15 public inputs");
    for (key, path) in inputs {
        let golden = std::fs::read(data.join("golden").join(format!("{key}.final.bits"))).unwrap();
        // hexagonal cells find the same contacts: the same bits
        for (threads, cells) in [("1", "square"), ("2", "square"), ("1", "hex"), ("2", "hex")] {
            let out = cellist(&[
                "billiards",
                "run",
                path.to_str().unwrap(),
                "--format",
                "bits",
                "--threads",
                threads,
                "--cells",
                cells,
            ]);
            assert!(out.status.success(), "{key}: {}", text(&out.stderr));
            assert!(
                out.stdout == golden,
                "{key} on {threads} thread(s) with {cells} cells differs from the golden bits"
            );
        }
        let out = cellist(&["billiards", "run", path.to_str().unwrap()]);
        let golden_out =
            std::fs::read(data.join("golden").join(format!("{key}.final.out"))).unwrap();
        assert!(
            out.stdout == golden_out,
            "{key}: the 8-decimal form differs"
        );
    }
}

/// A collision-benchmark input as SPEC.md writes it (N, L, r, S, then `i x y
/// vx vy` per disc), read here without the tool's reader.
struct Discs {
    side: f64,
    radius: f64,
    steps: u64,
    x: Vec<f64>,
    y: Vec<f64>,
    v: Vec<[f64; 2]>,
}

impl Discs {
    fn read(path: &Path) -> Discs {
        let text = std::fs::read_to_string(path).unwrap();
        let mut lines = text.lines();
        let mut header = || lines.next().unwrap().trim().to_string();
        let (n, side, radius, steps) = (header(), header(), header(), header());
        let mut discs = Discs {
            side: side.parse().unwrap(),
            radius: radius.parse().unwrap(),
            steps: steps.parse().unwrap(),
            x: Vec::new(),
            y: Vec::new(),
            v: Vec::new(),
        };
        for line in lines {
            let f: Vec<f64> = line
                .split_whitespace()
                .map(|w| w.parse().unwrap())
                .collect();
            discs.x.push(f[1]);
            discs.y.push(f[2]);
            discs.v.push([f[3], f[4]]);
        }
        assert_eq!(discs.x.len(), n.parse::<usize>().unwrap());
        discs
    }

    /// Pairs whose centres are at most 2r apart, over all pairs.
    fn overlapping_pairs(&self) -> usize {
        let reach = (2.0 * self.radius).powi(2);
        (0..self.x.len())
            .flat_map(|a| (a + 1..self.x.len()).map(move |b| (a, b)))
            .filter(|&(a, b)| {
                (self.x[a] - self.x[b]).powi(2) + (self.y[a] - self.y[b]).powi(2) <= reach
            })
            .count()
    }

    /// Discs that touch a wall: `x - r <= 0`, `x + r >= L`, the same in y.
    fn on_walls(&self) -> usize {
        let (r, l) = (self.radius, self.side);
        let touches = |c: f64| c - r <= 0.0 || c + r >= l;
        (0..self.x.len())
            .filter(|&k| touches(self.x[k]) || touches(self.y[k]))
            .count()
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

#[test]
fn generated_inputs_match_the_reference_simulator() {
    let (Some(data), Some(python)) = (shared_testdata("billiards"), python()) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // the course's recipe (overlaps) at two densities, and the separated placement
    let cases: [(&str, &[&str]); 4] = [
        (
            "dense",
            &[
                "400",
                "40",
                "1",
                "30",
                "-0.5",
                "0.5",
                "--overlaps",
                "--seed",
                "5",
            ],
        ),
        (
            "drift",
            &[
                "300",
                "60",
                "2",
                "20",
                "0.2",
                "0.6",
                "--overlaps",
                "--seed",
                "6",
            ],
        ),
        (
            "sparse",
            &[
                "200",
                "100",
                "1",
                "40",
                "-1",
                "1",
                "--overlaps",
                "--seed",
                "7",
            ],
        ),
        (
            "separated",
            &["300", "50", "1", "40", "-0.7", "0.7", "--seed", "8"],
        ),
    ];
    for (name, args) in cases {
        let input = dir.path().join(format!("{name}.in"));
        let mut gen = vec!["billiards", "gen"];
        gen.extend_from_slice(args);
        gen.extend_from_slice(&["--output", input.to_str().unwrap()]);
        let out = cellist(&gen);
        assert!(out.status.success(), "{name}: {}", text(&out.stderr));
        let reference = Command::new(&python)
            .arg(data.join("ref_sim.py"))
            .args([input.to_str().unwrap(), "--format", "bits"])
            .output()
            .unwrap();
        assert!(
            reference.status.success(),
            "{name}: ref_sim.py: {}",
            text(&reference.stderr)
        );
        for threads in ["1", "2"] {
            let ours = cellist(&[
                "billiards",
                "run",
                input.to_str().unwrap(),
                "--format",
                "bits",
                "--threads",
                threads,
            ]);
            assert!(ours.status.success(), "{name}: {}", text(&ours.stderr));
            assert!(
                ours.stdout == reference.stdout,
                "{name} on {threads} thread(s) differs from ref_sim.py"
            );
        }
    }
}

#[test]
fn the_checker_accepts_our_own_trajectories() {
    let Some(data) = shared_testdata("billiards") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for (key, path) in public_inputs(&data) {
        let viz = dir.path().join(format!("{key}.viz"));
        let args = [
            "billiards",
            "run",
            path.to_str().unwrap(),
            "--viz",
            viz.to_str().unwrap(),
            "--output",
            "/dev/null",
        ];
        let out = cellist(&args);
        assert!(out.status.success(), "{key}: {}", text(&out.stderr));
        let out = cellist(&[
            "billiards",
            "check",
            path.to_str().unwrap(),
            viz.to_str().unwrap(),
        ]);
        assert!(
            out.status.success(),
            "{key}: {}{}",
            text(&out.stdout),
            text(&out.stderr)
        );
        assert!(
            text(&out.stdout).starts_with("OK: ") && text(&out.stdout).contains(" steps pass"),
            "{key}: {}",
            text(&out.stdout)
        );
    }
}

#[test]
fn the_checker_prints_its_verdict_and_exits_1_on_a_broken_run() {
    // the mistakes it must catch are tested against check_traj.py in
    // cellist-sim's tests/billiards_check.rs; here, the command's verdict line
    let Some(data) = shared_testdata("billiards") else {
        return;
    };
    let path = data.join("inputs/small/random10.in");
    let input = Discs::read(&path);
    // step 1 written as the input state: nothing moved by its velocity
    let mut still = String::new();
    for k in 0..input.x.len() {
        let [vx, vy] = input.v[k];
        still += &format!(
            "1 {k} {:.8} {:.8} {vx:.8} {vy:.8}\n",
            input.x[k], input.y[k]
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let traj = dir.path().join("still.viz");
    std::fs::write(&traj, still).unwrap();
    let out = cellist(&[
        "billiards",
        "check",
        path.to_str().unwrap(),
        traj.to_str().unwrap(),
    ]);
    let verdict = text(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{verdict}");
    assert!(verdict.starts_with("FAIL at step 1: "), "{verdict}");
    assert_eq!(verdict.lines().count(), 1, "{verdict}");
}

#[test]
fn the_checker_agrees_with_check_traj_py_on_accepted_runs() {
    let (Some(data), Some(python)) = (shared_testdata("billiards"), python()) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for name in [
        "correctness/cradle.in",
        "small/random10.in",
        "small/random80.in",
    ] {
        let path = data.join("inputs").join(name);
        let viz = dir.path().join("run.viz");
        let out = cellist(&[
            "billiards",
            "run",
            path.to_str().unwrap(),
            "--viz",
            viz.to_str().unwrap(),
            "--format",
            "bits",
            "--output",
            "/dev/null",
        ]);
        assert!(out.status.success());
        let ours = cellist(&[
            "billiards",
            "check",
            path.to_str().unwrap(),
            viz.to_str().unwrap(),
        ]);
        let theirs = Command::new(&python)
            .arg(data.join("check_traj.py"))
            .args([path.to_str().unwrap(), viz.to_str().unwrap()])
            .output()
            .unwrap();
        assert_eq!(text(&ours.stdout), text(&theirs.stdout), "{name}");
        assert!(ours.status.success() && theirs.status.success(), "{name}");
    }
}

#[test]
fn bad_inputs_are_named_with_their_line() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("4\n13\n1\n", ":4: missing; expected the number of steps S"),
        (
            "2\n13\n1\n5\n0 1 1 0 0\n",
            ":6: missing; expected particle line 2 of 2",
        ),
        (
            "1\n13\n1\n5\n0 1 one 0 0\n",
            ":5: field 3 (y) is 'one'; expected a number",
        ),
        (
            "2\n13\n1\n5\n1 1 1 0 0\n1 5 5 0 0\n",
            ":6: id 1 was already given on line 5",
        ),
        (
            "1\n13\n0\n5\n0 1 1 0 0\n",
            ":3: the radius r is 0; it must be at least 1",
        ),
        (
            "1\n0\n1\n5\n0 1 1 0 0\n",
            ":2: the side L of the box is 0; it must be at least 1",
        ),
        (
            "1\n13\n1\n5\n0 1 1 0\n",
            ":5: expected 5 fields (i x y vx vy)",
        ),
    ];
    for (k, (content, expected)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad{k}.in"));
        std::fs::write(&path, content).unwrap();
        let out = cellist(&["billiards", "run", path.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2), "{content:?}");
        let err = text(&out.stderr);
        assert!(err.contains(expected), "{content:?}: {err}");
        assert!(out.stdout.is_empty());
    }
    // lines after the particles: a warning, then the run
    let path = dir.path().join("extra.in");
    std::fs::write(&path, "1\n13\n1\n2\n0 5 5 1 0\n1 2 2 0 0\n").unwrap();
    let out = cellist(&["billiards", "run", path.to_str().unwrap()]);
    assert!(out.status.success());
    assert!(
        text(&out.stderr).contains("warning: "),
        "{}",
        text(&out.stderr)
    );
    assert_eq!(
        text(&out.stdout),
        "2 0 7.00000000 5.00000000 1.00000000 0.00000000\n"
    );
    // a step that does not settle within the bound stops with the step named
    let path = dir.path().join("pair.in");
    std::fs::write(&path, "2\n20\n1\n3\n0 5 5 0.5 0\n1 7.5 5 -0.5 0\n").unwrap();
    // (in the folder of the inputs: the last good state is written where the
    // run is, as last.lammpstrj and last.ckpt)
    let out = Command::new(env!("CARGO_BIN_EXE_cellist"))
        .args(["billiards", "run", "pair.in", "--max-sweeps", "1"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    // a run that stops is status 3 (issue 14), bad input 2
    assert_eq!(out.status.code(), Some(3));
    assert!(
        text(&out.stderr).contains("step 1: the collisions did not settle within 1 sweeps"),
        "{}",
        text(&out.stderr)
    );
    for last in ["last.lammpstrj", "last.ckpt"] {
        assert!(dir.path().join(last).is_file(), "{last}");
    }
}

#[test]
fn gen_writes_inputs_that_read_back_exactly() {
    let dir = tempfile::tempdir().unwrap();
    for overlaps in [false, true] {
        let path = dir.path().join("gen.in");
        let mut args = vec![
            "billiards",
            "gen",
            "500",
            "200",
            "3",
            "7",
            "-0.5",
            "0.5",
            "--seed",
            "3",
            "--output",
            path.to_str().unwrap(),
        ];
        if overlaps {
            args.push("--overlaps");
        }
        let out = cellist(&args);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let input = Discs::read(&path);
        assert_eq!(
            (input.x.len(), input.side, input.radius, input.steps),
            (500, 200.0, 3.0, 7)
        );
        assert!(input.v.iter().flatten().all(|c| (-0.5..=0.5).contains(c)));
        let (pairs, on_wall) = (input.overlapping_pairs(), input.on_walls());
        if overlaps {
            assert!(
                pairs > 0 && on_wall > 0,
                "the course recipe overlaps at this density"
            );
        } else {
            assert!(
                pairs == 0 && on_wall == 0,
                "{pairs} pairs, {on_wall} on walls"
            );
        }
    }
    let out = cellist(&["billiards", "gen", "10000", "100", "3", "1", "0", "1"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("use --overlaps"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn pictures_and_the_benchmark_are_written() {
    let Some(data) = shared_testdata("billiards") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let input = data.join("inputs/small/random40.in");
    let (gif, png) = (dir.path().join("run.gif"), dir.path().join("last.png"));
    let out = cellist(&[
        "billiards",
        "run",
        input.to_str().unwrap(),
        "--steps",
        "20",
        "--gif",
        gif.to_str().unwrap(),
        "--png",
        png.to_str().unwrap(),
        "--picture-size",
        "200",
        "--output",
        "/dev/null",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(&std::fs::read(&gif).unwrap()[..6], b"GIF89a");
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");
    // the frames are charts like the PNG (at least 640 pixels wide), one per step
    let png_size = {
        let decoder = png::Decoder::new(std::fs::File::open(&png).unwrap());
        let reader = decoder.read_info().unwrap();
        let info = reader.info();
        (info.width, info.height)
    };
    assert_eq!(png_size.0, 640);
    let mut decoder = gif::DecodeOptions::new()
        .read_info(std::fs::File::open(&gif).unwrap())
        .unwrap();
    let mut frames = 0;
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        assert_eq!((frame.width as u32, frame.height as u32), png_size);
        frames += 1;
    }
    assert_eq!(frames, 21, "steps 0 to 20");
    let out = cellist(&[
        "bench",
        "billiards",
        input.to_str().unwrap(),
        "--threads",
        "2",
        "--repeat",
        "1",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["particles"], 1000);
    assert_eq!(json["steps"], 100);
    assert_eq!(json["max_sweeps"], 5);
    assert!(json["seconds"].as_f64().unwrap() > 0.0);
}

#[test]
fn hex_cells_give_the_bytes_of_square_cells() {
    // seed 001's hexagon arrangement only changes which cells are searched: every
    // step's state, hence the trajectory and the final state, is the same bytes
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("crowded.in");
    let out = cellist(&[
        "billiards",
        "gen",
        "3000",
        "200",
        "2",
        "30",
        "-1",
        "1",
        "--overlaps",
        "--seed",
        "5",
        "--output",
        input.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let mut runs = Vec::new();
    for (cells, threads) in [("square", "1"), ("hex", "1"), ("hex", "2")] {
        let viz = dir.path().join(format!("{cells}-{threads}.viz"));
        let out = cellist(&[
            "billiards",
            "run",
            input.to_str().unwrap(),
            "--format",
            "bits",
            "--cells",
            cells,
            "--threads",
            threads,
            "--viz",
            viz.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{cells}: {}", text(&out.stderr));
        assert!(!out.stdout.is_empty());
        runs.push((cells, threads, out.stdout, std::fs::read(&viz).unwrap()));
    }
    for (cells, threads, last, viz) in &runs[1..] {
        assert!(
            *last == runs[0].2,
            "--cells {cells} --threads {threads}: final state"
        );
        assert!(
            *viz == runs[0].3,
            "--cells {cells} --threads {threads}: trajectory"
        );
    }
    // the input does collide: pairs overlap in the first steps
    let pairs = Discs::read(&input).overlapping_pairs();
    assert!(pairs > 100, "{pairs} overlapping pairs");

    let out = cellist(&[
        "bench",
        "billiards",
        input.to_str().unwrap(),
        "--cells",
        "hex",
        "--steps",
        "3",
        "--repeat",
        "1",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["cells"], "hex");
    let out = cellist(&[
        "billiards",
        "run",
        input.to_str().unwrap(),
        "--cells",
        "hexagon",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
}

#[test]
fn sweep_times_every_combination_of_generated_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("sweep");
    let out = cellist(&[
        "billiards",
        "sweep",
        "--n",
        "200,400",
        "--l",
        "2000",
        "--r",
        "5",
        "--steps",
        "5",
        "--threads",
        "1,2",
        "--overlaps",
        "--repeat",
        "2",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    // one progress line per timed run: 4 combinations, 2 rounds
    assert_eq!(stdout.matches("(round ").count(), 8, "{stdout}");
    let csv = std::fs::read_to_string(out_dir.join("sweep.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(
        lines[0],
        "N,L,r,S,cells,threads,time,steps_per_s,ns_per_disc_step,max_sweeps"
    );
    assert_eq!(lines.len(), 5, "{csv}");
    let expected = [("200", "1"), ("200", "2"), ("400", "1"), ("400", "2")];
    for (line, (n, threads)) in lines[1..].iter().zip(expected) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[..6], [n, "2000", "5", "5", "square", threads], "{line}");
        let metrics: Vec<f64> = f[6..].iter().map(|v| v.parse().unwrap()).collect();
        assert!(metrics.iter().all(|&m| m > 0.0), "{line}");
        let time = metrics[0];
        assert!(
            (metrics[1] - 5.0 / time).abs() <= 1e-9 * metrics[1],
            "{line}"
        );
        assert!(metrics[3] >= 1.0 && metrics[3].fract() == 0.0, "{line}");
    }
    // the hardest step's sweeps do not depend on the thread count
    assert_eq!(
        lines[1].rsplit(',').next(),
        lines[2].rsplit(',').next(),
        "{csv}"
    );
    assert_eq!(
        &std::fs::read(out_dir.join("sweep.png")).unwrap()[1..4],
        b"PNG"
    );
}

#[test]
fn sweep_refuses_bad_flags_naming_them_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("sweep");
    let base = ["--n", "200", "--l", "2000", "--r", "5", "--steps", "5"];
    let cases: [(&[&str], &str); 11] = [
        (&["--n", ""], "--n"),
        (&["--n", "100,0"], "--n"),
        (&["--threads", "0"], "--threads"),
        (&["--threads", ""], "--threads"),
        (&["--l", "-5"], "--l"),
        (&["--l", "0"], "--l"),
        (&["--r", "0"], "--r"),
        (&["--r", "-1,5"], "--r"),
        (&["--repeat", "0"], "--repeat"),
        (&["--cells", "triangle"], "--cells"),
        (&["--steps", "0"], "--steps"),
    ];
    for (extra, flag) in cases {
        let mut args = vec!["billiards", "sweep"];
        args.extend(base);
        args.extend(extra);
        args.extend(["--out", out_dir.to_str().unwrap()]);
        let out = cellist(&args);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {stderr}");
        assert!(
            stderr.contains(flag),
            "{extra:?} does not name {flag}: {stderr}"
        );
        assert!(!out_dir.exists(), "{extra:?} wrote {}", out_dir.display());
    }
    // too dense for the separated placement: refused, naming the combination,
    // before anything is timed
    let out = cellist(&[
        "billiards",
        "sweep",
        "--n",
        "100,3000",
        "--l",
        "1000",
        "--r",
        "10",
        "--steps",
        "5",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("N = 3000, L = 1000, r = 10") && stderr.contains("--overlaps"),
        "{stderr}"
    );
    assert!(text(&out.stdout).is_empty(), "nothing timed");
    assert!(!out_dir.exists());
}

#[test]
fn a_billiards_scenario_runs_the_input_to_the_golden_bits() {
    let Some(data) = shared_testdata("billiards") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let input = data.join("inputs/small/random10.in");
    let header: Vec<u64> = std::fs::read_to_string(&input)
        .unwrap()
        .lines()
        .take(4)
        .map(|l| l.trim().parse::<f64>().unwrap() as u64)
        .collect();
    let steps = header[3];
    let scenario = dir.path().join("discs.toml");
    std::fs::write(
        &scenario,
        format!(
            "model = \"billiards\"\ninput = \"{}\"\n[run]\ncells = \"hex\"\n[output]\n\
             dump = {{ every = {steps}, file = \"discs.lammpstrj\" }}\n",
            input.display()
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let run = cellist(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--threads",
        "2",
    ]);
    assert!(run.status.success(), "{}", text(&run.stderr));
    // the dump's last frame, at %.17g, read back to the same doubles
    let dump = std::fs::read_to_string(out.join("discs.lammpstrj")).unwrap();
    let lines: Vec<&str> = dump.lines().collect();
    let last = lines
        .iter()
        .rposition(|l| l.starts_with("ITEM: TIMESTEP"))
        .unwrap();
    assert_eq!(lines[last + 1].trim(), steps.to_string());
    let mut state: Vec<(u64, [u64; 4])> = lines[last + 9..]
        .iter()
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let bits = |k: usize| f[k].parse::<f64>().unwrap().to_bits();
            (f[0].parse().unwrap(), [bits(2), bits(3), bits(5), bits(6)])
        })
        .collect();
    state.sort_unstable();
    let golden = std::fs::read_to_string(data.join("golden/small__random10.final.bits")).unwrap();
    let golden: Vec<(u64, [u64; 4])> = golden
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let bits = |k: usize| u64::from_str_radix(f[k], 16).unwrap();
            (f[1].parse().unwrap(), [bits(2), bits(3), bits(4), bits(5)])
        })
        .collect();
    assert_eq!(state.len(), golden.len());
    assert_eq!(state, golden);
    let thermo = std::fs::read_to_string(out.join("thermo.csv")).unwrap();
    assert!(thermo.starts_with("step,energy"), "{thermo}");
    let bad = cellist(&[
        "run",
        scenario.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--set",
        "run.cells=\"round\"",
    ]);
    assert!(!bad.status.success());
    assert!(
        text(&bad.stderr).contains("run.cells 'round' is unknown"),
        "{}",
        text(&bad.stderr)
    );
}
