//! The warning of `identify` and `validate` when a model simulates a record
//! worse than an affine ARX model of the same orders fitted on it
//! (`hysid::select::against_affine`; `docs/selection.md`).

use hysid_core::model::Model;
use hysid_core::priors::Priors;
use hysid_model::data::Dataset;

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
    if let Some(c) = hysid::against_affine(model, data, priors, warmup)
        && c.below()
    {
        eprintln!("hysid: warning: {}{hint}", c.warning(rows));
    }
}
