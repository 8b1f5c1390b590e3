//! Refinement of the mode parameters of a PWARX fit by the
//! multiple-shooting **simulation error**, the stage any PWARX back-end may
//! end with, between its `fit` and [`crate::pwarx::assemble`].
//!
//! A back-end fits its modes by one-step prediction error (equation error,
//! the ARX criterion of Ljung, *System Identification*, 2nd ed., 1999,
//! section 7.3). Refinement then minimises the error of the model as it
//! will be used, its free-run simulation: with the regions held fixed, it
//! minimises over the mode parameters
//!
//! ```text
//! V(theta) = sum_s sum_{k in segment s} (y(k) - y_s(k; theta))^2
//! ```
//!
//! where the identification rows are cut into consecutive segments of
//! `segment` samples and `y_s` is the free-run simulation of segment `s`
//! started from the measured outputs before it (multiple shooting, Bock &
//! Plitt, IFAC World Congress 1984, with the segment starts taken from the
//! data). A segment at least as long as the record is the output-error
//! criterion (Ljung 1999, sections 4.2 and 7.2); shorter segments keep the
//! criterion smooth enough for a local method on lightly damped or
//! unstable modes. Each segment is simulated by the model's own simulator
//! (`hysid_model::simulate`): the region of the simulated regressor picks
//! the mode, the mode of least violation outside every region, and with
//! known stops (`[[saturation]]`) the automaton of
//! `HybridAutomaton::from_pwarx_with_stops`, so `V` is the simulation error
//! of exactly the model [`crate::pwarx::assemble`] writes.
//!
//! The minimisation is Levenberg-Marquardt (Marquardt 1963; the damping
//! update of Madsen, Nielsen & Tingleff, *Methods for non-linear least
//! squares problems*, 2004, section 3.2) over the free variables `z` of
//! [`Parametrisation::from_priors`] (`theta = T z + t0`), so ties and
//! fixed values hold exactly. Each step solves
//!
//! ```text
//! min_z' |J z' - (e + J z)|^2 + mu |z' - z|^2
//! ```
//!
//! (`e = y - y_sim` the errors, `J = d y_sim / d z`) by
//! [`constrained::solve_in_z`], under the same `[[equality]]` entries and
//! `[bounds]` as the ordinary fit, so they hold after every step. A step
//! is accepted only when the cost decreases; a simulation that diverges
//! costs `+inf`.
//!
//! The Jacobian is the sensitivity recursion of the simulation (Ljung
//! 1999, section 10.3, for output-error models), not finite differences:
//! for the PWARX simulation
//!
//! ```text
//! dy(k)/dtheta_j = [q(k) = j] [phi(k); 1] + sum_i a_{q(k),i} dy(k-i)/dtheta_j
//! ```
//!
//! with `q(k)` the mode the simulation used and `phi(k)` the simulated
//! regressor (a measured initial output has zero sensitivity); with stops,
//! the same recursion on the automaton state: `dx(k+1) = A_q dx(k) +
//! d(A_q x + B_q u + f_q)/dz`, through the reset maps of the transitions
//! that fired (a reset to the stop level, and a held sample, have zero
//! sensitivity). The regions are piecewise constant in `theta` almost
//! everywhere, so this is the derivative of `V` wherever the mode sequence
//! does not change.

use super::{PwarxData, PwarxFit};
use crate::constrained::{self, Parametrisation, Slot};
use hysid_core::backend::IdentifyError;
use hysid_core::stages::{Refine, Stages};
use hysid_model::data::{Dataset, RowRange};
use hysid_model::model::{
    HybridAutomaton, ModelInfo, PwarxMode, PwarxModel, RunStatus, arx_state_positions,
};
pub use hysid_model::model::{Refinement, RefinementStatus};
use hysid_model::regressors::RegressorSpec;
use hysid_model::simulate::{Simulation, SimulationOptions, automaton, pwarx as pwarx_sim};
use nalgebra::{DMatrix, DVector};

pub mod regions;

/// A step that lowers the cost by less than this fraction of it ends the
/// refinement (converged).
pub const RELATIVE_TOLERANCE: f64 = 1e-10;

