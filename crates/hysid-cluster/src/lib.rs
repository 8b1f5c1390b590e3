//! # hysid-cluster
//!
//! The `cluster` back-end: the clustering procedure of Ferrari-Trecate,
//! Muselli, Liberati and Morari, "A clustering technique for the
//! identification of piecewise affine systems", *Automatica* 39(2),
//! 2003 — the method of the founding pick-and-place paper (Juloski,
//! Heemels, Ferrari-Trecate, ADHS 2003). It follows the reference
//! implementation (HIT, the Hybrid Identification Toolbox) where that
//! serves users, and deviates from it where HIT fails them (the deviations
//! are listed in `docs/cluster.md`, "HIT parity and fixes"):
//!
//! 1. local datasets: every sample and its `c - 1` nearest neighbours in
//!    (standardised, by default) regressor space, found with a k-d tree
//!    ([`knn`]);
//! 2. local least squares and feature vectors `xi_j = [theta_j; m_j]` with
//!    their confidence `R_j = blkdiag(V_j, Q_j)`; degenerate local datasets
//!    are regularised and counted instead of aborting ([`local`]);
//! 3. weighted K-means with HIT's update rule, seeded restarts, or single
//!    linkage ([`kmeans`]);
//! 4. mode datasets, the discard rule `max(c, alpha (n+1))`, weighted least
//!    squares per mode, outliers and mixed points reattributed by residual
//!    ([`procedure`]);
//! 5. regions by `hysid_estimation::regions` (MRLP by default: a complete partition).
//!
//! `hysid sweep` scores a grid of `c` and mode counts by simulation FIT on
//! selection rows.
//!
//! Priors honoured (`docs/cluster.md`, "Priors"): `modes`
//! (required unless `max_modes` is given, in which case the mode count is
//! chosen by hold-out simulation FIT) and `max_modes`, both counting the
//! saturation modes; `[[saturation]]` (samples at a stop removed before the
//! local datasets, the model a hybrid automaton with the stops as modes on
//! their guard sets, Juloski et al. 2003, section 5); `[[tie]]`, `[fixed]`,
//! `[[equality]]` and `[bounds]` in every weighted least-squares step
//! ([`priors`]);
//! `switching` (region normals restricted to the chosen regressors).

mod error;
pub mod fit;
pub mod kmeans;
pub mod knn;
pub mod local;
pub mod priors;
pub mod procedure;

pub use error::ClusterError;
pub use fit::{ClusterDiagnostics, default_c, fit};

use hysid_core::backend::{IdentifyError, Problem, RunContext};
use hysid_core::options::{CheckOptions, OptionError, check_count, check_float};
use hysid_core::priors::PriorKind;
use hysid_core::search::SearchSpace;
use hysid_core::stages::{AUTO_TRIM, Stages};
use hysid_estimation::pwarx::{PwarxData, PwarxFit, PwarxMethod};

hysid_core::option_enum! {
    /// What is clustered (HIT `what_to_clust`).
    pub enum Features {
        /// `xi_j = [theta_j; m_j]`: parameters and local mean (HIT `FVs`).
        Fv => "fv",
        /// `xi_j = theta_j`: parameters only (HIT `LPVs`).
        Lpv => "lpv",
    }
}

hysid_core::option_enum! {
    /// Clustering algorithm (HIT `clustalgo.name`).
    pub enum Clustering {
        /// Weighted K-means with restarts.
        Kmeans => "kmeans",
        /// Single linkage on Euclidean feature distances.
        SingleLinkage => "single_linkage",
    }
}

hysid_core::option_enum! {
    /// K-means initialisation.
    pub enum Init {
        /// HIT: weighted means of `s` random blocks of the feature vectors.
        Blocks => "blocks",
        /// k-means++ seeding on the weighted distance.
        Plusplus => "plusplus",
    }
}

hysid_core::option_enum! {
    /// Weights of the per-mode weighted least squares (step 4).
    pub enum Weights {
        /// `w_j / median_{k in F_i} w_k`, capped at 1: confident points count
        /// equally, points of mixed local datasets are down-weighted.
        Capped => "capped",
        /// HIT: `w_j` itself (normalised by the largest in the mode); a few
        /// very confident points can carry the whole fit.
        Confidence => "confidence",
        /// Ordinary least squares.
        Uniform => "uniform",
    }
}

