//! The models the `physical` back-end fits: named parameters and an
//! event-aware simulator ([`Target`], [`Simulator`]): any [`GrayBoxModel`]
//! with its compiled form ([`GrayBoxTarget`]), a mechanical model as its
//! gray-box form ([`crate::mechanical`]).

use hysid_graybox::compile::CompiledInitial;
use hysid_graybox::{CompiledModel, GrayBoxInitialState, GrayBoxModel, InvalidGrayBox};
use hysid_model::data::Dataset;
use hysid_model::model::{ModelInfo, PhysicalParameter};
use hysid_model::simulate::{SimError, substeps};
use nalgebra::DMatrix;

/// What the objective needs of a model: its simulations.
pub trait Simulator: Sync {
    /// Free-run output with parameter values `values` and the first
    /// simulated sample, or why the run failed.
    fn free_run(&self, values: &[f64], data: &Dataset) -> Result<(usize, Vec<f64>), SimError>;
    /// Residuals `y(k+1) - yhat(k+1)` of the multiple-shooting run: segments
    /// of `segment` samples, each from the position measured at its start
    /// and the velocity [`segment_velocity`] with rest threshold
    /// `velocity_tol`.
    fn segmented_residuals(
        &self,
        values: &[f64],
        data: &Dataset,
        segment: usize,
        velocity_tol: f64,
    ) -> Option<Vec<f64>>;
    /// Number of initial states estimated per record: the values a
    /// simulation takes are the parameters, then these.
    fn estimated_count(&self) -> usize;
    /// The states of [`Target::estimated_states`] as the warm-up outputs of
    /// `record` give them at the parameter values `parameters` (what
    /// `validate` does on a record of its own); `None` where the model
    /// estimates none or the estimate fails.
    fn warmup_states(&self, parameters: &[f64], record: &Dataset) -> Option<Vec<f64>>;
    /// Whether [`Simulator::residual_jacobian`] gives the exact Jacobian.
    fn exact_jacobian(&self) -> bool;
    /// The residuals of [`Simulator::free_run`] (`segment` 0) or of
    /// [`Simulator::segmented_residuals`], with their exact Jacobian in
    /// `values` (a column per value); `None` where the model gives none or
    /// the run fails.
    fn residual_jacobian(
        &self,
        values: &[f64],
        data: &Dataset,
        segment: usize,
        velocity_tol: f64,
    ) -> Option<(Vec<f64>, DMatrix<f64>)>;
}

/// What the fit needs of a model declared by its physics.
pub trait Target: Simulator + Clone {
    /// The parameters, in order.
    fn parameters(&self) -> &[PhysicalParameter];
    /// Mutable parameters (the fitted values are written here).
    fn parameters_mut(&mut self) -> &mut [PhysicalParameter];
    /// Provenance and diagnostics.
    fn info_mut(&mut self) -> &mut ModelInfo;
    /// Number of inputs.
    fn inputs(&self) -> usize;
    /// The model's own structural checks.
    fn check(&self) -> Result<(), Box<dyn std::error::Error + Send + Sync>>;
    /// Sub-steps per sample at the sampling time `ts`.
    fn substeps(&self, ts: f64) -> Result<usize, SimError>;
    /// Samples of the warm-up the initial state reads: a measured state,
    /// or the outputs that estimate the states it leaves unknown (`None`:
    /// a given or rest state that estimates nothing).
    fn warmup_samples(&self) -> Option<usize>;
    /// The model with a warm-up of the first `samples` samples, velocities
    /// below `velocity_tol` taken as zero (at least the model's own
    /// tolerance); `None` for a rule that reads no warm-up.
    fn with_warmup(&self, samples: usize, velocity_tol: f64) -> Option<Self>;
    /// The states of the initial state that the model leaves unknown:
    /// `(name, [low, high], starting guess)`. They are fitted with the
    /// parameters, as nuisance parameters of the record: their values
    /// follow the parameters' in the values a [`Simulator`] takes.
    fn estimated_states(&self) -> Vec<(String, [f64; 2], f64)>;
}

/// A gray-box model with its compiled form (compiled once per fit).
#[derive(Debug, Clone)]
pub struct GrayBoxTarget {
    /// The model.
    pub model: GrayBoxModel,
    compiled: CompiledModel,
}

impl GrayBoxTarget {
    /// Checks and compiles `model`.
    pub fn new(model: GrayBoxModel) -> Result<Self, InvalidGrayBox> {
        let compiled = CompiledModel::new(&model)?;
        Ok(GrayBoxTarget { model, compiled })
    }
}

impl Target for GrayBoxTarget {
    fn parameters(&self) -> &[PhysicalParameter] {
        &self.model.parameters
    }

    fn parameters_mut(&mut self) -> &mut [PhysicalParameter] {
        &mut self.model.parameters
    }

    fn info_mut(&mut self) -> &mut ModelInfo {
        &mut self.model.info
    }

    fn inputs(&self) -> usize {
        self.model.inputs.len()
    }

