//! The `bounded` back-end on the shared PWARX set-up: the steps of
//! Bemporad, Garulli, Paoletti and Vicino, "A bounded-error approach to
//! piecewise affine system identification", IEEE TAC 50(10), 2005, on the
//! ordinary samples of a [`PwarxData`].
//!
//! [`fit`] = [`classify`] (the error bound delta, then [`procedure::run`]:
//! greedy MIN PFS by MAX FS, refinement with drops and merges, final
//! classification), the optional [`alternate_classification`], then the
//! region estimation of `hysid_estimation::regions`.

use crate::constraints::ModeConstraints;
use crate::noise;
use crate::options::{BoundedOptions, Delta, Refit};
use crate::procedure::{self, Classification, ProcedureError, ProcedureSettings, RefitKind};
use crate::samples::Samples;
use hysid_core::backend::{IdentifyError, RunContext};
use hysid_core::options::OptionError;
use hysid_estimation::pwarx::{PwarxData, PwarxFit};
use hysid_estimation::regions::{
    AlternationReport, AlternationSettings, Partition, RegionFailure, RegionOptions,
};
use hysid_model::model::{PwarxMode, RunStatus};
use hysid_model::regressors::Regressors;
use nalgebra::DMatrix;
use serde::Serialize;

/// What the `bounded` back-end reports besides the common diagnostics
/// (`docs/bounded.md`, "Diagnostics").
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BoundedDiagnostics {
    /// The error bound used, output units.
    pub delta: f64,
    /// Whether delta was estimated from the data (`delta = auto`).
    pub delta_auto: bool,
    /// Ordinary modes found (the stops not counted).
    pub modes_found: usize,
    /// Modes extracted by the greedy MIN PFS, before refinement.
    pub greedy_modes: usize,
    /// With known stops: the samples at no stop, which the modes are
    /// identified from.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ordinary_samples: Option<usize>,
    /// Samples explained by exactly one mode.
    pub assigned: usize,
    /// Samples explained by several modes (labelled by nearest neighbours).
    pub undecidable: usize,
    /// Samples explained by no mode (outliers).
    pub infeasible: usize,
    /// Refinement rounds run.
    pub rounds: usize,
    /// Whether the refinement reached a fixed point.
    pub converged: bool,
    /// Merges done.
    pub merged: usize,
    /// Modes dropped (too few samples).
    pub dropped: usize,
    /// Modes added by splitting a mode whose samples lie on pieces another
    /// mode separates (same parameters, one region each).
    pub split_modes: usize,
    /// Largest `|residual|` of each mode over the samples labelled with it.
    pub max_residual: Vec<f64>,
    /// Samples labelled with each mode.
    pub samples_per_mode: Vec<usize>,
    /// Fraction of the labelled samples inside their own mode's region.
    pub region_training_accuracy: f64,
    /// With ties and several greedy modes: the largest residual of the joint
    /// fit under the ties on the greedy classification.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tie_projection_error: Option<f64>,
    /// Whether that error is within delta.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tie_projection_within_delta: Option<bool>,
    /// Set (true) only when the time budget cut the procedure short.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub stopped_by_deadline: bool,
    /// The alternation after the classification, when `alternation > 0`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub alternation: Option<AlternationReport>,
}

/// What [`classify`] returns.
#[derive(Debug, Clone)]
pub struct Classified {
    /// Classification of the ordinary samples.
    pub classification: Classification,
    /// The ordinary samples (saturated ones removed).
    pub samples: Samples,
    /// The settings used.
    pub settings: ProcedureSettings,
    /// For every regression row of the record, the known stop its target
    /// sits at ([`PwarxData::stop_of`]).
    pub stops: Vec<Option<usize>>,
    /// Regression row of each ordinary sample ([`PwarxData::ordinary`]).
    pub ordinary: Vec<usize>,
}

impl Classified {
    /// Mode of every regression row of the record: ordinary modes
    /// `0..s`, then the stops in prior order (`s + stop`), `None` for
    /// infeasible samples.
    pub fn row_labels(&self) -> Vec<Option<usize>> {
        let s = self.classification.thetas.len();
        let mut out: Vec<Option<usize>> = self.stops.iter().map(|o| o.map(|i| s + i)).collect();
        for (r, &k) in self.ordinary.iter().enumerate() {
            out[k] = self.classification.labels[r];
        }
        out
    }
}