/// `fit` with its ordinary modes' parameters refined by the
/// multiple-shooting simulation error (see the module doc), the regions
/// unchanged, and with [`Refine::SimRegions`] then the region
/// boundaries moved ([`regions`]); the outcome in `fit.refinement`. With
/// [`Refine::None`], `fit` unchanged. The settings are those a
/// back-end's checked options hold ([`Stages`]). When no
/// step lowers the cost, the parameters stay as the back-end gave them. A
/// refinement stopped by its iteration bound marks the run
/// [`RunStatus::IterationLimit`].
pub fn refine<D>(
    data: &PwarxData<'_>,
    mut fit: PwarxFit<D>,
    settings: &Stages,
) -> Result<PwarxFit<D>, IdentifyError> {
    if settings.refine == Refine::None {
        return Ok(fit);
    }
    let mut r = fit_parameters(data, &mut fit.modes, settings)?;
    if settings.refine == Refine::SimRegions {
        r.regions = Some(regions::move_regions(data, &mut fit, settings)?);
    }
    if r.status == RefinementStatus::IterationLimit {
        if fit.run_status == RunStatus::Completed {
            fit.run_status = RunStatus::IterationLimit;
        }
        fit.status.push(format!(
            "the simulation-error refinement stopped at its iteration bound ({})",
            r.max_iterations
        ));
    }
    fit.refinement = Some(r);
    Ok(fit)
}

/// The parameters of `modes` refined by Levenberg-Marquardt on the
/// shooting cost with their regions fixed (see the module doc); the
/// outcome.
fn fit_parameters(
    data: &PwarxData<'_>,
    modes: &mut [PwarxMode],
    settings: &Stages,
) -> Result<Refinement, IdentifyError> {
    let par = Parametrisation::from_priors(data.priors(), &data.spec, modes.len())
        .map_err(|e| data.prior_error(e))?;
    let shooting = Shooting::new(data, modes, settings.refine_segment)?;
    let thetas: Vec<Vec<f64>> = modes.iter().map(|m| m.theta.clone()).collect();
    let start = par
        .free_values(&thetas)
        .map_err(|e| IdentifyError::failed(format!("refinement: {e}")))?;
    let problem = ParameterResiduals {
        shooting: &shooting,
        par: &par,
    };
    let descent = levenberg_marquardt(&problem, start, settings.refine_iterations)?;
    if let Some(z) = &descent.v {
        for (mode, theta) in modes.iter_mut().zip(par.thetas(z)) {
            mode.theta = theta;
        }
    }
    let finite = descent.cost_before.is_finite();
    Ok(Refinement {
        segment: shooting.segment,
        segments: shooting.segments(),
        iterations: descent.iterations,
        max_iterations: settings.refine_iterations,
        cost_before: finite.then_some(descent.cost_before),
        cost_after: finite.then_some(descent.cost_after),
        status: descent.status,
        regions: None,
    })
}

/// One shooting segment: the record's samples `offset ..`, of which those
/// from `first` (in segment indices) on are counted in the cost; the ones
/// before are the measured initial outputs.
#[derive(Debug, Clone)]
struct Segment {
    data: Dataset,
    offset: usize,
    first: usize,
}

/// The multiple-shooting simulation error of a PWARX fit with fixed
/// regions under a parametrisation: simulated outputs, errors, cost and
/// sensitivities.
#[derive(Debug, Clone)]
pub struct Shooting<'a> {
    spec: RegressorSpec,
    modes: Vec<PwarxMode>,
    stops: &'a [hysid_model::model::Stop],
    segment: usize,
    segments: Vec<Segment>,
    options: SimulationOptions,
}

/// The simulation of every segment at one parameter point.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// For every counted sample: its index in the record.
    pub samples: Vec<usize>,
    /// Simulated outputs of the counted samples.
    pub simulated: Vec<f64>,
    /// Errors `y - y_sim` of the counted samples.
    pub errors: DVector<f64>,
    /// Sensitivities `d y_sim / d z`, one row per counted sample.
    pub jacobian: DMatrix<f64>,
    /// Sum of squared errors; `+inf` when a segment's simulation diverges.
    pub cost: f64,
}

