//! The warning of `identify` and `validate` when a model simulates a record
//! worse than an affine ARX model of the same orders fitted on it
//! (`hysid_select::against_affine`; `docs/selection.md`).

use hysid_core::model::Model;
use hysid_core::priors::Priors;
use hysid_model::data::Dataset;
use hysid_select::against_affine;

/// One line on stderr when `model` (with ARX orders, not itself the affine
/// reference) simulates `data` worse than the affine model of its orders
/// and `priors` fitted on `data`. `rows` names the rows ("its
/// identification rows", "these rows"); `hint` ends the line.
pub fn warn_if_below(
    model: &Model,
    data: &Dataset,
    priors: &Priors,
    warmup: usize,
    rows: &str,
    hint: &str,
) {
    let registry = hysid_backends::registry();
    let (Some(orders), Some(affine)) = (
        model.orders(),
        hysid_backends::affine_reference(&registry, &model.info().method),
    ) else {
        return;
    };
    if let Some(c) = against_affine(model, affine, data, orders, priors, warmup)
        && c.below()
    {
        eprintln!(
            "hysid: warning: the model's free-run FIT on {rows} ({:.2} %) is below that of an affine ARX model of the same orders fitted on them ({:.2} %){hint}",
            c.model, c.affine
        );
    }
}
