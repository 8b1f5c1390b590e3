//! # hysid-testkit
//!
//! The benchmark systems of the hybrid-identification literature (B1 of
//! Ferrari-Trecate et al. 2003; H1-H4 and H7, the examples of the Hybrid
//! Identification Toolbox, HIT), with their exact parameters, as seeded
//! generators. HIT draws without a seed, so these reproduce its examples
//! statistically, not sample for sample. Each returns the data, the
//! true model and the true mode of every sample, so that back-ends can be
//! scored with `hysid_model::metrics::{mode_accuracy, parameter_error}`.
//!
//! Static maps (H1, H2, H4, H7) are written as PWARX models with `na = 0`,
//! `nb = 1`: the regressor of `y(k)` is the input `u(k-1)` (one column per
//! input), so every back-end treats them like dynamic data.

use hysid_core::backend::{Backend, IdentifyError, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_core::simulate::simulate;
use hysid_model::data::{Dataset, Signal};
use hysid_model::excitation::Excitation;
use hysid_model::geometry::Polyhedron;
use hysid_model::metrics::{mode_accuracy, parameter_error};
use hysid_model::model::Stop;
use hysid_model::model::StopBound;
use hysid_model::model::{HybridAutomaton, ModelInfo, PwarxMode, PwarxModel};
use hysid_model::simulate::SimulationOptions;
use hysid_model::statistics::upper_median;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// Measurement/equation noise of a benchmark.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Noise {
    /// None.
    None,
    /// Uniform on `[-a, a]`.
    Uniform(f64),
    /// Gaussian with this standard deviation.
    Gaussian(f64),
}

impl Noise {
    fn draw(&self, rng: &mut ChaCha8Rng) -> f64 {
        match *self {
            Noise::None => 0.0,
            Noise::Uniform(a) => {
                if a > 0.0 {
                    rng.random_range(-a..=a)
                } else {
                    0.0
                }
            }
            Noise::Gaussian(s) => Normal::new(0.0, s).map(|d| d.sample(rng)).unwrap_or(0.0),
        }
    }
}

/// A generated record with its ground truth.
#[derive(Debug, Clone)]
pub struct Benchmark {
    /// The record (inputs `u` or `u1, u2`, output `y`).
    pub data: Dataset,
    /// The true model.
    pub truth: PwarxModel,
    /// True mode of every sample from `truth.spec().lag()` on (earlier entries are `None`).
    pub modes: Vec<Option<usize>>,
}

impl Benchmark {
    /// True modes of the regressor rows (what `RegressorSpec::build` returns).
    pub fn row_modes(&self) -> Vec<usize> {
        self.modes.iter().flatten().copied().collect()
    }

    /// The true parameter vectors.
    pub fn thetas(&self) -> Vec<Vec<f64>> {
        self.truth.modes.iter().map(|m| m.theta.clone()).collect()
    }

    /// The identification problem of the record with the true orders and
    /// `priors`.
    pub fn problem<'a>(&'a self, priors: &'a Priors) -> Problem<'a> {
        Problem {
            data: &self.data,
            orders: self.truth.spec(),
            priors,
            priors_origin: None,
        }
    }

    /// `backend` on the record (true orders, `priors`, `settings`, seed
    /// `seed`, no deadline).
    pub fn run(
        &self,
        backend: &dyn Backend,
        priors: &Priors,
        settings: &Settings,
        seed: u64,
    ) -> Result<Model, IdentifyError> {
        backend.run(&self.problem(priors), settings, &RunContext::quiet(seed))
    }

    /// [`Benchmark::recovery`] of a model that must be PWARX (test code:
    /// panics otherwise).
    pub fn score(&self, model: &Model) -> (f64, f64) {
        self.recovery(as_pwarx(model))
    }

    /// How `model` recovers the truth: the mode its regions give each
    /// regressor of the record against the true mode (after the best
    /// matching), and the largest relative parameter error of the matched
    /// modes (infinite when a true mode has no match).
    pub fn recovery(&self, model: &PwarxModel) -> (f64, f64) {
        let spec = model.spec();
        let u: Vec<&[f64]> = (0..self.data.inputs.len())
            .map(|i| self.data.u(i))
            .collect();
        let (mut truth, mut found) = (Vec::new(), Vec::new());
        let mut x = vec![0.0; spec.dim()];
        for k in spec.lag()..self.data.len() {
            if let Some(q) = self.modes[k] {
                spec.fill(self.data.y(), &u, k, &mut x);
                truth.push(q);
                found.push(model.predict(&x).1.mode);
            }
        }
        let thetas: Vec<Vec<f64>> = model.modes.iter().map(|q| q.theta.clone()).collect();
        let accuracy = mode_accuracy(&truth, &found).map_or(0.0, |m| m.accuracy);
        let error = parameter_error(&self.thetas(), &thetas)
            .map_or(f64::INFINITY, |p| p.max_relative_error);
        (accuracy, error)
    }
}