/// The bounded-error identification of the ordinary samples of `data`:
/// the samples classified into modes within delta ([`classify`]), then the
/// regions estimated from the classification ([`estimate_regions`]).
pub fn fit(
    options: &BoundedOptions,
    data: &PwarxData<'_>,
    ctx: &RunContext<'_>,
) -> Result<PwarxFit<BoundedDiagnostics>, IdentifyError> {
    let mut classified = classify(options, data, ctx)?;
    let alternation = alternate_classification(options, data, &mut classified, ctx)?;
    let partition = estimate_regions(options, data, &classified)?;
    let c = &classified.classification;
    let (run_status, status) = how_it_ended(c, classified.settings.delta);
    let diagnostics = diagnostics(options, data, &classified, &partition, alternation);
    Ok(PwarxFit {
        modes: PwarxMode::unnamed(c.thetas.iter().cloned(), partition.regions),
        regions_complete: partition.complete,
        uncovered_fraction: None,
        run_status,
        status,
        scaling: None,
        refinement: None,
        trimming: None,
        diagnostics,
    })
}

/// The modes and the classification of the ordinary samples of `data`:
/// the error bound ([`error_bound`]), then the procedure of Bemporad et al.
/// (2005) ([`procedure::run`]: greedy MIN PFS by MAX FS, refinement with
/// drops and merges, final classification).
pub fn classify(
    options: &BoundedOptions,
    data: &PwarxData<'_>,
    ctx: &RunContext<'_>,
) -> Result<Classified, IdentifyError> {
    let reg = data.ordinary_regressors();
    let samples = Samples::from_regressors(&reg);
    let settings = procedure_settings(options, data, &reg, ctx)?;
    let classification = procedure::run(&samples, &settings).map_err(BoundedError::Procedure)?;
    Ok(Classified {
        classification,
        samples,
        settings,
        stops: data.stop_of.clone(),
        ordinary: data.ordinary.clone(),
    })
}

/// Step 3b (`alternation > 0`, ours, not in the paper): the alternation of
/// [`hysid_estimation::regions::alternate`] from the classification, for at most
/// `alternation` rounds: least squares per mode under the priors, a
/// softmax gate, every sample to its mode of least cost. Infeasible
/// samples start in the mode of least residual. The mode datasets and
/// least-squares parameters it ends with replace the classification's, so
/// the modes no longer certify `delta` (`max_residual` says by how much).
/// `None` with one mode, or when a mode starts with fewer samples than its
/// least squares needs.
pub fn alternate_classification(
    options: &BoundedOptions,
    data: &PwarxData<'_>,
    classified: &mut Classified,
    ctx: &RunContext<'_>,
) -> Result<Option<AlternationReport>, IdentifyError> {
    let (s, c) = (&classified.samples, &mut classified.classification);
    let modes = c.thetas.len();
    if options.alternation == 0 || modes < 2 {
        return Ok(None);
    }
    let labels: Vec<usize> = (0..s.len())
        .map(|k| {
            c.labels[k]
                .or_else(|| procedure::least_residual_mode(s, k, &c.thetas, 0..modes))
                .unwrap_or(0)
        })
        .collect();
    if groups(&labels, modes).iter().any(|g| g.len() < s.p) {
        return Ok(None);
    }
    let settings = AlternationSettings {
        switching: data.switching.clone(),
        deadline: ctx.deadline.clone(),
        ..AlternationSettings::new(options.alternation, s.p)
    };
    let x = DMatrix::from_fn(s.len(), s.p - 1, |r, j| s.row(r)[j]);
    let constraints = &classified.settings.constraints;
    let out = hysid_estimation::regions::alternate(&x, &s.y, labels, modes, &settings, |labels| {
        constraints
            .least_squares_modes(s, &groups(labels, modes))
            .ok_or_else(|| BoundedError::AlternationLeastSquares.into())
    })?;
    let report = AlternationReport::from(&out);
    c.labels = out.labels.into_iter().map(Some).collect();
    c.max_residual = procedure::max_residuals(s, &out.theta, &c.labels);
    c.thetas = out.theta;
    Ok(Some(report))
}