impl<'a> Shooting<'a> {
    /// The segments of `segment` samples of `data`'s identification rows,
    /// for modes with the regions of `modes`.
    pub fn new(
        data: &'a PwarxData<'_>,
        modes: &[PwarxMode],
        segment: usize,
    ) -> Result<Self, IdentifyError> {
        let record = data.problem.data;
        let spec = data.spec;
        let stops = &data.priors().saturation[..];
        let lag = spec.lag();
        // Samples of measured initial outputs the model's simulator takes.
        let initial = if stops.is_empty() { lag } else { lag.max(1) };
        let rows = data.regressors.len();
        let segment = segment.max(1);
        let mut segments = Vec::new();
        let mut a = lag;
        while a < lag + rows {
            let b = (a + segment).min(lag + rows);
            let offset = a.saturating_sub(initial);
            let slice = record
                .slice(RowRange {
                    start: Some(offset),
                    end: Some(b),
                })
                .map_err(IdentifyError::Data)?;
            if slice.len() > initial {
                segments.push(Segment {
                    data: slice,
                    offset,
                    first: a - offset,
                });
            }
            a = b;
        }
        Ok(Self {
            spec,
            modes: modes.to_vec(),
            stops,
            segment,
            segments,
            options: SimulationOptions::for_data(record),
        })
    }

    /// Number of segments.
    pub fn segments(&self) -> usize {
        self.segments.len()
    }

    /// The record's samples of segment `i` (measured initial outputs
    /// first) and the index in the record of its first sample.
    pub fn segment_data(&self, i: usize) -> (&Dataset, usize) {
        (&self.segments[i].data, self.segments[i].offset)
    }

    /// The PWARX model of parameters `thetas` with the fixed regions.
    pub fn model(&self, thetas: Vec<Vec<f64>>) -> PwarxModel {
        self.model_of(
            self.modes
                .iter()
                .zip(thetas)
                .map(|(m, theta)| PwarxMode {
                    theta,
                    region: m.region.clone(),
                    name: m.name.clone(),
                })
                .collect(),
        )
    }

    /// The PWARX model of `modes` (parameters and regions) at these
    /// orders.
    fn model_of(&self, modes: Vec<PwarxMode>) -> PwarxModel {
        PwarxModel {
            na: self.spec.na,
            nb: self.spec.nb,
            inputs: self.spec.inputs,
            modes,
            info: ModelInfo::default(),
        }
    }

    /// Simulates every segment at the free variables `z` of `par`.
    pub fn evaluate(&self, par: &Parametrisation, z: &[f64]) -> Result<Evaluation, IdentifyError> {
        let model = self.model(par.thetas(z));
        let automaton = (!self.stops.is_empty())
            .then(|| HybridAutomaton::from_pwarx_with_stops(&model, self.stops));
        let nz = par.n_free();
        let mut samples = Vec::new();
        let mut simulated = Vec::new();
        let mut errors = Vec::new();
        let mut rows: Vec<f64> = Vec::new();
        let mut diverged = false;
        let bad = |e: hysid_model::simulate::SimError| IdentifyError::input(e);
        for seg in &self.segments {
            let (sim, sens) = match &automaton {
                None => {
                    let sim = pwarx_sim::simulate(&model, &seg.data, self.options).map_err(bad)?;
                    let sens = pwarx_sensitivities(&model, par, &seg.data, &sim);
                    (sim, sens)
                }
                Some(a) => {
                    let (sim, trace) =
                        automaton::simulate_traced(a, &seg.data, self.options).map_err(bad)?;
                    let sens = automaton_sensitivities(a, &self.spec, par, &seg.data, &sim, &trace);
                    (sim, sens)
                }
            };
            if sim.diverged_at.is_some() {
                diverged = true;
            }
            let y = seg.data.y();
            for k in seg.first.max(sim.start)..y.len() {
                samples.push(seg.offset + k);
                simulated.push(sim.y[k]);
                errors.push(y[k] - sim.y[k]);
                rows.extend_from_slice(&sens[k * nz..(k + 1) * nz]);
            }
        }
        let errors = DVector::from_vec(errors);
        let cost = if diverged {
            f64::INFINITY
        } else {
            let c = errors.norm_squared();
            if c.is_finite() { c } else { f64::INFINITY }
        };
        let jacobian = DMatrix::from_row_slice(samples.len(), nz, &rows);
        Ok(Evaluation {
            samples,
            simulated,
            errors,
            jacobian,
            cost,
        })
    }
}

/// Adds `d (theta_q . w) / dz` to `out` (`w`: `[phi; 1]`).
fn add_parameter_gradient(par: &Parametrisation, q: usize, w: &[f64], out: &mut [f64]) {
    for (j, wj) in w.iter().enumerate() {
        if let Slot::Free(v) = par.slot(q, j) {
            out[v] += wj;
        }
    }
}

