//! The mounting head written as a gray-box model
//! (`models/pick-and-place/head-graybox.toml`) against the mechanical
//! simulator that runs `head.toml`: the same physics must give the same
//! trajectory, for any parameters within the bounds and any input.

use crate::{from_toml, repository_file};
use hysid_graybox::simulate::run;
use hysid_graybox::{CompiledModel, GrayBoxModel};
use hysid_mechanical::MechanicalModel;
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use proptest::prelude::*;

fn models(z: &[f64]) -> (GrayBoxModel, MechanicalModel) {
    let mut g: GrayBoxModel = from_toml(
        &repository_file("models/pick-and-place/head-graybox.toml"),
        Some("gray_box"),
    );
    let mut m: MechanicalModel = from_toml(
        &repository_file("models/pick-and-place/head.toml"),
        Some("mechanical"),
    );
    for (p, zi) in m.parameters.iter_mut().zip(z) {
        if !p.fixed {
            p.value = p.bounds[0] + (p.bounds[1] - p.bounds[0]) * zi;
        }
    }
    assert_eq!(g.parameters.len(), m.parameters.len());
    for (a, b) in g.parameters.iter_mut().zip(&m.parameters) {
        assert_eq!(a.name, b.name);
        a.value = b.value;
    }
    g.validate().unwrap();
    m.validate().unwrap();
    (g, m)
}

const TS: f64 = 0.0025;

fn record(seed: u64, low: f64, n: usize) -> Dataset {
    let ex = Excitation {
        n,
        hold: 40,
        low,
        high: 0.05,
        ts: Some(TS),
        inputs: 1,
    };
    let u = ex.generate(seed).remove(0);
    // A measured output for the initial state: at rest 3 mm below the upper stop.
    Dataset::siso(u, vec![3.0; n], Some(TS)).unwrap()
}

#[test]
fn nominal_head_matches_the_mechanical_simulator() {
    let (g, m) = models(&[0.5; 12]);
    let names = g.mode_names();
    let regimes = [
        "free",
        "impact",
        "stick",
        "upper_saturation",
        "lower_saturation",
    ];
    // The first record on which the reference visits every regime, so that
    // the comparison covers them all.
    let (data, b) = (0..200)
        .map(|seed| {
            let data = record(seed, -0.3 + 0.001 * seed as f64, 1200);
            let b = hysid_mechanical::simulate::run(&m, &m.values(), &data).unwrap();
            (data, b)
        })
        .find(|(_, b)| {
            regimes.iter().all(|want| {
                let i = m.modes.iter().position(|q| q.name == *want).unwrap();
                b.modes.contains(&Some(i))
            })
        })
        .expect("a record that visits every regime");
    let c = CompiledModel::new(&g).unwrap();
    let a = run(&c, &g.values(), &data).unwrap();
    let worst =
        a.y.iter()
            .zip(&b.y)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
    assert!(worst < 1e-9, "max |y difference| {worst} mm");
    for k in 0..data.len() {
        let la = a.modes[k].map(|i| names[i].as_str());
        let lb = b.modes[k].map(|i| m.modes[i].name.as_str());
        assert_eq!(la, lb, "mode at {k}");
    }
    assert!(a.events > 0 && a.zeno.is_none());
}

