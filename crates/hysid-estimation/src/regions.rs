//! Region estimation for hysid: given regressors `x` (one per row) and a mode
//! label per row, find one polyhedral region per mode.
//!
//! This is step 4 of the clustering procedure of Ferrari-Trecate et al.
//! (the founding paper of hysid, Juloski, Heemels and Ferrari-Trecate,
//! ADHS 2003, uses it for the pick-and-place head) and the last step of the
//! bounded-error procedure of Bemporad et al. (2005). Four methods
//! ([`RegionMethod`]):
//!
//! * [`RegionMethod::Mrlp`] (default): the multicategory robust linear
//!   program of Bredensteiner and Bennett (1999), after Bennett and
//!   Mangasarian (1992/1994). One LP on clarabel. The regions are the
//!   argmax partition `{x : f_i(x) >= f_j(x) for all j}` of affine scores
//!   `f_i(x) = w_i.x - g_i`, so they **cover the whole space** (ties only on
//!   boundaries). That removes the holes that made the founding paper's
//!   simulation produce no output.
//! * [`RegionMethod::Msvm`]: the soft-margin multicategory SVM of Weston and
//!   Watkins (1999), a QP on clarabel, again an argmax partition.
//! * [`RegionMethod::Psvc`]: pairwise proximal SVC (Fung and Mangasarian,
//!   2001) in closed form, HIT's default. The regions are intersections of
//!   pairwise half-spaces and may leave holes (`complete = false`); use
//!   [`coverage`] to measure them.
//! * [`RegionMethod::Softmax`]: multinomial logistic regression (the
//!   multinomial-logistic separator of PARC, Bemporad 2023) by damped
//!   Newton: an argmax partition again, linear in `N` and by far the fastest
//!   complete method, but it does not minimise the MRLP objective.
//!
//! The LP and QP are solved by an exact working-set (cutting-plane) scheme:
//! only points whose hinge loss is active matter, so the solver sees a
//! subset and points outside it are checked afterwards; the scheme stops
//! only when every point outside the subset has zero loss, which certifies
//! that the subset optimum is an optimum of the full problem (see
//! `docs/regions.md`). The working set is seeded with the points near the
//! boundaries of a softmax fit (on a sample, its scores rescaled to the
//! program's units). The restricted MRLP is solved by a bounded-variable
//! simplex on its dual, which has only `(modes - 1)(d + 1)` rows and is
//! warm-started from round to round (clarabel is the fallback, and solves
//! the MSVM QP); measured times are in `docs/performance-regions.md`.
//!
//! ```
//! use hysid_estimation::regions::{estimate, RegionOptions};
//! use nalgebra::DMatrix;
//! // two modes on a line, switching at x = 0
//! let x = DMatrix::from_row_slice(6, 1, &[-3.0, -2.0, -1.0, 1.0, 2.0, 3.0]);
//! let labels = [0, 0, 0, 1, 1, 1];
//! let p = estimate(&x, &labels, 2, &RegionOptions::default()).unwrap();
//! assert!(p.complete);
//! assert_eq!(p.training_accuracy, 1.0);
//! assert!(p.regions[0].contains(&[-0.5]) && p.regions[1].contains(&[0.5]));
//! ```

use hysid_model::geometry::Polyhedron;
use nalgebra::DMatrix;
use problem::{Prepared, prepare};
use rand::{Rng, SeedableRng};

pub use adjacency::adjacency;
pub use alternation::{
    AUTO_ROUNDS, Alternation, AlternationReport, AlternationSettings, AlternationStatus,
    GATE_POINTS, alternate,
};
pub use hysid_model::geometry::argmax_regions;
pub use options::{
    DEFAULT_MAX_POINTS, Partition, RegionError, RegionFailure, RegionMethod, RegionOptions,
    SoftmaxSettings, SolveStats,
};

mod adjacency;
mod alternation;
mod options;
mod problem;
mod psvc;
mod simplex;
mod softmax;
mod working_set;

