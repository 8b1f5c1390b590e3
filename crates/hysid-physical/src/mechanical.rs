//! A mechanical model is fitted as its gray-box form
//! ([`hysid_core::model::to_gray_box`]), run by the one simulator of
//! physical models with its exact Jacobian; the fitted values, the
//! initial-state rule and the diagnostics go back into the mechanical
//! model.

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