/// `d y_sim(k) / dz` of a PWARX simulation (row `k` of a row-major
/// `len x n_free` array): the output-error sensitivity recursion of the
/// module doc, zero before the simulation starts.
fn pwarx_sensitivities(
    model: &PwarxModel,
    par: &Parametrisation,
    data: &Dataset,
    sim: &Simulation,
) -> Vec<f64> {
    let nz = par.n_free();
    let spec = model.spec();
    let na = spec.na;
    let u: Vec<&[f64]> = (0..spec.inputs).map(|i| data.u(i)).collect();
    let mut sens = vec![0.0; data.len() * nz];
    let mut w = vec![0.0; spec.dim() + 1];
    w[spec.dim()] = 1.0;
    let end = sim.diverged_at.unwrap_or(data.len());
    for k in sim.start..end {
        let Some(q) = sim.modes[k] else { break };
        spec.fill(&sim.y, &u, k, &mut w[..spec.dim()]);
        let (done, rest) = sens.split_at_mut(k * nz);
        let row = &mut rest[..nz];
        add_parameter_gradient(par, q, &w, row);
        let theta = &model.modes[q].theta;
        for i in 1..=na {
            let a = theta[i - 1];
            if a != 0.0 {
                let prev = &done[(k - i) * nz..(k - i + 1) * nz];
                for (r, p) in row.iter_mut().zip(prev) {
                    *r += a * p;
                }
            }
        }
    }
    sens
}

/// `d y_sim(k) / dz` of the discrete-time automaton of a PWARX model with
/// stops, from the trace of its simulation: the state sensitivity goes
/// through each step's condition resets, flow and crossing reset.
fn automaton_sensitivities(
    a: &HybridAutomaton,
    spec: &RegressorSpec,
    par: &Parametrisation,
    data: &Dataset,
    sim: &Simulation,
    trace: &[automaton::DiscreteStep],
) -> Vec<f64> {
    let nz = par.n_free();
    let n = a.states.len();
    let ordinary = par.modes();
    let pos = arx_state_positions(spec);
    let d = spec.dim();
    let mut sens = vec![0.0; data.len() * nz];
    let mut dx = DMatrix::<f64>::zeros(n, nz);
    let mut w = vec![0.0; d + 1];
    w[d] = 1.0;
    let reset = |ti: usize, dx: &DMatrix<f64>| -> DMatrix<f64> {
        let r = &a.transitions[ti].reset.r;
        if r.is_empty() {
            dx.clone()
        } else {
            DMatrix::from_fn(n, n, |i, j| r[i][j]) * dx
        }
    };
    let end = sim.diverged_at.unwrap_or(data.len());
    for (i, step) in trace.iter().enumerate() {
        let k = sim.start + i;
        if k >= end {
            break;
        }
        for &ti in &step.guards {
            dx = reset(ti, &dx);
        }
        let q = step.flow_mode;
        let flow = &a.modes[q].flow;
        let mut next = DMatrix::from_fn(n, n, |r, c| flow.a[r][c]) * &dx;
        if q < ordinary {
            let u_prev: Vec<f64> = (0..spec.inputs).map(|j| data.u(j)[k - 1]).collect();
            for (r, &p) in pos.iter().enumerate() {
                w[r] = if p < n { step.state[p] } else { u_prev[p - n] };
            }
            let mut g = vec![0.0; nz];
            add_parameter_gradient(par, q, &w, &mut g);
            for (v, gv) in g.iter().enumerate() {
                next[(0, v)] += gv;
            }
        }
        if let Some(ti) = step.crossing {
            next = reset(ti, &next);
        }
        dx = next;
        let row = &mut sens[k * nz..(k + 1) * nz];
        for (v, r) in row.iter_mut().enumerate() {
            *r = a
                .output
                .c
                .iter()
                .enumerate()
                .map(|(s, c)| c * dx[(s, v)])
                .sum();
        }
    }
    sens
}

