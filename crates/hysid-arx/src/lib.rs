//! # hysid-arx
//!
//! The `arx` back-end: a single affine ARX model
//! `y(k) = theta . [x(k); 1]` fitted by least squares (Ljung, *System
//! Identification*, 2nd ed., section 7.3). It is the baseline every hybrid
//! back-end must beat, and it proves the pipeline end to end.
//!
//! Priors honoured (all of them, `docs/priors.md`): `modes = 1` /
//! `max_modes`; `[fixed]` and `[[equality]]` (solved exactly by the
//! null-space method); `[[tie]]` (trivially true with one mode); `[bounds]`
//! (the box-constrained least-squares QP of `hysid_estimation::constrained` when
//! the equality-constrained estimate leaves the box); `switching` (trivially
//! true: one mode, no region); `[[saturation]]` (samples whose target sits
//! at a known stop are left out of the fit, and the model is the hybrid
//! automaton of `HybridAutomaton::from_pwarx_with_stops`: the one ordinary
//! mode plus a mode on each stop's guard set, so a simulation never passes a
//! stop).

use hysid_core::backend::{IdentifyError, Problem, RunContext};
use hysid_core::options::{CheckOptions, OptionError, check_float};
use hysid_core::priors::PriorKind;
use hysid_core::search::SearchSpace;
use hysid_estimation::constrained::{self, ModeSamples, Parametrisation};
use hysid_estimation::linalg;
use hysid_estimation::pwarx::prepare::FixedModeCount;
use hysid_estimation::pwarx::{ModeRule, PwarxData, PwarxFit, PwarxMethod};
use hysid_model::geometry::Polyhedron;
use hysid_model::model::PwarxMode;
use hysid_model::regressors::{RegressorSpec, Regressors};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

hysid_core::backend_options! {
    /// Options of the `arx` back-end.
    pub struct ArxOptions {
        /// Tikhonov (ridge) weight lambda: minimises |y - Phi theta|^2 + lambda |theta|^2
        /// (the constant included). 0 is plain least squares.
        ridge: f64 = 0.0,
    }
}

impl CheckOptions for ArxOptions {
    fn check(&self) -> Result<(), OptionError> {
        check_float(
            "ridge",
            self.ridge,
            |r| r >= 0.0,
            "must be a finite number >= 0",
        )?;
        Ok(())
    }
}

/// The `arx` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Arx;

impl PwarxMethod for Arx {
    type Options = ArxOptions;
    type Diagnostics = ArxDiagnostics;
    const MODE_RULE: ModeRule = ModeRule::Method;
    const ORDINARY_MODES: Option<usize> = Some(1);
    const NAME: &'static str = "arx";
    const SEEDED: bool = false;
    const SUMMARY: &'static str = "one affine ARX model by least squares: the linear baseline";
    const HONOURS: &'static [PriorKind] = PriorKind::ALL;
    const SEARCH: &'static str = "the orders from na = nb = 1 up to the given --na and --nb";

    fn search_space(&self, problem: &Problem<'_>) -> Result<SearchSpace, IdentifyError> {
        let RegressorSpec { na, nb, .. } = problem.orders;
        Ok(SearchSpace::default()
            .with("na", 1..=na.max(1))
            .with("nb", 1..=nb.max(1)))
    }

    fn fit(
        &self,
        data: &PwarxData<'_>,
        options: &ArxOptions,
        _ctx: &RunContext<'_>,
    ) -> Result<PwarxFit<ArxDiagnostics>, IdentifyError> {
        fit(options, data)
    }
}

/// What the `arx` back-end reports besides the common diagnostics.
#[derive(Debug, Clone, Serialize)]
pub struct ArxDiagnostics {
    /// Numerical rank of the (equilibrated) least-squares problem.
    pub rank: usize,
    /// Root mean square of the residuals on the ordinary samples.
    pub rmse_fit: f64,
    /// With `[bounds]`: whether the box-constrained QP replaced the
    /// equality-constrained estimate (a bound is active).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bounds_active: Option<bool>,
}

