//! Gray-box priors in the `cluster` back-end: ties, fixed values
//! and bounds in the returned model, switching variables in the regions,
//! known stops (saturated samples assigned to the stop modes, simulation
//! never passing a stop), and the gain on the stopped test system.

use hysid_cluster::{Cluster, ClusterOptions};
use hysid_core::backend::{Backend, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::{Equality, Priors, Tie};
use hysid_core::simulate::simulate;
use hysid_core::simulate::validate;
use hysid_estimation::constrained::PriorConflict;
use hysid_estimation::pwarx::{self, Pwarx};
use hysid_model::data::Dataset;
use hysid_model::metrics::{mode_accuracy, parameter_error};
use hysid_model::model::PwarxModel;
use hysid_model::model::StopBound;
use hysid_model::regressors::RegressorSpec;
use hysid_model::simulate::SimulationOptions;
use hysid_testkit::{Noise, StoppedBenchmark, b1, h3, stopped_head};
use proptest::prelude::*;

/// The model of `s` modes (stops included) on `problem` and the mode of
/// every regression row: the ordinary modes of the final weighted least
/// squares, then the known stops in prior order.
fn labelled(problem: &Problem<'_>, opts: &ClusterOptions, s: usize) -> (Model, Vec<usize>) {
    let data = pwarx::prepare(problem, "cluster").unwrap();
    let fit = hysid_cluster::fit(opts, &data, s, &RunContext::quiet(7)).unwrap();
    let ordinary = fit.modes.len();
    let mut labels: Vec<usize> = data
        .stop_of
        .iter()
        .map(|k| k.map_or(0, |k| ordinary + k))
        .collect();
    for (&row, &l) in data.ordinary.iter().zip(&fit.diagnostics.labels) {
        labels[row] = l;
    }
    (pwarx::assemble(&data, fit), labels)
}

fn run(
    data: &Dataset,
    orders: RegressorSpec,
    priors: &Priors,
    set: &[&str],
) -> Result<Model, IdentifyError> {
    let problem = Problem {
        data,
        orders,
        priors,
        priors_origin: Some("p.toml"),
    };
    Pwarx(Cluster).run(
        &problem,
        &Settings::parse(set).unwrap(),
        &RunContext::quiet(7),
    )
}

fn pwarx(m: Model) -> PwarxModel {
    match m {
        Model::Pwarx(p) => p,
        other => panic!("expected a PWARX model, got {}", other.kind()),
    }
}

fn b1_priors(modes: usize) -> Priors {
    Priors {
        modes: Some(modes),
        ..Priors::default()
    }
}

/// Mode accuracy (Hungarian matching) over the samples where both are known.
fn accuracy(truth: &[Option<usize>], got: &[Option<usize>]) -> f64 {
    let (mut t, mut i) = (Vec::new(), Vec::new());
    for (a, b) in truth.iter().zip(got) {
        if let (Some(a), Some(b)) = (a, b) {
            t.push(*a);
            i.push(*b);
        }
    }
    mode_accuracy(&t, &i).unwrap().accuracy
}

/// Mode accuracy of the free-run simulation against the true modes, and the
/// simulation FIT, on a validation record.
fn score(model: &Model, valid: &StoppedBenchmark) -> (f64, f64) {
    let (r, sim, _) = validate(model, &valid.data, 0).unwrap();
    (accuracy(&valid.modes, &sim.modes), r.fit_sim)
}

#[test]
fn names_and_inconsistent_priors_are_one_line_errors() {
    let b = b1(200, 4.0, Noise::Uniform(0.1), 1);
    let orders = RegressorSpec::new(1, 1, 1);
    let mut p = b1_priors(3);
    p.fixed.insert("a2".into(), 0.0);
    let e = run(&b.data, orders, &p, &[]).unwrap_err();
    assert!(matches!(e, IdentifyError::PriorMismatch { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("a2") && msg.contains("p.toml") && !msg.contains('\n'),
        "{msg}"
    );
    let mut p = b1_priors(3);
    p.fixed.insert("b1".into(), 5.0);
    p.bounds.insert("b1".into(), [0.0, 1.0]);
    let e = run(&b.data, orders, &p, &[]).unwrap_err();
    assert!(
        e.downcast_ref::<PriorConflict>().is_some() && e.to_string().contains("b1"),
        "{e}"
    );
    let mut p = b1_priors(3);
    p.switching = vec!["u2".into()];
    assert!(matches!(
        run(&b.data, orders, &p, &[]),
        Err(IdentifyError::PriorMismatch { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// Ties hold to 1e-9 (bitwise, in fact) and fixed values come back
    /// unchanged in the returned model; bounds hold; with and without the
    /// alternation after the clustering.
    #[test]
    fn ties_fixed_and_bounds_hold_in_the_model(
        seed in 0u64..1000,
        c in -2.0f64..2.0,
        hi in 0.0f64..1.0,
        scale in any::<bool>(),
        alternation in prop_oneof![Just(0usize), Just(20)],
    ) {
        let b = b1(180, 4.0, Noise::Uniform(0.1), seed);
        let mut p = b1_priors(3);
        p.tie.push(Tie { params: vec!["a1".into()] });
        p.fixed.insert("c".into(), c);
        p.bounds.insert("b1".into(), [-1.0, hi]);
        // discard=0: the constrained fits may leave a small cluster, which the
        // exact mode count would refuse; the property is about the priors.
        let set = ["restarts=3".to_string(), "discard=0".to_string(), format!("scale={scale}"), format!("alternation={alternation}")];
        let set: Vec<&str> = set.iter().map(String::as_str).collect();
        let m = pwarx(run(&b.data, RegressorSpec::new(1, 1, 1), &p, &set).unwrap());
        let a0 = m.modes[0].theta[0];
        for mode in &m.modes {
            prop_assert!((mode.theta[0] - a0).abs() <= 1e-9, "{:?}", m.modes);
            prop_assert_eq!(mode.theta[2].to_bits(), c.to_bits());
            prop_assert!(mode.theta[1] >= -1.0 && mode.theta[1] <= hi, "{:?}", mode.theta);
        }
    }

    /// Random `[[equality]]` entries (among one mode's parameters, in every
    /// mode), with or without a tie and in working units scaled or not:
    /// every equality holds to 1e-9 in every identified mode, with and
    /// without the alternation.
    #[test]
    fn random_equalities_hold(
        seed in 0u64..1000,
        ca in -2.0f64..2.0,
        cb in prop_oneof![-2.0f64..-0.1, 0.1f64..2.0],
        v in -1.0f64..1.0,
        tie in any::<bool>(),
        scale in any::<bool>(),
        alternation in prop_oneof![Just(0usize), Just(20)],
    ) {
        let b = b1(180, 4.0, Noise::Uniform(0.1), seed);
        let mut p = b1_priors(3);
        p.equality.push(Equality {
            coefficients: [("a1".to_string(), ca), ("c".to_string(), cb)].into(),
            value: v,
        });
        if tie {
            p.tie.push(Tie { params: vec!["b1".into()] });
        }
        let set = ["restarts=3".to_string(), format!("scale={scale}"), format!("alternation={alternation}")];
        let set: Vec<&str> = set.iter().map(String::as_str).collect();
        let m = pwarx(run(&b.data, RegressorSpec::new(1, 1, 1), &p, &set).unwrap());
        let b0 = m.modes[0].theta[1];
        for mode in &m.modes {
            let t = &mode.theta;
            let scale = 1.0 + t.iter().map(|x| x.abs()).fold(0.0, f64::max);
            prop_assert!((ca * t[0] + cb * t[2] - v).abs() <= 1e-9 * scale, "{:?}", m.modes);
            if tie {
                prop_assert!((t[1] - b0).abs() <= 1e-9, "tie b1: {:?}", m.modes);
            }
        }
    }

    /// With switching variables the region normals are exactly zero outside
    /// the chosen regressors.
    #[test]
    fn switching_variables_zero_the_other_normals(seed in 0u64..1000, on_y in any::<bool>()) {
        let b = b1(180, 4.0, Noise::Uniform(0.1), seed);
        let mut p = b1_priors(3);
        p.switching = vec![if on_y { "y1" } else { "u1" }.into()];
        let other = if on_y { 1 } else { 0 };
        let m = pwarx(run(&b.data, RegressorSpec::new(1, 1, 1), &p, &["restarts=3"]).unwrap());
        for mode in &m.modes {
            for row in &mode.region.a {
                prop_assert_eq!(row[other], 0.0, "{:?}", mode.region);
            }
        }
    }

    /// Every sample whose target sits at a known stop is assigned to that
    /// stop's mode, and a simulation of the identified automaton never
    /// passes a known stop, also with inputs that drive the ordinary
    /// dynamics far beyond it.
    #[test]
    fn stops_take_their_samples_and_are_never_passed(
        seed in 0u64..1000,
        hold in 30usize..80,
        noisy in any::<bool>(),
        gain in 1.0f64..2.5,
    ) {
        let b = stopped_head(700, hold, if noisy { 0.02 } else { 0.0 }, seed);
        let p = b.priors();
        let problem = Problem {
            data: &b.data,
            orders: RegressorSpec::new(2, 1, 1),
            priors: &p,
            priors_origin: None,
        };
        let opts = ClusterOptions { restarts: 3, ..Default::default() };
        let (model, row_labels) = labelled(&problem, &opts, 4);
        prop_assert!(matches!(model, Model::HybridAutomaton(_)));
        prop_assert_eq!(model.mode_count(), 4);
        let d = &model.info().diagnostics;
        let targets = &b.data.y()[2..];
        // Sample by sample: a target at a stop (within the prior's
        // tolerance, or beyond it) is in that stop's mode (2 ordinary
        // modes, then the stops in prior order), every other one in an
        // ordinary mode.
        prop_assert_eq!(row_labels.len(), targets.len());
        for (r, (&l, &y)) in row_labels.iter().zip(targets).enumerate() {
            let at = p.saturation.iter().position(|st| {
                let beyond = match st.bound {
                    StopBound::Max => y > st.level,
                    StopBound::Min => y < st.level,
                };
                beyond || (y - st.level).abs() <= st.tolerance()
            });
            match at {
                Some(k) => prop_assert_eq!(l, 2 + k, "row {} (y = {}) not in stop {}", r, y, k),
                None => prop_assert!(l < 2, "row {} (y = {}) in stop mode {}", r, y, l),
            }
        }
        let want: Vec<usize> = p
            .saturation
            .iter()
            .enumerate()
            .map(|(k, _)| {
                pwarx::saturated_samples(&p, targets).iter().filter(|s| **s == Some(k)).count()
            })
            .collect();
        prop_assert_eq!(d.saturated_per_stop.clone(), Some(want.clone()));
        // The ordinary regions (default MRLP) cover the regressor space.
        prop_assert_eq!(d.regions_complete, Some(true));
        prop_assert_eq!(
            d.method["ordinary_samples"].as_u64().unwrap() as usize + want.iter().sum::<usize>(),
            targets.len()
        );
        // From the record start (at the upper stop, y = 0), and from inside.
        let mut y0 = b.data.y().to_vec();
        y0[0] = 1.0;
        y0[1] = 1.0;
        let u: Vec<f64> = b.data.u(0).iter().map(|v| gain * v - 0.3 * (gain - 1.0)).collect();
        let drive = Dataset::siso(u.clone(), b.data.y().to_vec(), None).unwrap();
        let inside = Dataset::siso(u, y0, None).unwrap();
        for data in [&b.data, &drive, &inside] {
            let sim = simulate(&model, data, SimulationOptions::for_data(data)).unwrap();
            for y in &sim.y[sim.start..] {
                prop_assert!((0.0..=25.0).contains(y), "simulation passed a stop: {y}");
            }
        }
    }
}

/// Known stops on the stopped head (noise 0.05, N = 1500, three records):
/// the priors give a clearly better mode sequence and simulation FIT on
/// fresh validation records than clustering four ordinary modes, the
/// paper's treatment of the stops. Measured (seeds 1, 2, 3): simulation
/// mode accuracy 0.774, 0.884, 0.808 with priors against 0.711, 0.740,
/// 0.637 without; FIT 87.4, 85.3, 85.2 against 82.6, 81.9, 82.6.
#[test]
fn stops_improve_mode_accuracy_and_simulation_fit() {
    let orders = RegressorSpec::new(2, 1, 1);
    let (mut with, mut without) = ((0.0, 0.0), (0.0, 0.0));
    for seed in [1u64, 2, 3] {
        let ident = stopped_head(1500, 60, 0.05, seed);
        let valid = stopped_head(1000, 60, 0.05, seed + 100);
        let p = ident.priors();
        let plain = b1_priors(4);
        let a = score(&run(&ident.data, orders, &p, &[]).unwrap(), &valid);
        let b = score(&run(&ident.data, orders, &plain, &[]).unwrap(), &valid);
        eprintln!("seed {seed}: with stops {a:?}, without {b:?}");
        with = (with.0 + a.0 / 3.0, with.1 + a.1 / 3.0);
        without = (without.0 + b.0 / 3.0, without.1 + b.1 / 3.0);
    }
    // Measured means: accuracy 0.822 vs 0.696, FIT 86.0 vs 82.4.
    assert!(with.0 >= without.0 + 0.08, "{with:?} vs {without:?}");
    assert!(with.1 >= without.1 + 2.5, "{with:?} vs {without:?}");
    assert!(with.0 >= 0.8 && with.1 >= 84.0, "{with:?}");
}

/// `max_modes` with stops: the count is chosen among `#stops + 1 ..= max`
/// (every count includes the stop modes).
#[test]
fn max_modes_counts_the_stops() {
    let b = stopped_head(900, 60, 0.02, 5);
    let mut p = b.priors();
    p.modes = None;
    p.max_modes = Some(4);
    let m = run(&b.data, RegressorSpec::new(2, 1, 1), &p, &["restarts=3"]).unwrap();
    assert!(matches!(m, Model::HybridAutomaton(_)));
    assert!((3..=4).contains(&m.mode_count()), "{}", m.mode_count());
    let choice = m.info().diagnostics.method["mode_choice"]
        .as_array()
        .unwrap()
        .clone();
    assert_eq!(choice.len(), 2, "{choice:?}");
    assert_eq!(choice[0][0], 3);
}

/// Figures for the report (H3 with `c = 0` fixed, B1 with ties): run with
/// `cargo test -p hysid-cluster --test it priors:: -- --ignored --nocapture`.
#[test]
#[ignore]
fn figures() {
    let sh = stopped_head(1500, 60, 0.05, 1);
    for p in [sh.priors(), b1_priors(4)] {
        let m = run(&sh.data, RegressorSpec::new(2, 1, 1), &p, &[]).unwrap();
        let d = &m.info().diagnostics.method;
        eprintln!(
            "stopped head, stops {}: degenerate {} flat scatter {}",
            p.saturation.len(),
            d["degenerate_local_datasets"],
            d["degenerate_flat_scatter"]
        );
    }
    let big = b1(20_000, 4.0, Noise::Uniform(0.1), 1);
    for tie in [false, true] {
        let mut p = b1_priors(3);
        if tie {
            p.tie.push(Tie {
                params: vec!["a1".into()],
            });
            p.bounds.insert("b1".into(), [-0.8, 0.8]);
        }
        let t = std::time::Instant::now();
        run(&big.data, RegressorSpec::new(1, 1, 1), &p, &[]).unwrap();
        eprintln!(
            "B1 N=20000 tie+bounds={tie}: {:.2} s",
            t.elapsed().as_secs_f64()
        );
    }
    for seed in [1u64, 2, 3] {
        let b = h3(300, seed);
        let v = h3(300, seed + 100);
        let orders = RegressorSpec::new(1, 1, 1);
        let mut p = b1_priors(3);
        let plain = pwarx(run(&b.data, orders, &p, &[]).unwrap());
        p.fixed.insert("c".into(), 0.0);
        let fixed = pwarx(run(&b.data, orders, &p, &[]).unwrap());
        let truth: Vec<Vec<f64>> = b.truth.modes.iter().map(|m| m.theta.clone()).collect();
        for (name, m) in [("plain", plain), ("c=0", fixed)] {
            let th: Vec<Vec<f64>> = m.modes.iter().map(|q| q.theta.clone()).collect();
            let err = parameter_error(&truth, &th).unwrap();
            let (r, _, _) = validate(&Model::Pwarx(m), &v.data, 0).unwrap();
            eprintln!(
                "H3 seed {seed} {name}: param err {:?} fit_sim {:.2}",
                err, r.fit_sim
            );
        }
    }
}
