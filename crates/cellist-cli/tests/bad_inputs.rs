//! Bad input files and their errors, word for word (issue 14, item 4).
//!
//! Every folder under `tests/bad-inputs/` is one case: input files, a `cmd` file
//! (the arguments of `cellist`, one per line) and an `expected` file (the exit
//! status on the first line, then standard error exactly as printed). Each case
//! runs with its folder as the working directory; `{dir}` (the case folder) and
//! `{out}` (a fresh temporary folder) are substituted in `cmd` and `expected`.
//! All differing cases are reported at once. See `tests/bad-inputs/README.md`.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

/// The case folders, sorted.
fn cases() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad-inputs");
    let mut cases: Vec<PathBuf> = std::fs::read_dir(&root)
        .unwrap_or_else(|e| panic!("{}: {e}", root.display()))
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.is_dir())
        .collect();
    cases.sort();
    cases
}

/// Every file under `dir` with its size, relative to `dir`, sorted.
fn listing(dir: &Path) -> Vec<(PathBuf, u64)> {
    common::files(dir)
        .into_iter()
        .map(|(name, bytes)| (name, bytes.len() as u64))
        .collect()
}

/// Indents every line of `text` for the report, showing where it ends.
fn quoted(text: &str) -> String {
    let mut out: String = text.lines().map(|l| format!("    | {l}\n")).collect();
    if !text.is_empty() && !text.ends_with('\n') {
        out.push_str("    (no newline at the end)\n");
    }
    if text.is_empty() {
        out.push_str("    (nothing)\n");
    }
    out
}

/// Runs one case; `Err` describes every way it differs.
fn run_case(case: &Path) -> Result<(), String> {
    let name = case.file_name().unwrap().to_string_lossy().into_owned();
    let read = |file: &str| {
        std::fs::read_to_string(case.join(file)).map_err(|e| format!("{name}/{file}: {e}"))
    };
    let out = tempfile::tempdir().unwrap();
    let dir = case.display().to_string();
    let out_dir = out.path().display().to_string();
    let fill = |text: &str| text.replace("{dir}", &dir).replace("{out}", &out_dir);

    let args: Vec<String> = read("cmd")?
        .lines()
        .filter(|line| !line.is_empty())
        .map(fill)
        .collect();
    let expected = read("expected")?;
    let (status_line, message) = expected.split_once('\n').unwrap_or((&expected, ""));
    let status: i32 = status_line.trim().parse().map_err(|_| {
        format!("{name}/expected: the first line is '{status_line}'; expected an exit status")
    })?;
    let message = fill(message);

    let before = listing(case);
    let output = Command::new(env!("CARGO_BIN_EXE_cellist"))
        .args(&args)
        .current_dir(case)
        .env_remove("RUST_BACKTRACE")
        .output()
        .map_err(|e| format!("{name}: cellist does not start: {e}"))?;
    let after = listing(case);

    let got_status = output.status.code().unwrap_or(-1);
    let got = String::from_utf8_lossy(&output.stderr);
    let mut report = String::new();
    if got_status != status {
        report.push_str(&format!("  exit status {got_status}; expected {status}\n"));
    }
    if got != message {
        report.push_str(&format!(
            "  standard error:\n{}  expected:\n{}",
            quoted(&got),
            quoted(&message)
        ));
    }
    if before != after {
        report.push_str(&format!(
            "  the case folder changed (outputs must go to {{out}}): {before:?} -> {after:?}\n"
        ));
    }
    if report.is_empty() {
        Ok(())
    } else {
        Err(format!("{name} (cellist {}):\n{report}", args.join(" ")))
    }
}

#[test]
fn every_bad_input_fails_with_its_expected_message() {
    let cases = cases();
    // a folder that went missing must not pass as "no case failed"
    assert!(cases.len() >= 40, "only {} cases", cases.len());
    let failures: Vec<String> = cases.iter().filter_map(|c| run_case(c).err()).collect();
    assert!(
        failures.is_empty(),
        "{} of {} bad-input cases differ:\n\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}