/// Estimates one region per mode from labelled regressors.
///
/// `x` is `N x d` with one regressor per row; `labels[r]` in `0..modes` is
/// the mode of row `r`. Every mode must have at least one point. With
/// `modes == 1` the single region is the whole space.
pub fn estimate(
    x: &DMatrix<f64>,
    labels: &[usize],
    modes: usize,
    opts: &RegionOptions,
) -> Result<Partition, RegionError> {
    if let Some(rows) = opts.max_points.and_then(|m| thinned_rows(labels, modes, m)) {
        let sub_x = x.select_rows(&rows);
        let sub_labels: Vec<usize> = rows.iter().map(|&r| labels[r]).collect();
        let all = RegionOptions {
            max_points: None,
            ..opts.clone()
        };
        let mut partition = estimate(&sub_x, &sub_labels, modes, &all)?;
        partition.training_accuracy = training_accuracy(&partition.regions, x, labels);
        return Ok(partition);
    }
    let prep = prepare(x, labels, modes, opts)?;
    let d = x.ncols();
    if modes == 1 {
        return Ok(Partition {
            regions: vec![Polyhedron::everything()],
            training_accuracy: 1.0,
            complete: true,
            scores: vec![vec![0.0; d + 1]],
            stats: SolveStats {
                working_points: prep.n,
                ..SolveStats::default()
            },
        });
    }
    let (regions, complete, scores, stats) = match opts.method {
        RegionMethod::Mrlp | RegionMethod::Msvm => {
            let (wg, stats) = working_set::solve(&prep, labels, modes, opts)?;
            let scores = scores_in_original_units(&prep, &wg, d);
            (argmax_regions(&scores), true, scores, stats)
        }
        RegionMethod::Softmax => {
            let (wg, steps) = softmax::fit(&prep, labels, modes, &opts.softmax)?;
            let scores = scores_in_original_units(&prep, &wg, d);
            let stats = SolveStats {
                working_points: prep.n,
                newton_steps: steps,
                ..SolveStats::default()
            };
            (argmax_regions(&scores), true, scores, stats)
        }
        RegionMethod::Psvc => {
            let regions = psvc::regions(&prep, labels, modes, d)?;
            let stats = SolveStats {
                working_points: prep.n,
                ..SolveStats::default()
            };
            (regions, modes <= 2, Vec::new(), stats)
        }
    };
    let training_accuracy = training_accuracy(&regions, x, labels);
    Ok(Partition {
        regions,
        training_accuracy,
        complete,
        scores,
        stats,
    })
}

/// The rows [`RegionOptions::max_points`] keeps of `labels.len()` points:
/// every `stride`-th, plus every point of a mode the stride misses; `None`
/// when there are at most `max_points` points (or `max_points` is 0).
fn thinned_rows(labels: &[usize], modes: usize, max_points: usize) -> Option<Vec<usize>> {
    let n = labels.len();
    if max_points == 0 || n <= max_points {
        return None;
    }
    let stride = n.div_ceil(max_points);
    let mut rows: Vec<usize> = (0..n).step_by(stride).collect();
    let mut seen = vec![false; modes];
    for &r in &rows {
        if let Some(s) = seen.get_mut(labels[r]) {
            *s = true;
        }
    }
    if seen.iter().any(|s| !s) {
        rows.extend((0..n).filter(|&r| labels[r] < modes && !seen[labels[r]]));
        rows.sort_unstable();
    }
    Some(rows)
}

/// The regions of a PWARX back-end's final assignment: [`estimate`] with
/// `method`, the normals restricted to the `switching` regressors of the
/// priors, and the error worded for the run.
pub fn for_pwarx(
    method: RegionMethod,
    data: &crate::pwarx::PwarxData<'_>,
    reg: &hysid_model::regressors::Regressors,
    labels: &[usize],
    modes: usize,
) -> Result<Partition, hysid_core::backend::IdentifyError> {
    let options = RegionOptions {
        method,
        switching: data.switching.clone(),
        ..Default::default()
    };
    estimate(&reg.x, labels, modes, &options)
        .map_err(|e| hysid_core::backend::IdentifyError::failed(RegionFailure::Estimate(e)))
}