/// Least squares (Ljung 1999, section 7.3) on the ordinary samples: the
/// equality-constrained estimate, then the box-constrained QP when it
/// leaves the `[bounds]`.
pub fn fit(
    options: &ArxOptions,
    data: &PwarxData<'_>,
) -> Result<PwarxFit<ArxDiagnostics>, IdentifyError> {
    check_one_mode(data)?;
    let par = Parametrisation::from_priors(data.priors(), &data.spec, 1)
        .map_err(|e| data.prior_error(e))?;
    let reg = data.ordinary_regressors();
    check_sample_count(data, &reg, par.n_dof())?;
    let (mut theta, rank) = equality_least_squares(options, data, &reg)?;
    let bounds_active = if leaves_bounds(data, &theta) {
        theta = box_least_squares(options, &par, &reg)?;
        true
    } else {
        false
    };
    let diagnostics = ArxDiagnostics {
        rank,
        rmse_fit: rmse(&reg, &theta),
        bounds_active: (!data.priors().bounds.is_empty()).then_some(bounds_active),
    };
    Ok(PwarxFit::complete(
        PwarxMode::unnamed([theta], [Polyhedron::everything()]),
        diagnostics,
    ))
}

/// One ordinary mode: a `modes` prior must count exactly one besides the
/// stops ([`FixedModeCount`]).
fn check_one_mode(data: &PwarxData<'_>) -> Result<(), IdentifyError> {
    FixedModeCount::check(Arx::NAME, Arx::ORDINARY_MODES, data.problem.priors)
        .map_err(|e| IdentifyError::prior_mismatch(None, e))
}

fn check_sample_count(
    data: &PwarxData<'_>,
    reg: &Regressors,
    free: usize,
) -> Result<(), IdentifyError> {
    if reg.len() >= free.max(1) {
        return Ok(());
    }
    let saturated = data.regressors.len() - reg.len();
    Err(ArxError::TooFewSamples {
        rows: reg.len(),
        saturated,
        free,
    }
    .into())
}

/// The least-squares estimate under `[fixed]` and `[[equality]]` (exact, by
/// the null-space method), with the ridge as extra rows
/// `[Phi; sqrt(lambda) I] theta ~ [y; 0]`. Columns are equilibrated to unit
/// norm, so that a record in 1e-12 or 1e12 units is solved as accurately as
/// one in units: a change of variables that keeps the objective, the
/// constraints and a full-rank solution. Returns the estimate and the rank.
fn equality_least_squares(
    options: &ArxOptions,
    data: &PwarxData<'_>,
    reg: &Regressors,
) -> Result<(Vec<f64>, usize), IdentifyError> {
    let p = data.spec.n_params();
    let mut phi = reg.phi();
    let mut y = reg.y.clone();
    if options.ridge > 0.0 {
        let n = phi.nrows();
        phi = phi.insert_rows(n, p, 0.0);
        y = y.insert_rows(n, p, 0.0);
        for j in 0..p {
            phi[(n + j, j)] = options.ridge.sqrt();
        }
    }
    let (mut e, f) = equality_rows(data);
    let mut scale = vec![1.0; p];
    for (j, d) in scale.iter_mut().enumerate() {
        let c = phi.column(j).norm();
        if c.is_finite() && c > 0.0 {
            *d = c;
            phi.column_mut(j).unscale_mut(c);
            e.column_mut(j).unscale_mut(c);
        }
    }
    let sol = linalg::lstsq_equality(&phi, &y, &e, &f).map_err(ArxError::LeastSquares)?;
    let mut theta: Vec<f64> = sol.theta.iter().zip(&scale).map(|(t, d)| t / d).collect();
    // Fixed values come back exactly as given.
    for (name, value) in &data.priors().fixed {
        theta[param_index(data, name)] = *value;
    }
    Ok((theta, sol.rank))
}

