//! Speed of the bounded-error procedure: B1 (3 modes, noise
//! U[-0.1, 0.1], delta = 0.1, default options, seed 1) for growing N.
//! Run on one core: `taskset -c 0 cargo bench -p hysid-bounded --bench bounded`.
//! Figures in `docs/performance-bounded.md`.

use hysid_bounded::{Bounded, BoundedOptions, Delta};
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::options::{Checked, Settings};
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::regressors::RegressorSpec;

fn main() {
    divan::main();
}

/// Whole identification (MIN PFS, refinement, regions by MRLP).
#[divan::bench(args = [1000, 2000, 4000, 8000, 16000], sample_count = 5, sample_size = 1)]
fn identify(bencher: divan::Bencher, n: usize) {
    let g = hysid_testkit::b1(n, 4.0, hysid_testkit::Noise::Uniform(0.1), 1);
    let pri = Priors::default();
    let problem = Problem {
        data: &g.data,
        orders: RegressorSpec::new(1, 1, 1),
        priors: &pri,
        priors_origin: None,
    };
    let settings = Settings::parse(&["delta=0.1"]).unwrap();
    bencher.bench(|| {
        Pwarx(Bounded)
            .run(&problem, &settings, &RunContext::quiet(1))
            .unwrap()
    });
}

/// Classification only (MIN PFS and refinement, no regions).
#[divan::bench(args = [1000, 2000, 4000, 8000, 16000], sample_count = 5, sample_size = 1)]
fn classify(bencher: divan::Bencher, n: usize) {
    let g = hysid_testkit::b1(n, 4.0, hysid_testkit::Noise::Uniform(0.1), 1);
    let pri = Priors::default();
    let problem = Problem {
        data: &g.data,
        orders: RegressorSpec::new(1, 1, 1),
        priors: &pri,
        priors_origin: None,
    };
    let opts = Checked::new(BoundedOptions {
        delta: Delta::Value(0.1),
        ..Default::default()
    })
    .unwrap();
    bencher.bench(|| Bounded::classify(&problem, &opts, &RunContext::quiet(1)).unwrap());
}
