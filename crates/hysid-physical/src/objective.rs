//! The simulation-error objective: free-run and segmented (multiple-
//! shooting) residuals of the model's event-aware simulation
//! ([`Simulator`]), their mean square, the velocity thresholds from the
//! measurement noise, and the cost argmin's solvers see.

use crate::parameters::ParameterMap;
use crate::target::Simulator;
use argmin::core::{CostFunction, Error as ArgminError};
use hysid_core::backend::{Deadline, Progress};
use hysid_model::data::Dataset;
use hysid_model::simulate::estimate_velocity;
use hysid_model::statistics::{MAD_TO_SIGMA, upper_median};
use nalgebra::DMatrix;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Cost of a diverged or failed simulation.
pub const FAILED: f64 = 1e30;

/// Free-run simulation residuals `y(k) - yhat(k)` after the initial state,
/// as simulated (`None` only when the simulation fails), of each record of
/// `records` from its own initial state ([`per_record`]).
pub fn free_run_residuals(
    model: &dyn Simulator,
    values: &[f64],
    records: &[Dataset],
) -> Option<Vec<f64>> {
    per_record(model, values, records, |values, data| {
        let (start, y) = model.free_run(values, data).ok()?;
        Some(
            data.y()[start + 1..]
                .iter()
                .zip(&y[start + 1..])
                .map(|(a, b)| a - b)
                .collect(),
        )
    })
}

/// The residuals `residuals` gives on each of `records` (the records of
/// the data, [`Dataset::records`], split once per fit), computed in
/// parallel and concatenated in record order. `values` holds the
/// parameters, then the estimated initial states of each record in turn
/// ([`Simulator::estimated_count`] each); a record is simulated with the
/// parameters and its own states. One record: `residuals(values, record)`.
pub fn per_record(
    model: &dyn Simulator,
    values: &[f64],
    records: &[Dataset],
    residuals: impl Fn(&[f64], &Dataset) -> Option<Vec<f64>> + Sync,
) -> Option<Vec<f64>> {
    if let [record] = records {
        return residuals(values, record);
    }
    let (_, each) = each_record(model, values, records, residuals)?;
    Some(each.concat())
}

/// `f` of every record (in parallel, in record order) with the values it
/// takes: the parameters, then its own estimated initial states; and the
/// number of parameters. `None` when `values` is too short or `f` fails.
fn each_record<T: Send>(
    model: &dyn Simulator,
    values: &[f64],
    records: &[Dataset],
    f: impl Fn(&[f64], &Dataset) -> Option<T> + Sync,
) -> Option<(usize, Vec<T>)> {
    let states = model.estimated_count();
    let parameters = values.len().checked_sub(states * records.len())?;
    let each = records
        .par_iter()
        .enumerate()
        .map(|(i, record)| {
            let at = parameters + i * states;
            let mut own = values[..parameters].to_vec();
            own.extend_from_slice(&values[at..at + states]);
            f(&own, record)
        })
        .collect::<Option<_>>()?;
    Some((parameters, each))
}

/// The residuals of the free run (`segment` 0) or of the segmented run of
/// every record, as [`per_record`] orders them, and their exact Jacobian
/// in `values` (each record's estimated states in their own columns):
/// `None` where the model gives no exact Jacobian
/// ([`Simulator::exact_jacobian`]), a run fails, or a value is not finite.
pub fn residual_jacobian(
    model: &dyn Simulator,
    values: &[f64],
    records: &[Dataset],
    segment: usize,
    velocity_tol: f64,
) -> Option<(Vec<f64>, DMatrix<f64>)> {
    if !model.exact_jacobian() {
        return None;
    }
    let states = model.estimated_count();
    let (parameters, each) = each_record(model, values, records, |own, record| {
        model.residual_jacobian(own, record, segment, velocity_tol)
    })?;
    let rows: usize = each.iter().map(|(r, _)| r.len()).sum();
    let mut jacobian = DMatrix::zeros(rows, values.len());
    let mut residuals = Vec::with_capacity(rows);
    for (i, (r, j)) in each.into_iter().enumerate() {
        let (row, n) = (residuals.len(), r.len());
        let at = parameters + i * states;
        jacobian
            .view_mut((row, 0), (n, parameters))
            .copy_from(&j.columns(0, parameters));
        jacobian
            .view_mut((row, at), (n, states))
            .copy_from(&j.columns(parameters, states));
        residuals.extend(r);
    }
    let finite = residuals
        .iter()
        .chain(jacobian.iter())
        .all(|x| x.is_finite());
    (finite && !residuals.is_empty()).then_some((residuals, jacobian))
}

