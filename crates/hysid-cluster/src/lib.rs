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
//! 5. regions by `hysid-regions` (MRLP by default: a complete partition).
//!
//! [`sweep()`] scores a grid of `c` and mode counts by validation simulation
//! FIT.
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

pub mod dense;
pub mod kmeans;
pub mod knn;
pub mod local;
pub mod priors;
pub mod procedure;
pub mod sweep;

pub use sweep::{SweepPoint, sweep};

use hysid_core::backend::{Identifier, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::{CheckOptions, Checked, OptionError};
use hysid_core::priors::PriorKind;
use hysid_model::data::Standardization;
use hysid_model::geometry::Polyhedron;
use hysid_model::model::{HybridAutomaton, ModelInfo, PwarxMode, PwarxModel};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

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
        /// multicategory SVM, complete partition) or psvc (pairwise proximal SVM, HIT's
        /// default, may leave holes).
        regions: hysid_regions::RegionMethod = hysid_regions::RegionMethod::Mrlp,
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
        Ok(())
    }
}

/// The `cluster` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Cluster;

impl Identifier for Cluster {
    type Options = ClusterOptions;
    const NAME: &'static str = "cluster";
    const SUMMARY: &'static str = "Ferrari-Trecate clustering procedure (local LS, weighted K-means, WLS, MRLP regions): HIT, fixed";
    const HONOURS: &'static [PriorKind] = PriorKind::ALL;

    fn identify(
        &self,
        problem: &Problem<'_>,
        options: &Checked<ClusterOptions>,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        let priors = problem.priors;
        match (priors.modes, priors.max_modes) {
            (Some(s), _) => identify_with(problem, options, s, ctx.seed, ctx.deadline),
            (None, Some(max)) => choose_modes(problem, options, max, ctx),
            (None, None) => Err(IdentifyError::BadData(
                "method 'cluster' needs the number of modes: give the prior `modes = S` (or `max_modes = S` \
                 to choose it by hold-out simulation FIT)"
                    .into(),
            )),
        }
    }
}

/// The default `c`: `max(4(n+1), ceil(sqrt(N)/2))`, capped at `N/(2s)`, at
/// least `n+2` (`n` regressors, `big_n` samples, `s` modes). It grows with N
/// so that the local scatter does not dominate the K-means distance
/// (`docs/cluster.md`).
pub fn default_c(n: usize, big_n: usize, s: usize) -> usize {
    let want = (4 * (n + 1)).max(((big_n as f64).sqrt() / 2.0).ceil() as usize);
    want.min(big_n / s.max(1).saturating_mul(2)).max(n + 2)
}

fn bad(msg: String) -> IdentifyError {
    IdentifyError::BadData(msg)
}

fn check_options(o: &ClusterOptions) -> Result<(), IdentifyError> {
    if o.restarts == 0 {
        return Err(bad("--set restarts=0: need at least one K-means run".into()));
    }
    if o.max_iter == 0 {
        return Err(bad(
            "--set max_iter=0: need at least one K-means sweep".into()
        ));
    }
    if !(o.discard.is_finite() && o.discard >= 0.0) {
        return Err(bad(format!(
            "--set discard={}: must be a finite number >= 0",
            o.discard
        )));
    }
    if !(o.regularization.is_finite() && o.regularization > 0.0) {
        return Err(bad(format!(
            "--set regularization={}: must be a finite number > 0",
            o.regularization
        )));
    }
    if !(o.min_weight.is_finite() && o.min_weight > 0.0 && o.min_weight <= 1.0) {
        return Err(bad(format!(
            "--set min_weight={}: must be in (0, 1]",
            o.min_weight
        )));
    }
    if !(o.svm_c.is_finite() && o.svm_c > 0.0) {
        return Err(bad(format!(
            "--set svm_c={}: must be a finite number > 0",
            o.svm_c
        )));
    }
    if let Some(t) = o.sl_distance
        && !(t.is_finite() && t >= 0.0)
    {
        return Err(bad(format!(
            "--set sl_distance={t}: must be a finite number >= 0"
        )));
    }
    Ok(())
}

