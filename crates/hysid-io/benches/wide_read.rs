//! Reading files whose size lies in one dimension a reader could treat
//! quadratically: a CSV of 10^5 columns and a gray-box model file of 10^4
//! chained definitions (and a tenth of each, to see the growth), each
//! against reading the same bytes as plain text lines, in the same run.
//! Run with `cargo bench -p hysid-io --bench wide_read`.
//!
//! - CSV: 50 rows of `u` and `y` then `c2` .. (all zero), 10^4 or 10^5
//!   columns (10.7 MB); `csv_load` is `hysid_io::load` with the default
//!   selection (`u`, `y`).
//! - Model: a gray-box model (one state `v1`, input `u`, parameter `a`)
//!   whose flow is the last of 10^3 or 10^4 definitions
//!   `zz0 = "-a*v1 + u"`, `zz{i} = "zz{i-1} + 0"` (0.2 MB); `model_load`
//!   is `hysid_core::model::Model::load` (the TOML parsed, the model
//!   checked and compiled, the flow written out with every definition).
//! - `csv_lines`, `model_lines`: the baseline, the same file read line by
//!   line as text (`BufRead::lines`, one `String` per line).
//! - `model_toml`: the model file read and parsed by the toml crate alone
//!   (`toml::from_str::<toml::Table>`), the share of `model_load` that is
//!   the TOML parse.
//!
//! Under `cargo test` (no `--bench` argument) the files are 100 times
//! smaller, so that the benchmarks only check that they run.

use divan::Bencher;
use divan::counter::BytesCount;
use hysid_core::model::Model;
use hysid_io::load;
use hysid_model::data::DataSelection;
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// One file written for the benchmarks.
#[derive(Debug)]
struct File {
    kind: &'static str,
    /// Columns or definitions.
    size: usize,
    path: PathBuf,
    bytes: usize,
}

static FILES: OnceLock<Vec<File>> = OnceLock::new();

fn main() {
    let scale = if std::env::args().any(|a| a == "--bench") {
        1
    } else {
        100
    };
    let dir = tempfile::tempdir().expect("temporary directory");
    let mut files = Vec::new();
    for (kind, size) in [
        ("csv", 10_000),
        ("csv", 100_000),
        ("model", 1_000),
        ("model", 10_000),
    ] {
        let size = size / scale;
        let (text, name) = match kind {
            "csv" => (csv(size), format!("wide-{size}.csv")),
            _ => (model(size), format!("chain-{size}.toml")),
        };
        let path = dir.path().join(&name);
        std::fs::write(&path, &text).expect("writing a file");
        println!(
            "{name}: {} bytes ({:.2} MB)",
            text.len(),
            text.len() as f64 / 1e6
        );
        files.push(File {
            kind,
            size,
            path,
            bytes: text.len(),
        });
    }
    FILES.set(files).expect("set once");
    divan::main();
    // The directory is removed here, after the benchmarks.
    drop(dir);
}

/// 50 rows of `columns` columns: `u`, `y` (a first-order response), then
/// zeros.
fn csv(columns: usize) -> String {
    let names: Vec<String> = (2..columns).map(|i| format!("c{i}")).collect();
    let mut text = format!("u,y,{}\n", names.join(","));
    let zeros = ",0".repeat(columns - 2);
    let mut y = 0.0;
    for k in 0..50 {
        let u = ((k * 7919) % 13) as f64 / 6.0 - 1.0;
        text.push_str(&format!("{u},{y}{zeros}\n"));
        y = 0.6 * y + 0.8 * u + 0.2;
    }
    text
}

/// A gray-box model whose flow is the last of `n` chained definitions.
fn model(n: usize) -> String {
    let mut text = String::from(
        "kind = \"gray_box\"\nformat = 1\ninternal_step = 0.001\nstates = [\"v1\"]\n\
         inputs = [\"u\"]\noutputs = [{ name = \"y\", value = \"v1\" }]\n\
         initial_state = { from = \"given\", values = { v1 = 0.0 } }\n\n\
         [[parameters]]\nname = \"a\"\nvalue = 1.0\nbounds = [0.0, 2.0]\n\n[definitions]\n\
         zz0 = \"-a*v1 + u\"\n",
    );
    for i in 1..n {
        text.push_str(&format!("zz{i} = \"zz{} + 0\"\n", i - 1));
    }
    text.push_str(&format!(
        "\n[[modes]]\nname = \"only\"\nflow = {{ v1 = \"zz{}\" }}\n",
        n - 1
    ));
    text
}

/// The sizes written of files of `kind`.
fn sizes(kind: &str) -> Vec<usize> {
    let files = FILES.get().expect("written in main");
    files
        .iter()
        .filter(|f| f.kind == kind)
        .map(|f| f.size)
        .collect()
}

fn file(kind: &str, size: usize) -> (&'static Path, usize) {
    let files = FILES.get().expect("written in main");
    let f = files
        .iter()
        .find(|f| f.kind == kind && f.size == size)
        .expect("a file of each size");
    (&f.path, f.bytes)
}

/// The baseline: the file's lines as text.
fn lines(path: &Path) -> usize {
    let f = std::io::BufReader::new(std::fs::File::open(path).expect("the file opens"));
    f.lines().map(|l| l.expect("a line").len()).sum()
}

#[divan::bench(args = sizes("csv"), sample_count = 20, sample_size = 1)]
fn csv_load(bencher: Bencher, columns: usize) {
    let (path, len) = file("csv", columns);
    let sel = DataSelection::default();
    bencher
        .counter(BytesCount::new(len))
        .bench_local(|| load(path, &sel).expect("the file reads"));
}

#[divan::bench(args = sizes("csv"), sample_count = 20, sample_size = 1)]
fn csv_lines(bencher: Bencher, columns: usize) {
    let (path, len) = file("csv", columns);
    bencher
        .counter(BytesCount::new(len))
        .bench_local(|| lines(path));
}

#[divan::bench(args = sizes("model"), sample_count = 20, sample_size = 1)]
fn model_load(bencher: Bencher, definitions: usize) {
    let (path, len) = file("model", definitions);
    bencher
        .counter(BytesCount::new(len))
        .bench_local(|| Model::load(path).expect("the model reads"));
}

#[divan::bench(args = sizes("model"), sample_count = 20, sample_size = 1)]
fn model_lines(bencher: Bencher, definitions: usize) {
    let (path, len) = file("model", definitions);
    bencher
        .counter(BytesCount::new(len))
        .bench_local(|| lines(path));
}

#[divan::bench(args = sizes("model"), sample_count = 20, sample_size = 1)]
fn model_toml(bencher: Bencher, definitions: usize) {
    let (path, len) = file("model", definitions);
    bencher.counter(BytesCount::new(len)).bench_local(|| {
        let text = std::fs::read_to_string(path).expect("the file reads");
        toml::from_str::<toml::Table>(&text).expect("the file is TOML")
    });
}