/// `E theta = f`: one row per `[fixed]` entry, then one per `[[equality]]`.
fn equality_rows(data: &PwarxData<'_>) -> (DMatrix<f64>, DVector<f64>) {
    let priors = data.priors();
    let rows = priors.fixed.len() + priors.equality.len();
    let mut e = DMatrix::zeros(rows, data.spec.n_params());
    let mut f = DVector::zeros(rows);
    for (r, (name, value)) in priors.fixed.iter().enumerate() {
        e[(r, param_index(data, name))] = 1.0;
        f[r] = *value;
    }
    for (k, eq) in priors.equality.iter().enumerate() {
        let r = priors.fixed.len() + k;
        for (name, c) in &eq.coefficients {
            e[(r, param_index(data, name))] += c;
        }
        f[r] = eq.value;
    }
    (e, f)
}

/// Position of a parameter named in the priors (names were checked by
/// [`pwarx::prepare`]).
fn param_index(data: &PwarxData<'_>, name: &str) -> usize {
    data.spec
        .param_names()
        .iter()
        .position(|n| n == name)
        .expect("prior names are checked by prepare")
}

fn leaves_bounds(data: &PwarxData<'_>, theta: &[f64]) -> bool {
    data.priors().bounds.iter().any(|(name, [lo, hi])| {
        let t = theta[param_index(data, name)];
        t < *lo || t > *hi
    })
}

/// The box-constrained least squares (the clarabel QP of
/// `hysid_estimation::constrained`), for bounds that bind.
fn box_least_squares(
    options: &ArxOptions,
    par: &Parametrisation,
    reg: &Regressors,
) -> Result<Vec<f64>, IdentifyError> {
    if options.ridge > 0.0 {
        return Err(IdentifyError::Options(OptionError::invalid(
            "ridge",
            options.ridge,
            "cannot be combined with [bounds] that bind (the estimate leaves the box): use ridge=0",
        )));
    }
    let ys: Vec<f64> = reg.y.iter().copied().collect();
    let fitted = constrained::fit_modes(
        par,
        &[ModeSamples {
            phi: &reg.x,
            y: &ys,
            weights: None,
        }],
    )
    .map_err(ArxError::BoundedLeastSquares)?;
    Ok(fitted.into_iter().next().ok_or(ArxError::NoMode)?)
}

fn rmse(reg: &Regressors, theta: &[f64]) -> f64 {
    (reg.phi() * DVector::from_column_slice(theta) - &reg.y).norm() / (reg.len() as f64).sqrt()
}

/// What the `arx` back-end refuses (an [`IdentifyError::Input`]) or fails
/// at (an [`IdentifyError::Failed`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ArxError {
    /// Fewer ordinary regressors than free parameters.
    #[error(
        "{rows} regressors{} for {free} free parameters: need at least as many samples as parameters",
        if *.saturated > 0 { format!(" outside the stops ({} at a stop)", .saturated) } else { String::new() }
    )]
    TooFewSamples {
        /// Ordinary regression rows.
        rows: usize,
        /// Rows at a stop.
        saturated: usize,
        /// Free parameters.
        free: usize,
    },
    /// The equality-constrained least squares failed.
    #[error("least squares failed: {0}")]
    LeastSquares(linalg::LinalgError),
    /// The least squares under the priors' bounds failed.
    #[error("bounded least squares failed: {0}")]
    BoundedLeastSquares(constrained::EstimationError),
    /// The least squares under the priors' bounds returned no mode.
    #[error("bounded least squares returned no mode")]
    NoMode,
}

