//! The clustering procedure of Ferrari-Trecate, Muselli, Liberati and
//! Morari (Automatica 39(2), 2003, section 3) on the data of
//! `pwarx::prepare`, one named function per step. The step numbers are
//! those of `docs/cluster.md`:
//!
//! - `working_data`: the ordinary samples in working units (standardised
//!   by default), where distances between regressors are compared;
//! - `clustering_sample`: above `cluster_points` samples, the every-k-th
//!   sample the steps up to the region refit see;
//! - `choose_c`: the size `c` of the local datasets;
//! - `prior_fit`: the gray-box priors of the weighted least squares, in
//!   data units (`ConstrainedFit`);
//! - `cluster_features`: steps 1 to 6, local datasets, local regressions
//!   and feature vectors, clustering, mode datasets and discard, weighted
//!   least squares, reattribution (`procedure::run_with`);
//! - `alternate_partition`: the alternation of
//!   `hysid_estimation::regions::alternate` from the clustering's mode datasets
//!   (`alternation` bounds its rounds; 0: none);
//! - `estimate_regions`: step 7, the regions of the modes
//!   (`hysid_estimation::regions`);
//! - `refit_on_regions`: step 7 continued, the mode datasets made
//!   consistent with the regions and the parameters re-estimated;
//! - `extend_to_all`: after a run on a clustering sample, every sample to
//!   the mode of its region, and the parameters refitted on all of them;
//!   `trimmed_on_all` then leaves out the mixed points;
//! - `holes`: the part of the data box no region covers;
//! - `modes_in_data_units`: step 8, the modes mapped back to data units.

use crate::priors::ConstrainedFit;
use crate::procedure::{self, ModeFit};
use crate::{ClusterError, ClusterOptions, Clustering, Init, Weights, kmeans, local};
use hysid_core::backend::{Deadline, IdentifyError, RunContext};
use hysid_core::options::OptionError;
use hysid_core::stages::AUTO_TRIM;
use hysid_estimation::pwarx::trim::trim;
use hysid_estimation::pwarx::{PwarxData, PwarxFit};
pub use hysid_estimation::regions::AlternationReport;
use hysid_estimation::regions::{AlternationSettings, RegionFailure};
use hysid_model::data::Standardization;
use hysid_model::geometry::Polyhedron;
use hysid_model::model::{ModelInfo, PwarxMode, PwarxModel, RunStatus, region_of};
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// What the `cluster` back-end reports besides the common diagnostics
/// (`docs/cluster.md`, "Diagnostics").
#[derive(Debug, Clone, Serialize)]
pub struct ClusterDiagnostics {
    /// Local dataset size used.
    pub c: usize,
    /// Modes asked for, the saturation modes included.
    pub modes_requested: usize,
    /// With more ordinary samples than `cluster_points`: the samples the
    /// clustering saw.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub clustering_sample: Option<usize>,
    /// With known stops: the samples at no stop, which the procedure saw.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ordinary_samples: Option<usize>,
    /// Regularised local datasets (any of the three causes below).
    pub degenerate_local_datasets: usize,
    /// Local fits with (numerically) zero residual.
    pub degenerate_noise_free: usize,
    /// Local datasets with collinear regressors.
    pub degenerate_collinear: usize,
    /// Local datasets with a singular regressor scatter.
    pub degenerate_flat_scatter: usize,
    /// K-means cost of the kept restart.
    pub kmeans_cost: f64,
    /// K-means cost of every restart run.
    pub kmeans_restart_costs: Vec<f64>,
    /// Sweeps of the kept restart.
    pub kmeans_iterations: usize,
    /// Whether the kept restart met the stopping rule.
    pub kmeans_converged: bool,
    /// Minimum cluster size `max(c, discard (n+1))`.
    pub discard_size: usize,
    /// Clusters discarded (first and second check).
    pub discarded_clusters: usize,
    /// Points of discarded clusters, reattributed by residual.
    pub outliers: usize,
    /// Points moved by the mixed-point reattribution.
    pub reattributed: usize,
    /// `reattributed / N`.
    pub reattributed_fraction: f64,
    /// Fraction of the samples whose region is their mode.
    pub region_training_accuracy: f64,
    /// Samples moved to the mode of their region by the region refit.
    pub region_refit_moved: usize,
    /// The alternation after the clustering, when `alternation > 0`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub alternation: Option<AlternationReport>,
    /// Mode of every ordinary sample (`data.ordinary` order), after the
    /// region refit; not written to the model file.
    #[serde(skip)]
    pub labels: Vec<usize>,
}

