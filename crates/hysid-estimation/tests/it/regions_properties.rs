//! Property tests: the default partition covers the space, and MRLP
//! separates argmax-separable classes exactly.

use hysid_estimation::regions::{
    RegionMethod, RegionOptions, argmax_regions, classify, coverage, estimate,
};
use nalgebra::DMatrix;
use proptest::prelude::*;

/// A random Voronoi (hence argmax-linear) partition: centres `c_i`, scores
/// `f_i(x) = c_i . x - |c_i|^2 / 2`. Points within `gap` of a boundary (in
/// score difference) are dropped, the centres themselves are added so that
/// every mode has a point.
fn voronoi_cloud(
    centres: &[Vec<f64>],
    points: &[Vec<f64>],
    gap: f64,
) -> (DMatrix<f64>, Vec<usize>) {
    let d = centres[0].len();
    let score = |c: &Vec<f64>, x: &[f64]| -> f64 {
        c.iter().zip(x).map(|(a, b)| a * b).sum::<f64>()
            - 0.5 * c.iter().map(|v| v * v).sum::<f64>()
    };
    let mut rows = Vec::new();
    let mut labels = Vec::new();
    for x in centres.iter().chain(points) {
        let f: Vec<f64> = centres.iter().map(|c| score(c, x)).collect();
        let best = (0..f.len()).max_by(|&a, &b| f[a].total_cmp(&f[b])).unwrap();
        let second = (0..f.len())
            .filter(|&j| j != best)
            .map(|j| f[j])
            .fold(f64::NEG_INFINITY, f64::max);
        if f[best] - second >= gap {
            rows.extend_from_slice(x);
            labels.push(best);
        }
    }
    (DMatrix::from_row_slice(labels.len(), d, &rows), labels)
}

fn cloud_strategy() -> impl Strategy<Value = (Vec<Vec<f64>>, Vec<Vec<f64>>)> {
    (2usize..=3, 2usize..=4).prop_flat_map(|(d, s)| {
        (
            prop::collection::vec(prop::collection::vec(-1.0f64..1.0, d), s),
            prop::collection::vec(prop::collection::vec(-1.5f64..1.5, d), 20..80),
        )
    })
}

fn min_distance(c: &[Vec<f64>]) -> f64 {
    let mut m = f64::INFINITY;
    for i in 0..c.len() {
        for j in i + 1..c.len() {
            let d2: f64 = c[i].iter().zip(&c[j]).map(|(a, b)| (a - b) * (a - b)).sum();
            m = m.min(d2.sqrt());
        }
    }
    m
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    #[test]
    fn mrlp_covers_the_space_and_separates_argmax_classes((centres, points) in cloud_strategy(), seed in any::<u64>()) {
        prop_assume!(min_distance(&centres) >= 0.4);
        let (x, labels) = voronoi_cloud(&centres, &points, 0.05);
        let d = x.ncols();
        let s = centres.len();
        let p = estimate(&x, &labels, s, &RegionOptions::default()).unwrap();
        prop_assert!(p.complete);
        prop_assert_eq!(p.training_accuracy, 1.0);
        let c = coverage(&p.regions, &vec![-10.0; d], &vec![10.0; d], 2_000, seed);
        prop_assert_eq!(c.uncovered_fraction, 0.0);
        prop_assert_eq!(c.multiply_covered_fraction, 0.0);
        // The other complete methods cover too.
        for method in [RegionMethod::Msvm, RegionMethod::Softmax] {
            let q = estimate(&x, &labels, s, &RegionOptions { method, ..RegionOptions::default() }).unwrap();
            prop_assert!(q.complete);
            let c = coverage(&q.regions, &vec![-10.0; d], &vec![10.0; d], 1_000, seed);
            prop_assert_eq!(c.uncovered_fraction, 0.0);
        }
    }

    #[test]
    fn argmax_regions_cover_every_point(
        scores in (1usize..=4, 1usize..=5).prop_flat_map(|(d, s)| prop::collection::vec(prop::collection::vec(-1e3f64..1e3, d + 1), s)),
        z in prop::collection::vec(-1e4f64..1e4, 4),
    ) {
        let d = scores[0].len() - 1;
        let regions = argmax_regions(&scores);
        let z = &z[..d];
        let hit = classify(&regions, z);
        prop_assert!(hit.is_some());
        // the first match is a maximiser of the scores (up to rounding)
        let f = |i: usize| scores[i][..d].iter().zip(z).map(|(a, b)| a * b).sum::<f64>() + scores[i][d];
        let best = (0..scores.len()).map(f).fold(f64::NEG_INFINITY, f64::max);
        let scale = 1.0 + scores.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs())) * (1.0 + z.iter().fold(0.0f64, |m, v| m.max(v.abs())));
        prop_assert!(f(hit.unwrap()) >= best - 1e-6 * scale);
    }
}