/// A nonlinear least-squares problem for [`levenberg_marquardt`]: the
/// errors and their Jacobian at a point, and the damped linearised step
/// under the problem's constraints.
trait Residuals {
    /// Number of unknowns.
    fn unknowns(&self) -> usize;
    /// Errors, Jacobian and cost at `v`.
    fn evaluate(&self, v: &[f64]) -> Result<Evaluation, IdentifyError>;
    /// `argmin |design v - rhs|^2` under the problem's constraints; `None`
    /// when the subproblem fails (the step is then rejected).
    fn solve(&self, design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>>;
}

/// The mode parameters' problem: the shooting cost over the free
/// variables of the priors' parametrisation, steps solved under its
/// equalities and bounds.
struct ParameterResiduals<'s, 'a> {
    shooting: &'s Shooting<'a>,
    par: &'s Parametrisation,
}

impl Residuals for ParameterResiduals<'_, '_> {
    fn unknowns(&self) -> usize {
        self.par.n_free()
    }

    fn evaluate(&self, z: &[f64]) -> Result<Evaluation, IdentifyError> {
        self.shooting.evaluate(self.par, z)
    }

    fn solve(&self, design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>> {
        constrained::solve_in_z(self.par, design, rhs).ok()
    }
}

/// What [`levenberg_marquardt`] found.
struct Descent {
    /// The unknowns reached (`None` when no step was accepted).
    v: Option<Vec<f64>>,
    /// Solved steps, accepted or not.
    iterations: usize,
    /// The cost at the start (`+inf` when its simulation diverges).
    cost_before: f64,
    /// The cost at the end.
    cost_after: f64,
    /// How it ended.
    status: RefinementStatus,
}

/// Levenberg-Marquardt on `problem` from `v` (see the module doc), at most
/// `max_iterations` solved steps.
fn levenberg_marquardt(
    problem: &dyn Residuals,
    mut v: Vec<f64>,
    max_iterations: usize,
) -> Result<Descent, IdentifyError> {
    let mut current = problem.evaluate(&v)?;
    let mut descent = Descent {
        v: None,
        iterations: 0,
        cost_before: current.cost,
        cost_after: current.cost,
        status: RefinementStatus::IterationLimit,
    };
    if !current.cost.is_finite() {
        descent.status = RefinementStatus::Diverged;
        return Ok(descent);
    }
    let n = problem.unknowns();
    let gram_diagonal = |j: &DMatrix<f64>| {
        (0..j.ncols())
            .map(|c| j.column(c).norm_squared())
            .fold(0.0, f64::max)
    };
    let scale = gram_diagonal(&current.jacobian).max(f64::MIN_POSITIVE);
    let mut mu = 1e-3 * scale;
    let mut nu = 2.0;
    let mut accepted = false;
    while descent.iterations < max_iterations {
        if current.cost == 0.0 || n == 0 {
            descent.status = RefinementStatus::Converged;
            break;
        }
        descent.iterations += 1;
        // [J; sqrt(mu) I] v' = [e + J v; sqrt(mu) v].
        let rows = current.jacobian.nrows();
        let vv = DVector::from_column_slice(&v);
        let target = &current.errors + &current.jacobian * &vv;
        let sm = mu.sqrt();
        let mut design = DMatrix::zeros(rows + n, n);
        design.rows_mut(0, rows).copy_from(&current.jacobian);
        let mut rhs = DVector::zeros(rows + n);
        rhs.rows_mut(0, rows).copy_from(&target);
        for c in 0..n {
            design[(rows + c, c)] = sm;
            rhs[rows + c] = sm * v[c];
        }
        // A failed subproblem is a rejected step: more damping.
        let trial_v = problem.solve(&design, &rhs);
        let trial = match &trial_v {
            Some(t) => {
                let step = DVector::from_iterator(n, t.iter().zip(&v).map(|(a, b)| a - b));
                if step.norm() <= 1e-14 * (vv.norm() + 1e-14) {
                    descent.status = RefinementStatus::Converged;
                    break;
                }
                let predicted =
                    current.cost - (&current.errors - &current.jacobian * &step).norm_squared();
                Some((problem.evaluate(t)?, predicted))
            }
            None => None,
        };
        match (trial, trial_v) {
            (Some((next, predicted)), Some(t)) if next.cost < current.cost => {
                let decrease = current.cost - next.cost;
                let rho = if predicted > 0.0 {
                    decrease / predicted
                } else {
                    0.0
                };
                let relative = decrease / current.cost;
                v = t;
                current = next;
                accepted = true;
                mu *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                nu = 2.0;
                if relative < RELATIVE_TOLERANCE {
                    descent.status = RefinementStatus::Converged;
                    break;
                }
            }
            _ => {
                mu *= nu;
                nu *= 2.0;
                if !mu.is_finite() || mu > 1e16 * scale {
                    descent.status = RefinementStatus::NoDescent;
                    break;
                }
            }
        }
    }
    descent.cost_after = current.cost;
    descent.v = accepted.then_some(v);
    Ok(descent)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pwarx;
    use hysid_core::backend::Problem;
    use hysid_core::model::Model;
    use hysid_core::priors::Priors;
    use hysid_model::data::Signal;
    use hysid_model::geometry::Polyhedron;
    use hysid_model::model::{RegionRefinementStatus, Stop, StopBound};
    use proptest::prelude::*;

    /// The true modes: `y(k) = a y(k-1) + b u(k-1) + c`, mode 0 where
    /// `y(k-1) <= 0`, mode 1 where `y(k-1) >= 0`; continuous across the
    /// boundary (a discontinuous PWARX map makes the simulation error
    /// discontinuous in the parameters, and a local method stalls at the
    /// jumps).
    const TRUTH: [[f64; 3]; 2] = [[0.6, 1.0, 0.1], [0.3, 1.0, 0.1]];

    fn regions() -> [Polyhedron; 2] {
        [
            Polyhedron::from_inequalities(vec![vec![1.0, 0.0]], vec![0.0]),
            Polyhedron::from_inequalities(vec![vec![-1.0, 0.0]], vec![0.0]),
        ]
    }

    fn modes(thetas: &[[f64; 3]]) -> Vec<PwarxMode> {
        thetas
            .iter()
            .zip(regions())
            .map(|(t, region)| PwarxMode {
                theta: t.to_vec(),
                region,
                name: None,
            })
            .collect()
    }

    fn record(u: Vec<f64>, y: Vec<f64>) -> Dataset {
        Dataset::new(
            vec![Signal {
                name: "u".into(),
                values: u,
            }],
            Signal {
                name: "y".into(),
                values: y,
            },
            None,
        )
        .unwrap()
    }

    /// The noise-free record of `model` (or of its automaton with `stops`)
    /// driven by a seeded input.
    pub(super) fn simulated_record(
        model: &PwarxModel,
        stops: &[Stop],
        n: usize,
        seed: u64,
    ) -> Dataset {
        let u = hysid_testkit::uniform(n, seed);
        let blank = record(u.clone(), vec![0.0; n]);
        let sim = if stops.is_empty() {
            pwarx_sim::simulate(model, &blank, SimulationOptions::default()).unwrap()
        } else {
            let a = HybridAutomaton::from_pwarx_with_stops(model, stops);
            automaton::simulate(&a, &blank, SimulationOptions::default()).unwrap()
        };
        record(u, sim.y)
    }

    fn true_model() -> PwarxModel {
        PwarxModel {
            na: 1,
            nb: 1,
            inputs: 1,
            modes: modes(&TRUTH),
            info: ModelInfo::default(),
        }
    }

    pub(super) fn problem<'a>(data: &'a Dataset, priors: &'a Priors) -> Problem<'a> {
        Problem {
            data,
            orders: RegressorSpec::new(1, 1, 1),
            priors,
            priors_origin: None,
        }
    }

    fn start_fit(thetas: Vec<Vec<f64>>) -> PwarxFit<()> {
        PwarxFit::complete(PwarxMode::unnamed(thetas, regions()), ())
    }

    fn sim_settings(segment: usize, iterations: usize) -> Stages {
        Stages {
            trim: None,
            refine: Refine::Sim,
            refine_segment: segment,
            refine_iterations: iterations,
        }
    }

    fn perturbed() -> Vec<Vec<f64>> {
        vec![vec![0.55, 1.08, 0.15], vec![0.36, 0.93, 0.05]]
    }

    /// From perturbed parameters, on a noise-free record with the true
    /// regions, refinement recovers the true parameters to 1e-6, with
    /// multiple shooting and with one free-run segment.
    #[test]
    fn noise_free_record_gives_the_true_parameters() {
        let data = simulated_record(&true_model(), &[], 600, 7);
        let priors = Priors::default();
        let problem = problem(&data, &priors);
        let prepared = pwarx::prepare(&problem, "test").unwrap();
        for segment in [50, 10_000] {
            let fit = refine(
                &prepared,
                start_fit(perturbed()),
                &sim_settings(segment, 100),
            )
            .unwrap();
            let r = fit.refinement.clone().unwrap();
            assert!(
                matches!(
                    r.status,
                    RefinementStatus::Converged | RefinementStatus::NoDescent
                ),
                "{r:?}"
            );
            assert!(
                r.cost_after.unwrap() < 1e-12 * r.cost_before.unwrap(),
                "{r:?}"
            );
            for (m, t) in fit.modes.iter().zip(TRUTH) {
                for (g, w) in m.theta.iter().zip(t) {
                    assert!((g - w).abs() < 1e-6, "segment {segment}: {:?}", fit.modes);
                }
            }
            assert_eq!(fit.modes[0].region, regions()[0]);
        }
    }

    /// `refine = none` returns the fit untouched.
    #[test]
    fn none_leaves_the_fit_alone() {
        let data = simulated_record(&true_model(), &[], 100, 3);
        let priors = Priors::default();
        let problem = problem(&data, &priors);
        let prepared = pwarx::prepare(&problem, "test").unwrap();
        let fit = refine(&prepared, start_fit(perturbed()), &Stages::default()).unwrap();
        assert!(fit.refinement.is_none());
        assert_eq!(fit.modes[0].theta, perturbed()[0]);
    }

    fn stop() -> Stop {
        Stop {
            level: 0.5,
            bound: StopBound::Max,
            tol: None,
        }
    }

    /// The outputs the objective uses are those of the model's own
    /// simulator for the model `assemble` writes (a PWARX model, and with a
    /// stop the automaton), segment by segment, bit for bit; refinement
    /// never raises the cost; and the sensitivities match central finite
    /// differences of the simulation.
    #[test]
    fn objective_is_the_simulation_error_of_the_written_model() {
        for stops in [vec![], vec![stop()]] {
            let priors = Priors {
                saturation: stops.clone(),
                ..Default::default()
            };
            let data = simulated_record(&true_model(), &stops, 400, 11);
            if !stops.is_empty() {
                let held = data.y().iter().filter(|&&v| v == 0.5).count();
                assert!(
                    held > 10,
                    "the record should sit at the stop: {held} samples"
                );
            }
            let problem = problem(&data, &priors);
            let prepared = pwarx::prepare(&problem, "test").unwrap();
            let par = Parametrisation::from_priors(&priors, &prepared.spec, 2).unwrap();
            let start = start_fit(perturbed());
            let shooting = Shooting::new(&prepared, &start.modes, 60).unwrap();
            assert_eq!(shooting.segments(), 7);
            let z = par.free_values(&perturbed()).unwrap();
            let ev = shooting.evaluate(&par, &z).unwrap();
            assert!(ev.cost.is_finite() && ev.cost > 0.0);
            // The model assemble writes, simulated on each segment.
            let model = pwarx::assemble(&prepared, start_fit(perturbed()));
            let mut at = 0;
            for i in 0..shooting.segments() {
                let (seg, offset) = shooting.segment_data(i);
                let sim = match &model {
                    Model::Pwarx(m) => {
                        assert!(stops.is_empty());
                        pwarx_sim::simulate(m, seg, shooting.options).unwrap()
                    }
                    Model::HybridAutomaton(a) => {
                        assert!(!stops.is_empty());
                        automaton::simulate(a, seg, shooting.options).unwrap()
                    }
                    other => panic!("unexpected model kind {}", other.kind()),
                };
                while at < ev.samples.len() && ev.samples[at] < offset + seg.len() {
                    let k = ev.samples[at] - offset;
                    assert!(k >= sim.start);
                    assert_eq!(
                        ev.simulated[at].to_bits(),
                        sim.y[k].to_bits(),
                        "segment {i}, sample {k}"
                    );
                    at += 1;
                }
            }
            assert_eq!(at, ev.samples.len());
            assert_eq!(ev.samples.len(), prepared.regressors.len());
            // Sensitivities against central differences.
            let h = 1e-6;
            for v in 0..z.len() {
                let mut zp = z.clone();
                zp[v] += h;
                let mut zm = z.clone();
                zm[v] -= h;
                let (p, m) = (
                    shooting.evaluate(&par, &zp).unwrap(),
                    shooting.evaluate(&par, &zm).unwrap(),
                );
                for r in 0..ev.samples.len() {
                    let fd = (p.simulated[r] - m.simulated[r]) / (2.0 * h);
                    let an = ev.jacobian[(r, v)];
                    assert!(
                        (fd - an).abs() <= 1e-5 * (1.0 + an.abs()),
                        "stops {}: z[{v}], sample {}: {an} vs {fd}",
                        stops.len(),
                        ev.samples[r]
                    );
                }
            }
            // Refinement lowers the cost, and the written cost is the
            // objective at the refined parameters.
            let fit = refine(&prepared, start_fit(perturbed()), &sim_settings(60, 30)).unwrap();
            let r = fit.refinement.clone().unwrap();
            assert!(r.cost_after.unwrap() <= r.cost_before.unwrap(), "{r:?}");
            assert!(
                r.cost_after.unwrap() < 1e-3 * r.cost_before.unwrap(),
                "{r:?}"
            );
            let thetas: Vec<Vec<f64>> = fit.modes.iter().map(|m| m.theta.clone()).collect();
            let after = shooting
                .evaluate(&par, &par.free_values(&thetas).unwrap())
                .unwrap();
            assert!((after.cost - r.cost_after.unwrap()).abs() <= 1e-12 * (1.0 + after.cost));
            let written = pwarx::assemble(&prepared, fit);
            let text = serde_json::to_string(&written.info().diagnostics).unwrap();
            assert!(text.contains("\"refinement\":{"), "{text}");
        }
    }

    /// A start whose simulation diverges is left as it is.
    #[test]
    fn diverging_start_is_kept() {
        let data = simulated_record(&true_model(), &[], 300, 5);
        let priors = Priors::default();
        let problem = problem(&data, &priors);
        let prepared = pwarx::prepare(&problem, "test").unwrap();
        let wild = vec![vec![3.0, 1.0, 0.3], vec![3.0, 0.8, -0.2]];
        let fit = refine(
            &prepared,
            start_fit(wild.clone()),
            &sim_settings(10_000, 20),
        )
        .unwrap();
        let r = fit.refinement.unwrap();
        assert_eq!(r.status, RefinementStatus::Diverged);
        assert_eq!(r.cost_before, None);
        assert_eq!(fit.modes[0].theta, wild[0]);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

        /// Random ties, fixed values, bounds and equalities: after
        /// refinement they hold to 1e-9 (ties and fixed values bit for
        /// bit), and the cost did not rise.
        #[test]
        fn priors_hold_after_refinement(
            move_regions in any::<bool>(),
            with_tie in any::<bool>(),
            fixed_c in prop::option::of(-0.3f64..0.3),
            lo in 0.0f64..1.0,
            width in 0.05f64..1.0,
            value in 0.8f64..1.6,
            eq_c in -1.0f64..1.0,
            seed in 0u64..1000,
        ) {
            let constraints = crate::fixtures::ConstraintPriors {
                terms: &[("a1", 1.0), ("b1", 1.0)],
                eq_c,
                value,
                lo,
                width,
                tied: with_tie.then_some("a1"),
                fixed_c,
            };
            let priors = constraints.priors();
            let data = simulated_record(&true_model(), &[], 300, seed);
            let problem = problem(&data, &priors);
            let prepared = pwarx::prepare(&problem, "test").unwrap();
            let par = Parametrisation::from_priors(&priors, &prepared.spec, 2).unwrap();
            // A back-end's fit satisfies the priors: the projection of a
            // perturbed truth.
            let start = match par.project(&perturbed()) {
                Ok(t) => t,
                Err(_) => return Ok(()), // bounds and equality without a common point
            };
            let settings = Stages {
                refine: if move_regions { Refine::SimRegions } else { Refine::Sim },
                ..sim_settings(40, 15)
            };
            let fit = refine(&prepared, start_fit(start), &settings).unwrap();
            let r = fit.refinement.clone().unwrap();
            if let (Some(b), Some(a)) = (r.cost_before, r.cost_after) {
                prop_assert!(a <= b, "{:?}", r);
            }
            if let Some(g) = &r.regions {
                prop_assert!(move_regions);
                if let (Some(b), Some(a)) = (g.cost_before, g.cost_after)
                    && g.status == RegionRefinementStatus::Moved
                {
                    prop_assert!(a < b, "{:?}", g);
                }
            }
            let thetas: Vec<Vec<f64>> = fit.modes.iter().map(|m| m.theta.clone()).collect();
            let broken = constraints.broken(&prepared.spec.param_names(), &thetas);
            prop_assert!(broken.is_none(), "{}", broken.unwrap_or_default());
        }
    }
}
