//! The one place where identification back-ends are registered. Adding a
//! back-end is one crate and one line in [`registry`].

use crate::select::AgainstAffine;
use hysid_core::backend::{Backend, Registry};
use hysid_core::model::Model;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::{Pwarx, PwarxMethod as _};
use hysid_model::data::Dataset;

/// Every back-end hysid ships, in the order `hysid methods` lists them.
pub fn registry() -> Registry {
    Registry::new()
        .with(Pwarx(hysid_arx::Arx))
        .with(Pwarx(hysid_cluster::Cluster))
        .with(Pwarx(hysid_bounded::Bounded))
        .with(hysid_physical::Physical)
        .with(Pwarx(hysid_klinreg::KLinReg))
        .with(Pwarx(hysid_parc::Parc))
        .with(Pwarx(hysid_bayes::Bayes))
        .with(Pwarx(hysid_milp::Milp))
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
/// `priors` fitted on `data` (`crate::select::against_affine`); `None` when
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
    crate::select::against_affine(model, affine, data, orders, priors, warmup)
}

#[cfg(test)]
mod tests {
    use hysid_core::backend::{Problem, RunContext};
    use hysid_core::options::Settings;
    use hysid_core::priors::Priors;

    /// What `refine_fitted` of every back-end with a refinement gives from
    /// its unrefined fit equals what `run` with the refinement on gives
    /// (the affine `arx` without the mode count, `bounded` with `delta =
    /// auto`); the back-ends compared, leaving out those that cannot fit
    /// `problem` at all.
    fn refining_the_fit_equals_fitting_refined(
        problem: &Problem<'_>,
        values: &[&str],
    ) -> Vec<&'static str> {
        let ctx = RunContext::quiet(3);
        let affine = Priors {
            modes: None,
            ..problem.priors.clone()
        };
        let mut compared = Vec::new();
        for b in super::registry().iter() {
            if !b.options().iter().any(|o| o.key == "refine") {
                continue;
            }
            let problem = match b.name() {
                "arx" => Problem {
                    priors: &affine,
                    ..*problem
                },
                _ => *problem,
            };
            let settings = |v: &str| {
                let mut pairs = vec![("refine".to_string(), v.to_string())];
                // `bounded` has no default error bound.
                if b.name() == "bounded" {
                    pairs.push(("delta".into(), "auto".into()));
                }
                Settings::from_pairs(pairs)
            };
            let Ok(fitted) = b.run(&problem, &settings("none"), &ctx) else {
                continue;
            };
            for &v in values {
                let direct = b.run(&problem, &settings(v), &ctx).unwrap();
                let refined = b
                    .refine_fitted(&problem, fitted.clone(), &settings(v), &ctx)
                    .expect("a back-end with the refine option refines its fits")
                    .unwrap();
                assert!(direct.info().diagnostics.refinement.is_some());
                assert_eq!(
                    serde_json::to_value(&refined).unwrap(),
                    serde_json::to_value(&direct).unwrap(),
                    "{} with refine={v}",
                    b.name()
                );
            }
            compared.push(b.name());
        }
        compared
    }

    /// Every back-end with the `trim` option runs the trimmed
    /// re-estimation when it is set, and records it; and `--auto` gives it
    /// to every candidate of the hybrid ones (`arx` has one mode: nothing
    /// is misassigned).
    #[test]
    fn every_back_end_with_trim_trims() {
        let short = hysid_testkit::h3(41, 4);
        // `milp`'s branch and bound grows quickly with the samples.
        let shorter = hysid_testkit::h3(31, 4);
        let priors = Priors {
            modes: Some(2),
            ..Default::default()
        };
        let affine = Priors::default();
        let problem = short.problem(&priors);
        let mut trimmed = Vec::new();
        for b in super::registry().iter() {
            if !b.options().iter().any(|o| o.key == "trim") {
                continue;
            }
            let space = b.search_space(&problem).unwrap();
            assert_eq!(space.has("trim"), b.name() != "arx", "{}", b.name());
            let mut pairs = vec![("trim".to_string(), "3".to_string())];
            if b.name() == "bounded" {
                pairs.push(("delta".into(), "auto".into()));
            }
            let problem = match b.name() {
                "arx" => Problem {
                    priors: &affine,
                    ..problem
                },
                "milp" => shorter.problem(&priors),
                _ => problem,
            };
            let model = b
                .run(
                    &problem,
                    &Settings::from_pairs(pairs),
                    &RunContext::quiet(1),
                )
                .unwrap_or_else(|e| panic!("{}: {e}", b.name()));
            let t = model.info().diagnostics.trimming.clone();
            assert_eq!(t.map(|t| t.cutoff), Some(3.0), "{}", b.name());
            trimmed.push(b.name());
        }
        assert_eq!(
            trimmed,
            [
                "arx", "cluster", "bounded", "klinreg", "parc", "bayes", "milp"
            ]
        );
    }

    #[test]
    fn a_refined_fit_is_the_fit_with_the_refinement_on() {
        let h3 = hysid_testkit::h3(150, 4);
        let priors = Priors {
            modes: Some(3),
            ..Default::default()
        };
        let compared =
            refining_the_fit_equals_fitting_refined(&h3.problem(&priors), &["sim", "sim_regions"]);
        assert_eq!(compared, ["arx", "cluster", "bounded", "klinreg", "bayes"]);
        // `parc` keeps fewer clusters than asked on this record, `milp`
        // takes at most 40 samples (and its branch and bound grows quickly
        // with them).
        let short = hysid_testkit::h3(31, 4);
        let priors = Priors {
            modes: Some(2),
            ..Default::default()
        };
        let compared = refining_the_fit_equals_fitting_refined(&short.problem(&priors), &["sim"]);
        assert!(
            compared.contains(&"milp") && compared.contains(&"parc"),
            "{compared:?}"
        );
    }

    #[test]
    fn a_refined_fit_with_stops_is_the_fit_with_the_refinement_on() {
        let head = hysid_testkit::stopped_head(300, 25, 0.02, 5);
        let priors = head.priors();
        let problem = Problem {
            data: &head.data,
            orders: head.ordinary.spec(),
            priors: &priors,
            priors_origin: None,
        };
        let compared = refining_the_fit_equals_fitting_refined(&problem, &["sim"]);
        assert_eq!(
            compared,
            ["arx", "cluster", "bounded", "klinreg", "parc", "bayes"]
        );
    }

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