/// The procedure on `data` with `s` modes in all (the known stops
/// included, as the prior `modes` counts them), seeded by `ctx.seed`. No
/// K-means restart and no region round starts after `ctx.deadline`; the
/// run then reports `RunStatus::TimeBudget`. Its three steps (clustering,
/// regions, region refit) advance `ctx.progress`. With more than
/// `cluster_points` samples the steps before the region refit see the
/// clustering sample (`clustering_sample`), and the parameters are those of
/// the trimmed re-estimation on every sample (`trimmed_on_all`).
pub fn fit(
    o: &ClusterOptions,
    data: &PwarxData<'_>,
    s: usize,
    ctx: &RunContext<'_>,
) -> Result<PwarxFit<ClusterDiagnostics>, IdentifyError> {
    let (seed, deadline) = (ctx.seed, &ctx.deadline);
    let modes = ordinary_modes(data, s)?;
    let work = working_data(o, data)?;
    let sample = clustering_sample(o, &work);
    let seen = sample.as_ref().unwrap_or(&work);
    let c = choose_c(o, data, seen, work.y.len(), modes)?;
    check_sample_count(&work, modes)?;
    if sample.is_some()
        && let Err(IdentifyError::TooFewRegressors {
            rows,
            modes,
            params,
        }) = check_sample_count(seen, modes)
    {
        let need = format!("{modes} modes of {params} parameters");
        return Err(sample_too_small(o, rows, need));
    }
    let prior_fit = prior_fit(data, seen, modes)?;
    ctx.progress.start(3, "cluster: clustering, regions, refit");
    let mut clustered = cluster_features(o, seen, c, modes, seed, deadline, prior_fit.as_ref())?;
    check_modes_found(o, &clustered, s, modes, c)?;
    let alternation =
        alternate_partition(o, data, seen, &mut clustered, prior_fit.as_ref(), deadline)?;
    ctx.progress.advance(1);
    let regions = estimate_regions(o, data, seen, &clustered, deadline)?;
    ctx.progress.advance(1);
    let region_refit_moved = if o.region_refit && modes > 1 {
        refit_on_regions(
            o,
            seen,
            &mut clustered,
            &regions.polyhedra,
            prior_fit.as_ref(),
            o.weights,
        )?
    } else {
        0
    };
    if sample.is_some() {
        extend_to_all(o, data, &work, &mut clustered, &regions.polyhedra, modes)?;
    }
    ctx.progress.advance(1);
    ctx.progress.finish();
    let uncovered_fraction = (!regions.complete).then(|| holes(&work, &regions.polyhedra, seed));
    let status = time_budget_status(o, &clustered, &regions);
    let d = &clustered.diagnostics;
    let diagnostics = ClusterDiagnostics {
        c,
        modes_requested: s,
        clustering_sample: sample.as_ref().map(|w| w.y.len()),
        ordinary_samples: (data.stops() > 0).then_some(work.y.len()),
        degenerate_local_datasets: d.degenerate.total,
        degenerate_noise_free: d.degenerate.noise_free,
        degenerate_collinear: d.degenerate.collinear,
        degenerate_flat_scatter: d.degenerate.flat_scatter,
        kmeans_cost: d.kmeans_cost,
        kmeans_restart_costs: d.restart_costs.clone(),
        kmeans_iterations: d.kmeans_iterations,
        kmeans_converged: d.kmeans_converged,
        discard_size: d.discard_size,
        discarded_clusters: d.discarded_clusters,
        outliers: d.outliers,
        reattributed: d.reattributed,
        reattributed_fraction: d.reattributed_fraction,
        region_training_accuracy: regions.training_accuracy,
        region_refit_moved,
        alternation,
        labels: std::mem::take(&mut clustered.labels),
    };
    let fit = PwarxFit {
        modes: modes_in_data_units(o, data, &work, clustered, regions.polyhedra),
        regions_complete: regions.complete,
        uncovered_fraction,
        run_status: if status.is_empty() {
            RunStatus::Completed
        } else {
            RunStatus::TimeBudget
        },
        status,
        scaling: o.scale.then(|| work.scale.clone()),
        refinement: None,
        trimming: None,
        diagnostics,
    };
    match sample {
        Some(_) => trimmed_on_all(data, fit),
        None => Ok(fit),
    }
}

