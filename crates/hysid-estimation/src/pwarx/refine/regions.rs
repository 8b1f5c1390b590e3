//! The second stage of `refine = sim_regions`: the region boundaries of a
//! PWARX fit moved to lower the multiple-shooting simulation error.
//!
//! The regions of an argmax partition are `{x : f_i(x) >= f_j(x)}` for
//! affine scores `f_i(x) = g_i . [x; 1]`
//! ([`hysid_model::geometry::argmax_regions`]). The mode a hard partition
//! picks is piecewise constant in `g`, so the simulation error has no
//! useful derivative in the boundaries. The relaxation replaces the hard
//! choice by a softmax gate of sharpness `beta`, the mixture of experts of
//! Jordan and Jacobs (*Neural Computation* 6(2), 1994):
//!
//! ```text
//! y_sim(k) = sum_i p_i(k) e_i(k),   e_i(k) = theta_i . [x(k); 1],
//! p_i(k) = exp(beta f_i(x(k))) / sum_j exp(beta f_j(x(k)))
//! ```
//!
//! with `x(k)` the simulated regressor. With the mode parameters fixed,
//! Levenberg-Marquardt minimises the shooting cost of this smooth model
//! over the scores' entries (the `switching` columns and the offset).
//! Mode 0's scores stay fixed (the gate is invariant to a common shift)
//! and the norm of the others' entries on the regressors is held (the
//! unknowns are normalised), so the gate cannot make itself softer than
//! `beta` says: only the boundaries move. The sensitivities follow the
//! simulation as in the first stage (then through the normalisation):
//!
//! ```text
//! dy(k)/dg_ic = beta p_i (e_i - y(k)) [x(k); 1]_c
//!             + sum_l alpha_l(k) dy(k-l)/dg_ic,
//! alpha_l = sum_i p_i a_{i,l} + beta sum_i p_i (e_i - y(k)) g_{i,l}
//! ```
//!
//! (`a_{i,l}` and `g_{i,l}` the entries of mode `i` on the regressor
//! `y(k-l)`). The gate is sharpened by continuation over
//! [`SHARPNESS`], each level started from the last; after each level the
//! gate is hardened (its argmax partition) and the hard model's shooting
//! cost computed. The best hardened partition gets its mode parameters
//! refined as in the first stage; from the new parameters and regions the
//! gate is relaxed again, for at most [`ROUNDS`] rounds while the hard cost
//! falls. The result replaces the back-end's regions only when the hard
//! model simulates the identification rows with a lower cost than before
//! this stage; otherwise nothing changes
//! ([`RegionRefinementStatus::NoGain`]). The regions stay a complete
//! partition: an argmax partition covers the space.
//!
//! At the start of each round the scores are scaled so that the median
//! gap between the largest and the second largest score over the
//! identification regressors is 1:
//! at `beta = 1` a typical sample is then weighted about 0.73 to its own
//! mode, at `beta = 10` nearly 1.

use super::parameters::fit_parameters;
use super::shooting::{Evaluation, JacobianRows, Shooting};
use crate::pwarx::assemble::PwarxFit;
use crate::pwarx::prepare::PwarxData;
use hysid_core::backend::{Deadline, IdentifyError};
use hysid_core::stages::Stages;
use hysid_model::geometry::{argmax_regions, argmax_scores};
use hysid_model::model::{PwarxMode, RegionRefinement, RegionRefinementStatus};
use hysid_model::simulate::pwarx as pwarx_sim;
use hysid_model::statistics::upper_median;
use hysid_numerics::least_squares::{self, LeastSquares, LmSettings, Stop, levenberg_marquardt};
use nalgebra::{DMatrix, DVector};

/// Bound on the rounds of relaxed gate and mode parameters in turn.
pub const ROUNDS: usize = 5;

/// The gate sharpness levels of the continuation, in order.
pub const SHARPNESS: [f64; 3] = [1.0, 10.0, 100.0];

