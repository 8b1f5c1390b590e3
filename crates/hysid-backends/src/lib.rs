//! # hysid-backends
//!
//! The one place where identification back-ends are registered. Adding a
//! back-end is one crate and one line in [`registry`].

use hysid_core::backend::Identifier as _;
use hysid_core::backend::{Backend, Registry};

/// Every back-end hysid ships, in the order `hysid methods` lists them.
pub fn registry() -> Registry {
    Registry::new()
        .with(hysid_arx::Arx)
        .with(hysid_cluster::Cluster)
        .with(hysid_bounded::Bounded)
        .with(hysid_physical::Physical)
        .with(hysid_klinreg::KLinReg)
        .with(hysid_parc::Parc)
}

/// The back-end whose model is the affine reference a hybrid model is
/// compared with (automatic selection, the warning of `identify` and
/// `validate`): `arx`, unless `method` is that back-end itself.
pub fn affine_reference<'r>(registry: &'r Registry, method: &str) -> Option<&'r dyn Backend> {
    registry
        .get(hysid_arx::Arx::NAME)
        .filter(|a| a.name() != method)
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
