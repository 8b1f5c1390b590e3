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
//! samples ([`refit`]), and estimates the regions with `hysid-regions`.
//! `delta` trades fit for the number of modes: [`sweep::delta_sweep`]
//! reports the trade-off. `docs/bounded.md` lists every constant and which
//! parts are the paper's and which are ours.
//!
//! Priors honoured (`docs/priors.md`, `docs/bounded.md` "Priors"):
//! all of them. `modes` / `max_modes` count every mode, saturation modes
//! included; samples at a `[[saturation]]` stop are assigned to that stop
//! before extraction and the result is a hybrid automaton with the stops as
//! modes on their guard sets; `[fixed]`, `[bounds]` and `[[tie]]` restrict
//! the parameters in every fit ([`constraints`]); `switching` restricts the
//! region normals.

pub mod constraints;
pub mod maxfs;
pub mod noise;
pub mod procedure;
pub mod refit;
pub mod samples;
pub mod sweep;

use constraints::Constraints;
use hysid_core::backend::{Identifier, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::OptionType;
use hysid_core::options::{CheckOptions, Checked, OptionError};
use hysid_core::priors::PriorKind;
use hysid_model::model::{HybridAutomaton, ModelInfo, PwarxMode, PwarxModel};
use hysid_regions::{RegionMethod, RegionOptions};
use nalgebra::DMatrix;
use procedure::{Classification, ProcedureSettings, RefitKind, SampleClass};
use samples::Samples;
use serde::{Deserialize, Serialize};

/// The keyword `auto` of `--set delta=auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum AutoKeyword {
    /// `auto`.
    #[serde(rename = "auto")]
    Auto,
}

/// The error bound: a number (output units) or `auto`
/// ([`noise::auto_delta`]). Parses from `--set delta=0.1` and
/// `--set delta=auto`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Delta {
    /// A bound in output units.
    Value(f64),
    /// Estimated from the data.
    Auto(AutoKeyword),
}

impl OptionType for Delta {
    fn type_name() -> String {
        "float|auto".into()
    }
}

hysid_core::option_enum! {
    /// How each mode is re-estimated on its assigned samples.
    pub enum Refit {
        /// Chebyshev (l-infinity) LP: certifies |residual| <= delta on every assigned sample.
        Linf => "linf",
        /// Least squares (not certified).
        Ls => "ls",
    }
}

hysid_core::backend_options! {
    /// Options of the `bounded` back-end.
    pub struct BoundedOptions {
        /// Bound delta on the identification error |y - phi' theta|, in output
        /// units; required. `auto`: 3 times the median noise standard deviation
        /// of local affine fits (docs/bounded.md). Larger delta, fewer modes.
        delta: Option<Delta> = None,
        /// Thermal relaxation cycles per MAX FS problem (each visits all remaining
        /// samples once in a random order).
        cycles: usize = 100,
        /// Initial temperature T0 as a multiple of max(median |residual of the start|,
        /// delta), per relaxed start; the temperature falls linearly to 0 over the cycles.
        t0: f64 = 2.0,
        /// Candidate starts of each MAX FS problem besides the least-squares fit of the
        /// remaining samples: least-squares fits of random local neighbourhoods (3p nearest
        /// samples in standardised regressor space); the best candidate is relaxed too.
        restarts: usize = 8,
        /// Merge two modes when |theta_i - theta_j| / min(|theta_i|, |theta_j|) <= alpha.
        alpha: f64 = 0.05,
        /// Drop modes with fewer than max(beta N, number of parameters) assigned samples.
        beta: f64 = 0.02,
        /// Re-estimation of each mode: linf (Chebyshev LP, certified) or ls.
        refit: Refit = Refit::Linf,
        /// Upper bound on the number of modes, saturation modes included (also taken
        /// from the prior max_modes); none: no bound.
        max_modes: Option<usize> = None,
        /// Region estimation from the classified samples (hysid-regions): mrlp
        /// (multicategory robust LP, complete partition), msvm (multicategory SVM,
        /// complete partition), psvc (pairwise proximal SVM, may leave holes) or
        /// softmax (multinomial logistic regression, complete partition).
        regions: RegionMethod = RegionMethod::Mrlp,
    }
}

impl CheckOptions for BoundedOptions {
    fn check(&self) -> Result<(), OptionError> {
        Ok(())
    }
}

/// The `bounded` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Bounded;