/// Moves the regions of `fit` (see the module doc), refining its mode
/// parameters under the moved regions, no descent step begun after
/// `deadline`; the outcome.
pub(super) fn move_regions<D>(
    data: &PwarxData<'_>,
    fit: &mut PwarxFit<D>,
    settings: &Stages,
    deadline: &Deadline,
) -> Result<RegionRefinement, IdentifyError> {
    let d = data.spec.dim();
    if fit.modes.len() < 2 {
        return Ok(RegionRefinement::skipped(RegionRefinementStatus::OneMode));
    }
    if data.stops() > 0 {
        return Ok(RegionRefinement::skipped(RegionRefinementStatus::WithStops));
    }
    let regions: Vec<_> = fit.modes.iter().map(|m| m.region.clone()).collect();
    let Some(scores) = argmax_scores(&regions, d) else {
        return Ok(RegionRefinement::skipped(RegionRefinementStatus::NotArgmax));
    };
    let shooting = Shooting::new(data, &fit.modes, settings.refine_segment)?;
    let before = shooting.hard_cost(&fit.modes)?;
    if !before.is_finite() {
        return Ok(RegionRefinement::skipped(RegionRefinementStatus::Diverged));
    }
    let start = scaled_to_unit_gap(scores, &data.regressors.x);
    let columns = data.switching.clone().unwrap_or_else(|| (0..d).collect());
    let mut outcome = RegionRefinement {
        cost_before: Some(before),
        ..RegionRefinement::skipped(RegionRefinementStatus::NoGain)
    };
    let (mut modes, mut scores, mut cost) = (fit.modes.clone(), start.clone(), before);
    for _ in 0..ROUNDS {
        let thetas: Vec<Vec<f64>> = modes.iter().map(|m| m.theta.clone()).collect();
        let mut gate = RelaxedGate::new(&shooting, &thetas, &scores, columns.clone());
        let hardened = sharpen(&mut gate, &modes, settings, deadline, &mut outcome)?;
        let Some(hardened) = hardened else { break };
        let mut next = with_regions(&modes, &hardened.scores);
        outcome.parameter_iterations +=
            fit_parameters(data, &mut next, settings, deadline)?.iterations;
        let next_cost = shooting.hard_cost(&next)?;
        if next_cost >= cost {
            break;
        }
        (modes, scores, cost) = (
            next,
            scaled_to_unit_gap(hardened.scores, &data.regressors.x),
            next_cost,
        );
        outcome.sharpness = Some(hardened.sharpness);
    }
    if cost < before {
        outcome.status = RegionRefinementStatus::Moved;
        outcome.cost_after = Some(cost);
        outcome.moved_samples = moved_samples(&start, &scores, &data.regressors.x);
        fit.modes = modes;
        fit.regions_complete = true;
        fit.uncovered_fraction = None;
    }
    Ok(outcome)
}

/// A hardened gate: its scores, the sharpness it was relaxed at and the
/// hard model's shooting cost.
struct Hardened {
    scores: Vec<Vec<f64>>,
    sharpness: f64,
    cost: f64,
}

/// The continuation over [`SHARPNESS`]: at each level the relaxed gate's
/// Levenberg-Marquardt from the last level's gate, then its hardening into
/// regions for `modes` (the parameters the gate was relaxed with). The
/// hardened gate of least hard cost (`None` when every one diverges); the
/// descents' iterations and ends added to `outcome`.
fn sharpen(
    gate: &mut RelaxedGate<'_, '_>,
    modes: &[PwarxMode],
    settings: &Stages,
    deadline: &Deadline,
    outcome: &mut RegionRefinement,
) -> Result<Option<Hardened>, IdentifyError> {
    let mut v = gate.unknowns_of(&gate.base);
    let mut best: Option<Hardened> = None;
    for sharpness in SHARPNESS {
        gate.sharpness = sharpness;
        let descent = levenberg_marquardt(
            gate,
            v.clone(),
            &LmSettings::new(settings.refine_iterations),
            deadline,
        )?;
        outcome.gate_iterations += descent.iterations;
        outcome.gate_descents += 1;
        if descent.stop == Stop::IterationLimit {
            outcome.gate_descents_at_bound += 1;
        }
        if let Some(next) = descent.v {
            v = next;
        }
        let scores = gate.scores(&v);
        let cost = gate.shooting.hard_cost(&with_regions(modes, &scores))?;
        if cost.is_finite() && best.as_ref().is_none_or(|b| cost < b.cost) {
            best = Some(Hardened {
                scores,
                sharpness,
                cost,
            });
        }
    }
    Ok(best)
}

