//! The multiple-shooting simulation error of a PWARX fit with fixed
//! regions, and its sensitivities (the recursions of the module doc of
//! [`super`]): what both stages of the refinement minimise.

use crate::constrained::{Parametrisation, Slot};
use crate::pwarx::prepare::PwarxData;
use hysid_core::backend::IdentifyError;
use hysid_model::data::{Dataset, RowRange};
use hysid_model::model::{HybridAutomaton, ModelInfo, PwarxMode, PwarxModel, arx_state_positions};
use hysid_model::regressors::RegressorSpec;
use hysid_model::simulate::{Simulation, SimulationOptions, automaton, pwarx as pwarx_sim};
use hysid_numerics::least_squares;
use nalgebra::{DMatrix, DVector};

/// One shooting segment: the record's samples `offset ..`, of which those
/// from `first` (in segment indices) on are counted in the cost; the ones
/// before are the measured initial outputs.
#[derive(Debug, Clone)]
pub(super) struct Segment {
    pub(super) data: Dataset,
    pub(super) offset: usize,
    pub(super) first: usize,
}

/// The multiple-shooting simulation error of a PWARX fit with fixed
/// regions under a parametrisation: simulated outputs, errors, cost and
/// sensitivities.
#[derive(Debug, Clone)]
pub struct Shooting<'a> {
    pub(super) spec: RegressorSpec,
    pub(super) modes: Vec<PwarxMode>,
    pub(super) stops: &'a [hysid_model::model::Stop],
    pub(super) segment: usize,
    pub(super) segments: Vec<Segment>,
    pub(super) options: SimulationOptions,
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
    /// for modes with the regions of `modes`; each record of a joined
    /// dataset is cut on its own.
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
        let segment = segment.max(1);
        let mut segments = Vec::new();
        // Segments of each record's regressor samples; none spans two
        // records.
        for range in record.record_ranges() {
            let mut a = range.start + lag;
            while a < range.end {
                let b = (a + segment).min(range.end);
                let offset = a.saturating_sub(initial).max(range.start);
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
    pub(super) fn model_of(&self, modes: Vec<PwarxMode>) -> PwarxModel {
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
        // An upper bound: a segment counts from `first` on at the earliest.
        let counted = self
            .segments
            .iter()
            .map(|seg| seg.data.len().saturating_sub(seg.first))
            .sum();
        let mut samples = Vec::with_capacity(counted);
        let mut simulated = Vec::with_capacity(counted);
        let mut errors = Vec::with_capacity(counted);
        let mut jacobian = JacobianRows::new(counted, nz);
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
                jacobian.push(&sens[k * nz..(k + 1) * nz]);
            }
        }
        let errors = DVector::from_vec(errors);
        let cost = if diverged {
            f64::INFINITY
        } else {
            let c = errors.norm_squared();
            if c.is_finite() { c } else { f64::INFINITY }
        };
        Ok(Evaluation {
            samples,
            simulated,
            errors,
            jacobian: jacobian.finish(),
            cost,
        })
    }
}

/// A Jacobian gathered row by row, one row per counted sample, written
/// straight into its column-major storage. The rows planned are an upper
/// bound on the rows pushed (the counted samples of every segment).
pub(super) struct JacobianRows {
    matrix: DMatrix<f64>,
    filled: usize,
}

impl JacobianRows {
    /// Room for `rows` rows of `columns` entries.
    pub(super) fn new(rows: usize, columns: usize) -> Self {
        JacobianRows {
            matrix: DMatrix::zeros(rows, columns),
            filled: 0,
        }
    }

    /// Appends `row` (`columns` entries); rows past the planned number are
    /// dropped.
    pub(super) fn push(&mut self, row: &[f64]) {
        let rows = self.matrix.nrows();
        if self.filled == rows {
            return;
        }
        let at = self.filled;
        for (column, value) in self.matrix.as_mut_slice().chunks_mut(rows).zip(row) {
            column[at] = *value;
        }
        self.filled += 1;
    }

    /// The rows appended.
    pub(super) fn finish(self) -> DMatrix<f64> {
        if self.filled == self.matrix.nrows() {
            self.matrix
        } else {
            self.matrix.rows(0, self.filled).into_owned()
        }
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

impl From<Evaluation> for least_squares::Evaluation {
    fn from(e: Evaluation) -> Self {
        least_squares::Evaluation {
            errors: e.errors,
            jacobian: Some(e.jacobian),
            cost: e.cost,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::JacobianRows;
    use nalgebra::DMatrix;

    #[test]
    fn rows_pushed_form_the_row_major_matrix_cut_to_the_rows_given() {
        let rows = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]];
        let mut planned = JacobianRows::new(4, 3);
        for row in &rows {
            planned.push(row);
        }
        let expected = DMatrix::from_row_slice(2, 3, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(planned.finish(), expected);
        let mut exact = JacobianRows::new(1, 3);
        exact.push(&rows[0]);
        exact.push(&rows[1]);
        assert_eq!(
            exact.finish(),
            DMatrix::from_row_slice(1, 3, &[1.0, 2.0, 3.0])
        );
        assert_eq!(JacobianRows::new(0, 3).finish().nrows(), 0);
    }
}
