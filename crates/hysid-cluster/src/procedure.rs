//! Steps 1 to 5 and 7 of the procedure on a regression problem
//! `y_k = theta_i' [x_k; 1]`, in working units (region estimation, step 6,
//! is done by the caller with `hysid_estimation::regions`).
//!
//! 1. local datasets and feature vectors ([`crate::local`]);
//! 2. clustering of the feature vectors ([`crate::kmeans`]);
//! 3. mode datasets `F_i`; a cluster with fewer than `max(c, alpha (n+1))`
//!    points is discarded and its points become outliers
//!    (Ferrari-Trecate et al. 2003, section 3.3; HIT `discard_threshold_factor`);
//! 4. weighted least squares per mode with the confidences `w_j`
//!    (section 3.4): `theta_i = argmin sum_{j in F_i} w_j (y_j - [x_j' 1] theta)^2`;
//! 5. outliers go to the mode of least squared residual, and *mixed*
//!    points (a point whose local dataset holds points of another mode) to
//!    the mode of least squared residual among their own and the modes
//!    present in their local dataset (HIT `mix_detect`); the discard check
//!    runs again and the parameters are re-estimated.
//!
//! HIT restricts the mixed-point candidates to the modes whose *regions*
//! are adjacent to the point's. The modes present in the point's local
//! dataset are its neighbours in regressor space, which is what adjacency
//! stands for, and they do not need a first region estimate.

use crate::kmeans::{self, Clusters, KmeansInit};
use crate::local::{self, Degeneracy, FeatureVectors};
use crate::priors::{ConstrainedFit, Thetas};
use crate::{Clustering, Features, Weights};
use hysid_core::backend::Deadline;
use hysid_estimation::linalg;
use hysid_model::statistics::upper_median;
use nalgebra::{DMatrix, DVector};
use rand_chacha::ChaCha8Rng;

/// Settings of the procedure (the back-end's options, resolved).
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Local dataset size `c`.
    pub c: usize,
    /// Number of clusters `s`.
    pub modes: usize,
    /// Feature vectors.
    pub features: Features,
    /// Clustering algorithm.
    pub clustering: Clustering,
    /// Single-linkage distance threshold.
    pub sl_distance: Option<f64>,
    /// K-means restarts.
    pub restarts: usize,
    /// K-means sweeps per restart.
    pub max_iter: usize,
    /// K-means initialisation.
    pub init: KmeansInit,
    /// Discard factor `alpha` (0: only empty clusters are discarded).
    pub discard: f64,
    /// Mixed-point reattribution.
    pub reattribute: bool,
    /// Regularisation `eps` of degenerate local datasets.
    pub regularization: f64,
    /// Smallest relative confidence weight in the per-mode least squares.
    pub min_weight: f64,
    /// Weights of the per-mode least squares.
    pub weights: Weights,
    /// No K-means restart starts after this instant (time budget).
    pub deadline: Deadline,
}

/// What the procedure found, in working units.
#[derive(Debug, Clone)]
pub struct ModeFit {
    /// Mode of every sample, `0..theta.len()`.
    pub labels: Vec<usize>,
    /// Parameters `[theta_slopes; constant]` per mode.
    pub theta: Vec<Vec<f64>>,
    /// The same in original units when fitted under gray-box priors
    /// (where ties and fixed values hold exactly).
    pub theta_original: Option<Vec<Vec<f64>>>,
    /// Diagnostics.
    pub diagnostics: Diagnostics,
    /// The feature vectors (kept for the final refit).
    pub features: FeatureVectors,
}

/// Diagnostics of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostics {
    /// Regularised local datasets.
    pub degenerate: Degeneracy,
    /// Clusters produced by the clustering step.
    pub clusters: usize,
    /// K-means cost of the kept restart.
    pub kmeans_cost: f64,
    /// K-means cost of every restart.
    pub restart_costs: Vec<f64>,
    /// Sweeps of the kept restart.
    pub kmeans_iterations: usize,
    /// Whether the kept restart met the stopping rule.
    pub kmeans_converged: bool,
    /// Clusters discarded (first and second check).
    pub discarded_clusters: usize,
    /// Points of discarded clusters, reattributed by residual.
    pub outliers: usize,
    /// Points moved by mixed-point reattribution.
    pub reattributed: usize,
    /// `reattributed / N` (HIT's `stat_reattr`).
    pub reattributed_fraction: f64,
    /// Minimum discard size `max(c, alpha (n+1))`.
    pub discard_size: usize,
}

/// Why the procedure could not produce modes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProcedureError {
    /// Every cluster was smaller than the discard size.
    #[error(
        "every cluster has fewer than {0} points (the discard size max(c, alpha (n+1))): lower c or the mode count, or set discard=0"
    )]
    AllDiscarded(usize),
    /// Least squares failed (non-finite data).
    #[error("least squares failed: {0}")]
    LeastSquares(String),
}

fn residual2(x: &[f64], y: f64, th: &[f64]) -> f64 {
    let n = x.len();
    let pred: f64 = x.iter().zip(&th[..n]).map(|(a, b)| a * b).sum::<f64>() + th[n];
    (y - pred).powi(2)
}