/// `wg` holds per mode `[w (p); g]` on standardised selected columns, with
/// `f(z) = w.z - g`. Returns `[c (d); c0]` with `f = c.x + c0` in original
/// units and exact zeros outside the selected columns.
fn scores_in_original_units(prep: &Prepared, wg: &[Vec<f64>], d: usize) -> Vec<Vec<f64>> {
    wg.iter()
        .map(|v| {
            let mut c = vec![0.0; d + 1];
            let mut c0 = -v[prep.p];
            for k in 0..prep.p {
                let ck = v[k] / prep.scale[k];
                c[prep.cols[k]] = ck;
                c0 -= ck * prep.mean[k];
            }
            c[d] = c0;
            c
        })
        .collect()
}

/// The first region (lowest index) that contains `z`, as HIT's `hit_pwa`.
pub fn classify(regions: &[Polyhedron], z: &[f64]) -> Option<usize> {
    regions.iter().position(|r| r.contains(z))
}

/// The first region containing `z`, or else the region it violates least
/// ([`Polyhedron::violation`], Euclidean distance to the violated rows; ties
/// to the lowest index): a "nearest region" policy for points in holes.
/// `None` only when `regions` is empty.
/// The rule of `hysid_model::model::region_of`, which simulation uses.
pub fn classify_nearest(regions: &[Polyhedron], z: &[f64]) -> Option<usize> {
    (!regions.is_empty()).then(|| hysid_model::model::region_of(regions, z).mode)
}

/// Fraction of rows of `x` whose first-match region is their label.
pub fn training_accuracy(regions: &[Polyhedron], x: &DMatrix<f64>, labels: &[usize]) -> f64 {
    let n = x.nrows().min(labels.len());
    if n == 0 {
        return 1.0;
    }
    let mut row = vec![0.0; x.ncols()];
    let mut ok = 0usize;
    for (r, &label) in labels.iter().enumerate().take(n) {
        for (k, v) in row.iter_mut().enumerate() {
            *v = x[(r, k)];
        }
        if classify(regions, &row) == Some(label) {
            ok += 1;
        }
    }
    ok as f64 / n as f64
}

/// Result of [`coverage`].
#[derive(Debug, Clone, PartialEq)]
pub struct CoverageReport {
    /// Number of sampled points.
    pub samples: usize,
    /// Fraction of samples in no region (holes).
    pub uncovered_fraction: f64,
    /// Fraction of samples in two or more regions (overlaps; for exact
    /// partitions only boundary points, which have probability zero).
    pub multiply_covered_fraction: f64,
}

/// Holes report: `samples` uniform points in the box `[lo, hi]` (seeded
/// with `ChaCha8Rng::seed_from_u64(seed)`), counted as uncovered (in no
/// region) or multiply covered (in two or more), with the membership
/// tolerance of [`Polyhedron::contains`]. The box dimension is
/// `min(lo.len(), hi.len())`; a side with `lo > hi` is sampled in
/// `[hi, lo]`.
pub fn coverage(
    regions: &[Polyhedron],
    lo: &[f64],
    hi: &[f64],
    samples: usize,
    seed: u64,
) -> CoverageReport {
    let d = lo.len().min(hi.len());
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut z = vec![0.0; d];
    let (mut none, mut many) = (0usize, 0usize);
    for _ in 0..samples {
        for k in 0..d {
            let u: f64 = rng.random();
            let (a, b) = if lo[k] <= hi[k] {
                (lo[k], hi[k])
            } else {
                (hi[k], lo[k])
            };
            z[k] = a + u * (b - a);
        }
        let hits = regions.iter().filter(|r| r.contains(&z)).take(2).count();
        match hits {
            0 => none += 1,
            1 => {}
            _ => many += 1,
        }
    }
    let frac = |c: usize| {
        if samples == 0 {
            0.0
        } else {
            c as f64 / samples as f64
        }
    };
    CoverageReport {
        samples,
        uncovered_fraction: frac(none),
        multiply_covered_fraction: frac(many),
    }
}
