//! Every gray-box model file of the repository, with random parameters
//! within their bounds and random inputs of the amplitude its "Try:" line
//! shows: the run never fails (no reset leaves its target's invariant),
//! every sample satisfies its mode's invariant, the states stay finite, and
//! no stop is passed; and the energy a file declares never rises once the
//! input is zero.

use hysid_graybox::simulate::run;
use hysid_graybox::{CompiledModel, GrayBoxModel};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use proptest::prelude::*;

const FILES: [&str; 10] = [
    "models/pick-and-place/head-graybox.toml",
    "models/pick-and-place/structures/delay.toml",
    "models/pick-and-place/structures/lag.toml",
    "models/pick-and-place/structures/stribeck.toml",
    "models/pick-and-place/structures/asym.toml",
    "models/pick-and-place/structures/cubic.toml",
    "models/pick-and-place/structures/asym-cubic.toml",
    "models/examples/ball-on-table.toml",
    "models/examples/two-masses.toml",
    "models/examples/backlash-drive.toml",
];

/// The model, and the excitation of its "Try:" line.
fn file(path: &str) -> (GrayBoxModel, Excitation) {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let text = std::fs::read_to_string(format!("{root}/{path}")).unwrap();
    let spec = text
        .lines()
        .find_map(|l| l.split("--excite ").nth(1))
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("{path}: no Try: line with --excite"));
    let field = |key: &str| -> f64 {
        spec.split(',')
            .find_map(|kv| kv.strip_prefix(&format!("{key}=")))
            .unwrap_or_else(|| panic!("{path}: {key}"))
            .parse()
            .unwrap()
    };
    let ex = Excitation {
        n: 600,
        hold: field("hold") as usize,
        low: field("low"),
        high: field("high"),
        ts: Some(field("ts")),
        inputs: 1,
    };
    let mut table: toml::Table = text.parse().unwrap();
    assert_eq!(table.remove("kind").unwrap().as_str(), Some("gray_box"));
    let m: GrayBoxModel = toml::Value::Table(table).try_into().unwrap();
    m.validate().unwrap();
    (m, ex)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn every_model_file_runs_inside_its_invariants(
        which in 0usize..FILES.len(),
        z in proptest::collection::vec(0.0f64..=1.0, 16),
        seed in any::<u64>(),
    ) {
        let (mut m, ex) = file(FILES[which]);
        for (p, zi) in m.parameters.iter_mut().zip(&z) {
            if !p.fixed {
                p.value = p.bounds[0] + (p.bounds[1] - p.bounds[0]) * zi;
            }
        }
        let u = ex.generate(seed).remove(0);
        let data = Dataset::siso(u, vec![0.0; ex.n], ex.ts).unwrap();
        let c = CompiledModel::new(&m).unwrap();
        let r = run(&c, &m.values(), &data);
        prop_assert!(r.is_ok(), "{}: {:?}", FILES[which], r.err());
        let r = r.unwrap();
        let n = m.states.len();
        for k in r.start..ex.n {
            prop_assert!(r.covered[k], "{}: sample {} outside its invariant", FILES[which], k);
            prop_assert!(r.x[k * n..(k + 1) * n].iter().all(|x| x.is_finite()));
        }
        for (level, sign) in m.output_stops() {
            for k in r.start..ex.n {
                prop_assert!(sign * (r.y[k] - level) <= 0.0,
                    "{}: sample {}: output {} past the stop at {}", FILES[which], k, r.y[k], level);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Every model file that declares its stored energy, with random
    /// parameters within their bounds: driven by a random input of its
    /// "Try:" amplitude for the first half of the record, then with the
    /// input at zero, the declared energy never rises over the second
    /// half (to 1e-9 of its size): no flow, element or reset adds energy
    /// without input power.
    #[test]
    fn declared_energy_never_rises_without_input(
        which in 0usize..FILES.len(),
        z in proptest::collection::vec(0.0f64..=1.0, 16),
        seed in any::<u64>(),
    ) {
        let (mut m, ex) = file(FILES[which]);
        if m.energy.is_none() {
            return Ok(());
        }
        for (p, zi) in m.parameters.iter_mut().zip(&z) {
            if !p.fixed {
                p.value = p.bounds[0] + (p.bounds[1] - p.bounds[0]) * zi;
            }
        }
        let half = ex.n / 2;
        let mut u = ex.generate(seed).remove(0);
        u[half..].fill(0.0);
        let data = Dataset::siso(u, vec![0.0; ex.n], ex.ts).unwrap();
        let c = CompiledModel::new(&m).unwrap();
        let r = run(&c, &m.values(), &data).unwrap();
        let bound = c.bind(&m.values());
        let n = m.states.len();
        let energy = |k: usize| bound.energy_at(&r.x[k * n..(k + 1) * n]).unwrap();
        let mut before = energy(half);
        let scale = before.abs() + 1.0;
        for k in half + 1..ex.n {
            let e = energy(k);
            prop_assert!(e.is_finite());
            prop_assert!(e <= before + 1e-9 * scale,
                "{}: sample {}: energy {} > {}", FILES[which], k, e, before);
            before = e;
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// The drive with backlash, without input torque, from a random state:
    /// its declared energy (kinetic, and the shaft's spring past the dead
    /// zone) never rises; the viscous frictions only dissipate.
    #[test]
    fn drive_energy_never_rises_without_input(
        z in proptest::collection::vec(0.0f64..=1.0, 6),
        x0 in proptest::collection::vec(-1.0f64..1.0, 4),
    ) {
        let (mut m, _) = file("models/examples/backlash-drive.toml");
        for (p, zi) in m.parameters.iter_mut().zip(&z) {
            if !p.fixed {
                p.value = p.bounds[0] + (p.bounds[1] - p.bounds[0]) * zi;
            }
        }
        let names = ["thm", "wm", "thl", "wl"];
        m.initial_state = hysid_graybox::GrayBoxInitialState::Given {
            values: names.iter().map(|n| n.to_string()).zip(x0.iter().map(|v| v * 0.5)).collect(),
            mode: None,
        };
        let n = 400;
        let data = Dataset::siso(vec![0.0; n], vec![0.0; n], Some(0.01)).unwrap();
        let c = CompiledModel::new(&m).unwrap();
        let r = run(&c, &m.values(), &data).unwrap();
        let bound = c.bind(&m.values());
        let energy = |x: &[f64]| bound.energy_at(x).unwrap();
        let mut before = energy(&r.x[0..4]);
        let scale = before + 1.0;
        for k in 1..n {
            let e = energy(&r.x[4 * k..4 * k + 4]);
            prop_assert!(e <= before + 1e-9 * scale, "k {}: {} > {}", k, e, before);
            before = e;
        }
    }
}
