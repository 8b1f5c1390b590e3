//! Refinement of the mode parameters of a PWARX fit by the
//! multiple-shooting **simulation error**, the stage any PWARX back-end may
//! end with, between its `fit` and [`assemble`](fn@crate::pwarx::assemble).
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
//! of exactly the model [`assemble`](fn@crate::pwarx::assemble) writes.
//!
//! The minimisation is Levenberg-Marquardt (Marquardt 1963; the damping
//! update of Madsen, Nielsen & Tingleff, *Methods for non-linear least
//! squares problems*, 2004, section 3.2) over the free variables `z` of
//! [`Parametrisation::from_priors`](crate::constrained::Parametrisation::from_priors) (`theta = T z + t0`), so ties and
//! fixed values hold exactly. Each step solves
//!
//! ```text
//! min_z' |J z' - (e + J z)|^2 + mu |z' - z|^2
//! ```
//!
//! (`e = y - y_sim` the errors, `J = d y_sim / d z`) by
//! [`constrained::solve_in_z`](crate::constrained::solve_in_z), under the same `[[equality]]` entries and
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

mod parameters;
pub mod regions;
mod shooting;

pub use hysid_model::model::{Refinement, RefinementStatus};
pub use shooting::{Evaluation, Shooting};

use crate::pwarx::assemble::PwarxFit;
use crate::pwarx::prepare::PwarxData;
use hysid_core::backend::{Deadline, IdentifyError};
use hysid_core::stages::{Refine, Stages};
use hysid_model::model::RunStatus;

/// `fit` with its ordinary modes' parameters refined by the
/// multiple-shooting simulation error (see the module doc), the regions
/// unchanged, and with [`Refine::SimRegions`] then the region
/// boundaries moved ([`regions`]); the outcome in `fit.refinement`. With
/// [`Refine::None`], `fit` unchanged. The settings are those a
/// back-end's checked options hold ([`Stages`]). When no
/// step lowers the cost, the parameters stay as the back-end gave them. A
/// refinement stopped by its iteration bound marks the run
/// [`RunStatus::IterationLimit`]; one stopped by `deadline`,
/// [`RunStatus::TimeBudget`].
pub fn refine<D>(
    data: &PwarxData<'_>,
    mut fit: PwarxFit<D>,
    settings: &Stages,
    deadline: &Deadline,
) -> Result<PwarxFit<D>, IdentifyError> {
    if settings.refine == Refine::None {
        return Ok(fit);
    }
    let mut r = parameters::fit_parameters(data, &mut fit.modes, settings, deadline)?;
    if settings.refine == Refine::SimRegions {
        r.regions = Some(regions::move_regions(data, &mut fit, settings, deadline)?);
    }
    match r.status {
        RefinementStatus::IterationLimit => {
            if fit.run_status == RunStatus::Completed {
                fit.run_status = RunStatus::IterationLimit;
            }
            fit.status.push(format!(
                "the simulation-error refinement stopped at its iteration bound ({})",
                r.max_iterations
            ));
        }
        RefinementStatus::TimeBudget => {
            fit.run_status = RunStatus::TimeBudget;
            fit.status
                .push("the simulation-error refinement stopped at the time budget".to_string());
        }
        _ => {}
    }
    fit.refinement = Some(r);
    Ok(fit)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constrained::Parametrisation;
    use crate::pwarx;
    use hysid_core::backend::Problem;
    use hysid_core::model::Model;
    use hysid_core::priors::Priors;
    use hysid_model::data::Dataset;
    use hysid_model::geometry::Polyhedron;
    use hysid_model::model::{HybridAutomaton, ModelInfo, PwarxMode, PwarxModel};
    use hysid_model::model::{RegionRefinementStatus, Stop, StopBound};
    use hysid_model::regressors::RegressorSpec;
    use hysid_model::simulate::{SimulationOptions, automaton, pwarx as pwarx_sim};
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
        Dataset::siso(u, y, None).unwrap()
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
                &Deadline::none(),
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
        let fit = refine(
            &prepared,
            start_fit(perturbed()),
            &Stages::default(),
            &Deadline::none(),
        )
        .unwrap();
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
            let fit = refine(
                &prepared,
                start_fit(perturbed()),
                &sim_settings(60, 30),
                &Deadline::none(),
            )
            .unwrap();
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
            &Deadline::none(),
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
        /// bit), the cost did not rise, and regions the second stage did
        /// not move are the start's bit for bit.
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
            let par = match Parametrisation::from_priors(&priors, &prepared.spec, 2) {
                Ok(par) => par,
                // No parameters inside the bounds satisfy the equality.
                Err(crate::constrained::PriorConflict::OutsideBounds) => return Ok(()),
                Err(e) => return Err(TestCaseError::fail(e.to_string())),
            };
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
            let fit = refine(&prepared, start_fit(start), &settings, &Deadline::none()).unwrap();
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
            let moved = r.regions.as_ref().is_some_and(|g| g.status == RegionRefinementStatus::Moved);
            if !moved {
                for (m, region) in fit.modes.iter().zip(regions()) {
                    prop_assert_eq!(&m.region, &region);
                }
            }
            let thetas: Vec<Vec<f64>> = fit.modes.iter().map(|m| m.theta.clone()).collect();
            let broken = constraints.broken(&prepared.spec.param_names(), &thetas);
            prop_assert!(broken.is_none(), "{}", broken.unwrap_or_default());
        }
    }
}
