//! CSV reading time: hysid's reader against the csv crate alone. Run with
//! `cargo bench -p hysid-io --bench csv_read`.
//!
//! Data: 10^6 rows of `t,u,y` (t in steps of 1 ms, u a pseudo-random
//! telegraph-like input, y a first-order response to it, both printed with
//! full precision), about 45 MB, written once to a temporary file. Under
//! `cargo test` (no `--bench` argument) the file has 1000 rows, so that the
//! benchmarks only check that they run.
//!
//! - `hysid_load`: `hysid_io::load` with the default selection
//!   (inputs `u`, output `y`, sampling time from `t`).
//! - `csv_only`: the baseline, the csv crate reading the same file into
//!   three `f64` columns (one reused `ByteRecord`, `str::parse::<f64>`).

mod signals;

use divan::Bencher;
use divan::counter::BytesCount;
use hysid_io::load;
use hysid_model::data::DataSelection;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

static FILE: OnceLock<(PathBuf, usize)> = OnceLock::new();

fn main() {
    let rows = if std::env::args().any(|a| a == "--bench") {
        1_000_000
    } else {
        1_000
    };
    let dir = tempfile::tempdir().expect("temporary directory");
    let path = dir.path().join("data.csv");
    let text = data(rows);
    std::fs::write(&path, &text).expect("writing the CSV file");
    println!(
        "{rows} rows, {} bytes ({:.1} MB)",
        text.len(),
        text.len() as f64 / 1e6
    );
    FILE.set((path, text.len())).expect("set once");
    drop(text);
    divan::main();
    // The directory is removed here, after the benchmarks.
    drop(dir);
}

/// The CSV text: a header and `rows` rows of t, u, y.
fn data(rows: usize) -> String {
    let mut text = String::with_capacity(rows * 48);
    text.push_str("t,u,y\n");
    for (t, u, y) in signals::signals(rows) {
        writeln!(text, "{t},{u},{y}").expect("writing to a String");
    }
    text
}

fn file() -> (&'static Path, usize) {
    let (path, len) = FILE.get().expect("written in main");
    (path, *len)
}

#[divan::bench(sample_count = 10, sample_size = 1)]
fn hysid_load(bencher: Bencher) {
    let (path, len) = file();
    let sel = DataSelection::default();
    bencher
        .counter(BytesCount::new(len))
        .bench_local(|| load(path, &sel).expect("the file reads"));
}

#[divan::bench(sample_count = 10, sample_size = 1)]
fn csv_only(bencher: Bencher) {
    let (path, len) = file();
    bencher.counter(BytesCount::new(len)).bench_local(|| {
        let mut rdr = csv::Reader::from_path(path).expect("the file opens");
        let mut rec = csv::ByteRecord::new();
        let mut cols: [Vec<f64>; 3] = Default::default();
        while rdr.read_byte_record(&mut rec).expect("a record") {
            for (col, field) in cols.iter_mut().zip(rec.iter()) {
                let s = std::str::from_utf8(field).expect("UTF-8");
                col.push(s.parse().expect("a number"));
            }
        }
        cols
    });
}
