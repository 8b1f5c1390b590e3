//! # hysid-bounded
//!
//! The `bounded` back-end: bounded-error identification of PWARX models,
//! after A. Bemporad, A. Garulli, S. Paoletti and A. Vicino, "A
//! bounded-error approach to piecewise affine system identification", IEEE
//! Transactions on Automatic Control 50(10):1567-1580, 2005.
//!
//! Given a bound `delta` on the identification error, the procedure finds a
//! small number of modes `s` and their parameters such that every sample is
//! explained by some mode within `delta` (MIN PFS, solved greedily by MAX FS
//! with randomized thermal relaxation, [`maxfs`]), refines the
//! classification to a fixed point ([`procedure`]), refits every mode by a
//! Chebyshev LP that certifies `|y_k - phi_k' theta_i| <= delta` on its
//! samples ([`refit`]), and estimates the regions with `hysid_estimation::regions`.
//! `delta` trades fit for the number of modes (a sweep over `delta`
//! reports the trade-off). `docs/bounded.md` lists every constant and which
//! parts are the paper's and which are ours.
//!
//! The set-up shared by the PWARX back-ends (prior names, regressors, the
//! samples at known stops, the mode counts) and the assembly of the model
//! are `hysid_estimation::pwarx`'s; [`fit()`] holds the method's steps.
//!
//! Priors honoured (`docs/priors.md`, `docs/bounded.md` "Priors"):
//! all of them. `modes` / `max_modes` count every mode, saturation modes
//! included; samples at a `[[saturation]]` stop are assigned to that stop
//! before extraction and the result is a hybrid automaton with the stops as
//! modes on their guard sets; `[fixed]`, `[bounds]` and `[[tie]]` restrict
//! the parameters in every fit ([`constraints`]); `switching` restricts the
//! region normals.

pub mod constraints;
pub mod fit;
pub mod maxfs;
pub mod noise;
pub mod options;
pub mod procedure;
pub mod refit;
pub mod samples;
pub mod split;

pub use fit::{BoundedDiagnostics, BoundedError, Classified, fit};
pub use options::{AutoKeyword, BoundedOptions, Delta, NAME, Refit};

use hysid_core::backend::{IdentifyError, Problem, RunContext};
use hysid_core::options::Checked;
use hysid_core::priors::PriorKind;
use hysid_core::search::SearchSpace;
use hysid_core::stages::{AUTO_TRIM, Stages};
use hysid_estimation::pwarx;
use hysid_estimation::pwarx::{ModeRule, PwarxData, PwarxFit, PwarxMethod};
use procedure::{Classification, ProcedureSettings};
use samples::Samples;

/// The `bounded` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Bounded;

impl Bounded {
    /// Runs the procedure and returns the classification with the samples
    /// it was computed on (the ordinary samples: saturated ones removed)
    /// and the settings (for tests and benchmarks).
    pub fn classify(
        problem: &Problem<'_>,
        options: &BoundedOptions,
        ctx: &RunContext<'_>,
    ) -> Result<(Classification, Samples, ProcedureSettings), IdentifyError> {
        let c = Self::classify_all(problem, options, ctx)?;
        Ok((c.classification, c.samples, c.settings))
    }

    /// Checks the options, then classifies the samples of `problem`
    /// ([`fit::classify`]): samples at a known stop are assigned to it
    /// (they never enter MAX FS), the rest are classified.
    pub fn classify_all(
        problem: &Problem<'_>,
        options: &BoundedOptions,
        ctx: &RunContext<'_>,
    ) -> Result<Classified, IdentifyError> {
        let options = Checked::new(options.clone())?;
        let data = pwarx::prepare(problem, Self::NAME)?;
        fit::classify(&options, &data, ctx).map_err(|e| e.of_method(Self::NAME))
    }
}

/// Multiples of the noise standard deviation that automatic selection
/// tries as `delta`.
pub const DELTA_SIGMAS: [f64; 6] = [1.0, 1.5, 2.0, 3.0, 4.0, 6.0];

/// `v` with three significant digits, as text (a grid value a user can
/// read and type again, `8.94e-3`).
fn three_digits(v: f64) -> String {
    format!("{v:.2e}")
}