/// The cutoff, in robust standard deviations, of the trimmed
/// re-estimation that ends a run on a clustering sample: that of the
/// trimmed re-estimation under `--auto`.
pub const SAMPLE_TRIM: f64 = AUTO_TRIM;

/// After a run on a clustering sample: every mode estimated again on the
/// samples its region holds, leaving out those whose residual exceeds
/// [`SAMPLE_TRIM`] robust standard deviations ([`trim`], recorded in the
/// model's `trimming`). The samples outside the clustering sample have no
/// confidence weight (step 2), which is what keeps the mixed points near a
/// boundary from pulling the clustered run's estimates; without it,
/// ordinary least squares on every sample is pulled by them.
fn trimmed_on_all(
    data: &PwarxData<'_>,
    fit: PwarxFit<ClusterDiagnostics>,
) -> Result<PwarxFit<ClusterDiagnostics>, IdentifyError> {
    trim(data, fit, Some(SAMPLE_TRIM))
}

/// The default `c`: `max(4(n+1), ceil(sqrt(N)/2))`, capped at `N/(2s)`, at
/// least `n+2` (`n` regressors, `big_n` samples, `s` modes). It grows with N
/// so that the local scatter does not dominate the K-means distance
/// (`docs/cluster.md`).
pub fn default_c(n: usize, big_n: usize, s: usize) -> usize {
    let want = (4 * (n + 1)).max(((big_n as f64).sqrt() / 2.0).ceil() as usize);
    want.min(big_n / s.max(1).saturating_mul(2)).max(n + 2)
}

/// The ordinary modes among `s`: the count includes the known stops, and
/// leaves at least one ordinary mode.
fn ordinary_modes(data: &PwarxData<'_>, s: usize) -> Result<usize, IdentifyError> {
    let stops = data.stops();
    if s == 0 {
        return Err(ClusterError::NoMode.into());
    }
    if s <= stops {
        return Err(ClusterError::NoOrdinaryMode { modes: s, stops }.into());
    }
    Ok(s - stops)
}

/// The ordinary samples in working units.
struct Working {
    /// Positions in `data.ordinary` of these samples (all of them, or the
    /// clustering sample of [`clustering_sample`]).
    rows: Vec<usize>,
    /// Data units to working units (the identity with `scale = false`).
    scale: Standardization,
    /// Regressor dimension `n`.
    n: usize,
    /// Regressors of the ordinary samples, row-major.
    x: Vec<f64>,
    /// The same as a matrix, one row per sample.
    xs: DMatrix<f64>,
    /// Targets of the ordinary samples.
    y: Vec<f64>,
}

/// The ordinary samples in working units: every signal standardised (zero
/// mean, unit standard deviation) with `scale = true`, so that the
/// neighbour search and the clustering distances weigh the regressors
/// alike; as given otherwise (HIT).
fn working_data(o: &ClusterOptions, data: &PwarxData<'_>) -> Result<Working, IdentifyError> {
    let n = data.spec.dim();
    if n == 0 {
        return Err(ClusterError::NoRegressor.into());
    }
    if n > local::MAX_DIM {
        return Err(ClusterError::Dimension {
            dim: n,
            max: local::MAX_DIM,
        }
        .into());
    }
    let record = data.problem.data;
    let scale = if o.scale {
        Standardization::of(record)
    } else {
        Standardization::identity(record.inputs.len())
    };
    let reg = data.spec.build(&scale.apply(record))?;
    if let Some(&value) = reg.x.iter().chain(reg.y.iter()).find(|v| !v.is_finite()) {
        return Err(IdentifyError::NonFinite { value });
    }
    let x: Vec<f64> = data
        .ordinary
        .iter()
        .flat_map(|&r| (0..n).map(move |k| (r, k)))
        .map(|(r, k)| reg.x[(r, k)])
        .collect();
    let y: Vec<f64> = data.ordinary.iter().map(|&r| reg.y[r]).collect();
    Ok(Working {
        rows: (0..y.len()).collect(),
        scale,
        n,
        xs: DMatrix::from_row_slice(y.len(), n, &x),
        x,
        y,
    })
}

