//! Unit tests per method on separable and slightly overlapping 2-D data,
//! `switching`, holes of PSVC, determinism and error cases.

use hysid_regions::{RegionError, RegionMethod, RegionOptions, coverage, estimate};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Points uniform in [-3, 3]^2 labelled by the argmax of three affine scores
/// (a three-wedge partition meeting at (0.5, -0.25)); `flip` is the fraction
/// of labels replaced by a neighbouring mode when within `band` of a boundary.
fn wedges(n: usize, seed: u64, band: f64, flip: f64) -> (DMatrix<f64>, Vec<usize>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let scores = [[1.0, 0.0, -0.5], [-0.5, 0.9, 0.0], [-0.5, -0.9, 0.2]];
    let mut x = DMatrix::zeros(n, 2);
    let mut labels = Vec::with_capacity(n);
    for r in 0..n {
        let z = [rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)];
        x[(r, 0)] = z[0];
        x[(r, 1)] = z[1];
        let f: Vec<f64> = scores
            .iter()
            .map(|s| s[0] * z[0] + s[1] * z[1] + s[2])
            .collect();
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| f[b].total_cmp(&f[a]));
        let gap = f[order[0]] - f[order[1]];
        let label = if gap < band && rng.random::<f64>() < flip {
            order[1]
        } else {
            order[0]
        };
        labels.push(label);
    }
    (x, labels)
}

fn opts(method: RegionMethod) -> RegionOptions {
    RegionOptions {
        method,
        ..RegionOptions::default()
    }
}

#[test]
fn defaults() {
    let o = RegionOptions::default();
    assert_eq!(o.method, RegionMethod::Mrlp);
    assert_eq!(o.svm_c, 1.0);
    assert!(o.switching.is_none());
    assert!(o.standardize);
}

#[test]
fn every_method_separates_separable_wedges() {
    let (x, labels) = wedges(300, 1, 0.0, 0.0);
    for method in [RegionMethod::Mrlp, RegionMethod::Msvm, RegionMethod::Psvc] {
        let p = estimate(&x, &labels, 3, &opts(method)).unwrap();
        assert_eq!(p.regions.len(), 3);
        // MSVM is soft-margin (C = 1) and may give up a few points for margin.
        // PSVC is a regularised least-squares fit of +-1 labels, not a
        // max-margin separator: it misplaces boundaries even on separable data.
        let floor = match method {
            RegionMethod::Psvc => 0.9,
            RegionMethod::Msvm => 0.98,
            RegionMethod::Mrlp => 0.999,
        };
        assert!(
            p.training_accuracy > floor,
            "{method}: accuracy {}",
            p.training_accuracy
        );
        assert_eq!(p.complete, method != RegionMethod::Psvc, "{method}");
    }
    // MRLP reaches zero training error on argmax-separable data.
    let p = estimate(&x, &labels, 3, &RegionOptions::default()).unwrap();
    assert_eq!(p.training_accuracy, 1.0);
    let c = coverage(&p.regions, &[-10.0, -10.0], &[10.0, 10.0], 20_000, 7);
    assert_eq!(c.uncovered_fraction, 0.0);
    assert_eq!(c.multiply_covered_fraction, 0.0);
}

#[test]
fn every_method_handles_slight_overlap() {
    let (x, labels) = wedges(400, 2, 0.3, 0.5);
    for method in [RegionMethod::Mrlp, RegionMethod::Msvm, RegionMethod::Psvc] {
        let p = estimate(&x, &labels, 3, &opts(method)).unwrap();
        assert!(
            p.training_accuracy > 0.9 && p.training_accuracy < 1.0,
            "{method}: {}",
            p.training_accuracy
        );
        if p.complete {
            let c = coverage(&p.regions, &[-10.0, -10.0], &[10.0, 10.0], 20_000, 8);
            assert_eq!(c.uncovered_fraction, 0.0, "{method}");
        }
    }
}