impl PwarxMethod for Bounded {
    type Options = BoundedOptions;
    type Diagnostics = BoundedDiagnostics;
    const MODE_RULE: ModeRule = ModeRule::Method;
    const NAME: &'static str = NAME;
    const SUMMARY: &'static str = "bounded-error PWARX (Bemporad et al. 2005): the number of modes follows from the error bound delta";
    const HONOURS: &'static [PriorKind] = PriorKind::ALL;
    const PAPER: &'static [(&'static str, &'static str)] = &[("alternation", "0")];
    const OUTPUT_UNITS: &'static [&'static str] =
        &["delta", "max_residual", "tie_projection_error"];
    const SEARCH: &'static str = "delta at 1, 1.5, 2, 3, 4 and 6 times the noise standard deviation of local affine fits (delta = auto is 3 times it); the mode count follows; every candidate with alternation = 50 and trim = 3";

    /// `delta` on a grid of multiples of the noise level of the ordinary
    /// samples (the `auto` bound over [`noise::SIGMAS`], so floored as it
    /// is), every candidate with the alternation
    /// ([`hysid_estimation::regions::AUTO_ROUNDS`]).
    fn search_space(&self, problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError> {
        let data = pwarx::prepare(problem, Self::NAME)?;
        let sigma = noise::auto_delta(&data.ordinary_regressors()) / noise::SIGMAS;
        Ok(SearchSpace::default()
            .with(
                "delta",
                DELTA_SIGMAS.iter().map(|k| three_digits(k * sigma)),
            )
            .with("alternation", [hysid_estimation::regions::AUTO_ROUNDS])
            .with(Stages::TRIM, [AUTO_TRIM]))
    }

    fn fit(
        &self,
        data: &PwarxData<'_>,
        options: &BoundedOptions,
        ctx: &RunContext<'_>,
    ) -> Result<PwarxFit<BoundedDiagnostics>, IdentifyError> {
        fit(options, data, ctx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_core::backend::Backend;
    use hysid_core::model::Model;
    use hysid_core::options::Settings;
    use hysid_core::priors::Priors;
    use hysid_core::simulate::validate;
    use hysid_estimation::pwarx::Pwarx;
    use hysid_estimation::regions::RegionMethod;
    use hysid_model::data::Dataset;
    use hysid_model::model::{PwarxModel, RunStatus};
    use hysid_model::regressors::RegressorSpec;

    fn run(
        data: &Dataset,
        priors: &Priors,
        set: &[&str],
        seed: u64,
    ) -> Result<Model, IdentifyError> {
        let problem = Problem {
            data,
            orders: RegressorSpec::new(1, 1, 1),
            priors,
            priors_origin: None,
        };
        Pwarx(Bounded).run(
            &problem,
            &Settings::parse(set).unwrap(),
            &RunContext::quiet(seed),
        )
    }

    fn pwarx(m: &Model) -> &PwarxModel {
        match m {
            Model::Pwarx(p) => p,
            _ => unreachable!(),
        }
    }

    #[test]
    fn delta_parses_as_number_or_auto() {
        let r = |v: &[&str]| {
            Settings::parse(v)
                .unwrap()
                .resolve::<BoundedOptions>("bounded")
        };
        assert_eq!(r(&["delta=0.1"]).unwrap().delta, Delta::Value(0.1));
        assert_eq!(r(&["delta=1"]).unwrap().delta, Delta::Value(1.0));
        let auto = Delta::Auto(AutoKeyword::Auto);
        assert_eq!(r(&["delta=auto"]).unwrap().delta, auto);
        assert_eq!(r(&[]).unwrap().delta, auto);
        let e = r(&["delta=foo"]).unwrap_err().to_string();
        assert!(e.contains("delta=foo") && e.contains("float|auto"), "{e}");
        assert_eq!(r(&["refit=ls"]).unwrap().refit, Refit::Ls);
        assert_eq!(r(&["regions=psvc"]).unwrap().regions, RegionMethod::Psvc);
        assert!(r(&["refit=l2"]).is_err());
        // Provenance records the value as given.
        use hysid_core::options::BackendOptions;
        assert_eq!(r(&["delta=auto"]).unwrap().to_map()["delta"], "auto");
        assert_eq!(r(&["delta=0.25"]).unwrap().to_map()["delta"], 0.25);
    }

    #[test]
    fn b1_model_with_regions_in_original_units() {
        let g = hysid_testkit::b1(300, 4.0, hysid_testkit::Noise::Uniform(0.1), 7);
        // The published procedure, whose modes certify delta.
        let m = run(
            &g.data,
            &Priors::default(),
            &["delta=0.1", "preset=paper"],
            7,
        )
        .unwrap();
        let p = pwarx(&m);
        assert_eq!(p.modes.len(), 3);
        let common = &m.info().diagnostics;
        assert_eq!(common.modes, Some(3));
        assert_eq!(common.samples, Some(299));
        assert_eq!(common.regions_complete, Some(true));
        assert_eq!(common.run_status, RunStatus::Completed);
        assert!(common.status.is_empty(), "{common:?}");
        let dg = &common.method;
        assert_eq!(dg["modes_found"], 3);
        assert!(
            dg["region_training_accuracy"].as_f64().unwrap() > 0.95,
            "{dg:?}"
        );
        for r in dg["max_residual"].as_array().unwrap() {
            assert!(r.as_f64().unwrap() <= 0.1 + 1e-9);
        }
        // Parameters close to the truth after matching.
        let truth = g.thetas();
        let ident: Vec<Vec<f64>> = p.modes.iter().map(|m| m.theta.clone()).collect();
        let pe = hysid_model::metrics::parameter_error(&truth, &ident).unwrap();
        assert!(pe.max_relative_error < 0.05, "{pe:?}");
        // The regions classify fresh data from the same system: at least 97 %
        // of the regressors in the right mode (a misclassified sample costs a
        // prediction error of several units in B1, so FIT is not the measure).
        let v = hysid_testkit::b1(300, 4.0, hysid_testkit::Noise::Uniform(0.1), 99);
        let reg = RegressorSpec::new(1, 1, 1).build(&v.data).unwrap();
        let got: Vec<usize> = (0..reg.len())
            .map(|k| p.mode_of(&[reg.x[(k, 0)], reg.x[(k, 1)]]).mode)
            .collect();
        let acc = hysid_model::metrics::mode_accuracy(&v.row_modes(), &got)
            .unwrap()
            .accuracy;
        assert!(acc >= 0.97, "fresh-data mode accuracy {acc}");
        let (rep, _, _) = validate(&m, &v.data, 1).unwrap();
        assert_eq!(rep.coverage, 1.0);
        assert_eq!(m.info().method, "bounded");
    }

    #[test]
    fn same_seed_same_model() {
        let g = hysid_testkit::b1(200, 4.0, hysid_testkit::Noise::Uniform(0.1), 3);
        let a = run(&g.data, &Priors::default(), &["delta=0.1"], 5).unwrap();
        let b = run(&g.data, &Priors::default(), &["delta=0.1"], 5).unwrap();
        assert_eq!(a.to_json(), b.to_json());
    }

    #[test]
    fn delta_auto_is_near_the_noise_bound() {
        let g = hysid_testkit::b1(400, 4.0, hysid_testkit::Noise::Uniform(0.1), 11);
        let m = run(&g.data, &Priors::default(), &["delta=auto"], 1).unwrap();
        let d = m.info().diagnostics.method["delta"].as_f64().unwrap();
        // Uniform noise U[-0.1, 0.1]: sigma = 0.0577, 3 sigma = 0.173.
        assert!((0.1..0.3).contains(&d), "auto delta {d}");
        assert_eq!(pwarx(&m).modes.len(), 3);
    }

    #[test]
    fn priors_modes_and_max_modes() {
        let g = hysid_testkit::b1(300, 4.0, hysid_testkit::Noise::Uniform(0.1), 4);
        // Upper bound below the truth: at most 2 modes.
        let pri = Priors {
            max_modes: Some(2),
            ..Default::default()
        };
        assert!(
            pwarx(&run(&g.data, &pri, &["delta=0.1"], 1).unwrap())
                .modes
                .len()
                <= 2
        );
        assert!(
            pwarx(
                &run(
                    &g.data,
                    &Priors::default(),
                    &["delta=0.1", "max_modes=1"],
                    1
                )
                .unwrap()
            )
            .modes
            .len()
                == 1
        );
        // Exact count met.
        let pri = Priors {
            modes: Some(3),
            ..Default::default()
        };
        assert_eq!(
            pwarx(&run(&g.data, &pri, &["delta=0.1"], 1).unwrap())
                .modes
                .len(),
            3
        );
        // Exact count that delta cannot produce: an error naming both.
        let pri = Priors {
            modes: Some(3),
            ..Default::default()
        };
        let e = run(&g.data, &pri, &["delta=50"], 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("modes = 3") && e.contains("delta"), "{e}");
    }

    #[test]
    fn refuses_bad_options_and_priors() {
        let g = hysid_testkit::b1(100, 4.0, hysid_testkit::Noise::Uniform(0.1), 4);
        assert!(run(&g.data, &Priors::default(), &["delta=-1"], 1).is_err());
        assert!(run(&g.data, &Priors::default(), &["delta=0.1", "beta=1.5"], 1).is_err());
        assert!(run(&g.data, &Priors::default(), &["delta=0.1", "cycles=0"], 1).is_err());
        let mut pri = Priors::default();
        pri.fixed.insert("a3".into(), 0.0);
        let e = run(&g.data, &pri, &["delta=0.1"], 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown name 'a3'"), "{e}");
        let pri = Priors::from_toml("[fixed]\nc = 5.0\n[bounds]\nc = [0.0, 1.0]\n", "p").unwrap();
        let e = run(&g.data, &pri, &["delta=0.1"], 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("outside [bounds]"), "{e}");
    }

    /// A spent time budget ends the run after the first mode extraction:
    /// `run_status` says so, with the message in `status`.
    #[test]
    fn a_spent_time_budget_is_reported() {
        let g = hysid_testkit::b1(300, 4.0, hysid_testkit::Noise::Uniform(0.1), 7);
        let problem = Problem {
            data: &g.data,
            orders: RegressorSpec::new(1, 1, 1),
            priors: &Priors::default(),
            priors_origin: None,
        };
        let ctx = RunContext {
            deadline: hysid_core::backend::Deadline::at(std::time::Instant::now()),
            ..RunContext::quiet(7)
        };
        let m = Pwarx(Bounded)
            .run(&problem, &Settings::parse(&["delta=0.1"]).unwrap(), &ctx)
            .unwrap();
        let dg = &m.info().diagnostics;
        assert_eq!(dg.run_status, RunStatus::TimeBudget);
        assert_eq!(
            dg.status,
            [
                "time budget reached after 1 mode extraction(s) and 0 refinement round(s): \
              the modes found by then"
            ]
        );
        assert_eq!(dg.method["stopped_by_deadline"], true);
    }

    #[test]
    fn bad_options_are_option_errors() {
        let g = hysid_testkit::b1(100, 4.0, hysid_testkit::Noise::Uniform(0.1), 4);
        for (set, want) in [
            (
                "delta=0",
                "--set delta=0: must be a finite number > 0 (or auto)",
            ),
            ("cycles=0", "--set cycles=0: must be in 1..=100000"),
            ("t0=-1", "--set t0=-1: must be a finite number > 0"),
            (
                "alpha=-0.5",
                "--set alpha=-0.5: must be a finite number >= 0",
            ),
            ("beta=1", "--set beta=1: must be in [0, 1)"),
        ] {
            let given = if set.starts_with("delta") {
                vec![set]
            } else {
                vec!["delta=0.1", set]
            };
            let e = run(&g.data, &Priors::default(), &given, 1).unwrap_err();
            let IdentifyError::Options(o) = e else {
                panic!("{set}: {e}")
            };
            assert_eq!(o.render("--set"), want);
        }
    }

    /// Without `delta` the bound is `auto`'s, and the model says so.
    #[test]
    fn the_error_bound_is_auto_by_default() {
        let g = hysid_testkit::b1(300, 4.0, hysid_testkit::Noise::Uniform(0.1), 2);
        let given = run(&g.data, &Priors::default(), &["delta=auto"], 1).unwrap();
        let default = run(&g.data, &Priors::default(), &[], 1).unwrap();
        let d = &pwarx(&default).info.diagnostics.method;
        assert_eq!(d["delta_auto"], true);
        assert_eq!(d["delta"], pwarx(&given).info.diagnostics.method["delta"]);
        assert_eq!(pwarx(&default).info.options["delta"], "auto");
    }

    #[test]
    fn least_squares_refit_runs() {
        let g = hysid_testkit::b1(300, 4.0, hysid_testkit::Noise::Uniform(0.1), 2);
        let m = run(&g.data, &Priors::default(), &["delta=0.1", "refit=ls"], 1).unwrap();
        assert_eq!(pwarx(&m).modes.len(), 3);
    }
}