/// The PWARX model inside `model` (test code: panics for another kind).
pub fn as_pwarx(model: &Model) -> &PwarxModel {
    match model {
        Model::Pwarx(p) => p,
        other => panic!("a PWARX model, not {}", other.kind()),
    }
}

/// `n` numbers drawn uniformly from [-1, 1] by a `ChaCha8Rng` seeded with
/// `seed`: the same numbers on every platform and for every thread count,
/// with no generator to pass around.
pub fn uniform(n: usize, seed: u64) -> Vec<f64> {
    draws(n, -1.0, 1.0, &mut ChaCha8Rng::seed_from_u64(seed))
}

/// The median of `v` over a test's seeds (the upper one of an even count,
/// [`upper_median`]); `NaN` for none.
pub fn median(mut v: Vec<f64>) -> f64 {
    upper_median(&mut v).unwrap_or(f64::NAN)
}

fn region(rows: &[(&[f64], f64)]) -> Polyhedron {
    Polyhedron::from_inequalities(
        rows.iter().map(|(a, _)| a.to_vec()).collect(),
        rows.iter().map(|(_, b)| *b).collect(),
    )
}

fn mode(theta: &[f64], rows: &[(&[f64], f64)]) -> PwarxMode {
    PwarxMode {
        theta: theta.to_vec(),
        region: region(rows),
        name: None,
    }
}

/// Simulates `truth` with equation noise: `y(k) = theta_q . [x(k); 1] + e(k)`
/// where `q` is the region of the regressor built from past (noisy) outputs.
pub fn generate(
    truth: PwarxModel,
    inputs: Vec<Vec<f64>>,
    y_init: &[f64],
    noise: Noise,
    rng: &mut ChaCha8Rng,
) -> Benchmark {
    let n = inputs[0].len();
    let spec = truth.spec();
    let lag = spec.lag();
    let mut y = vec![0.0; n];
    y[..lag.min(n)].copy_from_slice(&y_init[..lag.min(n)]);
    let mut modes = vec![None; n];
    let u: Vec<&[f64]> = inputs.iter().map(Vec::as_slice).collect();
    let mut x = vec![0.0; spec.dim()];
    for k in lag..n {
        spec.fill(&y, &u, k, &mut x);
        let (v, c) = truth.predict(&x);
        y[k] = v + noise.draw(rng);
        modes[k] = Some(c.mode);
    }
    let names: Vec<String> = if inputs.len() == 1 {
        vec!["u".into()]
    } else {
        (1..=inputs.len()).map(|i| format!("u{i}")).collect()
    };
    let data = Dataset::new(
        inputs
            .into_iter()
            .zip(names)
            .map(|(values, name)| Signal { name, values })
            .collect(),
        Signal {
            name: "y".into(),
            values: y,
        },
        None,
    )
    .expect("finite benchmark data");
    Benchmark { data, truth, modes }
}

/// `n` draws uniform on `[lo, hi]` from `rng`.
fn draws(n: usize, lo: f64, hi: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
    (0..n).map(|_| rng.random_range(lo..=hi)).collect()
}

fn pwarx(na: usize, nb: usize, inputs: usize, modes: Vec<PwarxMode>) -> PwarxModel {
    PwarxModel {
        na,
        nb,
        inputs,
        modes,
        info: ModelInfo::default(),
    }
}