hysid_core::backend_options! {
    /// Options of the `cluster` back-end.
    pub struct ClusterOptions {
        /// Local dataset size c (each sample and its c-1 nearest neighbours); at least
        /// n+2 with n the regressor dimension. none: automatic, max(4(n+1), ceil(sqrt(N)/2)) capped at N/(2s).
        c: Option<usize> = None,
        /// K-means restarts with different seeds; the run of least cost is kept (HIT: 15).
        restarts: usize = 15,
        /// Bound on K-means sweeps per restart (HIT: 100).
        max_iter: usize = 100,
        /// K-means initialisation: plusplus (k-means++ on the weighted distance) or blocks
        /// (HIT: weighted means of random blocks, nearly equal centres that can all fall
        /// into one bad optimum).
        init: Init = Init::Plusplus,
        /// Feature vectors: fv = [theta_j; m_j] (HIT default) or lpv = theta_j.
        features: Features = Features::Fv,
        /// Clustering: kmeans (weighted by the confidences) or single_linkage.
        clustering: Clustering = Clustering::Kmeans,
        /// Single linkage: merge distance threshold; none: cut into `modes` clusters.
        sl_distance: Option<f64> = None,
        /// Region estimation: mrlp (one LP, complete partition), msvm (soft-margin
        /// multicategory SVM, complete partition), psvc (pairwise proximal SVM, HIT's
        /// default, may leave holes) or softmax (multinomial logistic regression,
        /// complete partition).
        regions: hysid_estimation::regions::RegionMethod = hysid_estimation::regions::RegionMethod::Mrlp,
        /// Soft-margin weight of msvm (and penalty of mrlp misclassifications where used).
        svm_c: f64 = 1.0,
        /// Standardise inputs and output (zero mean, unit variance) before the neighbour
        /// search and everything after; false = raw distances, as HIT. Models are always
        /// returned in original units.
        scale: bool = true,
        /// Reattribute mixed points (whose local dataset spans several modes) to the
        /// best-fitting mode among those in their local dataset, then re-estimate (HIT mix_detect).
        reattribute: bool = true,
        /// Discard factor alpha: clusters with fewer than max(c, alpha (n+1)) points are
        /// dropped and their points reattributed by residual (HIT: 2). 0 keeps every non-empty cluster.
        discard: f64 = 2.0,
        /// Regularisation eps of degenerate local datasets (noise-free fits, collinear
        /// regressors, flat scatter): see docs/cluster.md. Must be > 0.
        regularization: f64 = 1e-6,
        /// After region estimation, move every sample to the mode of the region that contains
        /// it and re-estimate the parameters on these mode datasets (deviation from HIT: HIT
        /// keeps the clustering's mode datasets, whose stray points bias the parameters).
        region_refit: bool = true,
        /// Bound on the rounds of the alternation between the modes' parameters, a softmax
        /// gate and the mode of every sample that follows the clustering (docs/cluster.md,
        /// "Alternation"); 0: none (the paper's procedure, preset=paper).
        alternation: usize = AUTO_ALTERNATION,
        /// With more samples than this, steps 1 to 7 run on every ceil(N / cluster_points)-th
        /// sample, every sample then goes to the mode of its region and the parameters are
        /// re-estimated on all of them, trimmed (docs/cluster.md, "Large records"); 0: every
        /// sample (preset=paper: 1000000).
        cluster_points: usize = 100_000,
        /// Weights of the per-mode least squares: capped (w_j relative to the mode's median
        /// confidence, capped at 1), confidence (HIT: w_j) or uniform.
        weights: Weights = Weights::Confidence,
        /// Smallest relative confidence weight in the per-mode weighted least squares
        /// (weights are normalised by the largest in the mode); keeps modes well posed.
        min_weight: f64 = 1e-8,
    }
}

impl CheckOptions for ClusterOptions {
    fn check(&self) -> Result<(), OptionError> {
        if self.restarts == 0 {
            return Err(OptionError::invalid(
                "restarts",
                0,
                "need at least one K-means run",
            ));
        }
        check_count("restarts", self.restarts, 1)?;
        if self.max_iter == 0 {
            return Err(OptionError::invalid(
                "max_iter",
                0,
                "need at least one K-means sweep",
            ));
        }
        check_float(
            "discard",
            self.discard,
            |d| d >= 0.0,
            "must be a finite number >= 0",
        )?;
        check_float(
            "regularization",
            self.regularization,
            |e| e > 0.0,
            "must be a finite number > 0",
        )?;
        check_float(
            "min_weight",
            self.min_weight,
            |w| w > 0.0 && w <= 1.0,
            "must be in (0, 1]",
        )?;
        check_float(
            "svm_c",
            self.svm_c,
            |c| c > 0.0,
            "must be a finite number > 0",
        )?;
        if let Some(t) = self.sl_distance {
            check_float(
                "sl_distance",
                t,
                |t| t >= 0.0,
                "must be a finite number >= 0",
            )?;
        }
        Ok(())
    }
}