/// Identifies a model with `s` modes (the whole procedure), in original
/// units: a PWARX model, or, with `[[saturation]]` priors, the hybrid
/// automaton of `HybridAutomaton::from_pwarx_with_stops` whose `s - stops`
/// ordinary modes are identified here (`s` counts every mode, as the prior
/// `modes` does). No K-means restart starts after `deadline` (the model
/// then records the restarts run in `status`).
pub fn identify_with(
    problem: &Problem<'_>,
    o: &ClusterOptions,
    s: usize,
    seed: u64,
    deadline: Option<std::time::Instant>,
) -> Result<Model, IdentifyError> {
    identify_labelled(problem, o, s, seed, deadline).map(|l| l.model)
}

/// What [`identify_labelled`] returns: the model and the mode every
/// regression row of the record was assigned to.
#[derive(Debug, Clone)]
pub struct Labelled {
    /// The identified model, as [`identify_with`] returns it.
    pub model: Model,
    /// Mode of every regression row: ordinary modes `0..k`, then the known
    /// stops in prior order (`k + stop`), where `k` is the number of
    /// ordinary modes. Ordinary rows carry the mode of the final
    /// weighted least squares (the region of the row after the region
    /// refit, when `region_refit` is on).
    pub row_labels: Vec<usize>,
}

