//! MAT reading time: hysid's reader against matrw alone. Run with
//! `cargo bench -p hysid-io --bench mat_read`.
//!
//! Data: 10^6 samples of `t`, `u` and `y` (the signals of the CSV
//! benchmark: t in steps of 1 ms, a telegraph-like input, a first-order
//! response) as `double` column vectors in a MAT v5/v7 file, written once
//! uncompressed (24 MB) and once compressed. Under `cargo test` (no
//! `--bench` argument) the files hold 1000 samples, so that the benchmarks
//! only check that they run.
//!
//! - `hysid_load_*`: `hysid_io::load` with the default selection (inputs
//!   `u`, output `y`, sampling time from `t`), which also checks the
//!   structure of every element before matrw allocates from it.
//! - `matrw_only_*`: the baseline, matrw parsing the same bytes and
//!   converting the three variables to `f64` vectors.

mod signals;

use divan::Bencher;
use divan::counter::BytesCount;
use hysid_io::load;
use hysid_model::data::DataSelection;
use matrw::{MatFile, matvar};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// The uncompressed and the compressed file, with their sizes in bytes.
static FILES: OnceLock<[(PathBuf, usize); 2]> = OnceLock::new();

fn main() {
    let samples = if std::env::args().any(|a| a == "--bench") {
        1_000_000
    } else {
        1_000
    };
    let dir = tempfile::tempdir().expect("temporary directory");
    let files = [false, true].map(|compress| {
        let path = dir.path().join(format!("data-{compress}.mat"));
        write(&path, samples, compress);
        let len = std::fs::metadata(&path).expect("the file exists").len() as usize;
        println!(
            "{samples} samples, compressed {compress}: {len} bytes ({:.1} MB)",
            len as f64 / 1e6
        );
        (path, len)
    });
    FILES.set(files).expect("set once");
    divan::main();
    // The directory is removed here, after the benchmarks.
    drop(dir);
}

/// The signals t, u, y of `samples` samples, written as a MAT file.
fn write(path: &Path, samples: usize, compress: bool) {
    let (mut ts, mut us, mut ys) = (Vec::new(), Vec::new(), Vec::new());
    for (t, u, y) in signals::signals(samples) {
        ts.push(t);
        us.push(u);
        ys.push(y);
    }
    let mut m = MatFile::new();
    m.insert("t", matvar!(ts));
    m.insert("u", matvar!(us));
    m.insert("y", matvar!(ys));
    let path = path.to_str().expect("a UTF-8 temporary path");
    matrw::save_matfile_v7(path, m, compress).expect("writing the MAT file");
}

fn file(compressed: bool) -> (&'static Path, usize) {
    let (path, len) = &FILES.get().expect("written in main")[usize::from(compressed)];
    (path, *len)
}

fn hysid_load(bencher: Bencher, compressed: bool) {
    let (path, len) = file(compressed);
    let sel = DataSelection::default();
    bencher
        .counter(BytesCount::new(len))
        .bench_local(|| load(path, &sel).expect("the file reads"));
}

fn matrw_only(bencher: Bencher, compressed: bool) {
    let (path, len) = file(compressed);
    bencher.counter(BytesCount::new(len)).bench_local(|| {
        let bytes = std::fs::read(path).expect("the file reads");
        let m = matrw::load_matfile_from_u8(&bytes).expect("the file parses");
        m.iter()
            .filter(|(name, _)| ["t", "u", "y"].contains(&name.as_str()))
            .map(|(_, var)| var.to_vec_f64().expect("a double vector"))
            .collect::<Vec<_>>()
    });
}

#[divan::bench(sample_count = 10, sample_size = 1)]
fn hysid_load_uncompressed(bencher: Bencher) {
    hysid_load(bencher, false);
}

#[divan::bench(sample_count = 10, sample_size = 1)]
fn matrw_only_uncompressed(bencher: Bencher) {
    matrw_only(bencher, false);
}

#[divan::bench(sample_count = 10, sample_size = 1)]
fn hysid_load_compressed(bencher: Bencher) {
    hysid_load(bencher, true);
}

#[divan::bench(sample_count = 10, sample_size = 1)]
fn matrw_only_compressed(bencher: Bencher) {
    matrw_only(bencher, true);
}
