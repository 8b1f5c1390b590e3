//! B1 (classic 3-mode PWARX) with uniform noise in [-0.1, 0.1], delta = 0.1,
//! no mode count: 3 modes and at least 90 % of the samples in the right mode.

use hysid_bounded::{Bounded, BoundedOptions, Delta};
use hysid_core::backend::{Problem, RunContext};
use hysid_core::priors::Priors;
use hysid_model::metrics::mode_accuracy;
use hysid_model::regressors::RegressorSpec;

#[test]
fn b1_three_modes_ninety_percent() {
    for seed in [1u64, 2, 3] {
        let g = hysid_testkit::b1(300, 4.0, hysid_testkit::Noise::Uniform(0.1), seed);
        let pri = Priors::default();
        let problem = Problem {
            data: &g.data,
            orders: RegressorSpec::new(1, 1, 1),
            priors: &pri,
            priors_origin: None,
        };
        let opts = BoundedOptions {
            delta: Some(Delta::Value(0.1)),
            ..Default::default()
        };
        let (c, _, _) = Bounded::classify(&problem, &opts, &RunContext::quiet(seed)).unwrap();
        let labels: Vec<usize> = c
            .labels
            .iter()
            .map(|l| l.unwrap_or(usize::MAX / 2))
            .collect();
        let known: Vec<usize> = labels.iter().map(|&l| l.min(c.thetas.len())).collect();
        let acc = mode_accuracy(&g.row_modes(), &known).accuracy;
        eprintln!(
            "seed {seed}: modes {} (greedy {}), acc {acc:.3}, rounds {}, merged {}, dropped {}, thetas {:?}",
            c.thetas.len(),
            c.greedy_modes,
            c.rounds,
            c.merged,
            c.dropped,
            c.thetas
        );
        assert_eq!(c.thetas.len(), 3, "seed {seed}");
        assert!(acc >= 0.9, "seed {seed}: accuracy {acc}");
    }
}