/// The `cluster` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Cluster;

/// Local dataset sizes automatic selection draws from (the paper's
/// section 4 finds `c` decisive for the mounting head). The small values
/// serve short records: HIT's examples of 60-100 rows use `c` = 6 or 8.
pub const C_GRID: [usize; 10] = [4, 6, 8, 10, 14, 20, 40, 80, 160, 320];
/// Most values of [`C_GRID`] one search tries: the largest that fit.
pub const C_VALUES: usize = 5;

/// The local dataset sizes automatic selection tries on `rows` regression
/// rows of regressor dimension `n`: the [`C_VALUES`] largest values of
/// [`C_GRID`] from `n + 2` to an eighth of the rows (a mode of a
/// five-mode partition then still holds more than one local dataset), and,
/// when fewer fit, the automatic rule (`None`) before them.
pub fn c_candidates(n: usize, rows: usize) -> Vec<Option<usize>> {
    let fitting: Vec<usize> = C_GRID
        .into_iter()
        .filter(|&c| c >= n + 2 && 8 * c <= rows)
        .collect();
    let largest = &fitting[fitting.len().saturating_sub(C_VALUES)..];
    let automatic = (largest.len() < C_VALUES).then_some(None);
    automatic
        .into_iter()
        .chain(largest.iter().map(|&c| Some(c)))
        .collect()
}

/// The alternation's round bound in every candidate of automatic selection
/// (`docs/cluster.md`, step 6b).
pub use hysid_estimation::regions::AUTO_ROUNDS as AUTO_ALTERNATION;
/// Most modes automatic selection tries when the priors give no bound.
pub const DEFAULT_MAX_MODES: usize = 5;

impl PwarxMethod for Cluster {
    type Options = ClusterOptions;
    type Diagnostics = ClusterDiagnostics;
    const NAME: &'static str = "cluster";
    const SUMMARY: &'static str = "Ferrari-Trecate clustering procedure (local LS, weighted K-means, WLS, MRLP regions): HIT, fixed";
    const HONOURS: &'static [PriorKind] = PriorKind::ALL;
    const PAPER: &'static [(&'static str, &'static str)] =
        &[("alternation", "0"), ("cluster_points", "1000000")];
    const SEARCH: &'static str = "c: the five largest of 4, 6, 8, 10, 14, 20, 40, 80, 160, 320 from n+2 to an eighth of the rows (and c = none, the automatic rule, when fewer fit), and the mode count from 1 (the affine model) to max_modes (5 unless the priors say) when the priors fix none; every candidate with alternation = 50 and trim = 3";

    /// The local dataset sizes of [`c_candidates`] times the ordinary mode
    /// counts `1..=max_modes` (the known stops added, as the
    /// prior `modes` counts them).
    fn search_space(&self, problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError> {
        let priors = problem.priors;
        let rows = problem.data.len().saturating_sub(problem.orders.lag());
        let c = c_candidates(problem.orders.dim(), rows)
            .into_iter()
            .map(|c| c.map_or_else(|| "none".to_string(), |c| c.to_string()));
        Ok(SearchSpace::default()
            .with("c", c)
            .with("alternation", [AUTO_ALTERNATION])
            .with(Stages::TRIM, [AUTO_TRIM])
            .with_mode_counts(priors, DEFAULT_MAX_MODES))
    }

    fn fit(
        &self,
        data: &PwarxData<'_>,
        options: &ClusterOptions,
        ctx: &RunContext<'_>,
    ) -> Result<PwarxFit<ClusterDiagnostics>, IdentifyError> {
        let modes = data.exact_modes(Self::NAME)? + data.stops();
        fit(options, data, modes, ctx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_records_try_the_large_grid_and_short_ones_add_the_automatic_rule() {
        // The pick-and-place fit rows (na = nb = 2: n = 4).
        let long = c_candidates(4, 3998);
        assert_eq!(long, [20, 40, 80, 160, 320].map(Some));
        // A record of 80 rows (HIT's 1-D example, n = 1): the small values.
        assert_eq!(
            c_candidates(1, 80),
            [None, Some(4), Some(6), Some(8), Some(10)]
        );
        // Too short for any grid value: the automatic rule alone.
        assert_eq!(c_candidates(4, 40), [None]);
        for (n, rows) in [(1, 56), (2, 48), (4, 800), (6, 10_000)] {
            for c in c_candidates(n, rows).into_iter().flatten() {
                assert!(
                    c >= n + 2 && 8 * c <= rows,
                    "c = {c} for n = {n}, {rows} rows"
                );
            }
        }
    }
}