/// `scores` divided by the median, over the rows of `x`, of the gap
/// between the largest and the second largest score (unchanged when that
/// median is not positive).
fn scaled_to_unit_gap(scores: Vec<Vec<f64>>, x: &DMatrix<f64>) -> Vec<Vec<f64>> {
    let mut gaps: Vec<f64> = (0..x.nrows())
        .map(|r| {
            let row: Vec<f64> = x.row(r).iter().copied().collect();
            let mut f: Vec<f64> = scores.iter().map(|g| score(g, &row)).collect();
            f.sort_by(|a, b| b.total_cmp(a));
            f[0] - f[1]
        })
        .filter(|g| g.is_finite())
        .collect();
    let Some(median) = upper_median(&mut gaps) else {
        return scores;
    };
    if !(median > 0.0 && median.is_finite()) {
        return scores;
    }
    scores
        .into_iter()
        .map(|g| g.into_iter().map(|c| c / median).collect())
        .collect()
}

/// `g . [x; 1]`.
fn score(g: &[f64], x: &[f64]) -> f64 {
    let d = x.len();
    g[..d].iter().zip(x).map(|(a, b)| a * b).sum::<f64>() + g[d]
}

/// Below this `libm::exp` returns `0.0` (its underflow test).
const EXP_UNDERFLOW: f64 = -745.133_219_101_941_1;

/// `libm::exp(x)` for `x <= 0`, the difference of a score from the
/// largest, bit for bit: the largest score's own `exp(0) = 1` and the
/// underflow to zero are answered without evaluating the exponential.
fn gate_weight(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else if x < EXP_UNDERFLOW {
        0.0
    } else {
        libm::exp(x)
    }
}

/// The mode of largest score at `x` (the first on a tie).
fn argmax(scores: &[Vec<f64>], x: &[f64]) -> usize {
    let mut best = 0;
    let mut top = f64::NEG_INFINITY;
    for (i, g) in scores.iter().enumerate() {
        let f = score(g, x);
        if f > top {
            top = f;
            best = i;
        }
    }
    best
}

/// Rows of `x` whose argmax mode differs between `old` and `new`.
fn moved_samples(old: &[Vec<f64>], new: &[Vec<f64>], x: &DMatrix<f64>) -> usize {
    (0..x.nrows())
        .filter(|&r| {
            let row: Vec<f64> = x.row(r).iter().copied().collect();
            argmax(old, &row) != argmax(new, &row)
        })
        .count()
}

/// `modes` with the argmax regions of `scores`.
fn with_regions(modes: &[PwarxMode], scores: &[Vec<f64>]) -> Vec<PwarxMode> {
    modes
        .iter()
        .zip(argmax_regions(scores))
        .map(|(m, region)| PwarxMode {
            region,
            ..m.clone()
        })
        .collect()
}

impl Shooting<'_> {
    /// The shooting cost of the PWARX model of `modes` (their own
    /// regions), without sensitivities: `+inf` when a segment's simulation
    /// diverges.
    fn hard_cost(&self, modes: &[PwarxMode]) -> Result<f64, IdentifyError> {
        let model = self.model_of(modes.to_vec());
        let mut cost = 0.0;
        for seg in &self.segments {
            let sim = pwarx_sim::simulate(&model, &seg.data, self.options)
                .map_err(IdentifyError::input)?;
            if sim.diverged_at.is_some() {
                return Ok(f64::INFINITY);
            }
            let y = seg.data.y();
            cost += (seg.first.max(sim.start)..y.len())
                .map(|k| (y[k] - sim.y[k]).powi(2))
                .sum::<f64>();
        }
        Ok(if cost.is_finite() {
            cost
        } else {
            f64::INFINITY
        })
    }
}

/// The relaxed model's shooting cost as a function of the gate's free
/// entries, the mode parameters fixed (see the module doc). The unknowns
/// are, mode by mode, the entries on `columns` and the offset.
struct RelaxedGate<'s, 'a> {
    shooting: &'s Shooting<'a>,
    thetas: &'s [Vec<f64>],
    /// The scores the unknowns overwrite (entries outside `columns` stay).
    base: Vec<Vec<f64>>,
    /// Regressor columns the gate may use (`switching`).
    columns: Vec<usize>,
    /// The scores are `sharpness * norm / |v_N|` times the unknowns `v`
    /// (`|v_N|` the norm of their entries on the regressor columns), so
    /// that their size is fixed and only the boundaries move.
    sharpness: f64,
    /// `|v_N|` of the starting scores: at sharpness 1 they are the
    /// starting scores.
    norm: f64,
}

