//! Region estimation times. Run with
//! `cargo bench -p hysid-estimation --bench regions`.
//!
//! Data: `benches/regions_data/mod.rs`, shared with the example
//! `regions_stats`.

mod regions_data;

use hysid_estimation::regions::{RegionMethod, RegionOptions, estimate};
use regions_data::data;

fn main() {
    divan::main();
}

const SIZES: [usize; 3] = [1_000, 8_000, 100_000];

fn run(bencher: divan::Bencher, n: usize, method: RegionMethod) {
    let (x, labels) = data(n);
    let opts = RegionOptions {
        method,
        ..RegionOptions::default()
    };
    bencher.bench_local(|| estimate(&x, &labels, 3, &opts).unwrap());
}

#[divan::bench(args = SIZES, sample_count = 3, sample_size = 1)]
fn mrlp(bencher: divan::Bencher, n: usize) {
    run(bencher, n, RegionMethod::Mrlp);
}

#[divan::bench(args = SIZES, sample_count = 3, sample_size = 1)]
fn msvm(bencher: divan::Bencher, n: usize) {
    run(bencher, n, RegionMethod::Msvm);
}

#[divan::bench(args = SIZES, sample_count = 3, sample_size = 1)]
fn psvc(bencher: divan::Bencher, n: usize) {
    run(bencher, n, RegionMethod::Psvc);
}

#[divan::bench(args = SIZES, sample_count = 3, sample_size = 1)]
fn softmax(bencher: divan::Bencher, n: usize) {
    run(bencher, n, RegionMethod::Softmax);
}