impl Bounded {
    /// Checks the options and the priors and turns them into procedure
    /// settings for samples `s` (resolving `delta = auto`).
    pub fn settings(
        problem: &Problem<'_>,
        options: &BoundedOptions,
        s: &Samples,
        ctx: &RunContext<'_>,
    ) -> Result<ProcedureSettings, IdentifyError> {
        let bad = |m: String| Err(IdentifyError::BadData(m));
        let delta = match options.delta {
            None => {
                return bad("method 'bounded' needs an error bound: --set delta=<bound in output units> or --set delta=auto".into());
            }
            Some(Delta::Value(d)) if !(d.is_finite() && d > 0.0) => {
                return bad(format!(
                    "--set delta={d}: must be a finite number > 0 (or auto)"
                ));
            }
            Some(Delta::Value(d)) => d,
            Some(Delta::Auto(_)) => noise::auto_delta(s),
        };
        if options.cycles == 0 || options.cycles > 100_000 {
            return bad(format!(
                "--set cycles={}: must be in 1..=100000",
                options.cycles
            ));
        }
        if !(options.t0.is_finite() && options.t0 > 0.0) {
            return bad(format!(
                "--set t0={}: must be a finite number > 0",
                options.t0
            ));
        }
        if !(options.alpha.is_finite() && options.alpha >= 0.0) {
            return bad(format!(
                "--set alpha={}: must be a finite number >= 0",
                options.alpha
            ));
        }
        if !(options.beta.is_finite() && (0.0..1.0).contains(&options.beta)) {
            return bad(format!("--set beta={}: must be in [0, 1)", options.beta));
        }
        let pri = problem.priors;
        let stops = pri.saturation.len();
        if let Some(m) = options.max_modes
            && m <= stops
        {
            return bad(format!(
                "--set max_modes={m}: counts every mode, the {stops} saturation mode(s) included: must be at least {}",
                stops + 1
            ));
        }
        if pri.modes.is_some_and(|m| m <= stops) || pri.max_modes.is_some_and(|m| m <= stops) {
            return bad(format!(
                "prior modes / max_modes must be at least {} (they count the {stops} saturation mode(s))",
                stops + 1
            ));
        }
        // Counts of ordinary modes (`modes` counts every mode).
        let max_modes = match (
            options.max_modes.map(|m| m - stops),
            pri.max_ordinary_modes(),
        ) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        let exact = pri.ordinary_modes();
        // An exact count the record cannot hold (each mode needs at least
        // n + 1 samples) is bad input, as in `cluster`.
        let rows = problem.data.len().saturating_sub(problem.orders.lag());
        let p = problem.orders.dim() + 1;
        if let Some(s_) = exact
            && s_.checked_mul(p).is_none_or(|need| need > rows)
        {
            return bad(format!(
                "{rows} regressors cannot identify {} modes of {p} parameters",
                s_ + stops
            ));
        }
        if let (Some(s_), Some(m)) = (exact, max_modes)
            && s_ > m
        {
            return bad(format!(
                "prior modes = {} exceeds the bound max_modes = {}",
                s_ + stops,
                m + stops
            ));
        }
        let constraints = Constraints::new(pri, problem.orders).map_err(IdentifyError::BadData)?;
        Ok(ProcedureSettings {
            delta,
            cycles: options.cycles,
            t0: options.t0,
            alpha: options.alpha,
            beta: options.beta,
            restarts: options.restarts,
            refit: match options.refit {
                Refit::Linf => RefitKind::Linf,
                Refit::Ls => RefitKind::Ls,
            },
            max_modes,
            exact_modes: exact,
            seed: ctx.seed,
            deadline: ctx.deadline,
            constraints,
        })
    }

    /// Runs the procedure and returns the classification with the samples
    /// it was computed on (the ordinary samples: saturated ones removed;
    /// for tests and the sweep).
    pub fn classify(
        problem: &Problem<'_>,
        options: &BoundedOptions,
        ctx: &RunContext<'_>,
    ) -> Result<(Classification, Samples, ProcedureSettings), IdentifyError> {
        let c = Self::classify_all(problem, options, ctx)?;
        Ok((c.classification, c.samples, c.settings))
    }

    /// Runs the procedure: samples at a known stop are assigned to it
    /// first (they never enter MAX FS), the rest are classified.
    pub fn classify_all(
        problem: &Problem<'_>,
        options: &BoundedOptions,
        ctx: &RunContext<'_>,
    ) -> Result<Classified, IdentifyError> {
        let spec = problem.orders;
        problem
            .priors
            .check_pwarx_names(&spec)
            .map_err(IdentifyError::BadData)?;
        let reg = spec
            .build(problem.data)
            .map_err(|e| IdentifyError::BadData(e.to_string()))?;
        let all = Samples::from_regressors(&reg);
        if all.y.iter().chain(&all.phi).any(|v| !v.is_finite()) {
            return Err(IdentifyError::BadData(
                "the record has non-finite samples".into(),
            ));
        }
        let stops = problem.priors.saturated_samples(&all.y);
        let ordinary: Vec<usize> = (0..all.len()).filter(|&k| stops[k].is_none()).collect();
        let s = if ordinary.len() == all.len() {
            all
        } else {
            let mut phi = Vec::with_capacity(ordinary.len() * all.p);
            for &k in &ordinary {
                phi.extend_from_slice(all.row(k));
            }
            Samples::new(all.p, phi, ordinary.iter().map(|&k| all.y[k]).collect())
        };
        let set = Self::settings(problem, options, &s, ctx)?;
        let c = procedure::run(&s, &set).map_err(|e| match e {
            procedure::ProcedureError::TooFewSamples { .. }
            | procedure::ProcedureError::Setting(_) => IdentifyError::BadData(e.to_string()),
            _ => IdentifyError::Failed {
                method: "bounded".into(),
                message: e.to_string(),
            },
        })?;
        Ok(Classified {
            classification: c,
            samples: s,
            settings: set,
            stops,
            ordinary,
        })
    }
}