    fn check(&self) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        self.model.validate().map_err(Into::into)
    }

    fn substeps(&self, ts: f64) -> Result<usize, SimError> {
        substeps(ts, self.model.internal_step)
    }

    fn warmup_samples(&self) -> Option<usize> {
        self.compiled.warmup_read()
    }

    fn estimated_states(&self) -> Vec<(String, [f64; 2], f64)> {
        self.compiled
            .estimates
            .iter()
            .map(|e| (e.name.clone(), e.bounds, e.start))
            .collect()
    }

    /// A given state keeps its values (which state the output measures
    /// is the model's to say); its warm-up, where it estimates states,
    /// takes `samples`.
    fn with_warmup(&self, samples: usize, velocity_tol: f64) -> Option<Self> {
        self.warmup_samples()?;
        let mut t = self.clone();
        match (&mut t.model.initial_state, &mut t.compiled.initial) {
            (
                GrayBoxInitialState::Measured {
                    samples: s,
                    velocity_tol: tol,
                    ..
                },
                CompiledInitial::Measured {
                    samples: cs,
                    velocity_tol: ctol,
                    ..
                },
            ) => {
                (*s, *cs) = (samples, samples);
                *tol = tol.max(velocity_tol);
                *ctol = *tol;
            }
            (
                GrayBoxInitialState::Given { samples: s, .. },
                CompiledInitial::Given { samples: cs, .. },
            ) => (*s, *cs) = (Some(samples), samples),
            _ => return None,
        }
        Some(t)
    }
}

impl GrayBoxTarget {
    /// `values` split into the parameters and the estimated initial states
    /// ([`Target::estimated_states`]) that follow them.
    fn split<'v>(&self, values: &'v [f64]) -> (&'v [f64], &'v [f64]) {
        values.split_at(self.compiled.parameters.min(values.len()))
    }
}

impl Simulator for GrayBoxTarget {
    fn estimated_count(&self) -> usize {
        self.compiled.estimates.len()
    }

    fn warmup_states(&self, parameters: &[f64], record: &Dataset) -> Option<Vec<f64>> {
        if self.compiled.estimates.is_empty() {
            return None;
        }
        hysid_graybox::simulate::estimate(&self.compiled, parameters, record).ok()
    }

    fn free_run(&self, values: &[f64], data: &Dataset) -> Result<(usize, Vec<f64>), SimError> {
        let (values, initial) = self.split(values);
        let r = hysid_graybox::simulate::outputs_from(&self.compiled, values, initial, data)?;
        Ok((r.start, r.y))
    }

    fn exact_jacobian(&self) -> bool {
        hysid_graybox::simulate::differentiable(&self.compiled)
    }

    /// The runs' forward sensitivities ([`mod@hysid_graybox::simulate`]).
    fn residual_jacobian(
        &self,
        values: &[f64],
        data: &Dataset,
        segment: usize,
        velocity_tol: f64,
    ) -> Option<(Vec<f64>, DMatrix<f64>)> {
        use hysid_graybox::simulate::{run_with_sensitivities, segmented_with_sensitivities};
        let (parameters, initial) = self.split(values);
        let y = data.y();
        let (first, yhat, s) = if segment == 0 {
            let r = run_with_sensitivities(&self.compiled, parameters, initial, data).ok()?;
            (r.start + 1, r.y, r.sensitivities?)
        } else {
            let ts = data.ts?;
            let slope_at = |s: usize| segment_velocity(y, s, ts, velocity_tol);
            let (yhat, s) = segmented_with_sensitivities(
                &self.compiled,
                parameters,
                initial,
                data,
                segment,
                &slope_at,
            )
            .ok()?;
            (1, yhat, s)
        };
        let rows = y.len().checked_sub(first)?;
        let residuals = (first..y.len()).map(|k| y[k] - yhat[k]).collect();
        let jacobian = DMatrix::from_fn(rows, s.columns, |i, j| -s.dy_row(first + i)[j]);
        Some((residuals, jacobian))
    }

    fn segmented_residuals(
        &self,
        values: &[f64],
        data: &Dataset,
        segment: usize,
        velocity_tol: f64,
    ) -> Option<Vec<f64>> {
        let ts = data.ts?;
        let y = data.y();
        let (values, initial) = self.split(values);
        // Without the measured rule there is nothing to restart from: the
        // free run.
        let slope_at = |s: usize| segment_velocity(y, s, ts, velocity_tol);
        let yhat = hysid_graybox::simulate::segmented(
            &self.compiled,
            values,
            initial,
            data,
            segment,
            &slope_at,
        )
        .ok()?;
        Some(y[1..].iter().zip(&yhat[1..]).map(|(a, b)| a - b).collect())
    }
}

/// Velocity at sample `k` for re-initialising a segment (offline, so it
/// may look ahead): the slopes `b` over `k-2..=k` and `f` over `k..=k+2`
/// (clipped to the record) are compared. Both within `tol`, or of opposite
/// signs: at rest (0). Within a factor 2 of each other: smooth motion,
/// their mean (the centred slope). Otherwise an event lies in the window
/// (break-away, impact on a stop) and the smaller one is the velocity at
/// `k` (0 at a break-away, the stop's 0 after an impact).
pub fn segment_velocity(y: &[f64], k: usize, ts: f64, tol: f64) -> f64 {
    let n = y.len();
    let slope = |a: usize, b: usize| {
        if b > a {
            (y[b] - y[a]) / ((b - a) as f64 * ts)
        } else {
            0.0
        }
    };
    let b = slope(k.saturating_sub(2), k);
    let f = slope(k, (k + 2).min(n - 1));
    let (ab, af) = (b.abs(), f.abs());
    if (ab <= tol && af <= tol) || b * f < 0.0 {
        return 0.0;
    }
    if k < 2 {
        return f;
    }
    if k + 2 >= n {
        return b;
    }
    let (lo, hi) = if ab < af { (ab, af) } else { (af, ab) };
    if hi <= 2.0 * lo {
        0.5 * (b + f)
    } else if ab < af {
        b
    } else {
        f
    }
}