/// B1, the classic 3-mode PWARX of Ferrari-Trecate et al. (Automatica 2003),
/// reused by Bemporad et al. (TAC 2005): `phi = [y(k-1), u(k-1), 1]`,
/// `theta_1 = [-0.4, 1, 1.5]` where `[4, -1, 10] phi < 0`,
/// `theta_2 = [0.5, -1, -0.5]` where `[4, -1, 10] phi >= 0` and `[5, 1, -6] phi <= 0`,
/// `theta_3 = [-0.3, 0.5, -1.7]` where `[5, 1, -6] phi > 0`.
/// Input uniform on `[-u_max, u_max]`.
pub fn b1(n: usize, u_max: f64, noise: Noise, seed: u64) -> Benchmark {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = pwarx(
        1,
        1,
        1,
        vec![
            mode(&[-0.4, 1.0, 1.5], &[(&[4.0, -1.0], -10.0)]),
            mode(
                &[0.5, -1.0, -0.5],
                &[(&[-4.0, 1.0], 10.0), (&[5.0, 1.0], 6.0)],
            ),
            mode(&[-0.3, 0.5, -1.7], &[(&[-5.0, -1.0], -6.0)]),
        ],
    );
    let u = draws(n, -u_max, u_max, &mut rng);
    generate(truth, vec![u], &[0.0], noise, &mut rng)
}

/// H1 (HIT `ex_pwarx_1d_3modes.m`): `y(k) = theta_i . [u(k-1); 1]`, equal
/// parameters on two disjoint regions: `[1, 0.2]` for `u <= -1`,
/// `[-1, 2]` for `-1 <= u <= 2`, `[1, 0.2]` for `u >= 2`; `u ~ U[-4, 4]`,
/// `e ~ N(0, 0.01)` (variance), N = 70 in HIT.
pub fn h1(n: usize, seed: u64) -> Benchmark {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = pwarx(
        0,
        1,
        1,
        vec![
            mode(&[1.0, 0.2], &[(&[1.0], -1.0)]),
            mode(&[-1.0, 2.0], &[(&[-1.0], 1.0), (&[1.0], 2.0)]),
            mode(&[1.0, 0.2], &[(&[-1.0], -2.0)]),
        ],
    );
    let u = draws(n, -4.0, 4.0, &mut rng);
    generate(truth, vec![u], &[0.0], Noise::Gaussian(0.1), &mut rng)
}

/// H2 (HIT `ex_pwarx_1d_5modes.m`): five modes on `u ~ U[-4, 8]`,
/// `e ~ N(0, 0.01)`: `[1, 0.2]` on `(-inf, -1]`, `[-1, 2]` on `[-1, 2]`,
/// `[1, -1]` on `[2, 4]`, `[0, 2]` on `[4, 6]`, `[2, -10]` on `[6, inf)`.
pub fn h2(n: usize, seed: u64) -> Benchmark {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = pwarx(
        0,
        1,
        1,
        vec![
            mode(&[1.0, 0.2], &[(&[1.0], -1.0)]),
            mode(&[-1.0, 2.0], &[(&[-1.0], 1.0), (&[1.0], 2.0)]),
            mode(&[1.0, -1.0], &[(&[-1.0], -2.0), (&[1.0], 4.0)]),
            mode(&[0.0, 2.0], &[(&[-1.0], -4.0), (&[1.0], 6.0)]),
            mode(&[2.0, -10.0], &[(&[-1.0], -6.0)]),
        ],
    );
    let u = draws(n, -4.0, 8.0, &mut rng);
    generate(truth, vec![u], &[0.0], Noise::Gaussian(0.1), &mut rng)
}

/// H3 (HIT `ex_pwarx_2d_3modes.m`): `x = [y(k-1), u(k-1)]`,
/// `theta_1 = theta_3 = [0.6, 0.3, 0]`, `theta_2 = [-0.6, -0.3, 0]`;
/// `X_1: 0.2 x1 + x2 <= -0.8`, `X_2: -0.8 - 0.2 x1 <= x2 <= 0.8 + 0.2 x1`,
/// `X_3: x2 >= 0.8 + 0.2 x1`; `u ~ U[-2, 2]`, `y(1) = 0.5`, `e ~ N(0, 0.01)`.
pub fn h3(n: usize, seed: u64) -> Benchmark {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = pwarx(
        1,
        1,
        1,
        vec![
            mode(&[0.6, 0.3, 0.0], &[(&[0.2, 1.0], -0.8)]),
            mode(
                &[-0.6, -0.3, 0.0],
                &[(&[-0.2, -1.0], 0.8), (&[-0.2, 1.0], 0.8)],
            ),
            mode(&[0.6, 0.3, 0.0], &[(&[0.2, -1.0], -0.8)]),
        ],
    );
    let u = draws(n, -2.0, 2.0, &mut rng);
    generate(truth, vec![u], &[0.5], Noise::Gaussian(0.1), &mut rng)
}