/// What [`Bounded::classify_all`] returns.
#[derive(Debug, Clone)]
pub struct Classified {
    /// Classification of the ordinary samples.
    pub classification: Classification,
    /// The ordinary samples (saturated ones removed).
    pub samples: Samples,
    /// The settings used.
    pub settings: ProcedureSettings,
    /// For every regression row of the record, the known stop its target
    /// sits at (`Priors::saturated_samples`).
    pub stops: Vec<Option<usize>>,
    /// Regression row of each ordinary sample.
    pub ordinary: Vec<usize>,
}

impl Classified {
    /// Mode of every regression row of the record: ordinary modes
    /// `0..s`, then the stops in prior order (`s + stop`), `None` for
    /// infeasible samples.
    pub fn row_labels(&self) -> Vec<Option<usize>> {
        let s = self.classification.thetas.len();
        let mut out: Vec<Option<usize>> = self.stops.iter().map(|o| o.map(|i| s + i)).collect();
        for (r, &k) in self.ordinary.iter().enumerate() {
            out[k] = self.classification.labels[r];
        }
        out
    }
}

impl Identifier for Bounded {
    type Options = BoundedOptions;
    const NAME: &'static str = "bounded";
    const SUMMARY: &'static str = "bounded-error PWARX (Bemporad et al. 2005): the number of modes follows from the error bound delta";
    const HONOURS: &'static [PriorKind] = PriorKind::ALL;

    fn identify(
        &self,
        problem: &Problem<'_>,
        options: &Checked<BoundedOptions>,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        let spec = problem.orders;
        let all = Self::classify_all(problem, options, ctx)?;
        let (c, s, set) = (&all.classification, &all.samples, &all.settings);
        let pri = problem.priors;
        let names = spec.regressor_names();
        let switching = (!pri.switching.is_empty()).then(|| {
            pri.switching
                .iter()
                .filter_map(|r| names.iter().position(|n| n == r))
                .collect::<Vec<usize>>()
        });
        let ropt = RegionOptions {
            method: options.regions,
            switching,
            ..Default::default()
        };
        let part =
            hysid_regions::estimate(&regressor_rows(s, c), &labelled(c), c.thetas.len(), &ropt)
                .map_err(|e| IdentifyError::Failed {
                    method: "bounded".into(),
                    message: format!("regions: {e}"),
                })?;
        let regions = part.regions;
        let mut info = ModelInfo::default();
        let dg = &mut info.diagnostics;
        dg.method.insert("delta".into(), set.delta.into());
        dg.method.insert(
            "delta_auto".into(),
            matches!(options.delta, Some(Delta::Auto(_))).into(),
        );
        dg.method
            .insert("modes_found".into(), c.thetas.len().into());
        dg.method
            .insert("greedy_modes".into(), c.greedy_modes.into());
        dg.method.insert("samples".into(), all.stops.len().into());
        if !pri.saturation.is_empty() {
            let mut per_stop = vec![0usize; pri.saturation.len()];
            for i in all.stops.iter().flatten() {
                per_stop[*i] += 1;
            }
            dg.method.insert("ordinary_samples".into(), s.len().into());
            dg.method
                .insert("saturated_per_stop".into(), serde_json::json!(per_stop));
        }
        if let Some(e) = c.tie_projection_error {
            dg.method.insert("tie_projection_error".into(), e.into());
            dg.method.insert(
                "tie_projection_within_delta".into(),
                (e <= set.delta).into(),
            );
        }
        dg.method
            .insert("assigned".into(), c.count(SampleClass::Assigned).into());
        dg.method.insert(
            "undecidable".into(),
            c.count(SampleClass::Undecidable).into(),
        );
        dg.method
            .insert("infeasible".into(), c.count(SampleClass::Infeasible).into());
        dg.method.insert("rounds".into(), c.rounds.into());
        dg.method.insert("converged".into(), c.converged.into());
        dg.method.insert("merged".into(), c.merged.into());
        dg.method.insert("dropped".into(), c.dropped.into());
        dg.method
            .insert("max_residual".into(), serde_json::json!(c.max_residual));
        let mut counts = vec![0usize; c.thetas.len()];
        for l in c.labels.iter().flatten() {
            counts[*l] += 1;
        }
        dg.method
            .insert("samples_per_mode".into(), serde_json::json!(counts));
        dg.method.insert(
            "region_training_accuracy".into(),
            part.training_accuracy.into(),
        );
        dg.method
            .insert("partition_complete".into(), part.complete.into());
        let mut status: Vec<String> = Vec::new();
        if c.stopped_by_deadline {
            dg.method.insert("stopped_by_deadline".into(), true.into());
            status.push(format!(
                "time budget reached after {} mode extraction(s) and {} refinement round(s): the modes found by then",
                c.greedy_modes, c.rounds
            ));
        }
        if let Some(e) = c.tie_projection_error
            && e > set.delta
        {
            // The greedy extraction ran with the ties relaxed; imposing them
            // afterwards did not keep the greedy modes within delta.
            status.push(format!(
                "warning: the [[tie]] priors, imposed after the greedy extraction (which relaxes them), \
                 fit the greedy modes with a largest error of {e:.4} > delta = {}; the refinement \
                 re-classified the samples under the ties (docs/bounded.md, \"Priors\")",
                set.delta
            ));
        }
        if !status.is_empty() {
            dg.method.insert("status".into(), status.join("; ").into());
        }
        let pwarx = PwarxModel {
            na: spec.na,
            nb: spec.nb,
            inputs: spec.inputs,
            modes: c
                .thetas
                .iter()
                .zip(regions)
                .map(|(t, r)| PwarxMode {
                    theta: t.clone(),
                    region: r,
                    name: None,
                })
                .collect(),
            info,
        };
        Ok(if pri.saturation.is_empty() {
            Model::Pwarx(pwarx)
        } else {
            Model::HybridAutomaton(HybridAutomaton::from_pwarx_with_stops(
                &pwarx,
                &pri.saturation,
            ))
        })
    }
}