/// The weights of the per-mode least squares of the samples `rows` of one
/// mode (section 3.4: the confidences `w_j`, normalised within the mode and
/// floored at `min_weight`, or as chosen by [`Weights`]).
fn mode_weights(f: &FeatureVectors, rows: &[usize], min_weight: f64, weights: Weights) -> Vec<f64> {
    let top = match weights {
        Weights::Confidence => rows
            .iter()
            .map(|&j| f.log_w[j])
            .fold(f64::NEG_INFINITY, f64::max),
        Weights::Capped => {
            let mut lw: Vec<f64> = rows.iter().map(|&j| f.log_w[j]).collect();
            upper_median(&mut lw).unwrap_or(0.0)
        }
        Weights::Uniform => 0.0,
    };
    rows.iter()
        .map(|&j| match weights {
            Weights::Uniform => 1.0,
            _ => (f.log_w[j] - top).exp().clamp(min_weight, 1.0),
        })
        .collect()
}

/// Weighted least squares per mode (step 4) on the mode datasets given by
/// `labels` (`0..modes`).
#[allow(clippy::too_many_arguments)]
pub fn fit_modes(
    x: &[f64],
    n: usize,
    y: &[f64],
    f: &FeatureVectors,
    labels: &[usize],
    modes: usize,
    min_weight: f64,
    weights: Weights,
) -> Result<Vec<Vec<f64>>, ProcedureError> {
    let mut out = Vec::with_capacity(modes);
    for i in 0..modes {
        let rows: Vec<usize> = (0..labels.len()).filter(|&j| labels[j] == i).collect();
        let w = mode_weights(f, &rows, min_weight, weights);
        let mut phi = DMatrix::from_element(rows.len(), n + 1, 1.0);
        let mut t = DVector::zeros(rows.len());
        for (r, &j) in rows.iter().enumerate() {
            for k in 0..n {
                phi[(r, k)] = x[j * n + k];
            }
            t[r] = y[j];
        }
        let sol = linalg::weighted_lstsq(&phi, &t, &w)
            .map_err(|e| ProcedureError::LeastSquares(e.to_string()))?;
        out.push(sol.theta.iter().copied().collect());
    }
    Ok(out)
}

/// Step 4 with or without gray-box priors: [`fit_modes`] without
/// constraints; with them, the same weights go to
/// [`ConstrainedFit::fit`] (ties, fixed values and bounds of all modes solved
/// jointly by `hysid_estimation::constrained::fit_modes`).
#[allow(clippy::too_many_arguments)]
pub fn fit_modes_with(
    x: &[f64],
    n: usize,
    y: &[f64],
    f: &FeatureVectors,
    labels: &[usize],
    modes: usize,
    min_weight: f64,
    weights: Weights,
    constraints: Option<&ConstrainedFit>,
) -> Result<Thetas, ProcedureError> {
    let Some(con) = constraints else {
        return Ok(Thetas {
            working: fit_modes(x, n, y, f, labels, modes, min_weight, weights)?,
            original: None,
        });
    };
    let mut w = vec![0.0; labels.len()];
    for i in 0..modes {
        let rows: Vec<usize> = (0..labels.len()).filter(|&j| labels[j] == i).collect();
        for (r, wj) in rows.iter().zip(mode_weights(f, &rows, min_weight, weights)) {
            w[*r] = wj;
        }
    }
    con.fit(labels, modes, &w)
        .map_err(|e| ProcedureError::LeastSquares(e.to_string()))
}

/// Drops modes with fewer than `min_size` points, renumbering the rest in
/// order; returns the number dropped. Points of dropped modes get
/// `usize::MAX`.
fn discard_small(labels: &mut [usize], modes: usize, min_size: usize) -> (usize, usize) {
    let mut size = vec![0usize; modes];
    for &l in labels.iter() {
        if l < modes {
            size[l] += 1;
        }
    }
    let mut map = vec![usize::MAX; modes];
    let mut kept = 0;
    for i in 0..modes {
        if size[i] >= min_size.max(1) {
            map[i] = kept;
            kept += 1;
        }
    }
    for l in labels.iter_mut() {
        *l = if *l < modes { map[*l] } else { usize::MAX };
    }
    (kept, modes - kept)
}

/// Runs steps 1-5 and 7 on `x` (N x n, row-major) and `y`.
pub fn run(
    x: &[f64],
    n: usize,
    y: &[f64],
    s: &Settings,
    rng: &mut ChaCha8Rng,
) -> Result<ModeFit, ProcedureError> {
    run_with(x, n, y, s, rng, None)
}