fn unit() -> impl Strategy<Value = Vec<f64>> {
    proptest::collection::vec(0.0f64..=1.0, 12)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Same outputs and the same regimes at every sample (labels compared
    /// by name), for parameters anywhere in their bounds.
    #[test]
    fn head_matches_the_mechanical_simulator_anywhere(z in unit(), seed in any::<u64>(), low in -0.3f64..-0.1) {
        let (g, m) = models(&z);
        let data = record(seed, low, 600);
        let c = CompiledModel::new(&g).unwrap();
        let a = run(&c, &g.values(), &data).unwrap();
        let b = hysid_mechanical::simulate::run(&m, &m.values(), &data).unwrap();
        let names = g.mode_names();
        for k in 0..600 {
            prop_assert!((a.y[k] - b.y[k]).abs() < 1e-6, "k {}: {} vs {}", k, a.y[k], b.y[k]);
            let la = a.modes[k].map(|i| names[i].as_str());
            let lb = b.modes[k].map(|i| m.modes[i].name.as_str());
            prop_assert_eq!(la, lb, "mode at {}", k);
        }
    }

    /// Without input power the head's declared energy (kinetic, springs,
    /// constant force, the board's spring while penetrating) never rises,
    /// from any state: dampers, friction and the inelastic stops only
    /// dissipate.
    #[test]
    fn energy_never_rises_without_input(z in unit(), y0 in 0.0f64..1.0, v0 in -400.0f64..400.0) {
        let (mut g, _) = models(&z);
        let y0 = y0 * g.parameters[g.parameter_index("y_low").unwrap()].value;
        g.initial_state = hysid_graybox::GrayBoxInitialState::Given {
            values: [("y".to_string(), y0), ("v".to_string(), v0)].into(),
            mode: None,
            estimate: Default::default(),
            samples: None,
        };
        let n = 400;
        let data = Dataset::siso(vec![0.0; n], vec![0.0; n], Some(TS)).unwrap();
        let c = CompiledModel::new(&g).unwrap();
        let r = run(&c, &g.values(), &data).unwrap();
        let bound = c.bind(&g.values());
        let energy = |y: f64, v: f64| bound.energy_at(&[y, v]).unwrap();
        let scale = energy(y0, v0).abs() + 1.0;
        let mut before = energy(y0, v0);
        for k in 0..n {
            let e = energy(r.x[2 * k], r.x[2 * k + 1]);
            prop_assert!(e <= before + 1e-9 * scale, "k {}: {} > {}", k, e, before);
            before = e;
        }
    }

    /// A stop is never passed, and a head resting at a stop is exactly there.
    #[test]
    fn stops_are_never_passed(z in unit(), seed in any::<u64>(), low in -0.3f64..-0.1) {
        let (g, _) = models(&z);
        let data = record(seed, low, 600);
        let c = CompiledModel::new(&g).unwrap();
        let r = run(&c, &g.values(), &data).unwrap();
        let p = |n: &str| g.parameters[g.parameter_index(n).unwrap()].value;
        let names = g.mode_names();
        for k in 0..600 {
            prop_assert!(r.y[k] >= p("y_up") && r.y[k] <= p("y_low"), "k {}: {}", k, r.y[k]);
            match r.modes[k].map(|i| names[i].as_str()) {
                Some("upper_saturation") => prop_assert!(r.y[k] == p("y_up") && r.x[2 * k + 1] == 0.0),
                Some("lower_saturation") => prop_assert!(r.y[k] == p("y_low") && r.x[2 * k + 1] == 0.0),
                Some("stick") => prop_assert!(r.x[2 * k + 1] == 0.0),
                _ => {}
            }
        }
    }

    /// A stuck head stays stuck while the applied force is within the
    /// static level, and breaks away beyond it.
    #[test]
    fn sticking_holds_below_the_static_level(z in unit(), y0 in 0.05f64..0.45, frac in -0.98f64..0.98) {
        let (mut g, _) = models(&z);
        let p = |n: &str| g.parameters[g.parameter_index(n).unwrap()].value;
        // Below the board (free mode), so the force is ku u + f0 - c1 y.
        let y0 = y0 * p("yc");
        let (ku, f0, c1, fs) = (p("ku"), p("f0"), p("c1"), p("fs").max(p("f1")));
        g.initial_state = hysid_graybox::GrayBoxInitialState::Given {
            values: [("y".to_string(), y0)].into(),
            mode: None,
            estimate: Default::default(),
            samples: None,
        };
        let c = CompiledModel::new(&g).unwrap();
        let n = 200;
        let at = |force: f64| {
            let u = (force - f0 + c1 * y0) / ku;
            let data = Dataset::siso(vec![u; n], vec![0.0; n], Some(TS)).unwrap();
            run(&c, &g.values(), &data).unwrap()
        };
        let stuck = at(frac * fs);
        prop_assert!(stuck.y.iter().all(|y| *y == y0));
        let stick = g.mode_names().iter().position(|m| m == "stick");
        prop_assert!(stuck.modes.iter().all(|q| *q == stick));
        let moving = at((1.05 * fs).copysign(frac));
        prop_assert!(moving.y[1] != y0);
    }
}
