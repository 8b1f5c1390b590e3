//! # hysid-arx
//!
//! The `arx` back-end: a single affine ARX model
//! `y(k) = theta . [x(k); 1]` fitted by least squares (Ljung, *System
//! Identification*, 2nd ed., section 7.3). It is the baseline every hybrid
//! back-end must beat, and it proves the pipeline end to end.
//!
//! Priors honoured: `modes = 1` / `max_modes`, `[fixed]` (solved exactly
//! by the null-space method), `[[tie]]` (trivially true with one mode).
//! Anything else is refused.

use hysid_core::backend::{Identifier, IdentifyError, Problem, RunContext};
use hysid_core::geometry::Polyhedron;
use hysid_core::linalg;
use hysid_core::model::{Model, ModelInfo, PwarxMode, PwarxModel};
use hysid_core::priors::PriorKind;
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
    const HONOURS: &'static [PriorKind] = &[
        PriorKind::Modes,
        PriorKind::MaxModes,
        PriorKind::Fixed,
        PriorKind::Tie,
    ];

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
        if let Some(s) = priors.modes
            && s != 1
        {
            return Err(IdentifyError::BadData(format!(
                "prior modes = {s}: method 'arx' identifies exactly one mode"
            )));
        }
        priors
            .check_pwarx_names(&spec)
            .map_err(|e| IdentifyError::BadData(format!("prior {e}")))?;
        let reg = spec
            .build(problem.data)
            .map_err(|e| IdentifyError::BadData(e.to_string()))?;
        let p = spec.n_params();
        let free = p - priors.fixed.len();
        if reg.len() < free {
            return Err(IdentifyError::BadData(format!(
                "{} regressors for {free} free parameters: need at least as many samples as parameters",
                reg.len()
            )));
        }
        let mut phi = reg.phi();
        let mut y = reg.y.clone();
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
        let mut e = DMatrix::zeros(priors.fixed.len(), p);
        let mut f = DVector::zeros(priors.fixed.len());
        for (r, (name, value)) in priors.fixed.iter().enumerate() {
            let j = names.iter().position(|n| n == name).expect("names checked");
            e[(r, j)] = 1.0;
            f[r] = *value;
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
            let j = names.iter().position(|n| n == name).expect("names checked");
            theta[j] = *value;
        }
        let mut info = ModelInfo::default();
        info.diagnostics.insert("rank".into(), sol.rank.into());
        info.diagnostics.insert("samples".into(), reg.len().into());
        info.diagnostics.insert(
            "rmse_fit".into(),
            ((reg.phi() * DVector::from_vec(theta.clone()) - &reg.y).norm()
                / (reg.len() as f64).sqrt())
            .into(),
        );
        Ok(Model::Pwarx(PwarxModel {
            na: spec.na,
            nb: spec.nb,
            inputs: spec.inputs,
            modes: vec![PwarxMode {
                theta,
                region: Polyhedron::everything(),
                name: None,
            }],
            info,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hysid_core::backend::Backend;
    use hysid_core::data::Dataset;
    use hysid_core::options::Settings;
    use hysid_core::priors::Priors;
    use hysid_core::regressors::RegressorSpec;
    use hysid_core::simulate::{SimulationOptions, simulate};
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

    #[test]
    fn refuses_what_it_cannot_honour() {
        let d = data_from(&[0.5, 1.0, 0.0], 1, 1, 50, 3);
        let pri = Priors {
            switching: vec!["y1".into()],
            ..Default::default()
        };
        let e = run(&d, 1, 1, &pri, &[]).unwrap_err().to_string();
        assert!(
            e.contains("does not honour") && e.contains("switching"),
            "{e}"
        );
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
