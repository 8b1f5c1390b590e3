//! The last step of the pipeline: the ordinary modes a method found, as
//! the model file holds them. [`assemble`] writes a PWARX model, or with
//! known stops the hybrid automaton of
//! `HybridAutomaton::from_pwarx_with_stops`, with the common diagnostics
//! under their fixed names.

use super::prepare::PwarxData;
use hysid_core::model::Model;
use hysid_model::data::Standardization;
use hysid_model::model::{
    Diagnostics, HybridAutomaton, ModelInfo, PwarxMode, PwarxModel, Refinement, RunStatus, Trimming,
};
use serde::Serialize;

/// What a PWARX back-end's `fit` returns: its ordinary modes in data units
/// and how the run went.
#[derive(Debug, Clone)]
pub struct PwarxFit<D> {
    /// The ordinary modes: parameters and regions.
    pub modes: Vec<PwarxMode>,
    /// Whether the regions cover the regressor space.
    pub regions_complete: bool,
    /// Fraction of the identification regressors' box in no region, when
    /// the regions leave holes.
    pub uncovered_fraction: Option<f64>,
    /// How the run ended.
    pub run_status: RunStatus,
    /// Messages for the user (why the run was cut short, warnings).
    pub status: Vec<String>,
    /// How the back-end saw the data, when it worked in standardised units
    /// (recorded in the model's `info.scaling`).
    pub scaling: Option<Standardization>,
    /// The outcome of the simulation-error refinement, when it ran
    /// ([`crate::pwarx::refine::refine`]; back-ends set `None`).
    pub refinement: Option<Refinement>,
    /// The outcome of the trimmed re-estimation, when it ran
    /// ([`crate::pwarx::trim::trim`]; back-ends set `None`).
    pub trimming: Option<Trimming>,
    /// The back-end's own diagnostics.
    pub diagnostics: D,
}

impl<D> PwarxFit<D> {
    /// A finished fit whose regions cover the regressor space, with no
    /// message and no refinement yet: what a back-end with a complete
    /// partition by construction returns.
    pub fn complete(modes: Vec<PwarxMode>, diagnostics: D) -> Self {
        PwarxFit {
            modes,
            regions_complete: true,
            uncovered_fraction: None,
            run_status: RunStatus::Completed,
            status: Vec::new(),
            scaling: None,
            refinement: None,
            trimming: None,
            diagnostics,
        }
    }
}

/// The model of `fit` on `data`: a PWARX model, or with known stops the
/// automaton with a mode on each stop's guard set; the common diagnostics
/// filled in.
pub fn assemble<D: Serialize>(data: &PwarxData<'_>, fit: PwarxFit<D>) -> Model {
    let stops = data.stops();
    let diagnostics = Diagnostics {
        run_status: fit.run_status,
        status: fit.status,
        samples: Some(data.regressors.len()),
        modes: Some(fit.modes.len() + stops),
        regions_complete: Some(fit.regions_complete),
        uncovered_fraction_of_data_box: fit.uncovered_fraction,
        saturated_per_stop: (stops > 0).then(|| data.saturated_per_stop()),
        refinement: fit.refinement,
        trimming: fit.trimming,
        ..Default::default()
    }
    .with_method(&fit.diagnostics);
    let model = PwarxModel {
        na: data.spec.na,
        nb: data.spec.nb,
        inputs: data.spec.inputs,
        modes: fit.modes,
        info: ModelInfo {
            diagnostics,
            scaling: fit.scaling,
            // Named here, not only by `Backend::run`, so that an automaton
            // with stops takes the record's input names.
            input_names: data.problem.data.input_names(),
            ..Default::default()
        },
    };
    with_stops(data, model)
}

/// `model`, the ordinary modes, as the model file holds it: itself, or
/// with known stops the automaton with a mode on each stop's guard set.
pub(crate) fn with_stops(data: &PwarxData<'_>, model: PwarxModel) -> Model {
    if data.stops() == 0 {
        Model::Pwarx(model)
    } else {
        let stops = &data.priors().saturation;
        Model::HybridAutomaton(HybridAutomaton::from_pwarx_with_stops(&model, stops))
    }
}