impl<'s, 'a> RelaxedGate<'s, 'a> {
    /// The gate of `scores` for the modes of parameters `thetas`, at the
    /// first sharpness level.
    fn new(
        shooting: &'s Shooting<'a>,
        thetas: &'s [Vec<f64>],
        scores: &[Vec<f64>],
        columns: Vec<usize>,
    ) -> Self {
        let mut gate = RelaxedGate {
            shooting,
            thetas,
            base: scores.to_vec(),
            columns,
            sharpness: SHARPNESS[0],
            norm: 1.0,
        };
        gate.norm = gate.normal_norm(&gate.unknowns_of(scores));
        gate
    }

    /// Unknowns per mode.
    fn block(&self) -> usize {
        self.columns.len() + 1
    }

    /// The unknowns of `scores` (mode 0's scores stay as they are: the
    /// gate is invariant to a common shift of the scores).
    fn unknowns_of(&self, scores: &[Vec<f64>]) -> Vec<f64> {
        let d = self.shooting.spec.dim();
        scores[1..]
            .iter()
            .flat_map(|g| self.columns.iter().map(|&c| g[c]).chain([g[d]]))
            .collect()
    }

    /// `|v_N|`: the norm of the entries of `v` on the regressor columns.
    fn normal_norm(&self, v: &[f64]) -> f64 {
        let normals = self.columns.len();
        v.chunks(self.block())
            .flat_map(|block| &block[..normals])
            .map(|x| x * x)
            .sum::<f64>()
            .sqrt()
    }

    /// The factor from the unknowns `v` to the scores.
    fn factor(&self, v: &[f64]) -> f64 {
        let n = self.normal_norm(v);
        if n > 0.0 {
            self.sharpness * self.norm / n
        } else {
            self.sharpness
        }
    }

    /// The scores of the unknowns `v`.
    fn scores(&self, v: &[f64]) -> Vec<Vec<f64>> {
        let d = self.shooting.spec.dim();
        let factor = self.factor(v);
        let fixed = self.base[0].iter().map(|x| factor * x).collect();
        let free = self.base[1..]
            .iter()
            .zip(v.chunks(self.block()))
            .map(|(g, block)| {
                let mut g = g.clone();
                for (&c, value) in self.columns.iter().zip(block) {
                    g[c] = factor * value;
                }
                g[d] = factor * block[self.columns.len()];
                g
            });
        std::iter::once(fixed).chain(free).collect()
    }

    /// Row `r` of `d y / d s` (the scores' entries in unknown order) turned
    /// into `d y / d v`: with `s = k v / n`, `k` the sharpness times
    /// [`Self::norm`] and `n = |v_N|` ([`Self::normal_norm`] of `v`),
    /// `dy/dv_j = (k / n) dy/ds_j - (k / n^3) [j in N] v_j (v . dy/ds)`.
    fn chain(&self, v: &[f64], n: f64, row: &mut [f64]) {
        if n <= 0.0 {
            for r in row.iter_mut() {
                *r *= self.sharpness;
            }
            return;
        }
        let k = self.sharpness * self.norm;
        let along: f64 = v.iter().zip(row.iter()).map(|(a, b)| a * b).sum();
        let normals = self.columns.len();
        for (block, v) in row.chunks_mut(self.block()).zip(v.chunks(self.block())) {
            for r in block[normals..].iter_mut() {
                *r *= k / n;
            }
            for (r, vj) in block[..normals].iter_mut().zip(v) {
                *r *= k / n;
                *r -= k / (n * n * n) * vj * along;
            }
        }
    }