/// The samples of each of `modes` modes under `labels`.
fn groups(labels: &[usize], modes: usize) -> Vec<Vec<usize>> {
    let mut out = vec![Vec::new(); modes];
    for (k, &l) in labels.iter().enumerate() {
        out[l].push(k);
    }
    out
}

/// The error bound: the given delta, or with `auto` the noise bound of
/// [`noise::auto_delta`] on the ordinary samples.
pub fn error_bound(options: &BoundedOptions, reg: &Regressors) -> f64 {
    match options.delta {
        Delta::Value(d) => d,
        Delta::Auto(_) => noise::auto_delta(reg),
    }
}

/// The settings of the procedure: the options, the mode counts of the
/// priors and `max_modes`, the parameter priors, the error bound.
fn procedure_settings(
    options: &BoundedOptions,
    data: &PwarxData<'_>,
    reg: &Regressors,
    ctx: &RunContext<'_>,
) -> Result<ProcedureSettings, IdentifyError> {
    let (max_modes, exact_modes) = mode_counts(options, data)?;
    let constraints = ModeConstraints::new(data).map_err(|e| data.prior_error(e))?;
    Ok(ProcedureSettings {
        delta: error_bound(options, reg),
        cycles: options.cycles,
        t0: options.t0,
        alpha: options.alpha,
        beta: options.beta,
        restarts: options.restarts,
        refit: match options.refit {
            Refit::Linf => RefitKind::Linf,
            Refit::Ls => RefitKind::Ls,
        },
        max_modes,
        exact_modes,
        seed: ctx.seed,
        deadline: ctx.deadline.clone(),
        constraints,
    })
}

/// The bound on the ordinary modes (option `max_modes` and the priors) and
/// the exact count of the priors. `max_modes` counts every mode, the stops
/// included; an exact count the record cannot hold (each mode needs at
/// least `p` samples) is bad input.
fn mode_counts(
    options: &BoundedOptions,
    data: &PwarxData<'_>,
) -> Result<(Option<usize>, Option<usize>), IdentifyError> {
    let stops = data.stops();
    if let Some(m) = options.max_modes
        && m <= stops
    {
        return Err(OptionError::invalid(
            "max_modes",
            m,
            format!(
                "counts every mode, the {stops} saturation mode(s) included: must be at least {}",
                stops + 1
            ),
        )
        .into());
    }
    let max_modes = match (options.max_modes.map(|m| m - stops), data.modes.at_most()) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    };
    let exact = data.modes.exact();
    if let (Some(s), Some(m)) = (exact, max_modes)
        && s > m
    {
        let e = BoundedError::ModesExceedBound {
            modes: s + stops,
            max: m + stops,
        };
        // Not named by the file: `--modes` may have set the count.
        return Err(IdentifyError::prior_mismatch(None, e));
    }
    Ok((max_modes, exact))
}

/// Step 4: the regions from the labelled samples (`hysid_estimation::regions`, the
/// method of option `regions`; normals restricted to the `switching`
/// regressors).
pub fn estimate_regions(
    options: &BoundedOptions,
    data: &PwarxData<'_>,
    classified: &Classified,
) -> Result<Partition, IdentifyError> {
    let (s, c) = (&classified.samples, &classified.classification);
    let labelled: Vec<usize> = (0..s.len()).filter(|&k| c.labels[k].is_some()).collect();
    let rows = DMatrix::from_fn(labelled.len(), s.p - 1, |r, j| s.row(labelled[r])[j]);
    let labels: Vec<usize> = c.labels.iter().flatten().copied().collect();
    let region_options = RegionOptions {
        method: options.regions,
        switching: data.switching.clone(),
        ..Default::default()
    };
    hysid_estimation::regions::estimate(&rows, &labels, c.thetas.len(), &region_options)
        .map_err(|e| IdentifyError::failed(RegionFailure::Estimate(e)))
}

