//! Helpers shared by the end-to-end tests of the `hysid` program (cli.rs,
//! bad_input.rs, determinism.rs, edge_cases.rs): each test file uses a
//! subset.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `hysid` with `args` (and `CI=1`: no progress bars, no colours).
pub fn hysid(args: &[&str]) -> Output {
    hysid_env(args, &[])
}

/// Same, with extra environment variables.
pub fn hysid_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_hysid"));
    c.args(args).env("CI", "1");
    for (k, v) in env {
        c.env(k, v);
    }
    c.output().expect("hysid runs")
}

/// Runs `hysid`, asserts it succeeded and returns its standard output.
pub fn ok(args: &[&str]) -> String {
    ok_env(args, &[])
}

/// Same, with extra environment variables.
pub fn ok_env(args: &[&str], env: &[(&str, &str)]) -> String {
    let o = hysid_env(args, env);
    assert!(
        o.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

/// Runs `hysid`, asserts it succeeded and returns its standard error (its
/// warnings and notes).
pub fn ok_stderr(args: &[&str]) -> String {
    let o = hysid(args);
    assert!(o.status.success(), "{args:?}: {o:?}");
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A path as `&str` (test paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Writes `bytes` to `dir/name`.
pub fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// `Ok(message)` when `o` is a failure with exit code `code` and exactly one
/// `hysid: error: ` line on stderr, free of control characters.
pub fn one_line_error(o: &Output, code: i32) -> Result<String, String> {
    let err = String::from_utf8_lossy(&o.stderr);
    if o.status.code() != Some(code) {
        return Err(format!(
            "exit {:?}, expected {code}; stderr: {err}",
            o.status.code()
        ));
    }
    let line = err.trim_end();
    if line.lines().count() != 1
        || !line.starts_with("hysid: error: ")
        || line.chars().any(char::is_control)
    {
        return Err(format!("not a one-line hysid error: {err:?}"));
    }
    Ok(line.to_string())
}

thread_local! {
    static FAILURES: std::cell::RefCell<Vec<String>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Records a case that did not behave; [`report`] fails the test with all
/// of them, so one failure never hides the next cases.
pub fn fail(case: &str, why: String) {
    FAILURES.with(|f| f.borrow_mut().push(format!("{case}: {why}")));
}

/// Fails the test listing every case recorded by [`fail`].
pub fn report() {
    let f = FAILURES.with(|f| std::mem::take(&mut *f.borrow_mut()));
    assert!(
        f.is_empty(),
        "{} case(s) failed:\n{}",
        f.len(),
        f.join("\n")
    );
}

/// A noisy record of `n` samples of a two-mode PWARX model (modes split by
/// the sign of y(k-1)), written by `hysid simulate` into `dir/data.csv`.
pub fn two_mode_record(dir: &Path, n: usize) -> PathBuf {
    two_mode_record_as(dir, "data.csv", n, 11, 0.01)
}

/// The record of [`two_mode_record`]'s model from the excitation seed
/// `seed`, sampled every `ts` seconds, written into `dir/name`.
pub fn two_mode_record_as(dir: &Path, name: &str, n: usize, seed: u64, ts: f64) -> PathBuf {
    let truth = write(
        dir,
        "truth.json",
        r#"{"kind":"pwarx","na":1,"nb":1,"inputs":1,"modes":[
            {"theta":[0.5,1.0,0.3],"region":{"a":[[1.0,0.0]],"b":[0.0]}},
            {"theta":[-0.4,0.8,-0.2],"region":{"a":[[-1.0,0.0]],"b":[0.0]}}]}"#,
    );
    let data = dir.join(name);
    ok(&[
        "simulate",
        s(&truth),
        "--excite",
        &format!("n={n},hold=3,low=-1,high=1,ts={ts}"),
        "--noise",
        "0.01",
        "--seed",
        &seed.to_string(),
        "-o",
        s(&data),
    ]);
    data
}

/// The text of the repository's file at `path` (from the repository's
/// root).
pub fn repository_text(path: &str) -> String {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    std::fs::read_to_string(format!("{root}/{path}")).unwrap()
}

/// The 1-based number of the `nth` (from 0) line of `text` holding `part`.
pub fn line_holding(text: &str, part: &str, nth: usize) -> usize {
    text.lines()
        .enumerate()
        .filter(|(_, l)| l.contains(part))
        .nth(nth)
        .unwrap_or_else(|| panic!("no line {nth} holding {part:?}"))
        .0
        + 1
}

/// The pick-and-place head's model file.
pub const HEAD_MODEL: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../models/pick-and-place/head.toml"
);

/// The `--set` that makes `-m physical` fit the mounting head.
pub const HEAD_MODEL_SET: &str = concat!(
    "model=",
    env!("CARGO_MANIFEST_DIR"),
    "/../../models/pick-and-place/head.toml"
);