/// Free-run simulation residuals `y(k) - yhat(k)` after the initial state
/// (`None` when the simulation fails or diverges).
pub fn simulation_residuals(
    model: &dyn Simulator,
    values: &[f64],
    records: &[Dataset],
) -> Option<Vec<f64>> {
    free_run_residuals(model, values, records).and_then(finite)
}

/// `e` when it is non-empty and finite.
fn finite(e: Vec<f64>) -> Option<Vec<f64>> {
    (!e.is_empty() && e.iter().all(|x| x.is_finite())).then_some(e)
}

/// Mean square of the residuals; [`FAILED`] when there are none.
fn mse(e: Option<Vec<f64>>) -> f64 {
    match e {
        Some(e) => e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64,
        None => FAILED,
    }
}

/// Mean squared free-run simulation error over the samples after the initial state.
pub fn simulation_mse(model: &dyn Simulator, values: &[f64], records: &[Dataset]) -> f64 {
    mse(simulation_residuals(model, values, records))
}

/// Velocity thresholds below which an estimated velocity counts as zero
/// (the mass is taken to be at rest), from the measurement noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityTolerances {
    /// Output noise standard deviation, estimated.
    pub noise: f64,
    /// For [`crate::target::segment_velocity`] (a 3-point slope).
    pub centred: f64,
    /// For the initial-state estimator of the simulator (backward quadratic).
    pub backward: f64,
    /// The output's range (largest minus smallest sample).
    pub output_range: f64,
}

/// Below this fraction of the output's range a noise estimate is rounding
/// (a quantised record whose repeated samples leave second differences of
/// about 1e-15), not noise: [`VelocityTolerances::resolved_noise`].
const NOISE_RESOLUTION: f64 = 1e-9;

impl VelocityTolerances {
    /// [`Self::noise`] where it exceeds rounding (`1e-9` of the output's
    /// range), else 0.
    pub fn resolved_noise(&self) -> f64 {
        if self.noise > NOISE_RESOLUTION * self.output_range {
            self.noise
        } else {
            0.0
        }
    }
}

/// Estimates the output noise robustly from second differences
/// (`1.4826 median |d2 y| / sqrt(6)`; quantised records whose samples
/// repeat while stuck give 0) and sets the thresholds at three standard
/// deviations of each velocity estimator, plus a floor of `1e-6` of the
/// output range per second against rounding.
pub fn velocity_tolerances(y: &[f64], ts: f64) -> VelocityTolerances {
    let mut d2: Vec<f64> = y
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .collect();
    let noise = upper_median(&mut d2).map_or(0.0, |m| MAD_TO_SIGMA * m / 6f64.sqrt());
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let output_range = (hi - lo).max(0.0);
    let floor = 1e-6 * output_range / ts;
    // Noise gain of an estimator: the norm of its weights (unit impulses).
    let gain = |f: &dyn Fn(&[f64]) -> f64| -> f64 {
        (0..5)
            .map(|j| {
                let mut e = [0.0; 5];
                e[j] = 1.0;
                f(&e).powi(2)
            })
            .sum::<f64>()
            .sqrt()
    };
    let g_c = 0.5f64.sqrt() / ts;
    let g_b = gain(&|e| estimate_velocity(e, 4, ts));
    VelocityTolerances {
        noise,
        centred: 3.0 * noise * g_c + floor,
        backward: 3.0 * noise * g_b + floor,
        output_range,
    }
}

/// [`Simulator::segmented_residuals`] of each record ([`per_record`]).
fn segmented_residuals(
    model: &dyn Simulator,
    values: &[f64],
    records: &[Dataset],
    segment: usize,
    velocity_tol: f64,
) -> Option<Vec<f64>> {
    per_record(model, values, records, |values, data| {
        model.segmented_residuals(values, data, segment, velocity_tol)
    })
}

/// The segmented (multiple-shooting) simulation error: the record is cut
/// into segments of `segment` samples, each simulated from the state
/// measured at its start (position, [`crate::target::segment_velocity`]). Errors do not
/// accumulate across segments, so the cost is much smoother in the
/// parameters than the free-run error; it serves the global stage.
pub fn segmented_mse(
    model: &dyn Simulator,
    values: &[f64],
    records: &[Dataset],
    segment: usize,
    velocity_tol: f64,
) -> f64 {
    mse(segmented_residuals(model, values, records, segment, velocity_tol).and_then(finite))
}