/// How the run ended: cut short by the time budget or not, and the
/// warnings when the tie projection left the greedy modes beyond delta
/// and when most samples fit no mode.
fn how_it_ended(c: &Classification, delta: f64) -> (RunStatus, Vec<String>) {
    let mut status = Vec::new();
    let run_status = if c.stopped_by_deadline {
        status.push(format!(
            "time budget reached after {} mode extraction(s) and {} refinement round(s): the modes found by then",
            c.greedy_modes, c.rounds
        ));
        RunStatus::TimeBudget
    } else {
        RunStatus::Completed
    };
    if let Some(e) = c.tie_projection_error
        && e > delta
    {
        // The greedy extraction ran with the ties relaxed; imposing them
        // afterwards did not keep the greedy modes within delta. The
        // ratio reads the same in any units (standardised data too).
        status.push(format!(
            "warning: the [[tie]] priors, imposed after the greedy extraction (which relaxes them), \
             fit the greedy modes with a largest error of {:.2} times delta (tie_projection_error); \
             the refinement re-classified the samples under the ties (docs/bounded.md, \"Priors\")",
            e / delta
        ));
    }
    // A run cut short has the modes found by then: said above.
    let infeasible = c.count(procedure::SampleClass::Infeasible);
    if 2 * infeasible > c.labels.len() && !c.stopped_by_deadline {
        status.push(format!(
            "warning: {infeasible} of {} samples fit no mode within delta (infeasible): the modes \
             explain few of the data; raise delta, or check the priors on the modes' parameters",
            c.labels.len()
        ));
    }
    (run_status, status)
}

fn diagnostics(
    options: &BoundedOptions,
    data: &PwarxData<'_>,
    classified: &Classified,
    partition: &Partition,
    alternation: Option<AlternationReport>,
) -> BoundedDiagnostics {
    use procedure::SampleClass::{Assigned, Infeasible, Undecidable};
    let (c, delta) = (&classified.classification, classified.settings.delta);
    let mut samples_per_mode = vec![0usize; c.thetas.len()];
    for l in c.labels.iter().flatten() {
        samples_per_mode[*l] += 1;
    }
    BoundedDiagnostics {
        delta,
        delta_auto: matches!(options.delta, Delta::Auto(_)),
        modes_found: c.thetas.len(),
        greedy_modes: c.greedy_modes,
        ordinary_samples: (data.stops() > 0).then_some(classified.samples.len()),
        assigned: c.count(Assigned),
        undecidable: c.count(Undecidable),
        infeasible: c.count(Infeasible),
        rounds: c.rounds,
        converged: c.converged,
        merged: c.merged,
        dropped: c.dropped,
        split_modes: c.split,
        max_residual: c.max_residual.clone(),
        samples_per_mode,
        region_training_accuracy: partition.training_accuracy,
        tie_projection_error: c.tie_projection_error,
        tie_projection_within_delta: c.tie_projection_error.map(|e| e <= delta),
        stopped_by_deadline: c.stopped_by_deadline,
        alternation,
    }
}

/// What the `bounded` back-end refuses (an [`IdentifyError::Input`]) or
/// fails at (an [`IdentifyError::Failed`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BoundedError {
    /// A `modes` prior above the option `max_modes`.
    #[error("modes = {modes} exceeds the option max_modes = {max}")]
    ModesExceedBound {
        /// `modes`, stops included.
        modes: usize,
        /// `max_modes`, stops included.
        max: usize,
    },
    /// The record or a setting does not allow the procedure.
    #[error(transparent)]
    Procedure(procedure::ProcedureError),
    /// The least squares of a mode failed inside the alternation.
    #[error("alternation: the least squares of a mode failed")]
    AlternationLeastSquares,
}

impl From<BoundedError> for IdentifyError {
    /// Too few samples and a failed tie projection are the data's fault;
    /// no mode within delta, fewer modes than the priors ask, or a failed
    /// least squares, the method's.
    fn from(e: BoundedError) -> Self {
        match e {
            BoundedError::Procedure(ProcedureError::TooFewSamples { .. }) => {
                IdentifyError::too_few_samples(e)
            }
            BoundedError::Procedure(ProcedureError::Setting(_)) => IdentifyError::input(e),
            e => IdentifyError::failed(e),
        }
    }
}
