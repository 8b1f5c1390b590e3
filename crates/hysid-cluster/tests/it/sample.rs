//! A run on a clustering sample (`cluster_points` below the record's
//! samples): steps 1 to 7 on every k-th sample, then every sample to the
//! mode of its region and the trimmed re-estimation, which stands in for
//! the confidence weights the other samples lack.

use hysid_cluster::Cluster;
use hysid_cluster::fit::SAMPLE_TRIM;
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::metrics::parameter_error;
use hysid_model::model::{PwarxModel, TrimmingStatus};
use hysid_model::regressors::RegressorSpec;
use hysid_testkit::{Benchmark, Noise, b1};

/// B1 identified with three modes and the options `set`.
fn identify(b: &Benchmark, set: &[&str]) -> PwarxModel {
    let priors = Priors {
        modes: Some(3),
        ..Priors::default()
    };
    let problem = Problem {
        data: &b.data,
        orders: RegressorSpec::new(1, 1, 1),
        priors: &priors,
        priors_origin: None,
    };
    match Pwarx(Cluster)
        .run(
            &problem,
            &Settings::parse(set).unwrap(),
            &RunContext::quiet(3),
        )
        .unwrap()
    {
        Model::Pwarx(p) => p,
        other => panic!("kind {}", other.kind()),
    }
}

/// Largest relative parameter error against B1's modes.
fn error(b: &Benchmark, m: &PwarxModel) -> f64 {
    let thetas: Vec<Vec<f64>> = m.modes.iter().map(|q| q.theta.clone()).collect();
    parameter_error(&b.thetas(), &thetas)
        .unwrap()
        .max_relative_error
}

/// On 12 000 samples of B1, a clustering sample of 3000 (every fourth
/// sample) records its size and its trimming, and its parameters are as
/// close to the true ones as those of the clustering of every sample
/// (within twice the relative error, plus 1e-3: 0.0029 against 0.0068;
/// ordinary least squares on every sample of the regions, without the
/// trimming, ends at 0.020).
#[test]
fn a_clustering_sample_estimates_as_the_full_clustering() {
    let b = b1(12_001, 4.0, Noise::Uniform(0.1), 2);
    let full = identify(&b, &["cluster_points=0"]);
    let sampled = identify(&b, &["cluster_points=3000"]);
    let d = &sampled.info.diagnostics;
    assert_eq!(d.method["clustering_sample"], 3000);
    assert!(full.info.diagnostics.trimming.is_none());
    let trimming = d.trimming.as_ref().expect("the trimming recorded");
    assert_eq!(trimming.cutoff, SAMPLE_TRIM);
    assert_eq!(trimming.status, TrimmingStatus::Converged);
    assert!(
        trimming.left_out.iter().sum::<usize>() > 0,
        "no mixed point left out"
    );
    let (e_full, e_sampled) = (error(&b, &full), error(&b, &sampled));
    assert!(
        e_sampled <= 2.0 * e_full + 1e-3,
        "sampled {e_sampled} against every sample {e_full}"
    );
}
