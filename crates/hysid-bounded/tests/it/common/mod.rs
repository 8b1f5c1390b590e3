//! Test systems built on `hysid-testkit`.

use hysid_model::geometry::Polyhedron;
use hysid_model::model::{ModelInfo, PwarxMode, PwarxModel};
use hysid_testkit::{Benchmark, Noise};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A static-switching PWARX with `na = nb = 1` and parameters `thetas`
/// (`[a1, b1, c]` each), where the mode of sample `k` is chosen by the
/// input's interval: `u(k-1)` in the `i`-th of `thetas.len()` equal slices of
/// `[-2, 2]`. Input `U[-2, 2]`, equation noise `U[-noise, noise]`
/// (`hysid_testkit::generate`).
pub fn sliced(thetas: &[[f64; 3]], n: usize, noise: f64, seed: u64) -> Benchmark {
    let s = thetas.len().max(1);
    let w = 4.0 / s as f64;
    let modes = thetas
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let lo = -2.0 + w * i as f64;
            let (mut a, mut b) = (Vec::new(), Vec::new());
            if i > 0 {
                a.push(vec![0.0, -1.0]);
                b.push(-lo);
            }
            if i + 1 < s {
                a.push(vec![0.0, 1.0]);
                b.push(lo + w);
            }
            PwarxMode {
                theta: t.to_vec(),
                region: Polyhedron::from_inequalities(a, b),
                name: None,
            }
        })
        .collect();
    let truth = PwarxModel {
        na: 1,
        nb: 1,
        inputs: 1,
        modes,
        info: ModelInfo::default(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let u: Vec<f64> = (0..n).map(|_| rng.random_range(-2.0..2.0)).collect();
    hysid_testkit::generate(truth, vec![u], &[0.0], Noise::Uniform(noise), &mut rng)
}