impl From<ArxError> for IdentifyError {
    /// The mode count and the sample count are the input's; the least
    /// squares', the method's.
    fn from(e: ArxError) -> Self {
        match e {
            ArxError::TooFewSamples { .. } => IdentifyError::too_few_samples(e),
            e => IdentifyError::failed(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_core::backend::Backend;
    use hysid_core::model::Model;
    use hysid_core::options::Settings;
    use hysid_core::priors::Priors;
    use hysid_core::simulate::simulate;
    use hysid_estimation::pwarx::Pwarx;
    use hysid_model::data::Dataset;
    use hysid_model::model::{ModelInfo, PwarxModel};
    use hysid_model::regressors::RegressorSpec;
    use hysid_model::simulate::SimulationOptions;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Noise-free data from a stable ARX(na, nb) model driven by white noise.
    fn data_from(theta: &[f64], na: usize, nb: usize, n: usize, seed: u64) -> Dataset {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let u: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let one = PwarxModel {
            na,
            nb,
            inputs: 1,
            modes: vec![PwarxMode {
                theta: theta.to_vec(),
                region: Polyhedron::everything(),
                name: None,
            }],
            info: ModelInfo::default(),
        };
        let y0: Vec<f64> = (0..n)
            .map(|k| {
                if k < na.max(nb) {
                    rng.random_range(-1.0..1.0)
                } else {
                    0.0
                }
            })
            .collect();
        let d = Dataset::siso(u, y0, None).unwrap();
        let s = simulate(&Model::Pwarx(one), &d, SimulationOptions::default()).unwrap();
        Dataset::siso(d.u(0).to_vec(), s.y, None).unwrap()
    }

    fn run(
        data: &Dataset,
        na: usize,
        nb: usize,
        priors: &Priors,
        set: &[&str],
    ) -> Result<Model, IdentifyError> {
        let problem = Problem {
            data,
            orders: RegressorSpec::new(na, nb, 1),
            priors,
            priors_origin: None,
        };
        Pwarx(Arx).run(
            &problem,
            &Settings::parse(set).unwrap(),
            &RunContext::quiet(1),
        )
    }

    fn theta_of(m: &Model) -> Vec<f64> {
        match m {
            Model::Pwarx(p) => p.modes[0].theta.clone(),
            _ => unreachable!(),
        }
    }

    proptest! {
        /// ARX on noise-free data recovers theta to 1e-9; simulating the
        /// one-mode model and identifying it gives it back.
        #[test]
        fn recovers_theta_noise_free(a1 in -0.5f64..0.5, a2 in -0.3f64..0.3, b1 in -2.0f64..2.0, b2 in -2.0f64..2.0, c in -1.0f64..1.0, seed in any::<u64>()) {
            let theta = [a1, a2, b1, b2, c];
            let d = data_from(&theta, 2, 2, 200, seed);
            let m = run(&d, 2, 2, &Priors::default(), &[]).unwrap();
            let t = theta_of(&m);
            for (x, y) in t.iter().zip(theta) {
                prop_assert!((x - y).abs() < 1e-9, "{:?} vs {:?}", t, theta);
            }
        }

        /// Two noise-free records of one ARX model, each from its own
        /// initial outputs, fitted together recover theta to 1e-9: no row
        /// regresses across their seam. Their plain concatenation, whose
        /// rows at the seam mix the two records, does not.
        #[test]
        fn joined_records_recover_theta_and_their_concatenation_does_not(a1 in -0.5f64..0.5, b1 in -2.0f64..2.0, b2 in -2.0f64..2.0, c in -1.0f64..1.0, seed in 0u64..1_000_000, n in 30usize..120) {
            let theta = [a1, 0.2, b1, b2, c];
            let (x, y) = (data_from(&theta, 2, 2, n, seed), data_from(&theta, 2, 2, 150 - n, seed + 1));
            let joined = Dataset::join(&[x.clone(), y.clone()]).unwrap();
            let t = theta_of(&run(&joined, 2, 2, &Priors::default(), &[]).unwrap());
            for (got, want) in t.iter().zip(theta) {
                prop_assert!((got - want).abs() < 1e-9, "{:?} vs {:?}", t, theta);
            }
            let mut plain = joined.clone();
            plain.boundaries.clear();
            let t = theta_of(&run(&plain, 2, 2, &Priors::default(), &[]).unwrap());
            let off = t.iter().zip(theta).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            prop_assert!(off > 1e-6, "{:?} vs {:?}", t, theta);
        }

        /// Fixed values come back unchanged and the rest is re-fitted.
        #[test]
        fn fixed_values_are_kept(c in -1.0f64..1.0, seed in any::<u64>()) {
            let theta = [0.3, 1.0, c];
            let d = data_from(&theta, 1, 1, 100, seed);
            let mut pri = Priors::default();
            pri.fixed.insert("c".into(), 0.25);
            let t = theta_of(&run(&d, 1, 1, &pri, &[]).unwrap());
            prop_assert_eq!(t[2], 0.25);
        }
    }

    /// Simulated ARX(1,1) data with a stop at `level` (`max`): the
    /// output is held at the level while the dynamics push past it.
    fn data_with_stop(theta: &[f64; 3], level: f64, n: usize, seed: u64) -> Dataset {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let u: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut y = vec![0.0; n];
        for k in 1..n {
            let v = theta[0] * y[k - 1] + theta[1] * u[k - 1] + theta[2];
            y[k] = v.min(level);
        }
        Dataset::siso(u, y, None).unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]

        /// `[bounds]` hold in the returned model (the QP path when the
        /// estimate leaves the box).
        #[test]
        fn bounds_hold(b in -2.0f64..2.0, lo in -1.0f64..0.0, hi in 0.0f64..1.0, seed in 0u64..1000) {
            let d = data_from(&[0.5, b, 0.1], 1, 1, 120, seed);
            let pri = Priors::from_toml(&format!("[bounds]\nb1 = [{lo:?}, {hi:?}]\na1 = [-0.2, 0.2]\n"), "p").unwrap();
            let t = theta_of(&run(&d, 1, 1, &pri, &[]).unwrap());
            prop_assert!(t[1] >= lo - 1e-9 && t[1] <= hi + 1e-9, "{:?}", t);
            prop_assert!(t[0] >= -0.2 - 1e-9 && t[0] <= 0.2 + 1e-9, "{:?}", t);
        }

        /// Random `[[equality]]` entries hold to 1e-9 in the returned model,
        /// with fixed values unchanged.
        #[test]
        fn equalities_hold(c in prop::collection::vec(-2.0f64..2.0, 5), v in -1.0f64..1.0, seed in 0u64..1000) {
            let d = data_from(&[0.4, -0.2, 1.0, 0.5, 0.1], 2, 2, 150, seed);
            let names = ["a1", "a2", "b1", "b2", "c"];
            let terms: Vec<String> = names.iter().zip(&c).map(|(n, x)| format!("{n} = {x:?}")).collect();
            let pri = Priors::from_toml(&format!(
                "[[equality]]\ncoefficients = {{ {} }}\nvalue = {v:?}\n[[equality]]\ncoefficients = {{ b1 = 1.0, b2 = -1.0 }}\n[fixed]\na2 = -0.2\n",
                terms.join(", ")
            ), "p").unwrap();
            let t = match run(&d, 2, 2, &pri, &[]) {
                Ok(m) => theta_of(&m),
                Err(e) => {
                    // Only a (nearly) contradictory draw may fail, naming it.
                    prop_assert!(e.to_string().contains("[[equality]]"), "{}", e);
                    return Ok(());
                }
            };
            let lhs: f64 = t.iter().zip(&c).map(|(x, y)| x * y).sum();
            let scale = 1.0 + t.iter().map(|x| x.abs()).fold(0.0, f64::max);
            prop_assert!((lhs - v).abs() <= 1e-9 * scale, "{:?}: {} vs {}", t, lhs, v);
            prop_assert!((t[2] - t[3]).abs() <= 1e-9 * scale, "{:?}", t);
            prop_assert_eq!(t[1], -0.2);
        }

        /// With a `[[saturation]]` prior the samples at the stop are left
        /// out of the fit (the ordinary dynamics are recovered exactly from
        /// noise-free data), and a simulation of the model never passes the
        /// stop.
        #[test]
        fn saturation_excluded_and_never_passed(a in 0.3f64..0.8, b in 0.5f64..2.0, level in 0.5f64..1.5, seed in 0u64..1000) {
            let theta = [a, b, 0.4];
            let d = data_with_stop(&theta, level, 300, seed);
            let pri = Priors::from_toml(&format!(
                "modes = 2\n[[saturation]]\nlevel = {level:?}\nbound = \"max\"\n"
            ), "p").unwrap();
            let at_stop = d.y().iter().skip(1).filter(|&&y| y >= level - 1e-6 * (1.0 + level)).count();
            prop_assume!(at_stop > 5 && at_stop < 250);
            let m = run(&d, 1, 1, &pri, &[]).unwrap();
            prop_assert_eq!(m.info().diagnostics.saturated_per_stop.clone(), Some(vec![at_stop]));
            let Model::HybridAutomaton(h) = &m else {
                return Err(TestCaseError::fail("not an automaton"));
            };
            prop_assert_eq!(h.modes.len(), 2);
            let sim = simulate(&m, &d, SimulationOptions::default()).unwrap();
            for y in &sim.y {
                prop_assert!(*y <= level + 1e-9, "{} passes {}", y, level);
            }
            // Recovered ordinary dynamics (noise-free, stop samples left out).
            let fit = simulate(&m, &d, SimulationOptions::default()).unwrap();
            let err = fit.y.iter().zip(d.y()).map(|(p, q)| (p - q).abs()).fold(0.0, f64::max);
            prop_assert!(err < 1e-6, "max simulation error {}", err);
        }
    }

    #[test]
    fn refuses_what_it_cannot_honour() {
        let d = data_from(&[0.5, 1.0, 0.0], 1, 1, 50, 3);
        // Switching is honoured trivially (one mode, no region).
        let pri = Priors {
            switching: vec!["y1".into()],
            ..Default::default()
        };
        assert!(run(&d, 1, 1, &pri, &[]).is_ok());
        let pri = Priors::from_toml(
            "[[equality]]\ncoefficients = { a1 = 1.0 }\nvalue = 0.5\n[fixed]\na1 = 0.25\n",
            "p.toml",
        )
        .unwrap();
        let e = run(&d, 1, 1, &pri, &[]).unwrap_err().to_string();
        assert!(e.contains("[[equality]] #1"), "{e}");
        let pri = Priors {
            modes: Some(3),
            ..Default::default()
        };
        assert!(run(&d, 1, 1, &pri, &[]).is_err());
        let mut pri = Priors::default();
        pri.fixed.insert("a7".into(), 0.0);
        assert!(
            run(&d, 1, 1, &pri, &[])
                .unwrap_err()
                .to_string()
                .contains("a7")
        );
        assert!(run(&d, 1, 1, &Priors::default(), &["ridge=-1"]).is_err());
        assert!(run(&d, 1, 1, &Priors::default(), &["rigde=1"]).is_err());
    }

    #[test]
    fn standardize_refuses_data_unit_priors_and_ties_on_c() {
        use hysid_core::priors::Tie;
        use hysid_estimation::pwarx::run_standardized;
        let d = data_from(&[0.5, 1.0, 0.3], 1, 1, 60, 3);
        let go = |pri: &Priors| {
            let problem = Problem {
                data: &d,
                orders: RegressorSpec::new(1, 1, 1),
                priors: pri,
                priors_origin: None,
            };
            run_standardized(
                &Pwarx(Arx),
                &problem,
                &Settings::default(),
                &RunContext::quiet(1),
            )
        };
        let tie = |p: &str| Priors {
            tie: vec![Tie {
                params: vec![p.into()],
            }],
            ..Default::default()
        };
        let e = go(&tie("c")).unwrap_err().to_string();
        assert!(
            e.contains("standardization") && e.contains("offset c"),
            "{e}"
        );
        assert!(go(&tie("a1")).is_ok());
        let mut fixed = Priors::default();
        fixed.fixed.insert("c".into(), 0.3);
        assert!(go(&fixed).unwrap_err().to_string().contains("data units"));
    }

    #[test]
    fn provenance_is_recorded() {
        let d = data_from(&[0.5, 1.0, 0.0], 1, 1, 50, 3);
        let m = run(&d, 1, 1, &Priors::default(), &["ridge=0.5"]).unwrap();
        assert_eq!(m.info().method, "arx");
        assert_eq!(m.info().options["ridge"], 0.5);
        assert_eq!(m.info().seed, Some(1));
    }

    /// Sum of squared free-run simulation errors of `m` on `d`.
    fn free_run_error(m: &Model, d: &Dataset) -> f64 {
        let s = simulate(m, d, SimulationOptions::for_data(d)).unwrap();
        assert!(s.diverged_at.is_none());
        (s.start..d.len())
            .map(|k| (d.y()[k] - s.y[k]).powi(2))
            .sum()
    }

    /// On an output-error record (white noise added to the output of an
    /// ARX system), `refine=sim` with one free-run segment is the
    /// output-error model: a lower free-run error than least squares, and
    /// parameters near the truth where least squares is biased.
    #[test]
    fn refine_sim_gives_the_output_error_model() {
        let truth = [0.8, 0.5, 0.1];
        let clean = data_from(&truth, 1, 1, 1500, 4);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let noisy: Vec<f64> = clean
            .y()
            .iter()
            .map(|v| v + 0.3 * (rng.random_range(-1.0..1.0) + rng.random_range(-1.0..1.0)))
            .collect();
        let d = Dataset::siso(clean.u(0).to_vec(), noisy, None).unwrap();
        let ls = run(&d, 1, 1, &Priors::default(), &[]).unwrap();
        let oe = run(
            &d,
            1,
            1,
            &Priors::default(),
            &["refine=sim", "refine_segment=100000"],
        )
        .unwrap();
        let (e_ls, e_oe) = (free_run_error(&ls, &d), free_run_error(&oe, &d));
        assert!(
            e_oe < 0.95 * e_ls,
            "output error {e_oe} vs least squares {e_ls}"
        );
        let (t_ls, t_oe) = (theta_of(&ls), theta_of(&oe));
        assert!(
            (t_oe[0] - truth[0]).abs() < (t_ls[0] - truth[0]).abs(),
            "{t_oe:?} vs {t_ls:?}"
        );
        assert!((t_oe[0] - truth[0]).abs() < 0.03, "{t_oe:?}");
        let r = ls.info().diagnostics.refinement.clone();
        assert!(r.is_none());
        let r = oe.info().diagnostics.refinement.clone().unwrap();
        assert_eq!(r.segments, 1);
        assert!(r.cost_after.unwrap() < r.cost_before.unwrap(), "{r:?}");
        // The refinement options are recorded when given, not otherwise.
        assert_eq!(oe.info().options["refine"], "sim");
        assert_eq!(oe.info().options["refine_segment"], 100000);
        assert!(!ls.info().options.contains_key("refine"));
        assert!(!ls.info().options.contains_key("refine_segment"));
        assert!(!oe.info().options.contains_key("refine_iterations"));
    }

    /// With a known stop the refined model is still the automaton, the
    /// refinement is recorded, and bad refinement options are refused.
    #[test]
    fn refine_sim_with_a_stop_and_option_checks() {
        let d = data_with_stop(&[0.6, 1.0, 0.1], 1.0, 400, 5);
        let mut p = Priors::default();
        p.saturation.push(hysid_model::model::Stop {
            level: 1.0,
            bound: hysid_model::model::StopBound::Max,
            tol: None,
        });
        let m = run(&d, 1, 1, &p, &["refine=sim", "refine_segment=50"]).unwrap();
        assert!(matches!(m, Model::HybridAutomaton(_)));
        let r = m.info().diagnostics.refinement.clone().unwrap();
        assert!(r.cost_after.unwrap() <= r.cost_before.unwrap(), "{r:?}");
        let e = run(&d, 1, 1, &p, &["refine=sim", "refine_segment=0"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("refine_segment"), "{e}");
        let e = run(&d, 1, 1, &p, &["refine=newton"])
            .unwrap_err()
            .to_string();
        assert!(e.contains("refine"), "{e}");
    }
}