/// [`identify_with`], also returning the mode of every regression row.
pub fn identify_labelled(
    problem: &Problem<'_>,
    o: &ClusterOptions,
    s: usize,
    seed: u64,
    deadline: Option<std::time::Instant>,
) -> Result<Labelled, IdentifyError> {
    check_options(o)?;
    if s == 0 {
        return Err(bad("the number of modes must be at least 1".into()));
    }
    let priors = problem.priors;
    let stops = priors.saturation.len();
    if s <= stops {
        return Err(bad(format!(
            "{s} mode(s) requested, but the mode count includes the {stops} saturation mode(s) of the priors: \
             need at least {} for one ordinary mode",
            stops + 1
        )));
    }
    let s_all = s;
    let s = s - stops;
    let spec = problem.orders;
    let n = spec.dim();
    if n == 0 {
        return Err(bad(
            "method 'cluster' needs at least one regressor (na + nb > 0)".into(),
        ));
    }
    if n > local::MAX_DIM {
        return Err(bad(format!(
            "method 'cluster' supports regressors of dimension up to {}, got {n}",
            local::MAX_DIM
        )));
    }
    priors.check_pwarx_names(&spec).map_err(|e| {
        bad(match problem.priors_origin {
            Some(o) => format!("{o}: {e}"),
            None => e,
        })
    })?;
    let scale = if o.scale {
        Standardization::of(problem.data)
    } else {
        Standardization::identity(problem.data.inputs.len())
    };
    let work = scale.apply(problem.data);
    let reg = spec.build(&work).map_err(|e| bad(e.to_string()))?;
    let all_n = reg.len();
    if let Some(v) = reg.x.iter().chain(reg.y.iter()).find(|v| !v.is_finite()) {
        return Err(bad(format!("the data hold a non-finite value ({v})")));
    }
    let constrained = priors::constrains_parameters(priors);
    // Original-unit regressors: saturation is detected on the targets in
    // data units, and the constrained least squares run in data units.
    let reg_orig = if stops > 0 || constrained {
        Some(spec.build(problem.data).map_err(|e| bad(e.to_string()))?)
    } else {
        None
    };
    // Samples at a known stop (target y(k) at the level) belong to the
    // saturation modes: they are removed before the local datasets are
    // built (Juloski et al. 2003, section 5; docs/cluster.md "Priors").
    let stop_of: Vec<Option<usize>> = match &reg_orig {
        Some(r) if stops > 0 => priors.saturated_samples(r.y.as_slice()),
        _ => vec![None; all_n],
    };
    let keep: Vec<usize> = (0..all_n).filter(|&r| stop_of[r].is_none()).collect();
    let mut saturated = vec![0usize; stops];
    for k in stop_of.iter().flatten() {
        saturated[*k] += 1;
    }
    let big_n = keep.len();
    if big_n == 0 {
        return Err(bad(format!(
            "all {all_n} samples sit at a known stop: no ordinary sample is left to identify"
        )));
    }
    let c = o.c.unwrap_or_else(|| default_c(n, big_n, s));
    if c < n + 2 {
        return Err(bad(format!(
            "--set c={c}: the local dataset size must be at least n+2 = {} (n = {n} regressors): the local \
             noise variance is divided by c-n-1",
            n + 2
        )));
    }
    if c > big_n && o.c.is_none() {
        return Err(bad(format!(
            "{big_n} samples (regressors) are too few: method 'cluster' needs local datasets of at \
             least n+2 = {} samples (n = {n} parameters besides the constant; automatic c = {c})",
            n + 2
        )));
    }
    if c > big_n {
        return Err(bad(format!(
            "--set c={c}: larger than the {big_n} regressors of the data{}",
            if stops > 0 { " outside the stops" } else { "" }
        )));
    }
    if s.checked_mul(n + 1).is_none_or(|need| big_n < need) {
        return Err(bad(format!(
            "{big_n} regressors cannot identify {s} modes of {} parameters",
            n + 1
        )));
    }
    // Row-major regressors of the ordinary samples.
    let mut x = Vec::with_capacity(big_n * n);
    for &r in &keep {
        for k in 0..n {
            x.push(reg.x[(r, k)]);
        }
    }
    let y: Vec<f64> = keep.iter().map(|&r| reg.y[r]).collect();
    let xs = nalgebra::DMatrix::from_row_slice(big_n, n, &x);
    let constraints = match (&reg_orig, constrained) {
        (Some(r), true) => {
            let mut xo = Vec::with_capacity(big_n * n);
            for &row in &keep {
                for k in 0..n {
                    xo.push(r.x[(row, k)]);
                }
            }
            let yo = keep.iter().map(|&row| r.y[row]).collect();
            Some(
                priors::Constraints::new(priors, spec, xo, yo, &scale, s).map_err(|e| {
                    bad(match problem.priors_origin {
                        Some(o) => format!("{o}: {e}"),
                        None => e,
                    })
                })?,
            )
        }
        _ => None,
    };
    let settings = procedure::Settings {
        c,
        modes: s,
        features: o.features,
        clustering: o.clustering,
        sl_distance: o.sl_distance,
        restarts: o.restarts,
        max_iter: o.max_iter,
        init: match o.init {
            Init::Blocks => kmeans::KmeansInit::Blocks,
            Init::Plusplus => kmeans::KmeansInit::PlusPlus,
        },
        discard: o.discard,
        reattribute: o.reattribute,
        regularization: o.regularization,
        min_weight: o.min_weight,
        weights: o.weights,
        deadline,
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let fit =
        procedure::run_with(&x, n, &y, &settings, &mut rng, constraints.as_ref()).map_err(|e| {
            IdentifyError::Failed {
                method: "cluster".into(),
                message: e.to_string(),
            }
        })?;
    let modes = fit.theta.len();
    if modes < s {
        // `modes = S` is exact (docs/priors.md): a smaller model would drop
        // the prior silently.
        return Err(IdentifyError::Failed {
            method: "cluster".into(),
            message: format!(
                "exactly {s_all} modes were asked for, but only {modes} of the {s} clusters kept at least {} \
                 points (the discard size max(c, discard (n+1)), c = {c}): lower c, set discard=0, or give \
                 max_modes = {s_all} to allow fewer modes",
                fit.diagnostics.discard_size
            ),
        });
    }
    if modes > s {
        // Only a single-linkage distance threshold fixes the cluster count
        // independently of `modes`; more modes than asked would break the
        // prior as well.
        return Err(IdentifyError::Failed {
            method: "cluster".into(),
            message: format!(
                "exactly {s_all} modes were asked for, but {modes} clusters of at least {} points are \
                 left (single linkage with sl_distance = {}): raise sl_distance, or leave it unset to \
                 cut the tree into {s} clusters",
                fit.diagnostics.discard_size,
                o.sl_distance.map_or("none".into(), |t| t.to_string())
            ),
        });
    }
    let mut theta = fit.theta.clone();
    let mut theta_original = fit.theta_original.clone();
    let mut labels = fit.labels.clone();
    let mut region_moved = 0;
    let mut holes = None;
    let (regions, accuracy, complete) = if modes == 1 {
        (vec![Polyhedron::everything()], 1.0, true)
    } else {
        let ropts = hysid_regions::RegionOptions {
            method: o.regions,
            svm_c: o.svm_c,
            switching: priors::switching_columns(priors, &spec),
            standardize: !o.scale,
        };
        let part = hysid_regions::estimate(&xs, &fit.labels, modes, &ropts).map_err(|e| {
            IdentifyError::Failed {
                method: "cluster".into(),
                message: format!("region estimation: {e}"),
            }
        })?;
        if o.region_refit {
            // Mode datasets made consistent with the partition, then the
            // parameters re-estimated on them.
            for (j, l) in labels.iter_mut().enumerate() {
                let xj = &x[j * n..(j + 1) * n];
                let r = part
                    .regions
                    .iter()
                    .position(|p| p.contains(xj))
                    .unwrap_or_else(|| {
                        (0..modes)
                            .min_by(|&a, &b| {
                                part.regions[a]
                                    .violation(xj)
                                    .total_cmp(&part.regions[b].violation(xj))
                            })
                            .unwrap_or(*l)
                    });
                if r != *l {
                    region_moved += 1;
                    *l = r;
                }
            }
            let sizes = (0..modes).map(|i| labels.iter().filter(|&&l| l == i).count());
            if sizes.clone().all(|k| k > n) {
                let fitted = procedure::fit_modes_with(
                    &x,
                    n,
                    &y,
                    &fit.features,
                    &labels,
                    modes,
                    o.min_weight,
                    o.weights,
                    constraints.as_ref(),
                )
                .map_err(|e| IdentifyError::Failed {
                    method: "cluster".into(),
                    message: e.to_string(),
                })?;
                theta = fitted.working;
                theta_original = fitted.original;
            }
        }
        if !part.complete {
            // Holes report (pairwise PSVC): uncovered fraction of the data's bounding box.
            let lo: Vec<f64> = (0..n).map(|k| xs.column(k).min()).collect();
            let hi: Vec<f64> = (0..n).map(|k| xs.column(k).max()).collect();
            let rep = hysid_regions::coverage(&part.regions, &lo, &hi, 10_000, seed);
            holes = Some(rep.uncovered_fraction);
        }
        (part.regions, part.training_accuracy, part.complete)
    };
    let d = &fit.diagnostics;
    let mut info = ModelInfo::default();
    let mut put = |k: &str, v: serde_json::Value| {
        info.diagnostics.method.insert(k.into(), v);
    };
    put("samples", all_n.into());
    put("c", c.into());
    put("modes_requested", s_all.into());
    put("modes", (modes + stops).into());
    if stops > 0 {
        put("ordinary_samples", big_n.into());
        put("saturated_samples", serde_json::json!(saturated));
    }
    put("degenerate_local_datasets", d.degenerate.total.into());
    put("degenerate_noise_free", d.degenerate.noise_free.into());
    put("degenerate_collinear", d.degenerate.collinear.into());
    put("degenerate_flat_scatter", d.degenerate.flat_scatter.into());
    put("kmeans_cost", d.kmeans_cost.into());
    put("kmeans_restart_costs", serde_json::json!(d.restart_costs));
    if o.clustering == Clustering::Kmeans && d.restart_costs.len() < o.restarts {
        put(
            "status",
            format!(
                "time budget reached after {} of {} K-means restarts: the best clustering found by then",
                d.restart_costs.len(),
                o.restarts
            )
            .into(),
        );
    }
    put("kmeans_iterations", d.kmeans_iterations.into());
    put("kmeans_converged", d.kmeans_converged.into());
    put("discard_size", d.discard_size.into());
    put("discarded_clusters", d.discarded_clusters.into());
    put("outliers", d.outliers.into());
    put("reattributed", d.reattributed.into());
    put("reattributed_fraction", d.reattributed_fraction.into());
    put("region_training_accuracy", accuracy.into());
    put("region_refit_moved", region_moved.into());
    put("regions_complete", complete.into());
    if let Some(h) = holes {
        put("uncovered_fraction_of_data_box", h.into());
    }
    let working = PwarxModel {
        na: spec.na,
        nb: spec.nb,
        inputs: spec.inputs,
        modes: theta
            .into_iter()
            .zip(regions)
            .map(|(theta, region)| PwarxMode {
                theta,
                region,
                name: None,
            })
            .collect(),
        info,
    };
    let mut model = if o.scale {
        working.to_original_units(&scale)
    } else {
        working
    };
    // Under ties, fixed values and bounds the original-unit estimates are
    // the ones where the priors hold exactly (no round trip through the
    // working units).
    if let Some(th) = theta_original {
        for (mode, t) in model.modes.iter_mut().zip(th) {
            mode.theta = t;
        }
    }
    let mut row_labels: Vec<usize> = stop_of.iter().map(|k| k.map_or(0, |k| modes + k)).collect();
    for (&row, &l) in keep.iter().zip(&labels) {
        row_labels[row] = l;
    }
    let model = if stops > 0 {
        Model::HybridAutomaton(HybridAutomaton::from_pwarx_with_stops(
            &model,
            &priors.saturation,
        ))
    } else {
        Model::Pwarx(model)
    };
    Ok(Labelled { model, row_labels })
}

/// `max_modes` without `modes`: every mode count `1..=max` is identified
/// on the first 75 % of the record and scored by free-run simulation FIT on
/// the last 25 %; the best count (ties: fewer modes) is re-identified on
/// the whole record.
fn choose_modes(
    problem: &Problem<'_>,
    o: &ClusterOptions,
    max: usize,
    ctx: &RunContext<'_>,
) -> Result<Model, IdentifyError> {
    let len = problem.data.len();
    let cut = len * 3 / 4;
    let ident = problem
        .data
        .slice(hysid_model::data::RowRange {
            start: None,
            end: Some(cut),
        })
        .map_err(|e| bad(e.to_string()))?;
    let valid = problem
        .data
        .slice(hysid_model::data::RowRange {
            start: Some(cut),
            end: None,
        })
        .map_err(|e| bad(e.to_string()))?;
    let sub = Problem {
        data: &ident,
        ..*problem
    };
    let first = problem.priors.saturation.len() + 1;
    let points = sweep::sweep(
        &sub,
        &valid,
        0,
        &[],
        &(first..=max).collect::<Vec<_>>(),
        o,
        ctx,
    );
    let best = points
        .iter()
        .filter(|p| p.fit_sim.is_some_and(f64::is_finite))
        .fold(None::<&SweepPoint>, |b, p| match b {
            Some(q) if q.fit_sim >= p.fit_sim => Some(q),
            _ => Some(p),
        })
        .ok_or_else(|| IdentifyError::Failed {
            method: "cluster".into(),
            message: format!(
                "no mode count in 1..={max} could be identified and simulated on the hold-out part"
            ),
        })?;
    let mut model = identify_with(problem, o, best.modes, ctx.seed, ctx.deadline)?;
    model.info_mut().diagnostics.method.insert(
        "mode_choice".into(),
        serde_json::json!(
            points
                .iter()
                .map(|p| (p.modes, p.fit_sim))
                .collect::<Vec<_>>()
        ),
    );
    Ok(model)
}
