//! A mechanical model is fitted as its gray-box form
//! ([`hysid_core::model::to_gray_box`]), run by the one simulator of
//! physical models with its exact Jacobian; the fitted values, the
//! initial-state rule and the diagnostics go back into the mechanical
//! model.

use crate::parameters::ParameterError;
use hysid_core::priors::Priors;
use hysid_graybox::{GrayBoxInitialState, GrayBoxModel};
use hysid_mechanical::{MechanicalInitialState, MechanicalModel};

/// `model` with its initial state measured over the first `samples`
/// (`init_samples`; 0 keeps the file's rule): a given state becomes a
/// measured one, the state of a mechanical model being its output and the
/// output's slope.
pub fn with_warmup(mut model: MechanicalModel, samples: usize) -> MechanicalModel {
    if samples > 0
        && let MechanicalInitialState::Given { .. } = model.initial_state
    {
        model.initial_state = MechanicalInitialState::Measured {
            samples,
            velocity_tol: 0.0,
        };
    }
    model
}

/// `model` with the parameters, the measured rule's warm-up and the
/// provenance and diagnostics of `fitted`, its gray-box form fitted.
pub fn fitted(mut model: MechanicalModel, fitted: GrayBoxModel) -> MechanicalModel {
    model.parameters = fitted.parameters;
    model.info = fitted.info;
    if let GrayBoxInitialState::Measured {
        samples,
        velocity_tol,
        ..
    } = fitted.initial_state
    {
        model.initial_state = MechanicalInitialState::Measured {
            samples,
            velocity_tol,
        };
    }
    model
}

/// Checks `model` with the `[bounds]` and `[fixed]` of `priors` on its
/// parameters, as the fitted model will be read back: a friction level
/// the priors let go below 0 is refused before the fit
/// ([`MechanicalModel::check_friction_levels`]). Names the priors do not
/// fit are left to the parameter map.
pub fn check_under_priors(model: &MechanicalModel, priors: &Priors) -> Result<(), ParameterError> {
    let mut under = model.clone();
    for p in &mut under.parameters {
        if let Some(&[low, high]) = priors.bounds.get(&p.name) {
            p.bounds = [low, high];
        }
        if let Some(&value) = priors.fixed.get(&p.name) {
            p.value = value;
        }
        // Inside the bounds, so that only the friction levels are checked
        // here (a fixed value outside them is the parameter map's error).
        p.value = p.value.max(p.bounds[0]).min(p.bounds[1]);
    }
    under
        .check_friction_levels()
        .map_err(ParameterError::Refused)
}
