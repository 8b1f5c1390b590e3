//! The stages every PWARX back-end runs after its own fit, as one typed
//! struct: the trimmed re-estimation of the mode parameters (`trim`) and
//! the simulation-error refinement (`refine`, `refine_segment`,
//! `refine_iterations`). They are options of every PWARX back-end (set
//! with `--set`, listed after the back-end's own by `hysid methods`), and
//! automatic selection sets them by field ([`Stages::with_refine`]).
//! What the stages do is `hysid_estimation::pwarx`; this is what a caller
//! may ask of them.

use crate::options::{BackendOptions, CheckOptions, OptionError, Settings};

crate::option_enum! {
    /// The refinement a PWARX back-end ends with (option `refine`).
    pub enum Refine {
        /// None: the back-end's own estimate.
        None => "none",
        /// The multiple-shooting simulation error, by Levenberg-Marquardt.
        Sim => "sim",
        /// `sim`, then the region boundaries moved by a softmax relaxation
        /// of the same error and hardened again.
        SimRegions => "sim_regions",
    }
}

impl Refine {
    /// Whether no refinement is asked for (the default, not recorded in a
    /// model's options).
    pub fn is_none(&self) -> bool {
        *self == Refine::None
    }

    /// The option's value, as `--set refine=...` writes it.
    pub fn as_str(self) -> &'static str {
        match self {
            Refine::None => "none",
            Refine::Sim => "sim",
            Refine::SimRegions => "sim_regions",
        }
    }
}

/// Default samples per shooting segment (option `refine_segment`).
pub const DEFAULT_SEGMENT: usize = 200;
/// Default bound on the Levenberg-Marquardt iterations (option
/// `refine_iterations`).
pub const DEFAULT_ITERATIONS: usize = 50;
/// Largest `refine_iterations` accepted.
pub const MAX_ITERATIONS: usize = 100_000;
/// The cutoff of the trimmed re-estimation that automatic selection gives
/// every candidate of a hybrid back-end, in robust standard deviations:
/// the usual rejection level of Hampel et al.
pub const AUTO_TRIM: f64 = 3.0;

fn is_default_segment(segment: &usize) -> bool {
    *segment == DEFAULT_SEGMENT
}

fn is_default_iterations(iterations: &usize) -> bool {
    *iterations == DEFAULT_ITERATIONS
}

crate::backend_options! {
    /// What the stages after a PWARX fit are asked to do. Every field is
    /// recorded in a model's options only when it differs from its default.
    pub struct Stages {
        /// After the fit, before refine: every mode's parameters estimated again by least
        /// squares under the priors on the samples its region holds, leaving out those whose
        /// residual exceeds trim robust standard deviations of the mode (1.4826 times the median
        /// absolute residual), repeated until the samples left out no longer change; none: the
        /// back-end's estimate (docs/refinement.md).
        #[serde(skip_serializing_if = "Option::is_none")]
        trim: Option<f64> = None,
        /// Refinement after the fit: none; sim (the mode parameters by Levenberg-Marquardt on
        /// the multiple-shooting simulation error under the priors, regions fixed); or
        /// sim_regions (sim, then the region boundaries moved by a softmax relaxation of that
        /// error and hardened), docs/refinement.md.
        #[serde(skip_serializing_if = "Refine::is_none")]
        refine: Refine = Refine::None,
        /// Samples per shooting segment of refine=sim, each simulated free-run from the measured
        /// outputs before it; at least the record's length: output error (pure free run).
        #[serde(skip_serializing_if = "is_default_segment")]
        refine_segment: usize = DEFAULT_SEGMENT,
        /// Bound on the Levenberg-Marquardt iterations of refine=sim.
        #[serde(skip_serializing_if = "is_default_iterations")]
        refine_iterations: usize = DEFAULT_ITERATIONS,
    }
}

impl CheckOptions for Stages {
    /// `trim` finite and positive, `refine_segment` at least 1,
    /// `refine_iterations` in `1..=`[`MAX_ITERATIONS`].
    fn check(&self) -> Result<(), OptionError> {
        if let Some(t) = self.trim
            && !(t.is_finite() && t > 0.0)
        {
            return Err(OptionError::invalid(
                "trim",
                t,
                "must be a finite number > 0 (robust standard deviations)",
            ));
        }
        if self.refine_segment == 0 {
            return Err(OptionError::invalid(
                "refine_segment",
                0,
                "must be at least 1 sample",
            ));
        }
        if !(1..=MAX_ITERATIONS).contains(&self.refine_iterations) {
            return Err(OptionError::invalid(
                "refine_iterations",
                self.refine_iterations,
                format!("must be in 1..={MAX_ITERATIONS}"),
            ));
        }
        Ok(())
    }
}

impl Stages {
    /// The key of the refinement option.
    pub const REFINE: &'static str = "refine";
    /// The key of the trimmed re-estimation's cutoff.
    pub const TRIM: &'static str = "trim";

    /// Whether `key` is one of the stages' options.
    pub fn owns(key: &str) -> bool {
        Self::specs().iter().any(|s| s.key == key)
    }

    /// The refinement `settings` ask for, if they set one.
    pub fn refine_given(settings: &Settings) -> Option<&str> {
        settings.get(Self::REFINE)
    }

    /// `settings` with the refinement set to `refine` (the other values
    /// unchanged).
    pub fn with_refine(settings: &Settings, refine: Refine) -> Settings {
        settings.with(Self::REFINE, refine.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_resolve_check_and_record_only_what_differs() {
        let s: Stages = Settings::parse(&["trim=3", "refine=sim_regions"])
            .unwrap()
            .resolve("m")
            .unwrap();
        assert_eq!(s.trim, Some(3.0));
        assert_eq!(s.refine, Refine::SimRegions);
        assert_eq!(s.refine_segment, DEFAULT_SEGMENT);
        let keys: Vec<String> = s.to_map().into_keys().collect();
        assert_eq!(keys, ["refine", "trim"]);
        assert!(Stages::default().to_map().is_empty());
        let e = Stages {
            refine_iterations: 0,
            ..Stages::default()
        }
        .check()
        .unwrap_err();
        assert_eq!(
            e.render("--set"),
            "--set refine_iterations=0: must be in 1..=100000"
        );
        let e = Stages {
            trim: Some(f64::NAN),
            ..Stages::default()
        };
        assert!(e.check().is_err());
    }

    #[test]
    fn the_refinement_is_set_by_field() {
        let given = Settings::parse(&["c=40", "refine=sim"]).unwrap();
        assert_eq!(Stages::refine_given(&given), Some("sim"));
        let set = Stages::with_refine(&given, Refine::SimRegions);
        assert_eq!(set.get("refine"), Some("sim_regions"));
        assert_eq!(set.get("c"), Some("40"));
        for r in [Refine::None, Refine::Sim, Refine::SimRegions] {
            let s: Stages = Stages::with_refine(&Settings::default(), r)
                .resolve("m")
                .unwrap();
            assert_eq!(s.refine, r);
        }
        assert!(Stages::owns("refine_segment") && !Stages::owns("c"));
    }
}
