//! End-to-end runs of `cellist neighbors` and `cellist bench neighbors`.

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{cellist, shared_testdata};

fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8(o.stderr.clone()).unwrap()
}

fn testdata() -> Option<PathBuf> {
    shared_testdata("neighbors")
}

/// The box side from the header `... L=<value> ...`.
fn header_side(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap();
    let first = text.lines().next().unwrap();
    let field = first
        .split_whitespace()
        .find(|f| f.starts_with("L="))
        .unwrap();
    field[2..].to_string()
}

/// (i, j, r) lines, comments skipped.
fn parse_pairs(text: &str) -> Vec<(u32, u32, f64)> {
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
            )
        })
        .collect()
}

#[test]
fn reference_pair_lists_2d_and_3d() {
    let Some(dir) = testdata() else { return };
    for dim in [2, 3] {
        let points = dir.join(format!("nl_N2000_{dim}d_points.txt"));
        let side = header_side(&points);
        let mut args = vec![
            "neighbors",
            "--input",
            points.to_str().unwrap(),
            "--cutoff",
            "2.5",
            "--box",
        ];
        args.extend(std::iter::repeat_n(side.as_str(), dim));
        let out = cellist(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        let ours = parse_pairs(&stdout(&out));
        let reference = parse_pairs(
            &std::fs::read_to_string(dir.join(format!("nl_N2000_{dim}d_pairs.txt"))).unwrap(),
        );
        assert_eq!(ours.len(), reference.len(), "{dim}D pair count");
        for (a, b) in ours.iter().zip(&reference) {
            assert_eq!((a.0, a.1), (b.0, b.1), "{dim}D pair set");
            // same minimum-image arithmetic as the reference: the same double
            assert_eq!(a.2, b.2, "{dim}D distance of {:?}", (a.0, a.1));
        }
        args.push("--count");
        let out = cellist(&args);
        assert_eq!(stdout(&out), format!("{}\n", reference.len()));
    }
}

/// `n` points uniform in `[0, side)^dim` from `seed` (SplitMix64), as text.
fn write_random_points(path: &Path, n: usize, dim: usize, side: f64, seed: u64) {
    let mut state = seed;
    let mut uniform = || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut text = String::from("# random points\n");
    for _ in 0..n {
        let coords: Vec<String> = (0..dim).map(|_| format!("{}", uniform() * side)).collect();
        text.push_str(&coords.join(" "));
        text.push('\n');
    }
    std::fs::write(path, text).unwrap();
}

#[test]
fn output_bytes_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("pts.txt");
    write_random_points(&input, 5000, 3, 18.0, 3);
    let mut outputs = Vec::new();
    for t in ["1", "2"] {
        let file = dir.path().join(format!("pairs{t}.txt"));
        let out = cellist(&[
            "neighbors",
            "--input",
            input.to_str().unwrap(),
            "--cutoff",
            "2.0",
            "--box",
            "18",
            "18",
            "18",
            "--threads",
            t,
            "--output",
            file.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        outputs.push(std::fs::read(&file).unwrap());
    }
    assert!(!outputs[0].is_empty());
    assert_eq!(outputs[0], outputs[1]);
}

#[test]
fn open_boundaries_without_a_box_and_with_open() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("pts.txt");
    std::fs::write(&input, "0 0\n0.5 0\n9.75 0\n").unwrap();
    let cases: [(&[&str], &str); 3] = [
        (&[], "0 1 0.5\n"),
        // periodic box of side 10: 9.75 is 0.25 from 0 and 0.75 from 0.5
        (&["--box", "10", "10"], "0 1 0.5\n0 2 0.25\n1 2 0.75\n"),
        (&["--box", "10", "10", "--open"], "0 1 0.5\n"),
    ];
    for (flags, expected) in cases {
        let mut args = vec![
            "neighbors",
            "--input",
            input.to_str().unwrap(),
            "--cutoff",
            "1",
        ];
        args.extend_from_slice(flags);
        assert_eq!(stdout(&cellist(&args)), expected, "{flags:?}");
    }
}

#[test]
fn extended_xyz_box_and_periodicity() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("a.xyz");
    std::fs::write(
        &input,
        "3\nLattice=\"10 0 0 0 10 0 0 0 10\" Properties=species:S:1:pos:R:3 pbc=\"T T F\"\nAr 0.5 0.5 0.5\nAr 9.5 0.5 0.5\nAr 0.5 0.5 9.5\n",
    )
    .unwrap();
    let out = cellist(&[
        "neighbors",
        "--input",
        input.to_str().unwrap(),
        "--cutoff",
        "2",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    // across x (periodic) the pair is at 1; across z (open) it is 9 apart
    assert_eq!(stdout(&out), "0 1 1\n");
}

/// Runs a failing command and returns its message; checks the exit status.
fn failure(args: &[&str]) -> String {
    let out = cellist(args);
    assert_eq!(
        out.status.code(),
        Some(2),
        "exit status for {args:?}: {}",
        stderr(&out)
    );
    assert!(stdout(&out).is_empty());
    stderr(&out)
}

#[test]
fn bad_input_is_refused_with_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    // (file name, content or None for a missing file, extra flags, expected message)
    let cases: &[(&str, Option<&str>, &[&str], &str)] = &[
        (
            "malformed.txt",
            Some("1 2\n3 oops\n"),
            &["--cutoff", "1"],
            "malformed.txt:2: coordinate 2 is 'oops'; expected a number",
        ),
        (
            "nan.txt",
            Some("# c\n1 2 3\nnan 0 0\n"),
            &["--cutoff", "1"],
            "nan.txt:3: coordinate 1 is NaN",
        ),
        (
            "inf.txt",
            Some("1 2\n-inf 0\n"),
            &["--cutoff", "1"],
            "inf.txt:2: coordinate 1 is -inf",
        ),
        (
            "columns.txt",
            Some("1 2 3\n4 5\n"),
            &["--cutoff", "1"],
            "columns.txt:2: found 2 columns; expected 3",
        ),
        (
            "one.txt",
            Some("7\n"),
            &["--cutoff", "1"],
            "one.txt:1: found 1 columns; expected 2 or 3",
        ),
        ("missing.txt", None, &["--cutoff", "1"], "cannot read"),
        (
            "good.txt",
            Some("1 2\n3 4\n"),
            &["--cutoff", "0"],
            "--cutoff must be a finite number > 0",
        ),
        (
            "good.txt",
            Some("1 2\n3 4\n"),
            &["--cutoff", "-1"],
            "--cutoff must be a finite number > 0",
        ),
        (
            "good.txt",
            Some("1 2\n3 4\n"),
            &["--cutoff", "nan"],
            "--cutoff must be a finite number > 0",
        ),
        (
            "good.txt",
            Some("1 2\n3 4\n"),
            &["--cutoff", "3", "--box", "5", "10"],
            "larger than half the periodic box side along x",
        ),
        (
            "good.txt",
            Some("1 2\n3 4\n"),
            &["--cutoff", "1", "--box", "5", "5", "5"],
            "--box has 3 lengths",
        ),
        (
            "good.txt",
            Some("1 2\n3 4\n"),
            &["--cutoff", "1", "--periodic"],
            "--periodic needs a box",
        ),
        (
            "empty.txt",
            Some("# nothing here\n\n"),
            &["--cutoff", "1"],
            "empty.txt: no points",
        ),
        (
            "good.txt",
            Some("1 2\n3 4\n"),
            &["--cutoff", "1", "--box", "-5", "5", "--open"],
            "--box lengths must be finite and > 0",
        ),
    ];
    for (name, content, flags, expected) in cases {
        let path = dir.path().join(name);
        if let Some(text) = content {
            std::fs::write(&path, text).unwrap();
        }
        let mut args = vec!["neighbors", "--input", path.to_str().unwrap()];
        args.extend_from_slice(flags);
        let e = failure(&args);
        assert!(e.contains(expected), "{name} {flags:?}: {e}");
        assert!(
            e.contains(name) || !expected.contains(':'),
            "{name}: the file is not named in {e}"
        );
    }
}

#[test]
fn no_partial_output_file_on_error() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("bad.txt");
    std::fs::write(&input, "1 2\n3 4\n5\n").unwrap();
    let output = dir.path().join("pairs.txt");
    failure(&[
        "neighbors",
        "--input",
        input.to_str().unwrap(),
        "--cutoff",
        "10",
        "--output",
        output.to_str().unwrap(),
    ]);
    assert!(!output.exists());
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "{leftovers:?}");
}

#[test]
fn bench_neighbors_json() {
    let out = cellist(&[
        "bench",
        "neighbors",
        "--n",
        "20000",
        "--dim",
        "2",
        "--threads",
        "2",
        "--repeat",
        "1",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_str(stdout(&out).trim()).unwrap();
    for key in ["n", "dim", "threads", "pairs", "seconds", "ns_per_pair"] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["n"], 20000);
    assert_eq!(v["dim"], 2);
    // 2D at density 0.8442 and cutoff 2.5: about N/2 * rho * pi rc^2 = 165,754 pairs
    let pairs = v["pairs"].as_f64().unwrap();
    assert!((pairs / 165_754.0 - 1.0).abs() < 0.03, "{pairs}");
}

#[test]
fn bench_neighbors_refuses_too_few_points() {
    let e = failure(&["bench", "neighbors", "--n", "0"]);
    assert!(e.contains("--n must be at least 2"), "{e}");
}
