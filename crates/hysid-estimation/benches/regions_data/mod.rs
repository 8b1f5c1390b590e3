//! The benchmark data of `benches/regions.rs` and
//! `examples/regions_stats.rs`: the classic three-mode PWARX regressor
//! domain of Ferrari-Trecate et al. (boundaries `[4 -1 10] phi` and
//! `[5 1 -6] phi`), lifted to `d = 3` regressors `x = [y(k-1), y(k-2),
//! u(k-1)]` uniform in `[-5, 5]^3`, the mode given by the two boundaries
//! applied to `phi = [y(k-1), u(k-1), 1]`, with 10 % of the labels within
//! 0.5 of a boundary moved to the next mode (clustering noise).

use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// `n` regressors and their labels, from seed 42.
pub fn data(n: usize) -> (DMatrix<f64>, Vec<usize>) {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let mut x = DMatrix::zeros(n, 3);
    let mut labels = Vec::with_capacity(n);
    for r in 0..n {
        let z: [f64; 3] = std::array::from_fn(|_| rng.random_range(-5.0..5.0));
        for k in 0..3 {
            x[(r, k)] = z[k];
        }
        let h1 = 4.0 * z[0] - z[2] + 10.0;
        let h2 = 5.0 * z[0] + z[2] - 6.0;
        let mut label = if h1 < 0.0 {
            0
        } else if h2 <= 0.0 {
            1
        } else {
            2
        };
        let near = h1.abs() < 0.5 || h2.abs() < 0.5;
        if near && rng.random::<f64>() < 0.1 {
            label = (label + 1) % 3;
        }
        labels.push(label);
    }
    (x, labels)
}