    /// The relaxed simulation of one segment and `d y_sim(k) / dv`
    /// (row-major, `len x unknowns`); `None` when it diverges.
    fn simulate(
        &self,
        seg: &super::shooting::Segment,
        scores: &[Vec<f64>],
    ) -> Option<(Vec<f64>, Vec<f64>)> {
        let spec = self.shooting.spec;
        let (d, na, lag) = (spec.dim(), spec.na, spec.lag());
        let nv = self.unknowns();
        let block = self.block();
        let data = &seg.data;
        let u: Vec<&[f64]> = (0..spec.inputs).map(|i| data.u(i)).collect();
        let mut y = data.y().to_vec();
        let mut sens = vec![0.0; data.len() * nv];
        let mut w = vec![1.0; d + 1];
        let s = scores.len();
        let (mut p, mut e) = (vec![0.0; s], vec![0.0; s]);
        let mut alpha = vec![0.0; na];
        let mut f = vec![0.0; s];
        for k in lag..data.len() {
            spec.fill(&y, &u, k, &mut w[..d]);
            for (fi, g) in f.iter_mut().zip(scores) {
                *fi = score(g, &w[..d]);
            }
            let top = f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let mut total = 0.0;
            for i in 0..s {
                p[i] = gate_weight(f[i] - top);
                total += p[i];
                e[i] = self.thetas[i].iter().zip(&w).map(|(a, b)| a * b).sum();
            }
            let mut mean = 0.0;
            for i in 0..s {
                p[i] /= total;
                mean += p[i] * e[i];
            }
            if !(mean.is_finite() && mean.abs() <= self.shooting.options.bound) {
                return None;
            }
            y[k] = mean;
            let (done, rest) = sens.split_at_mut(k * nv);
            let row = &mut rest[..nv];
            alpha.fill(0.0);
            for i in 0..s {
                let spread = p[i] * (e[i] - mean);
                if i > 0 {
                    let at = (i - 1) * block;
                    for (j, &c) in self.columns.iter().enumerate() {
                        row[at + j] += spread * w[c];
                    }
                    row[at + self.columns.len()] += spread;
                }
                for (l, a) in alpha.iter_mut().enumerate() {
                    *a += p[i] * self.thetas[i][l] + spread * scores[i][l];
                }
            }
            for (l, &a) in alpha.iter().enumerate() {
                if a != 0.0 && k > l {
                    let prev = &done[(k - l - 1) * nv..(k - l) * nv];
                    for (r, q) in row.iter_mut().zip(prev) {
                        *r += a * q;
                    }
                }
            }
        }
        Some((y, sens))
    }
}

impl RelaxedGate<'_, '_> {
    /// Number of unknowns: the scores of every mode but the last.
    fn unknowns(&self) -> usize {
        (self.thetas.len() - 1) * self.block()
    }

    /// The simulation of every segment with the relaxed gate at `v`.
    fn shooting_cost(&self, v: &[f64]) -> Result<Evaluation, IdentifyError> {
        let scores = self.scores(v);
        let norm = self.normal_norm(v);
        let nv = self.unknowns();
        let lag = self.shooting.spec.lag();
        let first = |seg: &super::shooting::Segment| seg.first.max(lag);
        let counted = self
            .shooting
            .segments
            .iter()
            .map(|seg| seg.data.len().saturating_sub(first(seg)))
            .sum();
        let mut jacobian = JacobianRows::new(counted, nv);
        let (mut samples, mut simulated, mut errors) = (
            Vec::with_capacity(counted),
            Vec::with_capacity(counted),
            Vec::with_capacity(counted),
        );
        let mut diverged = false;
        for seg in &self.shooting.segments {
            let measured = seg.data.y();
            let Some((y, mut sens)) = self.simulate(seg, &scores) else {
                diverged = true;
                continue;
            };
            for k in first(seg)..measured.len() {
                samples.push(seg.offset + k);
                simulated.push(y[k]);
                errors.push(measured[k] - y[k]);
                let row = &mut sens[k * nv..(k + 1) * nv];
                self.chain(v, norm, row);
                jacobian.push(row);
            }
        }
        let errors = DVector::from_vec(errors);
        let cost = errors.norm_squared();
        let cost = if diverged || !cost.is_finite() {
            f64::INFINITY
        } else {
            cost
        };
        Ok(Evaluation {
            jacobian: jacobian.finish(),
            samples,
            simulated,
            errors,
            cost,
        })
    }
}

impl LeastSquares for RelaxedGate<'_, '_> {
    type Error = IdentifyError;

    fn unknowns(&self) -> usize {
        RelaxedGate::unknowns(self)
    }