/// H4 (HIT `ex_cake1.m`): a static map of `(x1, x2)` on `[-1, 1]^2`, three
/// wedges meeting at the origin: `theta_1 = [4, 2, 3]` on
/// `{x2 >= 0, x1 + x2/sqrt(3) >= 0}`, `theta_2 = [-6, 6, -5]` on
/// `{x1 <= -|x2|/sqrt(3)}`, `theta_3 = [4, -2, -2]` on `{x2 <= 0, x1 >= x2/sqrt(3)}`;
/// `e ~ N(0, 0.1)` (variance). Inputs `u1 = x1`, `u2 = x2` (regressor `u(k-1)`).
pub fn h4(n: usize, seed: u64) -> Benchmark {
    h4_with_noise(n, Noise::Gaussian(0.1f64.sqrt()), seed)
}

/// H4's map and inputs with another noise (`h4` is
/// `h4_with_noise(n, Noise::Gaussian(0.1f64.sqrt()), seed)`, draw for draw).
pub fn h4_with_noise(n: usize, noise: Noise, seed: u64) -> Benchmark {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let r = 1.0 / 3f64.sqrt();
    let truth = pwarx(
        0,
        1,
        2,
        vec![
            mode(&[4.0, 2.0, 3.0], &[(&[0.0, -1.0], 0.0), (&[-1.0, -r], 0.0)]),
            mode(&[-6.0, 6.0, -5.0], &[(&[1.0, r], 0.0), (&[1.0, -r], 0.0)]),
            mode(&[4.0, -2.0, -2.0], &[(&[0.0, 1.0], 0.0), (&[-1.0, r], 0.0)]),
        ],
    );
    let x1 = draws(n, -1.0, 1.0, &mut rng);
    let x2 = draws(n, -1.0, 1.0, &mut rng);
    generate(truth, vec![x1, x2], &[0.0], noise, &mut rng)
}

/// H7 (HIT `ex_estimate_c_s.m`): five modes on `u ~ U[-4, 8]`, `e ~ N(0, 0.01)`:
/// `[1, 0.2]` on `(-inf, -1]`, `[-1, 2]` on `[-1, 2]`, `[1, 0.2]` on `[2, 4]`,
/// `[3, -10]` on `[4, 6]`, `[-2, 15]` on `[6, inf)`.
pub fn h7(n: usize, seed: u64) -> Benchmark {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let truth = pwarx(
        0,
        1,
        1,
        vec![
            mode(&[1.0, 0.2], &[(&[1.0], -1.0)]),
            mode(&[-1.0, 2.0], &[(&[-1.0], 1.0), (&[1.0], 2.0)]),
            mode(&[1.0, 0.2], &[(&[-1.0], -2.0), (&[1.0], 4.0)]),
            mode(&[3.0, -10.0], &[(&[-1.0], -4.0), (&[1.0], 6.0)]),
            mode(&[-2.0, 15.0], &[(&[-1.0], -6.0)]),
        ],
    );
    let u = draws(n, -4.0, 8.0, &mut rng);
    generate(truth, vec![u], &[0.0], Noise::Gaussian(0.1), &mut rng)
}

/// A record of a PWARX system with known stops, with its ground truth.
#[derive(Debug, Clone)]
pub struct StoppedBenchmark {
    /// The record (input `u`, output `y`).
    pub data: Dataset,
    /// The ordinary (non-saturation) modes.
    pub ordinary: PwarxModel,
    /// The stops.
    pub stops: Vec<Stop>,
    /// The true model: `HybridAutomaton::from_pwarx_with_stops(ordinary, stops)`,
    /// whose modes are the ordinary ones (`0..ordinary.modes.len()`) followed
    /// by one saturation mode per stop.
    pub truth: HybridAutomaton,
    /// True automaton mode of every sample (`None` for the first `na`).
    pub modes: Vec<Option<usize>>,
}

impl StoppedBenchmark {
    /// True automaton modes of the regressor rows (from sample `na` on).
    pub fn row_modes(&self) -> Vec<usize> {
        self.modes.iter().flatten().copied().collect()
    }

    /// The priors a user with this knowledge writes: every mode counted,
    /// the stops given.
    pub fn priors(&self) -> Priors {
        Priors {
            modes: Some(self.ordinary.modes.len() + self.stops.len()),
            saturation: self.stops.clone(),
            ..Priors::default()
        }
    }
}