/// Regressors (without the constant) of the labelled samples, as rows.
fn regressor_rows(s: &Samples, c: &Classification) -> DMatrix<f64> {
    let rows: Vec<usize> = (0..s.len()).filter(|&k| c.labels[k].is_some()).collect();
    let d = s.p - 1;
    DMatrix::from_fn(rows.len(), d, |r, j| s.row(rows[r])[j])
}

/// Labels of the labelled samples (infeasible samples are left out).
fn labelled(c: &Classification) -> Vec<usize> {
    c.labels.iter().flatten().copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_core::backend::Backend;
    use hysid_core::options::Settings;
    use hysid_core::priors::Priors;
    use hysid_core::simulate::validate;
    use hysid_model::data::Dataset;
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
        Bounded.run(
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
        assert_eq!(r(&["delta=0.1"]).unwrap().delta, Some(Delta::Value(0.1)));
        assert_eq!(r(&["delta=1"]).unwrap().delta, Some(Delta::Value(1.0)));
        assert_eq!(
            r(&["delta=auto"]).unwrap().delta,
            Some(Delta::Auto(AutoKeyword::Auto))
        );
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
        let m = run(&g.data, &Priors::default(), &["delta=0.1"], 7).unwrap();
        let p = pwarx(&m);
        assert_eq!(p.modes.len(), 3);
        let dg = &m.info().diagnostics.to_map();
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
        let pe = hysid_model::metrics::parameter_error(&truth, &ident);
        assert!(pe.max_relative_error < 0.05, "{pe:?}");
        // The regions classify fresh data from the same system: at least 97 %
        // of the regressors in the right mode (a misclassified sample costs a
        // prediction error of several units in B1, so FIT is not the measure).
        let v = hysid_testkit::b1(300, 4.0, hysid_testkit::Noise::Uniform(0.1), 99);
        let reg = RegressorSpec::new(1, 1, 1).build(&v.data).unwrap();
        let got: Vec<usize> = (0..reg.len())
            .map(|k| p.mode_of(&[reg.x[(k, 0)], reg.x[(k, 1)]]).mode)
            .collect();
        let acc = hysid_model::metrics::mode_accuracy(&v.row_modes(), &got).accuracy;
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
        let e = run(&g.data, &Priors::default(), &[], 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("delta"), "{e}");
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

    #[test]
    fn least_squares_refit_runs() {
        let g = hysid_testkit::b1(300, 4.0, hysid_testkit::Noise::Uniform(0.1), 2);
        let m = run(&g.data, &Priors::default(), &["delta=0.1", "refit=ls"], 1).unwrap();
        assert_eq!(pwarx(&m).modes.len(), 3);
    }
}
