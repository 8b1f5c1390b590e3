//! Step 4 of the pipeline: the stages after a method's fit, as
//! [`Stages`] asks: the trimmed re-estimation ([`super::trim`]), then the
//! simulation-error refinement ([`super::refine`]).

use super::assemble::{PwarxFit, with_stops};
use super::failure::PwarxFailure;
use super::prepare::{PwarxData, prepare};
use hysid_core::backend::{Deadline, IdentifyError, Problem};
use hysid_core::model::Model;
use hysid_core::stages::Stages;

/// `fit` after the stages `stages` asks for, the refinement ending by
/// `deadline`.
pub fn run<D>(
    data: &PwarxData<'_>,
    fit: PwarxFit<D>,
    stages: &Stages,
    deadline: &Deadline,
) -> Result<PwarxFit<D>, IdentifyError> {
    let fit = super::trim::trim(data, fit, stages.trim)?;
    super::refine::refine(data, fit, stages, deadline)
}

/// `fitted`, a model the pipeline returned on `problem` without a
/// refinement, refined as `stages` ask without fitting it again:
/// the same model as the pipeline with that refinement gives, since the
/// refinement starts from the fit alone. Automatic selection refines its
/// candidates' own fits this way. A model of another kind than
/// [`assemble`](fn@super::assemble) writes, or one refined already, is refused.
pub fn refine_fitted(
    problem: &Problem<'_>,
    method: &str,
    fitted: Model,
    stages: &Stages,
    deadline: &Deadline,
) -> Result<Model, IdentifyError> {
    let data = prepare(problem, method)?;
    let mut pwarx = match fitted {
        Model::Pwarx(p) => p,
        Model::HybridAutomaton(a) => a
            .ordinary_pwarx()
            .ok_or_else(|| IdentifyError::failed(PwarxFailure::AutomatonNotPwarx))?,
        other => {
            return Err(IdentifyError::failed(PwarxFailure::NotPwarx {
                kind: other.kind(),
            }));
        }
    };
    let diagnostics = &mut pwarx.info.diagnostics;
    if diagnostics.refinement.is_some() {
        return Err(IdentifyError::failed(PwarxFailure::AlreadyRefined));
    }
    let fit = PwarxFit {
        modes: std::mem::take(&mut pwarx.modes),
        regions_complete: diagnostics.regions_complete.unwrap_or(true),
        uncovered_fraction: diagnostics.uncovered_fraction_of_data_box,
        run_status: diagnostics.run_status,
        status: std::mem::take(&mut diagnostics.status),
        scaling: None,
        refinement: None,
        trimming: None,
        diagnostics: (),
    };
    let fit = super::refine::refine(&data, fit, stages, deadline)?;
    pwarx.modes = fit.modes;
    diagnostics.regions_complete = Some(fit.regions_complete);
    diagnostics.uncovered_fraction_of_data_box = fit.uncovered_fraction;
    diagnostics.run_status = fit.run_status;
    diagnostics.status = fit.status;
    diagnostics.refinement = fit.refinement;
    Ok(with_stops(&data, pwarx))
}