/// A mounting-head-like PWARX with both stops (in the spirit of Juloski,
/// Heemels, Ferrari-Trecate, IFAC ADHS 2003, section 5):
/// `x = [y(k-1), y(k-2), u(k-1)]`, two ordinary modes switching on the
/// position `y(k-1)` (free below 18, impact at or above it):
/// - free: poles `0.95 e^(+-0.15 i)`, `y(k) = 1.87871 y1 - 0.9025 y2 + 0.476 u1 + 0.0476`
///   (equilibrium `20 u + 2`);
/// - impact: poles `0.9 e^(+-0.35 i)`, `y(k) = 1.68768 y1 - 0.81 y2 + 1.2232 u1 + 1.2232`
///   (equilibrium about `10 u + 10`);
/// - stops: `y = 0` (min, the upper stop of the head) and `y = 25` (max, the
///   lower stop), each a mode on the guard set `y = level` with the reset
///   `y(k), y(k-1) := level` (`HybridAutomaton::from_pwarx_with_stops`).
///
/// The input is the paper's random piecewise-constant signal
/// (`hysid_model::excitation`), levels `U[-0.3, 1.7]` held `hold` samples, so
/// both stops are reached and held. The record is the automaton's
/// noise-free simulation; with `noise_std > 0`, Gaussian measurement noise
/// is added to the samples of the ordinary modes only (a stop holds the
/// position exactly).
pub fn stopped_head(n: usize, hold: usize, noise_std: f64, seed: u64) -> StoppedBenchmark {
    let a = |r: f64, th: f64| (2.0 * r * th.cos(), -r * r);
    let (f1, f2) = a(0.95, 0.15);
    let (i1, i2) = a(0.9, 0.35);
    let gain = |a1: f64, a2: f64| 1.0 - a1 - a2;
    let (gf, gi) = (gain(f1, f2), gain(i1, i2));
    let ordinary = pwarx(
        2,
        1,
        1,
        vec![
            mode(&[f1, f2, 20.0 * gf, 2.0 * gf], &[(&[1.0, 0.0, 0.0], 18.0)]),
            mode(
                &[i1, i2, 10.0 * gi, 10.0 * gi],
                &[(&[-1.0, 0.0, 0.0], -18.0)],
            ),
        ],
    );
    let stops = vec![
        Stop {
            level: 0.0,
            bound: StopBound::Min,
            tol: None,
        },
        Stop {
            level: 25.0,
            bound: StopBound::Max,
            tol: None,
        },
    ];
    let truth = HybridAutomaton::from_pwarx_with_stops(&ordinary, &stops);
    let u = Excitation {
        n,
        hold: hold.max(1),
        low: -0.3,
        high: 1.7,
        ts: None,
        inputs: 1,
    }
    .generate(seed)
    .remove(0);
    let record = Dataset::siso(u, vec![0.0; n], None).expect("finite input");
    let sim = simulate(
        &Model::HybridAutomaton(truth.clone()),
        &record,
        SimulationOptions::default(),
    )
    .expect("the stopped head simulates");
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_add(0x5eed));
    let noise = Noise::Gaussian(noise_std);
    let n_ordinary = ordinary.modes.len();
    let y: Vec<f64> = sim
        .y
        .iter()
        .zip(&sim.modes)
        .map(|(&v, q)| match q {
            Some(q) if *q >= n_ordinary => v,
            _ => v + noise.draw(&mut rng),
        })
        .collect();
    let data = Dataset::siso(record.u(0).to_vec(), y, None).expect("finite simulation");
    StoppedBenchmark {
        data,
        ordinary,
        stops,
        truth,
        modes: sim.modes,
    }
}

/// A record of the mounting-head model simulated by the mechanical
/// simulator (`models/pick-and-place/simulated/`: Gaussian measurement noise
/// of 0.005 mm on every sample, the stops included), with the output
/// rounded to `quantum` (0: as written) as a position sensor does, and the
/// true mode of every sample.
#[derive(Debug, Clone)]
pub struct SimulatedHead {
    /// The record (input `u`, output `y`, sampling time 0.0025 s).
    pub data: Dataset,
    /// True mode name of every sample (`None` for the first samples).
    pub modes: Vec<Option<String>>,
}