/// With more than `cluster_points` ordinary samples, every
/// `ceil(N / cluster_points)`-th: the samples steps 1 to 7 see. The default
/// `c` grows like `sqrt(N)`, so the local datasets cost `O(N^1.5)`; on a
/// sample their cost is bounded, and every sample is given its mode by the
/// regions afterwards ([`extend_to_all`]). `None` with fewer samples.
fn clustering_sample(o: &ClusterOptions, work: &Working) -> Option<Working> {
    let (big_n, n) = (work.y.len(), work.n);
    let max = o.cluster_points;
    if max == 0 || big_n <= max {
        return None;
    }
    let rows: Vec<usize> = (0..big_n).step_by(big_n.div_ceil(max)).collect();
    let x: Vec<f64> = rows
        .iter()
        .flat_map(|&j| work.x[j * n..(j + 1) * n].iter().copied())
        .collect();
    Some(Working {
        scale: work.scale.clone(),
        n,
        xs: DMatrix::from_row_slice(rows.len(), n, &x),
        x,
        y: rows.iter().map(|&j| work.y[j]).collect(),
        rows,
    })
}

/// Every sample of `work` to the mode of its region, and the parameters
/// re-estimated by ordinary least squares (under the priors) on these mode
/// datasets: the end of a run on a clustering sample, whose confidences
/// exist only for the sample.
fn extend_to_all(
    o: &ClusterOptions,
    data: &PwarxData<'_>,
    work: &Working,
    fit: &mut ModeFit,
    regions: &[Polyhedron],
    modes: usize,
) -> Result<(), IdentifyError> {
    let prior_fit = prior_fit(data, work, modes)?;
    fit.labels = vec![0; work.y.len()];
    refit_on_regions(o, work, fit, regions, prior_fit.as_ref(), Weights::Uniform)?;
    Ok(())
}

/// The local dataset size: the option, or [`default_c`] on the samples
/// `work` (the clustering sample, or every ordinary sample); between `n+2`
/// (the local noise variance is divided by `c-n-1`) and the `whole`
/// number of ordinary samples. A clustering sample smaller than the local
/// datasets that every sample would hold is `cluster_points`' fault.
fn choose_c(
    o: &ClusterOptions,
    data: &PwarxData<'_>,
    work: &Working,
    whole: usize,
    modes: usize,
) -> Result<usize, IdentifyError> {
    let (n, big_n) = (work.n, work.y.len());
    let c = o.c.unwrap_or_else(|| default_c(n, big_n, modes));
    if c < n + 2 {
        return Err(OptionError::invalid(
            "c",
            c,
            format!(
                "the local dataset size must be at least n+2 = {} (n = {n} regressors): the local \
                 noise variance is divided by c-n-1",
                n + 2
            ),
        )
        .into());
    }
    if c > whole && o.c.is_none() {
        return Err(ClusterError::TooFewForLocalDatasets {
            samples: whole,
            n,
            c,
        }
        .into());
    }
    if c > whole {
        let outside = if data.stops() > 0 {
            " outside the stops"
        } else {
            ""
        };
        return Err(OptionError::invalid(
            "c",
            c,
            format!("larger than the {whole} regressors of the data{outside}"),
        )
        .into());
    }
    if c > big_n {
        return Err(sample_too_small(
            o,
            big_n,
            format!("local datasets of c = {c} samples"),
        ));
    }
    Ok(c)
}

/// A clustering sample of `samples` samples too small for `what`:
/// `cluster_points`' fault.
fn sample_too_small(o: &ClusterOptions, samples: usize, what: String) -> IdentifyError {
    OptionError::invalid(
        "cluster_points",
        o.cluster_points,
        format!(
            "its clustering sample of {samples} samples is too small for {what}; raise it, or 0 \
             clusters every sample"
        ),
    )
    .into()
}

/// At least `n+1` samples per mode.
fn check_sample_count(work: &Working, modes: usize) -> Result<(), IdentifyError> {
    let (n, big_n) = (work.n, work.y.len());
    if u32::try_from(big_n).is_err() {
        return Err(ClusterError::TooManySamples { samples: big_n }.into());
    }
    if modes.checked_mul(n + 1).is_none_or(|need| big_n < need) {
        return Err(IdentifyError::TooFewRegressors {
            rows: big_n,
            modes,
            params: n + 1,
        });
    }
    Ok(())
}

/// With `[[tie]]`, `[fixed]`, `[[equality]]` or `[bounds]`: the ordinary
/// samples in data units, where every weighted least squares of the
/// procedure is solved under the priors ([`ConstrainedFit`]).
fn prior_fit(
    data: &PwarxData<'_>,
    work: &Working,
    modes: usize,
) -> Result<Option<ConstrainedFit>, IdentifyError> {
    if !data.constrains_parameters() {
        return Ok(None);
    }
    let priors = data.priors();
    let (n, reg) = (work.n, &data.regressors);
    let rows = work.rows.iter().map(|&j| data.ordinary[j]);
    let x = rows
        .clone()
        .flat_map(|r| (0..n).map(move |k| reg.x[(r, k)]))
        .collect();
    let y = rows.map(|r| reg.y[r]).collect();
    ConstrainedFit::new(priors, data.spec, x, y, &work.scale, modes)
        .map(Some)
        .map_err(|e| data.prior_error(e))
}

