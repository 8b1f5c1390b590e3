//! Input delays: the model sees an input `d = q ts + r` seconds late,
//! switching inside the sample at `r`.

use crate::from_toml;
use hysid_graybox::simulate::run;
use hysid_graybox::{CompiledModel, GrayBoxModel};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use proptest::prelude::*;

/// `x' = -a x + b u(t - d)`, output `x`, from rest.
fn lag(d: f64) -> GrayBoxModel {
    let text = format!(
        r#"
format = 1
internal_step = 0.0005
states = ["x"]
inputs = ["u"]
delays = {{ u = "d" }}
outputs = [{{ name = "x", value = "x" }}]
initial_state = {{ from = "given", values = {{}} }}
parameters = [
  {{ name = "a", value = 7.0, bounds = [1.0, 20.0] }},
  {{ name = "b", value = 3.0, bounds = [1.0, 5.0] }},
  {{ name = "d", value = {d:?}, bounds = [0.0, 1.0] }},
]
[[modes]]
name = "only"
flow = {{ x = "-a*x + b*u" }}
"#
    );
    let m: GrayBoxModel = from_toml(&text, None);
    m.validate().unwrap();
    m
}

/// The exact response to the delayed, held input: on each interval of
/// constant input `x` relaxes to `b u / a` with rate `a`.
fn exact(u: &[f64], ts: f64, d: f64) -> Vec<f64> {
    let (a, b) = (7.0f64, 3.0f64);
    let delayed = |t: f64| {
        let k = ((t - d) / ts + 1e-9).floor();
        u[(k.max(0.0) as usize).min(u.len() - 1)]
    };
    // Every switching instant of the delayed input, and the sample instants.
    let mut times: Vec<f64> = (0..u.len()).map(|k| k as f64 * ts).collect();
    times.extend((0..u.len()).map(|k| k as f64 * ts + d));
    times.retain(|t| *t < (u.len() - 1) as f64 * ts + 1e-12);
    times.sort_by(f64::total_cmp);
    let mut out = vec![0.0; u.len()];
    let (mut x, mut t) = (0.0, 0.0);
    for &next in times
        .iter()
        .skip(1)
        .chain([(u.len() - 1) as f64 * ts].iter())
    {
        if next <= t {
            continue;
        }
        let v = delayed(t + 1e-12);
        let target = b * v / a;
        x = target + (x - target) * (-a * (next - t)).exp();
        t = next;
        let k = (t / ts).round() as usize;
        if (t - k as f64 * ts).abs() < 1e-9 {
            out[k] = x;
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Whole and fractional delays give the exact response within 1e-9.
    #[test]
    fn delayed_input_matches_the_exact_response(d in 0.0f64..0.05, seed in any::<u64>()) {
        let ts = 0.01;
        let n = 200;
        let ex = Excitation { n, hold: 7, low: -1.0, high: 1.0, ts: Some(ts), inputs: 1 };
        let u = ex.generate(seed).remove(0);
        let m = lag(d);
        let data = Dataset::siso(u.clone(), vec![0.0; n], Some(ts)).unwrap();
        let r = run(&CompiledModel::new(&m).unwrap(), &m.values(), &data).unwrap();
        let want = exact(&u, ts, d);
        for (k, (got, want)) in r.y.iter().zip(&want).enumerate() {
            prop_assert!((got - want).abs() < 1e-9, "k {}: {} vs {}", k, got, want);
        }
    }
}

/// A delay of whole samples is the undelayed run on the input shifted.
#[test]
fn whole_sample_delay_shifts_the_input() {
    let (ts, n, q) = (0.01, 100, 3);
    let ex = Excitation {
        n,
        hold: 5,
        low: -1.0,
        high: 1.0,
        ts: Some(ts),
        inputs: 1,
    };
    let u = ex.generate(4).remove(0);
    let mut shifted = vec![u[0]; q];
    shifted.extend_from_slice(&u[..n - q]);
    let run_on = |m: &GrayBoxModel, u: &[f64]| {
        let data = Dataset::siso(u.to_vec(), vec![0.0; n], Some(ts)).unwrap();
        run(&CompiledModel::new(m).unwrap(), &m.values(), &data)
            .unwrap()
            .y
    };
    let delayed = run_on(&lag(q as f64 * ts), &u);
    let plain = run_on(&lag(0.0), &shifted);
    for (k, (a, b)) in delayed.iter().zip(&plain).enumerate() {
        assert!((a - b).abs() < 1e-12, "k {k}: {a} vs {b}");
    }
}