/// [`run`] with every weighted least squares of steps 4, 5 and 7 under the
/// gray-box priors of `constraints`; the local regressions of
/// step 1 stay unconstrained (`docs/cluster.md`, "Priors").
pub fn run_with(
    x: &[f64],
    n: usize,
    y: &[f64],
    s: &Settings,
    rng: &mut ChaCha8Rng,
    constraints: Option<&ConstrainedFit>,
) -> Result<ModeFit, ProcedureError> {
    let big_n = y.len();
    let f = local::feature_vectors(x, n, y, s.c, s.features, s.regularization);
    let clusters = cluster(&f, s, rng);
    let discard_size = discard_size(s, n);
    let mut labels = clusters.labels.clone();
    let (mut modes, mut discarded) = discard_small(&mut labels, clusters.count, discard_size);
    if modes == 0 {
        return Err(ProcedureError::AllDiscarded(discard_size));
    }
    let outliers = labels.iter().filter(|&&l| l == usize::MAX).count();
    let fit = |labels: &[usize], modes: usize| {
        fit_modes_with(
            x,
            n,
            y,
            &f,
            labels,
            modes,
            s.min_weight,
            s.weights,
            constraints,
        )
    };
    let fitted = fit(&labels, modes)?;
    let mut theta = fitted.working;
    let mut theta_original = fitted.original;
    place_by_residual(&mut labels, modes, x, n, y, &theta);
    let mut reattributed = 0;
    if s.reattribute {
        reattributed = reattribute(&mut labels, &f, x, n, y, &theta);
        // Second discard check, then points of dropped modes go by residual.
        let (kept, dropped) = discard_small(&mut labels, modes, discard_size);
        if kept == 0 {
            return Err(ProcedureError::AllDiscarded(discard_size));
        }
        if dropped > 0 {
            theta = fit(&labels, kept)?.working;
            place_by_residual(&mut labels, kept, x, n, y, &theta);
            discarded += dropped;
            modes = kept;
        }
    }
    // The parameters are estimated again from the final labels whenever a
    // point moved: outliers placed by residual, or a reattribution.
    if outliers > 0 || s.reattribute {
        let fitted = fit(&labels, modes)?;
        theta = fitted.working;
        theta_original = fitted.original;
    }
    Ok(ModeFit {
        labels,
        theta,
        theta_original,
        diagnostics: Diagnostics {
            degenerate: f.degenerate,
            clusters: clusters.count,
            kmeans_cost: clusters.cost,
            restart_costs: clusters.restart_costs,
            kmeans_iterations: clusters.iterations,
            kmeans_converged: clusters.converged,
            discarded_clusters: discarded,
            outliers,
            reattributed,
            reattributed_fraction: reattributed as f64 / big_n.max(1) as f64,
            discard_size,
        },
        features: f,
    })
}

/// Step 2: the feature vectors clustered into `s.modes` clusters.
fn cluster(f: &FeatureVectors, s: &Settings, rng: &mut ChaCha8Rng) -> Clusters {
    match s.clustering {
        Clustering::Kmeans => kmeans::weighted_kmeans_until(
            f,
            s.modes,
            s.restarts,
            s.max_iter,
            s.init,
            rng,
            &s.deadline,
        ),
        Clustering::SingleLinkage => kmeans::single_linkage(f, s.modes, s.sl_distance),
    }
}

/// The smallest cluster kept: `max(c, discard (n + 1))`, or 1 without a
/// discard factor.
fn discard_size(s: &Settings, n: usize) -> usize {
    if s.discard > 0.0 {
        s.c.max((s.discard * (n + 1) as f64).ceil() as usize)
    } else {
        1
    }
}

/// Every point without a mode (`usize::MAX`) to the mode of least
/// residual among `0..modes` (the lower index among equals).
fn place_by_residual(
    labels: &mut [usize],
    modes: usize,
    x: &[f64],
    n: usize,
    y: &[f64],
    theta: &[Vec<f64>],
) {
    for (j, l) in labels.iter_mut().enumerate() {
        if *l == usize::MAX {
            let xj = &x[j * n..(j + 1) * n];
            let mut best = (f64::INFINITY, usize::MAX);
            for (i, t) in theta.iter().enumerate().take(modes) {
                let r = residual2(xj, y[j], t);
                if r < best.0 || (r == best.0 && i < best.1) {
                    best = (r, i);
                }
            }
            *l = best.1;
        }
    }
}

/// HIT's reattribution of mixed points: every point whose local dataset
/// spans several modes goes to the one among them of least residual (its
/// own mode wins ties); the number of points moved.
fn reattribute(
    labels: &mut [usize],
    f: &FeatureVectors,
    x: &[f64],
    n: usize,
    y: &[f64],
    theta: &[Vec<f64>],
) -> usize {
    let before = labels.to_vec();
    let mut cand = Vec::new();
    for j in 0..labels.len() {
        let own = before[j];
        cand.clear();
        cand.push(own);
        for &m in f.members(j) {
            let l = before[m as usize];
            if !cand.contains(&l) {
                cand.push(l);
            }
        }
        if cand.len() > 1 {
            // Own mode wins ties: it is listed first and compared strictly.
            let xj = &x[j * n..(j + 1) * n];
            let mut best = (residual2(xj, y[j], &theta[own]), own);
            for &i in &cand[1..] {
                let r = residual2(xj, y[j], &theta[i]);
                if r < best.0 {
                    best = (r, i);
                }
            }
            labels[j] = best.1;
        }
    }
    labels.iter().zip(&before).filter(|(a, b)| a != b).count()
}
