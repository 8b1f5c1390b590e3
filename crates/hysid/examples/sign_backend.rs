//! The worked example of `docs/architecture.md`: a complete PWARX back-end
//! in one file, on the pipeline of `hysid_estimation::pwarx`, registered
//! beside the shipped ones with one line. Its partition is known in
//! advance, one mode per sign of the first input `u1(k-1)`, so the whole
//! method is: split the samples by that sign, fit each mode by least
//! squares under the priors.
//!
//! `cargo run --example sign_backend -p hysid` identifies a simulated
//! record through the registry; `cargo test -p hysid --example
//! sign_backend` runs the tests below.

use hysid_core::backend::{IdentifyError, Problem, RunContext};
use hysid_core::options::{CheckOptions, OptionError, Settings, check_float};
use hysid_core::priors::{PriorKind, Priors};
use hysid_estimation::constrained::{Parametrisation, fit_modes_on};
use hysid_estimation::pwarx::{ModeCount, ModeRule, Pwarx, PwarxData, PwarxFit, PwarxMethod};
use hysid_model::geometry::Polyhedron;
use hysid_model::model::{ModelInfo, PwarxMode, PwarxModel};
use hysid_testkit::{Benchmark, Noise, generate};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

hysid_core::backend_options! {
    /// Options of the `sign` back-end.
    pub struct SignOptions {
        /// Samples with u1(k-1) at or above this threshold go to the second mode.
        threshold: f64 = 0.0,
    }
}

impl CheckOptions for SignOptions {
    fn check(&self) -> Result<(), OptionError> {
        check_float(
            "threshold",
            self.threshold,
            |_| true,
            "must be a finite number",
        )
    }
}

/// The `sign` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sign;

impl PwarxMethod for Sign {
    type Options = SignOptions;
    type Diagnostics = SignDiagnostics;
    const NAME: &'static str = "sign";
    const SEEDED: bool = false;
    const MODE_RULE: ModeRule = ModeRule::Method;
    const SUMMARY: &'static str = "one affine mode per sign of u1(k-1): the worked example";
    const HONOURS: &'static [PriorKind] = &[
        PriorKind::Modes,
        PriorKind::Saturation,
        PriorKind::Tie,
        PriorKind::Fixed,
        PriorKind::Bounds,
        PriorKind::Equality,
    ];

    fn fit(
        &self,
        data: &PwarxData<'_>,
        options: &SignOptions,
        _ctx: &RunContext<'_>,
    ) -> Result<PwarxFit<SignDiagnostics>, IdentifyError> {
        split_fit(options, data)
    }
}

/// What the `sign` back-end reports besides the common diagnostics.
#[derive(Debug, Clone, Serialize)]
pub struct SignDiagnostics {
    /// Ordinary samples in each mode.
    pub samples_per_mode: [usize; 2],
}

/// The method's steps: the regressor column of `u1(k-1)`, the split by its
/// sign, least squares per mode under the priors, the two half-spaces.
fn split_fit(
    options: &SignOptions,
    data: &PwarxData<'_>,
) -> Result<PwarxFit<SignDiagnostics>, IdentifyError> {
    let column = input_column(data)?;
    let split = split_by_sign(data, column, options.threshold);
    let thetas = least_squares(data, &split)?;
    let regions = half_spaces(data.spec.dim(), column, options.threshold);
    Ok(PwarxFit::complete(
        PwarxMode::unnamed(thetas, regions),
        SignDiagnostics {
            samples_per_mode: [split[0].len(), split[1].len()],
        },
    ))
}

/// The column of `u1(k-1)` among the regressors `[y(k-1..k-na), u1(k-1..)]`;
/// the mode count, if given, must be two.
fn input_column(data: &PwarxData<'_>) -> Result<usize, IdentifyError> {
    if data.spec.nb == 0 {
        return Err(SignError::NoInputLag.into());
    }
    match data.modes {
        ModeCount::Exact(s) if s != 2 => Err(SignError::ModeCount(s).into()),
        _ => Ok(data.spec.na),
    }
}

/// The ordinary rows below the threshold, then those at or above it.
fn split_by_sign(data: &PwarxData<'_>, column: usize, threshold: f64) -> [Vec<usize>; 2] {
    let (low, high) = data
        .ordinary
        .iter()
        .partition(|&&r| data.regressors.x[(r, column)] < threshold);
    [low, high]
}

/// One parameter vector per mode (`hysid_estimation::constrained`: ties,
/// fixed values and equalities exact, bounds by a QP).
fn least_squares(
    data: &PwarxData<'_>,
    split: &[Vec<usize>; 2],
) -> Result<Vec<Vec<f64>>, IdentifyError> {
    let par = Parametrisation::from_priors(data.priors(), &data.spec, 2)
        .map_err(|e| data.prior_error(e))?;
    fit_modes_on(&par, &data.regressors, split).map_err(IdentifyError::failed)
}