    fn evaluate(&self, v: &[f64]) -> Result<least_squares::Evaluation, IdentifyError> {
        Ok(self.shooting_cost(v)?.into())
    }

    fn jacobian(&self, v: &[f64]) -> Result<DMatrix<f64>, IdentifyError> {
        Ok(self.shooting_cost(v)?.jacobian)
    }

    fn solve(&self, design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>> {
        crate::linalg::lstsq(design, rhs)
            .ok()
            .map(|s| s.theta.iter().copied().collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pwarx;
    use crate::pwarx::refine::refine;
    use crate::pwarx::refine::tests::{problem, simulated_record};
    use hysid_core::priors::Priors;
    use hysid_core::stages::Refine;
    use hysid_model::data::Dataset;
    use hysid_model::geometry::Polyhedron;
    use hysid_model::model::{ModelInfo, PwarxModel};
    use proptest::prelude::*;

    /// The bits of `libm::exp(x)` and of [`gate_weight`] at `x`.
    fn both(x: f64) -> (u64, u64) {
        (libm::exp(x).to_bits(), gate_weight(x).to_bits())
    }

    #[test]
    fn gate_weights_are_the_exponentials_bits_at_its_edges() {
        let edge = [
            0.0,
            -0.0,
            -745.0,
            -745.133,
            EXP_UNDERFLOW,
            EXP_UNDERFLOW.next_up(),
            EXP_UNDERFLOW.next_down(),
            -708.5,
            -800.0,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::MIN_POSITIVE,
        ];
        for x in edge {
            let (exp, weight) = both(x);
            assert_eq!(exp, weight, "at {x:e}");
        }
        // The window where the exponential is subnormal, not zero.
        assert_ne!(libm::exp(EXP_UNDERFLOW.next_up()), 0.0);
    }

    proptest! {
        #[test]
        fn gate_weights_are_the_exponentials_bits(x in -760.0f64..0.0) {
            let (exp, weight) = both(x);
            prop_assert_eq!(exp, weight);
        }
    }

    /// `y(k) = a y(k-1) + b u(k-1) + c`, mode 0 where `y(k-1) <= 0`, mode 1
    /// where `y(k-1) >= 0`: continuous across the boundary, so a boundary
    /// in the wrong place is the only error left at the true parameters.
    const TRUTH: [[f64; 3]; 2] = [[0.7, 1.0, 0.05], [0.2, 1.0, 0.05]];

    /// The argmax partition with the boundary at `y(k-1) = at`.
    fn split_at(at: f64) -> Vec<Polyhedron> {
        argmax_regions(&[vec![0.0, 0.0, 0.0], vec![1.0, 0.0, -at]])
    }

    fn modes(at: f64) -> Vec<PwarxMode> {
        PwarxMode::unnamed(TRUTH.iter().map(|t| t.to_vec()), split_at(at))
    }

    /// A noise-free record of the true system driven by a deterministic
    /// white input in [-1, 1].
    fn record(n: usize) -> Dataset {
        let truth = PwarxModel {
            na: 1,
            nb: 1,
            inputs: 1,
            modes: modes(0.0),
            info: ModelInfo::default(),
        };
        simulated_record(&truth, &[], n, 17)
    }

    fn settings(refine: Refine) -> Stages {
        Stages {
            trim: None,
            refine,
            refine_segment: 100,
            refine_iterations: 60,
        }
    }

    /// From the true parameters and a boundary moved to `y(k-1) = 0.4`,
    /// the region stage brings the boundary back to within 0.05 of 0 and
    /// the simulation error down by more than a factor 100; the parameter
    /// stage alone cannot.
    #[test]
    fn a_misplaced_boundary_is_moved_back() {
        let data = record(800);
        let priors = Priors::default();
        let prepared = pwarx::prepare(&problem(&data, &priors), "test").unwrap();
        let start = || PwarxFit::complete(modes(0.4), ());
        let fixed = refine(
            &prepared,
            start(),
            &settings(Refine::Sim),
            &Deadline::none(),
        )
        .unwrap();
        let moved = refine(
            &prepared,
            start(),
            &settings(Refine::SimRegions),
            &Deadline::none(),
        )
        .unwrap();
        let r = moved.refinement.clone().unwrap();
        let g = r.regions.clone().unwrap();
        assert_eq!(g.status, RegionRefinementStatus::Moved, "{g:?}");
        assert!(g.moved_samples > 0, "{g:?}");
        let (before, after) = (g.cost_before.unwrap(), g.cost_after.unwrap());
        assert!(after < 1e-2 * before, "{g:?}");
        let fixed_cost = fixed.refinement.unwrap().cost_after.unwrap();
        assert!((before - fixed_cost).abs() <= 1e-9 * fixed_cost);
        // Mode 0's region is a . [y(k-1), u(k-1)] <= b: the boundary
        // y(k-1) = b / a_y, with no weight on the input.
        let row = &moved.modes[0].region.a[0];
        let b = moved.modes[0].region.b[0];
        assert!(row[0] > 0.0, "{row:?}");
        assert!((b / row[0]).abs() < 0.05, "boundary at {}", b / row[0]);
        assert!(row[1].abs() < 0.1 * row[0], "{row:?}");
        assert!(
            argmax_scores(
                &moved
                    .modes
                    .iter()
                    .map(|m| m.region.clone())
                    .collect::<Vec<_>>(),
                2
            )
            .is_some()
        );
        // One descent per sharpness level and round, and the record says
        // which of them ended at their bound.
        assert_eq!(g.gate_descents % SHARPNESS.len(), 0, "{g:?}");
        assert!(g.gate_descents >= SHARPNESS.len(), "{g:?}");
        assert!(g.gate_descents_at_bound < g.gate_descents, "{g:?}");
    }

    /// With one iteration allowed, every descent of the gate that is not
    /// stationary at its start ends at the bound, and the record counts it.
    #[test]
    fn gate_descents_at_their_bound_are_counted() {
        let data = record(800);
        let priors = Priors::default();
        let prepared = pwarx::prepare(&problem(&data, &priors), "test").unwrap();
        let one = Stages {
            refine_iterations: 1,
            ..settings(Refine::SimRegions)
        };
        let moved = refine(
            &prepared,
            PwarxFit::complete(modes(0.4), ()),
            &one,
            &Deadline::none(),
        )
        .unwrap();
        let g = moved.refinement.unwrap().regions.unwrap();
        assert!(g.gate_descents >= SHARPNESS.len(), "{g:?}");
        assert_eq!(g.gate_descents_at_bound, g.gate_descents, "{g:?}");
        assert_eq!(g.gate_iterations, g.gate_descents, "{g:?}");
    }

    /// The relaxed model's sensitivities match central finite differences
    /// of its simulation, at every sharpness level.
    #[test]
    fn relaxed_sensitivities_match_finite_differences() {
        let data = record(300);
        let priors = Priors::default();
        let prepared = pwarx::prepare(&problem(&data, &priors), "test").unwrap();
        let start = modes(0.3);
        let shooting = Shooting::new(&prepared, &start, 70).unwrap();
        let thetas: Vec<Vec<f64>> = vec![vec![0.6, 0.9, 0.1], vec![0.3, 1.1, 0.0]];
        let base = argmax_scores(&split_at(0.3), 2).unwrap();
        for sharpness in SHARPNESS {
            let gate = RelaxedGate {
                shooting: &shooting,
                thetas: &thetas,
                base: base.clone(),
                columns: vec![0, 1],
                sharpness,
                norm: 2.0,
            };
            let mut v = gate.unknowns_of(&base);
            v[1] = 0.4;
            v[2] -= 0.1;
            let ev = gate.shooting_cost(&v).unwrap();
            assert!(ev.cost.is_finite());
            let h = 1e-6;
            for j in 0..v.len() {
                let mut plus = v.clone();
                plus[j] += h;
                let mut minus = v.clone();
                minus[j] -= h;
                let (p, m) = (
                    gate.shooting_cost(&plus).unwrap(),
                    gate.shooting_cost(&minus).unwrap(),
                );
                for r in 0..ev.samples.len() {
                    let fd = (p.simulated[r] - m.simulated[r]) / (2.0 * h);
                    let an = ev.jacobian[(r, j)];
                    assert!(
                        (fd - an).abs() <= 1e-5 * (1.0 + an.abs()),
                        "sharpness {sharpness}, unknown {j}, sample {}: {an} vs {fd}",
                        ev.samples[r]
                    );
                }
            }
        }
    }
}
