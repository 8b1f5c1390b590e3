//! Synthetic PWARX systems with known modes, for tests, examples and
//! benchmarks.

use hysid_core::data::Dataset;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A record with the true mode of every regressor row.
#[derive(Debug, Clone)]
pub struct Generated {
    /// The record.
    pub data: Dataset,
    /// True mode of regressor row `r` (sample `r + lag`).
    pub modes: Vec<usize>,
}

/// True parameters of B1 (`shared/docs/algorithms.md` (c) B1), `[a1, b1, c]`.
pub const B1_THETA: [[f64; 3]; 3] = [[-0.4, 1.0, 1.5], [0.5, -1.0, -0.5], [-0.3, 0.5, -1.7]];

/// Mode of B1 at `phi = [y(k-1), u(k-1), 1]`: 0 when `[4 -1 10] phi < 0`,
/// 2 when `[5 1 -6] phi > 0`, else 1.
pub fn b1_mode(y1: f64, u1: f64) -> usize {
    if 4.0 * y1 - u1 + 10.0 < 0.0 {
        0
    } else if 5.0 * y1 + u1 - 6.0 > 0.0 {
        2
    } else {
        1
    }
}

/// B1: the classic 3-mode PWARX (na = nb = 1), `u ~ U[-4, 4]`, noise
/// `U[-noise, noise]`, `n` samples (`n - 1` regressor rows).
pub fn b1(n: usize, noise: f64, seed: u64) -> Generated {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let u: Vec<f64> = (0..n).map(|_| rng.random_range(-4.0..4.0)).collect();
    let mut y = vec![0.0; n];
    let mut modes = Vec::with_capacity(n.saturating_sub(1));
    for k in 1..n {
        let i = b1_mode(y[k - 1], u[k - 1]);
        let t = B1_THETA[i];
        let e = if noise > 0.0 {
            rng.random_range(-noise..noise)
        } else {
            0.0
        };
        y[k] = t[0] * y[k - 1] + t[1] * u[k - 1] + t[2] + e;
        modes.push(i);
    }
    Generated {
        data: Dataset::siso(u, y, None).expect("equal lengths"),
        modes,
    }
}

/// A static-switching PWARX with `na = nb = 1` and parameters `thetas`
/// (`[a1, b1, c]` each), where the mode of sample `k` is chosen by the
/// input's interval: `u(k-1)` in the `i`-th of `thetas.len()` equal slices of
/// `[-2, 2]`. Noise `U[-noise, noise]`.
pub fn sliced(thetas: &[[f64; 3]], n: usize, noise: f64, seed: u64) -> Generated {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let s = thetas.len().max(1);
    let u: Vec<f64> = (0..n).map(|_| rng.random_range(-2.0..2.0)).collect();
    let mut y = vec![0.0; n];
    let mut modes = Vec::with_capacity(n.saturating_sub(1));
    for k in 1..n {
        let i = (((u[k - 1] + 2.0) / 4.0 * s as f64) as usize).min(s - 1);
        let t = thetas[i];
        let e = if noise > 0.0 {
            rng.random_range(-noise..noise)
        } else {
            0.0
        };
        // Keep the output bounded whatever the draw.
        y[k] = (t[0] * y[k - 1] + t[1] * u[k - 1] + t[2] + e).clamp(-50.0, 50.0);
        modes.push(i);
    }
    Generated {
        data: Dataset::siso(u, y, None).expect("equal lengths"),
        modes,
    }
}