/// The simulation error as a function of the normalised coordinates `z`:
/// the free-run error (`segment == 0`) or the segmented one.
#[derive(Clone, Copy)]
pub struct Objective<'a> {
    /// 0: free-run error; else the segment length of the segmented error.
    pub segment: usize,
    /// Rest threshold of [`crate::target::segment_velocity`] ([`VelocityTolerances::centred`]).
    pub velocity_tol: f64,
    /// The model whose parameters are fitted.
    pub model: &'a dyn Simulator,
    /// The records of the data ([`Dataset::records`]).
    pub records: &'a [Dataset],
    /// Coordinates to parameter values.
    pub map: &'a ParameterMap,
}

impl Objective<'_> {
    /// The same objective on segments of `segment` samples (0: free run).
    pub fn with_segment(self, segment: usize) -> Self {
        Self { segment, ..self }
    }

    /// The residuals at `z` (`None` when the simulation fails or diverges).
    pub fn residuals(&self, z: &[f64]) -> Option<Vec<f64>> {
        let v = self.map.values(z);
        if self.segment == 0 {
            simulation_residuals(self.model, &v, self.records)
        } else {
            segmented_residuals(
                self.model,
                &v,
                self.records,
                self.segment,
                self.velocity_tol,
            )
            .and_then(finite)
        }
    }

    /// The mean squared error at `z` ([`FAILED`] when the simulation fails).
    pub fn mse(&self, z: &[f64]) -> f64 {
        mse(self.residuals(z))
    }

    /// [`Objective::mse`] for the unconstrained searches: outside the box
    /// `[0, 1]^d`, the cost at `z` (the simulation clamps the coordinates)
    /// raised by a penalty that points back inside.
    pub fn penalised(&self, z: &[f64]) -> f64 {
        let out: f64 = z.iter().map(|x| (x - x.clamp(0.0, 1.0)).powi(2)).sum();
        self.mse(z) * (1.0 + 10.0 * out) + out
    }

    /// The exact Jacobian of [`Objective::residuals`] in the coordinates
    /// `z` ([`residual_jacobian`] through [`ParameterMap::in_coordinates`]);
    /// `None` where there is none.
    pub fn jacobian(&self, z: &[f64]) -> Option<DMatrix<f64>> {
        let v = self.map.values(z);
        let (_, jacobian) = residual_jacobian(
            self.model,
            &v,
            self.records,
            self.segment,
            self.velocity_tol,
        )?;
        Some(self.map.in_coordinates(&jacobian))
    }
}

/// [`Objective`] as argmin's cost, counting evaluations and reporting
/// progress, with a penalty outside the box `[0, 1]^d`. Once `deadline`
/// has passed every point costs `+inf` without a simulation, so that a
/// solver inside argmin finishes its remaining iterations at once and
/// keeps the best point found before.
pub struct SimulationCost<'a> {
    /// The objective.
    pub objective: Objective<'a>,
    /// Progress reporter (one step per evaluation).
    pub progress: &'a dyn Progress,
    /// Evaluation counter shared by the stages.
    pub evals: &'a AtomicU64,
    /// The run's deadline (time budget or stop request).
    pub deadline: &'a Deadline,
}

impl CostFunction for SimulationCost<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, z: &Vec<f64>) -> Result<f64, ArgminError> {
        if self.deadline.passed() {
            return Ok(f64::INFINITY);
        }
        self.evals.fetch_add(1, Ordering::Relaxed);
        self.progress.advance(1);
        Ok(self.objective.penalised(z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn a_noise_estimate_of_rounding_is_resolved_to_zero() {
        // A quantised record: steps of 0.1 held for a while, each sample
        // off by rounding of 1e-15.
        let quantised: Vec<f64> = (0..400)
            .map(|k| 0.1 * (k / 7) as f64 + if k % 2 == 0 { 1e-15 } else { -1e-15 })
            .collect();
        let t = velocity_tolerances(&quantised, 0.01);
        assert!(t.noise > 0.0 && t.noise < 1e-13, "{}", t.noise);
        assert_eq!(t.resolved_noise(), 0.0);
        // Gaussian noise of 0.01 on a slow ramp is kept as estimated.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let normal = rand_distr::Normal::new(0.0, 0.01).unwrap();
        let noisy: Vec<f64> = (0..400)
            .map(|k| 0.01 * k as f64 + rand_distr::Distribution::sample(&normal, &mut rng))
            .collect();
        let t = velocity_tolerances(&noisy, 0.01);
        assert!((t.noise - 0.01).abs() < 0.002, "{}", t.noise);
        assert_eq!(t.resolved_noise(), t.noise);
    }
}
