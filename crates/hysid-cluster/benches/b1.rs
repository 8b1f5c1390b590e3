//! End-to-end identification of the classic three-mode PWARX B1
//! (na = 1, nb = 1, regions included) with the default options, and of the
//! same record with the orders na = 2, nb = 1 (B1 with a second output lag
//! whose true coefficient is zero).
//!
//! ```text
//! cargo bench -p hysid-cluster --bench b1
//! ```
//! Scaling from N = 10^3 to 10^6 with a per-stage breakdown:
//! `cargo run --release -p hysid-cluster --example cluster_scaling`.

use hysid_cluster::Cluster;
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::regressors::RegressorSpec;
use hysid_testkit::Noise;

fn main() {
    divan::main();
}

#[divan::bench(args = [1000, 8000], sample_count = 10, sample_size = 1)]
fn b1_end_to_end(bencher: divan::Bencher, n: usize) {
    bench_orders(bencher, n, None);
}

#[divan::bench(args = [8000], sample_count = 10, sample_size = 1)]
fn b1_na2_nb1_end_to_end(bencher: divan::Bencher, n: usize) {
    bench_orders(bencher, n, Some(RegressorSpec::new(2, 1, 1)));
}

fn bench_orders(bencher: divan::Bencher, n: usize, orders: Option<RegressorSpec>) {
    // `n` regressor rows of B1 (`u ~ U[-4, 4]`, noise `U[-0.1, 0.1]`).
    let ex = hysid_testkit::b1(n + 1, 4.0, Noise::Uniform(0.1), 1);
    let orders = orders.unwrap_or(ex.truth.spec());
    let priors = Priors {
        modes: Some(3),
        ..Default::default()
    };
    let settings = Settings::default();
    bencher.bench(|| {
        let problem = Problem {
            data: &ex.data,
            orders,
            priors: &priors,
            priors_origin: None,
        };
        Pwarx(Cluster)
            .run(&problem, &settings, &RunContext::quiet(1))
            .expect("B1 identifies")
    });
}
