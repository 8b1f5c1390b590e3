//! # hysid-backends
//!
//! The one place where identification back-ends are registered. Adding a
//! back-end is one crate and one line in [`registry`].

use hysid_core::backend::Identifier as _;
use hysid_core::backend::{Backend, Registry};
use hysid_core::model::Model;
use hysid_core::priors::Priors;
use hysid_model::data::Dataset;
use hysid_select::AgainstAffine;

/// Every back-end hysid ships, in the order `hysid methods` lists them.
pub fn registry() -> Registry {
    Registry::new()
        .with(hysid_arx::Arx)
        .with(hysid_cluster::Cluster)
        .with(hysid_bounded::Bounded)
        .with(hysid_physical::Physical)
        .with(hysid_klinreg::KLinReg)
        .with(hysid_parc::Parc)
        .with(hysid_bayes::Bayes)
        .with(hysid_milp::Milp)
}

/// The back-end whose model is the affine reference a hybrid model is
/// compared with (automatic selection, the warning of `identify` and
/// `validate`): `arx`, unless `method` is that back-end itself.
pub fn affine_reference<'r>(registry: &'r Registry, method: &str) -> Option<&'r dyn Backend> {
    registry
        .get(hysid_arx::Arx::NAME)
        .filter(|a| a.name() != method)
}

/// `model` (with ARX orders, identified by another back-end than the
/// reference) beside the affine reference model of its orders and
/// `priors` fitted on `data` (`hysid_select::against_affine`); `None` when
/// there is nothing to compare.
pub fn against_affine(
    model: &Model,
    data: &Dataset,
    priors: &Priors,
    warmup: usize,
) -> Option<AgainstAffine> {
    let registry = registry();
    let orders = model.orders()?;
    let affine = affine_reference(&registry, &model.info().method)?;
    hysid_select::against_affine(model, affine, data, orders, priors, warmup)
}

#[cfg(test)]
mod tests {
    #[test]
    fn names_are_unique_and_documented() {
        let r = super::registry();
        assert!(r.get("arx").is_some());
        assert!(r.get("cluster").is_some());
        assert!(r.get("bounded").is_some());
        assert!(r.get("physical").is_some());
        for b in r.iter() {
            assert!(!b.summary().is_empty());
            for o in b.options() {
                assert!(!o.doc.is_empty(), "{}.{} has no doc", b.name(), o.key);
            }
        }
    }
}
