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

use hysid_core::backend::{Identifier, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::priors::PriorKind;
use hysid_estimation::constrained::{self, ModeSamples, Parametrisation};
use hysid_estimation::linalg;
use hysid_model::geometry::Polyhedron;
use hysid_model::model::{HybridAutomaton, ModelInfo, PwarxMode, PwarxModel};
use nalgebra::{DMatrix, DVector};

hysid_core::backend_options! {
    /// Options of the `arx` back-end.
    pub struct ArxOptions {
        /// Tikhonov (ridge) weight lambda: minimises |y - Phi theta|^2 + lambda |theta|^2
        /// (the constant included). 0 is plain least squares.
        ridge: f64 = 0.0,
    }
}

/// The `arx` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Arx;

impl Identifier for Arx {
    type Options = ArxOptions;
    const NAME: &'static str = "arx";
    const SUMMARY: &'static str = "one affine ARX model by least squares: the linear baseline";
    const HONOURS: &'static [PriorKind] = PriorKind::ALL;

    fn identify(
        &self,
        problem: &Problem<'_>,
        options: &ArxOptions,
        _ctx: &RunContext<'_>,
    ) -> Result<Model, IdentifyError> {
        if !(options.ridge.is_finite() && options.ridge >= 0.0) {
            return Err(IdentifyError::BadData(format!(
                "--set ridge={}: must be a finite number >= 0",
                options.ridge
            )));
        }
        let spec = problem.orders;
        let priors = problem.priors;
        let stops = priors.saturation.len();
        if let Some(s) = priors.modes
            && s != 1 + stops
        {
            return Err(IdentifyError::BadData(format!(
                "prior modes = {s}: method 'arx' identifies exactly one ordinary mode{}",
                if stops > 0 {
                    format!(
                        " (modes = {} with the {stops} saturation mode(s))",
                        1 + stops
                    )
                } else {
                    String::new()
                }
            )));
        }
        priors
            .check_pwarx_names(&spec)
            .map_err(|e| IdentifyError::BadData(format!("prior {e}")))?;
        let origin = |e: String| match problem.priors_origin {
            Some(o) => IdentifyError::BadData(format!("{o}: {e}")),
            None => IdentifyError::BadData(format!("prior {e}")),
        };
        // Fixed values within their bounds, equalities consistent.
        let par = Parametrisation::from_priors(priors, &spec, 1).map_err(origin)?;
        let reg = spec
            .build(problem.data)
            .map_err(|e| IdentifyError::BadData(e.to_string()))?;
        // Samples whose target sits at a known stop belong to the stop's
        // mode: left out of the fit.
        let stop_of = priors.saturated_samples(reg.y.as_slice());
        let keep: Vec<usize> = (0..reg.len()).filter(|&k| stop_of[k].is_none()).collect();
        let saturated = reg.len() - keep.len();
        let p = spec.n_params();
        let free = par.n_dof();
        if keep.len() < free.max(1) {
            return Err(IdentifyError::BadData(format!(
                "{} regressors{} for {free} free parameters: need at least as many samples as parameters",
                keep.len(),
                if saturated > 0 {
                    format!(" outside the stops ({saturated} at a stop)")
                } else {
                    String::new()
                }
            )));
        }
        let phi_all = reg.phi();
        let phi0 = phi_all.select_rows(&keep);
        let y0 = reg.y.select_rows(&keep);
        let mut phi = phi0.clone();
        let mut y = y0.clone();
        if options.ridge > 0.0 {
            // Augment: [Phi; sqrt(lambda) I] theta ~ [y; 0].
            let n = phi.nrows();
            phi = phi.insert_rows(n, p, 0.0);
            y = y.insert_rows(n, p, 0.0);
            for j in 0..p {
                phi[(n + j, j)] = options.ridge.sqrt();
            }
        }
        let names = spec.param_names();
        let idx = |name: &str| names.iter().position(|n| n == name).expect("names checked");
        let rows = priors.fixed.len() + priors.equality.len();
        let mut e = DMatrix::zeros(rows, p);
        let mut f = DVector::zeros(rows);
        for (r, (name, value)) in priors.fixed.iter().enumerate() {
            e[(r, idx(name))] = 1.0;
            f[r] = *value;
        }
        for (k, eq) in priors.equality.iter().enumerate() {
            let r = priors.fixed.len() + k;
            for (name, c) in &eq.coefficients {
                e[(r, idx(name))] += c;
            }
            f[r] = eq.value;
        }
        // Equilibrate: unit-norm columns, so that a record in 1e-12 or 1e12
        // units is solved as accurately as one in units (the constant
        // column is always of order 1). A change of variables: the
        // objective, the constraints and a full-rank solution are the same.
        let mut scale = vec![1.0; p];
        for (j, d) in scale.iter_mut().enumerate() {
            let c = phi.column(j).norm();
            if c.is_finite() && c > 0.0 {
                *d = c;
                phi.column_mut(j).unscale_mut(c);
                e.column_mut(j).unscale_mut(c);
            }
        }
        let sol =
            linalg::lstsq_equality(&phi, &y, &e, &f).map_err(|err| IdentifyError::Failed {
                method: "arx".into(),
                message: format!("least squares failed: {err}"),
            })?;
        let mut theta: Vec<f64> = sol.theta.iter().zip(&scale).map(|(t, d)| t / d).collect();
        // Fixed values come back exactly as given.
        for (name, value) in &priors.fixed {
            theta[idx(name)] = *value;
        }
        let outside = priors.bounds.iter().any(|(name, [lo, hi])| {
            let t = theta[idx(name)];
            t < *lo || t > *hi
        });
        let mut bounded_qp = false;
        if outside {
            if options.ridge > 0.0 {
                return Err(IdentifyError::BadData(format!(
                    "--set ridge={} cannot be combined with [bounds] that bind (the estimate leaves the box): \
                     use ridge=0",
                    options.ridge
                )));
            }
            let x = phi0.columns(0, p - 1).into_owned();
            let ys: Vec<f64> = y0.iter().copied().collect();
            let fitted = constrained::fit_modes(
                &par,
                &[ModeSamples {
                    phi: &x,
                    y: &ys,
                    weights: None,
                }],
            )
            .map_err(|err| IdentifyError::Failed {
                method: "arx".into(),
                message: format!("bounded least squares failed: {err}"),
            })?;
            theta = fitted.into_iter().next().unwrap_or(theta);
            bounded_qp = true;
        }
        let mut info = ModelInfo::default();
        info.diagnostics.insert("rank".into(), sol.rank.into());
        info.diagnostics.insert("samples".into(), keep.len().into());
        if !priors.saturation.is_empty() {
            info.diagnostics
                .insert("saturated_samples".into(), saturated.into());
        }
        if !priors.bounds.is_empty() {
            info.diagnostics
                .insert("bounds_active".into(), bounded_qp.into());
        }
        info.diagnostics.insert(
            "rmse_fit".into(),
            ((&phi0 * DVector::from_vec(theta.clone()) - &y0).norm() / (keep.len() as f64).sqrt())
                .into(),
        );
        let model = PwarxModel {
            na: spec.na,
            nb: spec.nb,
            inputs: spec.inputs,
            modes: vec![PwarxMode {
                theta,
                region: Polyhedron::everything(),
                name: None,
            }],
            info,
        };
        Ok(if priors.saturation.is_empty() {
            Model::Pwarx(model)
        } else {
            Model::HybridAutomaton(HybridAutomaton::from_pwarx_with_stops(
                &model,
                &priors.saturation,
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_core::backend::Backend;
    use hysid_core::options::Settings;
    use hysid_core::priors::Priors;
    use hysid_core::simulate::simulate;
    use hysid_model::data::Dataset;
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
        Arx.run(
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
            prop_assert_eq!(m.info().diagnostics["saturated_samples"].as_u64(), Some(at_stop as u64));
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
        use hysid_core::backend::run_standardized;
        use hysid_core::priors::Tie;
        let d = data_from(&[0.5, 1.0, 0.3], 1, 1, 60, 3);
        let go = |pri: &Priors| {
            let problem = Problem {
                data: &d,
                orders: RegressorSpec::new(1, 1, 1),
                priors: pri,
                priors_origin: None,
            };
            run_standardized(&Arx, &problem, &Settings::default(), &RunContext::quiet(1))
        };
        let tie = |p: &str| Priors {
            tie: vec![Tie {
                params: vec![p.into()],
            }],
            ..Default::default()
        };
        let e = go(&tie("c")).unwrap_err().to_string();
        assert!(e.contains("--standardize") && e.contains("offset c"), "{e}");
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
}