/// Steps 1 to 6 (section 3 of the paper): local datasets of `c` samples,
/// local least squares and feature vectors with their confidences,
/// clustering into `modes` clusters (K-means restarts from `seed`, none
/// started after `deadline`), mode datasets and the discard rule, weighted
/// least squares per mode, reattribution of outliers and mixed points.
fn cluster_features(
    o: &ClusterOptions,
    work: &Working,
    c: usize,
    modes: usize,
    seed: u64,
    deadline: &Deadline,
    prior_fit: Option<&ConstrainedFit>,
) -> Result<ModeFit, IdentifyError> {
    let settings = procedure::Settings {
        c,
        modes,
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
        deadline: deadline.clone(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    procedure::run_with(&work.x, work.n, &work.y, &settings, &mut rng, prior_fit)
        .map_err(|e| ClusterError::Procedure(e).into())
}

/// `modes = S` is exact (`docs/priors.md`): fewer modes (clusters under the
/// discard size) or more (a single-linkage threshold) fail the run.
fn check_modes_found(
    o: &ClusterOptions,
    fit: &ModeFit,
    s: usize,
    modes: usize,
    c: usize,
) -> Result<(), IdentifyError> {
    let found = fit.theta.len();
    let discard_size = fit.diagnostics.discard_size;
    if found < modes {
        return Err(ClusterError::FewerModesFound {
            asked: s,
            found,
            clusters: modes,
            discard_size,
            c,
        }
        .into());
    }
    if found > modes {
        return Err(ClusterError::MoreModesFound {
            asked: s,
            found,
            clusters: modes,
            discard_size,
            sl_distance: o.sl_distance,
        }
        .into());
    }
    Ok(())
}

/// The alternation of [`hysid_estimation::regions::alternate`] from the clustering's
/// mode datasets, when `alternation > 0`: ordinary least squares per mode
/// under the priors, a softmax gate, every sample to its mode of least
/// cost, for at most `alternation` rounds. The mode datasets it ends with
/// replace the clustering's, and the parameters are estimated on them as
/// in step 4.
fn alternate_partition(
    o: &ClusterOptions,
    data: &PwarxData<'_>,
    work: &Working,
    fit: &mut ModeFit,
    prior_fit: Option<&ConstrainedFit>,
    deadline: &Deadline,
) -> Result<Option<AlternationReport>, IdentifyError> {
    let modes = fit.theta.len();
    if o.alternation == 0 || modes < 2 {
        return Ok(None);
    }
    let settings = AlternationSettings {
        switching: data.switching.clone(),
        deadline: deadline.clone(),
        ..AlternationSettings::new(o.alternation, work.n + 1)
    };
    let features = &fit.features;
    let least_squares = |labels: &[usize], weights: Weights| {
        procedure::fit_modes_with(
            &work.x,
            work.n,
            &work.y,
            features,
            labels,
            modes,
            o.min_weight,
            weights,
            prior_fit,
        )
        .map_err(|e| ClusterError::Procedure(e).into())
    };
    let out = hysid_estimation::regions::alternate(
        &work.xs,
        &work.y,
        fit.labels.clone(),
        modes,
        &settings,
        |labels| least_squares(labels, Weights::Uniform).map(|t| t.working),
    )?;
    let theta = least_squares(&out.labels, o.weights)?;
    let report = AlternationReport::from(&out);
    fit.labels = out.labels;
    fit.theta = theta.working;
    fit.theta_original = theta.original;
    Ok(Some(report))
}

/// The regions of the modes, in working units.
struct Regions {
    polyhedra: Vec<Polyhedron>,
    training_accuracy: f64,
    complete: bool,
    /// The time budget ended the region program's rounds early.
    cut_short: bool,
}

/// Step 7: the regions that separate the mode datasets (`regions`: MRLP,
/// multicategory SVM or pairwise proximal SVM), with normals restricted to
/// the `switching` regressors; one mode owns the whole space. No round of
/// the region program starts after `deadline`.
fn estimate_regions(
    o: &ClusterOptions,
    data: &PwarxData<'_>,
    work: &Working,
    fit: &ModeFit,
    deadline: &Deadline,
) -> Result<Regions, IdentifyError> {
    let modes = fit.theta.len();
    if modes == 1 {
        return Ok(Regions {
            polyhedra: vec![Polyhedron::everything()],
            training_accuracy: 1.0,
            complete: true,
            cut_short: false,
        });
    }
    let options = hysid_estimation::regions::RegionOptions {
        method: o.regions,
        svm_c: o.svm_c,
        switching: data.switching.clone(),
        standardize: !o.scale,
        deadline: deadline.clone(),
        ..Default::default()
    };
    let part = hysid_estimation::regions::estimate(&work.xs, &fit.labels, modes, &options)
        .map_err(|e| IdentifyError::failed(RegionFailure::Estimate(e)))?;
    Ok(Regions {
        polyhedra: part.regions,
        training_accuracy: part.training_accuracy,
        complete: part.complete,
        cut_short: part.stats.cut_short,
    })
}

/// Every sample moved to the mode of the region that contains it (of least
/// violation when none does), then the weighted least squares of step 5
/// repeated on these mode datasets when each holds more than `n` samples.
/// Returns the number of samples moved.
fn refit_on_regions(
    o: &ClusterOptions,
    work: &Working,
    fit: &mut ModeFit,
    regions: &[Polyhedron],
    prior_fit: Option<&ConstrainedFit>,
    weights: Weights,
) -> Result<usize, IdentifyError> {
    let (n, modes) = (work.n, fit.theta.len());
    let mut moved = 0;
    for (j, l) in fit.labels.iter_mut().enumerate() {
        let r = region_of(regions, &work.x[j * n..(j + 1) * n]).mode;
        if r != *l {
            moved += 1;
            *l = r;
        }
    }
    let mut sizes = (0..modes).map(|i| fit.labels.iter().filter(|&&l| l == i).count());
    if sizes.all(|k| k > n) {
        let refit = procedure::fit_modes_with(
            &work.x,
            n,
            &work.y,
            &fit.features,
            &fit.labels,
            modes,
            o.min_weight,
            weights,
            prior_fit,
        )
        .map_err(ClusterError::Procedure)?;
        fit.theta = refit.working;
        fit.theta_original = refit.original;
    }
    Ok(moved)
}

/// Fraction of the bounding box of the ordinary regressors in no region
/// (pairwise PSVC may leave holes), from 10 000 samples drawn with `seed`.
fn holes(work: &Working, regions: &[Polyhedron], seed: u64) -> f64 {
    let lo: Vec<f64> = (0..work.n).map(|k| work.xs.column(k).min()).collect();
    let hi: Vec<f64> = (0..work.n).map(|k| work.xs.column(k).max()).collect();
    hysid_estimation::regions::coverage(regions, &lo, &hi, 10_000, seed).uncovered_fraction
}

/// With `clustering = kmeans`, the message of a time budget that stopped
/// the restarts early.
fn time_budget_status(o: &ClusterOptions, fit: &ModeFit, regions: &Regions) -> Vec<String> {
    let run = fit.diagnostics.restart_costs.len();
    let mut status = Vec::new();
    if o.clustering == Clustering::Kmeans && run < o.restarts {
        status.push(format!(
            "time budget reached after {run} of {} K-means restarts: the best clustering found by then",
            o.restarts
        ));
    }
    if regions.cut_short {
        status.push(format!(
            "time budget reached during the {} region estimation: the regions found by then \
             (a complete partition, not the program's optimum)",
            o.regions
        ));
    }
    status
}

/// Step 8: the modes in data units (`PwarxModel::to_original_units`, exact);
/// under gray-box priors the parameters fitted in data units, where the
/// priors hold exactly.
fn modes_in_data_units(
    o: &ClusterOptions,
    data: &PwarxData<'_>,
    work: &Working,
    fit: ModeFit,
    regions: Vec<Polyhedron>,
) -> Vec<PwarxMode> {
    let working = PwarxModel {
        na: data.spec.na,
        nb: data.spec.nb,
        inputs: data.spec.inputs,
        modes: PwarxMode::unnamed(fit.theta, regions),
        info: ModelInfo::default(),
    };
    let mut modes = if o.scale {
        working.to_original_units(&work.scale).modes
    } else {
        working.modes
    };
    if let Some(original) = fit.theta_original {
        for (mode, theta) in modes.iter_mut().zip(original) {
            mode.theta = theta;
        }
    }
    modes
}