impl SimulatedHead {
    /// Reads `models/pick-and-place/simulated/<file>` (columns `t`, `u`,
    /// `y`, `mode`).
    pub fn read(file: &str, quantum: f64) -> Self {
        let path = format!(
            "{}/../../models/pick-and-place/simulated/{file}",
            env!("CARGO_MANIFEST_DIR")
        );
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let (mut u, mut y, mut modes) = (Vec::new(), Vec::new(), Vec::new());
        for line in text.lines().skip(1) {
            let cells: Vec<&str> = line.split(',').collect();
            let number = |i: usize| {
                cells[i]
                    .parse::<f64>()
                    .unwrap_or_else(|e| panic!("{path}: {e}"))
            };
            u.push(number(1));
            let v = number(2);
            y.push(if quantum > 0.0 {
                (v / quantum).round() * quantum
            } else {
                v
            });
            modes.push(Some(cells[3].to_string()).filter(|m| !m.is_empty()));
        }
        let data = Dataset::siso(u, y, Some(0.0025)).expect("a finite record");
        SimulatedHead { data, modes }
    }

    /// Samples `range` of the record.
    pub fn rows(&self, range: std::ops::Range<usize>) -> (Dataset, Vec<Option<String>>) {
        let data = self
            .data
            .slice(hysid_model::data::RowRange {
                start: Some(range.start),
                end: Some(range.end),
            })
            .expect("rows inside the record");
        (data, self.modes[range].to_vec())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_data_and_modes_follow_regions() {
        let a = b1(300, 4.0, Noise::Uniform(0.1), 1);
        let b = b1(300, 4.0, Noise::Uniform(0.1), 1);
        assert_eq!(a.data, b.data);
        assert_eq!(a.row_modes().len(), 299);
        // All three modes are visited.
        for q in 0..3 {
            assert!(a.row_modes().contains(&q));
        }
        let c = h4(200, 3);
        assert_eq!(c.data.inputs.len(), 2);
        assert_eq!(c.row_modes().len(), 199);
        for q in 0..3 {
            assert!(c.row_modes().contains(&q), "mode {q}");
        }
        assert_eq!(
            h1(70, 0).truth.modes[0].theta,
            h1(70, 0).truth.modes[2].theta
        );
        // H4's noise changes the output only.
        let d = h4_with_noise(200, Noise::None, 3);
        assert_eq!(d.data.inputs, c.data.inputs);
        assert_eq!(d.modes, c.modes);
        assert_ne!(d.data.y(), c.data.y());
        assert_eq!(
            h4_with_noise(200, Noise::Gaussian(0.1f64.sqrt()), 3).data,
            c.data
        );
        assert_eq!(h2(100, 0).truth.modes.len(), 5);
        assert_eq!(h3(60, 0).truth.modes.len(), 3);
        assert_eq!(h7(150, 0).truth.modes.len(), 5);
    }

    #[test]
    fn noise_free_b1_is_exactly_piecewise_affine() {
        let b = b1(100, 4.0, Noise::None, 2);
        let y = b.data.y();
        let u = b.data.u(0);
        for k in 1..100 {
            let q = b.modes[k].unwrap();
            let t = &b.truth.modes[q].theta;
            assert!((y[k] - (t[0] * y[k - 1] + t[1] * u[k - 1] + t[2])).abs() < 1e-12);
        }
    }

    #[test]
    fn stopped_head_reaches_and_holds_both_stops() {
        let b = stopped_head(3000, 60, 0.0, 7);
        let rows = b.row_modes();
        let count = |q: usize| rows.iter().filter(|&&m| m == q).count();
        // free, impact, upper stop (y = 0), lower stop (y = 25)
        let counts = [count(0), count(1), count(2), count(3)];
        assert!(counts.iter().all(|&c| c >= 100), "{counts:?}");
        let y = b.data.y();
        for (k, q) in b.modes.iter().enumerate() {
            match q {
                Some(2) => assert_eq!(y[k], 0.0),
                Some(3) => assert_eq!(y[k], 25.0),
                _ => assert!((0.0..=25.0).contains(&y[k]), "k={k} y={}", y[k]),
            }
        }
        // The priors' stops hold exactly at the saturated rows.
        let p = b.priors();
        assert_eq!((p.modes, p.saturation.len()), (Some(4), 2));
        let sat = y[2..]
            .iter()
            .map(|&v| p.saturation.iter().position(|s| s.holds(v)));
        for (s, &q) in sat.zip(&rows) {
            assert_eq!(s.map(|i| i + 2), (q >= 2).then_some(q), "{s:?} {q}");
        }
        // Same seed, same record.
        assert_eq!(
            stopped_head(3000, 60, 0.1, 7).data,
            stopped_head(3000, 60, 0.1, 7).data
        );
    }
}
