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
//! Priors honoured: `modes` (exact number of modes) and `max_modes` (upper
//! bound). Anything else is refused.

pub mod maxfs;
pub mod noise;
pub mod procedure;
pub mod refit;
pub mod samples;
pub mod sweep;
pub mod systems;

use hysid_core::backend::{Identifier, IdentifyError, Problem, RunContext};
use hysid_core::geometry::Polyhedron;
use hysid_core::model::{Model, ModelInfo, PwarxMode, PwarxModel};
use hysid_core::options::OptionType;
use hysid_core::priors::PriorKind;
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
        /// Initial temperature T0 as a multiple of max(median |residual of the LS
        /// start|, delta); the temperature falls linearly to 0 over the cycles.
        t0: f64 = 2.0,
        /// Starts of each MAX FS problem besides the least-squares fit of the remaining
        /// samples: least-squares fits of random local neighbourhoods (3p nearest samples
        /// in standardised regressor space); the start satisfying the most pairs wins.
        restarts: usize = 8,
        /// Merge two modes when |theta_i - theta_j| / min(|theta_i|, |theta_j|) <= alpha.
        alpha: f64 = 0.05,
        /// Drop modes with fewer than max(beta N, number of parameters) assigned samples.
        beta: f64 = 0.02,
        /// Re-estimation of each mode: linf (Chebyshev LP, certified) or ls.
        refit: Refit = Refit::Linf,
        /// Upper bound on the number of modes (also taken from the prior max_modes);
        /// none: no bound.
        max_modes: Option<usize> = None,
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
                return bad(format!("--set delta={d}: must be a finite number > 0 (or auto)"));
            }
            Some(Delta::Value(d)) => d,
            Some(Delta::Auto(_)) => noise::auto_delta(s),
        };
        if options.cycles == 0 || options.cycles > 100_000 {
            return bad(format!("--set cycles={}: must be in 1..=100000", options.cycles));
        }
        if !(options.t0.is_finite() && options.t0 > 0.0) {
            return bad(format!("--set t0={}: must be a finite number > 0", options.t0));
        }
        if !(options.alpha.is_finite() && options.alpha >= 0.0) {
            return bad(format!("--set alpha={}: must be a finite number >= 0", options.alpha));
        }
        if !(options.beta.is_finite() && (0.0..1.0).contains(&options.beta)) {
            return bad(format!("--set beta={}: must be in [0, 1)", options.beta));
        }
        if options.max_modes == Some(0) {
            return bad("--set max_modes=0: must be at least 1".into());
        }
        let pri = problem.priors;
        if pri.modes == Some(0) || pri.max_modes == Some(0) {
            return bad("prior modes / max_modes = 0: must be at least 1".into());
        }
        let max_modes = match (options.max_modes, pri.max_modes) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        if let (Some(s_), Some(m)) = (pri.modes, max_modes)
            && s_ > m
        {
            return bad(format!("prior modes = {s_} exceeds the bound max_modes = {m}"));
        }
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
            exact_modes: pri.modes,
            seed: ctx.seed,
            deadline: ctx.deadline,
        })
    }

    /// Runs the procedure and returns the classification with the samples
    /// it was computed on (for tests and the sweep).
    pub fn classify(
        problem: &Problem<'_>,
        options: &BoundedOptions,
        ctx: &RunContext<'_>,
    ) -> Result<(Classification, Samples, ProcedureSettings), IdentifyError> {
        let spec = problem.orders;
        let reg = spec.build(problem.data).map_err(|e| IdentifyError::BadData(e.to_string()))?;
        let s = Samples::from_regressors(&reg);
        if s.y.iter().chain(&s.phi).any(|v| !v.is_finite()) {
            return Err(IdentifyError::BadData("the record has non-finite samples".into()));
        }
        let set = Self::settings(problem, options, &s, ctx)?;
        let c = procedure::run(&s, &set).map_err(|e| match e {
            procedure::ProcedureError::TooFewSamples { .. } | procedure::ProcedureError::Setting(_) => {
                IdentifyError::BadData(e.to_string())
            }
            _ => IdentifyError::Failed { method: "bounded".into(), message: e.to_string() },
        })?;
        Ok((c, s, set))
    }
}

impl Identifier for Bounded {
    type Options = BoundedOptions;
    const NAME: &'static str = "bounded";
    const SUMMARY: &'static str =
        "bounded-error PWARX (Bemporad et al. 2005): the number of modes follows from the error bound delta";
    const HONOURS: &'static [PriorKind] = &[PriorKind::Modes, PriorKind::MaxModes];

    fn identify(
        &self,
        problem: &Problem<'_>,
        options: &BoundedOptions,
        ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        let spec = problem.orders;
        let (c, s, set) = Self::classify(problem, options, ctx)?;
        let regions = estimate_regions(&s, &c)?;
        let mut info = ModelInfo::default();
        let dg = &mut info.diagnostics;
        dg.insert("delta".into(), set.delta.into());
        dg.insert("delta_auto".into(), matches!(options.delta, Some(Delta::Auto(_))).into());
        dg.insert("modes_found".into(), c.thetas.len().into());
        dg.insert("greedy_modes".into(), c.greedy_modes.into());
        dg.insert("samples".into(), s.len().into());
        dg.insert("assigned".into(), c.count(SampleClass::Assigned).into());
        dg.insert("undecidable".into(), c.count(SampleClass::Undecidable).into());
        dg.insert("infeasible".into(), c.count(SampleClass::Infeasible).into());
        dg.insert("rounds".into(), c.rounds.into());
        dg.insert("converged".into(), c.converged.into());
        dg.insert("merged".into(), c.merged.into());
        dg.insert("dropped".into(), c.dropped.into());
        dg.insert("max_residual".into(), serde_json::json!(c.max_residual));
        let mut counts = vec![0usize; c.thetas.len()];
        for l in c.labels.iter().flatten() {
            counts[*l] += 1;
        }
        dg.insert("samples_per_mode".into(), serde_json::json!(counts));
        if c.stopped_by_deadline {
            dg.insert("stopped_by_deadline".into(), true.into());
        }
        Ok(Model::Pwarx(PwarxModel {
            na: spec.na,
            nb: spec.nb,
            inputs: spec.inputs,
            modes: c
                .thetas
                .iter()
                .zip(regions)
                .map(|(t, r)| PwarxMode { theta: t.clone(), region: r, name: None })
                .collect(),
            info,
        }))
    }
}

/// Regions of the modes from the labelled samples.
fn estimate_regions(_s: &Samples, c: &Classification) -> Result<Vec<Polyhedron>, IdentifyError> {
    // Placeholder until hysid-regions is merged.
    Ok(vec![Polyhedron::everything(); c.thetas.len()])
}