/// `u1(k-1) <= threshold` and `u1(k-1) >= threshold` as polyhedra.
fn half_spaces(dim: usize, column: usize, threshold: f64) -> [Polyhedron; 2] {
    let normal = |sign: f64| {
        let mut a = vec![0.0; dim];
        a[column] = sign;
        a
    };
    [
        Polyhedron::from_inequalities(vec![normal(1.0)], vec![threshold]),
        Polyhedron::from_inequalities(vec![normal(-1.0)], vec![-threshold]),
    ]
}

/// Bad input of the `sign` back-end (an [`IdentifyError::Input`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SignError {
    /// No `u1(k-1)` regressor.
    #[error("method 'sign' needs nb >= 1")]
    NoInputLag,
    /// A mode count other than two ordinary modes.
    #[error("method 'sign' identifies exactly two ordinary modes, not {0}")]
    ModeCount(usize),
}

impl From<SignError> for IdentifyError {
    fn from(e: SignError) -> Self {
        IdentifyError::input(e)
    }
}

/// The true parameters `[a1, b1, c]` of the two modes of [`record`].
const TRUTH: [[f64; 3]; 2] = [[0.5, 1.0, 0.2], [-0.3, -2.0, 1.0]];

/// `y(k) = theta_q . [y(k-1), u(k-1), 1]`, mode 0 for `u(k-1) < 0`,
/// without noise.
fn record(n: usize, seed: u64) -> Benchmark {
    let mode = |theta: [f64; 3], sign: f64| PwarxMode {
        theta: theta.to_vec(),
        region: Polyhedron::from_inequalities(vec![vec![0.0, sign]], vec![0.0]),
        name: None,
    };
    let truth = PwarxModel {
        na: 1,
        nb: 1,
        inputs: 1,
        modes: vec![mode(TRUTH[0], 1.0), mode(TRUTH[1], -1.0)],
        info: ModelInfo::default(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let u: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
    generate(truth, vec![u], &[0.0], Noise::None, &mut rng)
}

/// Registers the back-end beside the shipped ones (the one line) and
/// identifies a simulated record through the registry.
fn main() -> Result<(), IdentifyError> {
    let registry = hysid::registry().with(Pwarx(Sign));
    let b = record(200, 3);
    let problem = Problem {
        data: &b.data,
        orders: b.truth.spec(),
        priors: &Priors::default(),
        priors_origin: None,
    };
    let model =
        registry
            .require("sign")?
            .run(&problem, &Settings::default(), &RunContext::quiet(1))?;
    println!("{}", model.to_json());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_core::backend::Backend;
    use hysid_core::model::Model;

    fn run(priors: &Priors, set: &[&str]) -> Result<Model, IdentifyError> {
        let b = record(200, 3);
        let problem = Problem {
            data: &b.data,
            orders: b.truth.spec(),
            priors,
            priors_origin: None,
        };
        Pwarx(Sign).run(
            &problem,
            &Settings::parse(set).unwrap(),
            &RunContext::quiet(1),
        )
    }

    fn thetas(m: &Model) -> Vec<Vec<f64>> {
        match m {
            Model::Pwarx(p) => p.modes.iter().map(|q| q.theta.clone()).collect(),
            _ => panic!("not a PWARX model"),
        }
    }

    #[test]
    fn noise_free_parameters_are_recovered() {
        let m = run(&Priors::default(), &[]).unwrap();
        for (got, want) in thetas(&m).iter().zip(TRUTH) {
            for (g, w) in got.iter().zip(want) {
                assert!((g - w).abs() < 1e-9, "{got:?} vs {want:?}");
            }
        }
        let d = &m.info().diagnostics;
        assert_eq!((d.modes, d.regions_complete), (Some(2), Some(true)));
        assert_eq!(d.method["samples_per_mode"].as_array().unwrap().len(), 2);
    }

    #[test]
    fn a_tie_holds_in_both_modes() {
        let priors = Priors::from_toml("[[tie]]\nparams = [\"a1\"]\n", "p.toml").unwrap();
        let t = thetas(&run(&priors, &[]).unwrap());
        assert_eq!(t[0][0], t[1][0]);
    }

    #[test]
    fn bad_options_and_mode_counts_are_refused() {
        let e = run(&Priors::default(), &["threshold=inf"]).unwrap_err();
        assert!(matches!(e, IdentifyError::Options(_)), "{e}");
        let three = Priors {
            modes: Some(3),
            ..Default::default()
        };
        let e = run(&three, &[]).unwrap_err().to_string();
        assert!(e.contains("exactly two"), "{e}");
    }

    /// The pipeline's stages come with the method: `trim` is an option of
    /// the registered back-end and runs; so is the preset every back-end
    /// takes.
    #[test]
    fn the_pipeline_adds_the_stages() {
        let m = run(&Priors::default(), &["trim=3"]).unwrap();
        assert!(m.info().diagnostics.trimming.is_some());
        let registry = hysid::registry().with(Pwarx(Sign));
        let options = registry.require("sign").unwrap().options();
        let keys: Vec<&str> = options.iter().map(|o| o.key).collect();
        assert_eq!(
            keys,
            [
                "threshold",
                "trim",
                "refine",
                "refine_segment",
                "refine_iterations",
                "preset"
            ]
        );
    }
}
