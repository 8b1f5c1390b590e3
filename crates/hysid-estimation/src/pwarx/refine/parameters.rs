//! The first stage of the refinement: the mode parameters by
//! Levenberg-Marquardt ([`hysid_numerics::least_squares`]) on the shooting cost, the regions
//! fixed, over the free variables of the priors' parametrisation.

use super::shooting::Shooting;
use crate::constrained::{self, Parametrisation};
use crate::pwarx::failure::PwarxFailure;
use crate::pwarx::prepare::PwarxData;
use hysid_core::backend::{Deadline, IdentifyError};
use hysid_core::stages::Stages;
use hysid_model::model::{PwarxMode, Refinement, RefinementStatus};
use hysid_numerics::least_squares::{
    Evaluation, LeastSquares, LmSettings, Stop, levenberg_marquardt,
};
use nalgebra::{DMatrix, DVector};

/// The parameters of `modes` refined by Levenberg-Marquardt on the
/// shooting cost with their regions fixed (see the module doc), no step
/// begun after `deadline`; the outcome.
pub(super) fn fit_parameters(
    data: &PwarxData<'_>,
    modes: &mut [PwarxMode],
    settings: &Stages,
    deadline: &Deadline,
) -> Result<Refinement, IdentifyError> {
    let par = Parametrisation::from_priors(data.priors(), &data.spec, modes.len())
        .map_err(|e| data.prior_error(e))?;
    let shooting = Shooting::new(data, modes, settings.refine_segment)?;
    let thetas: Vec<Vec<f64>> = modes.iter().map(|m| m.theta.clone()).collect();
    let start = par
        .free_values(&thetas)
        .map_err(|e| IdentifyError::failed(PwarxFailure::RefinementStart(e)))?;
    let problem = ParameterResiduals {
        shooting: &shooting,
        par: &par,
    };
    let descent = levenberg_marquardt(
        &problem,
        start,
        &LmSettings::new(settings.refine_iterations),
        deadline,
    )?;
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
        status: status_of(descent.stop),
        regions: None,
    })
}

/// The mode parameters' problem: the shooting cost over the free
/// variables of the priors' parametrisation, steps solved under its
/// equalities and bounds.
struct ParameterResiduals<'s, 'a> {
    shooting: &'s Shooting<'a>,
    par: &'s Parametrisation,
}

impl LeastSquares for ParameterResiduals<'_, '_> {
    type Error = IdentifyError;

    fn unknowns(&self) -> usize {
        self.par.n_free()
    }

    fn evaluate(&self, z: &[f64]) -> Result<Evaluation, IdentifyError> {
        Ok(self.shooting.evaluate(self.par, z)?.into())
    }

    fn jacobian(&self, z: &[f64]) -> Result<DMatrix<f64>, IdentifyError> {
        Ok(self.shooting.evaluate(self.par, z)?.jacobian)
    }

    fn solve(&self, design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>> {
        constrained::solve_in_z(self.par, design, rhs).ok()
    }
}

/// The refinement's status after a descent that ended by `stop`.
fn status_of(stop: Stop) -> RefinementStatus {
    match stop {
        Stop::Converged => RefinementStatus::Converged,
        Stop::NoDescent => RefinementStatus::NoDescent,
        Stop::IterationLimit => RefinementStatus::IterationLimit,
        Stop::TimeBudget => RefinementStatus::TimeBudget,
        Stop::Diverged => RefinementStatus::Diverged,
    }
}
