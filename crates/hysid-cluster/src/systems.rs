//! Reference examples with their exact parameters, with seeded generators: HIT's `ex_pwarx_1d_3modes` (H1),
//! `ex_pwarx_1d_5modes` (H2), `ex_pwarx_2d_3modes` (H3), `ex_cake1` (H4)
//! and the classic three-mode PWARX of Ferrari-Trecate et al. 2003 (B1).
//! HIT draws without a seed, so these reproduce the examples
//! statistically, not bit for bit.
//!
//! Static maps (H1, H2, H4) are written as PWARX with `na = 0`, `nb = 1`:
//! `y(k) = theta . [u(k-1); 1]`, one input per coordinate.

use hysid_model::data::{Dataset, Signal};
use hysid_model::regressors::RegressorSpec;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A generated record with its true modes and parameters.
#[derive(Debug, Clone)]
pub struct Example {
    /// The record.
    pub data: Dataset,
    /// Orders of the true model.
    pub orders: RegressorSpec,
    /// True parameters per mode, `[slopes; constant]`.
    pub theta: Vec<Vec<f64>>,
    /// True mode of every regressor row (`orders.build(&data)` rows).
    pub modes: Vec<usize>,
    /// HIT's local dataset size for the example.
    pub c: usize,
}

impl Example {
    /// Number of true modes (distinct regions; H1 and H3 repeat parameters).
    pub fn mode_count(&self) -> usize {
        self.theta.len()
    }
}

fn gauss(rng: &mut ChaCha8Rng, var: f64) -> f64 {
    Normal::new(0.0, var.sqrt())
        .expect("finite variance")
        .sample(rng)
}

/// A static map of one input: `x ~ U[lo, hi]`, `y = theta_mode(x) . [x; 1] + N(0, var)`.
#[allow(clippy::too_many_arguments)]
fn static_1d(
    n: usize,
    lo: f64,
    hi: f64,
    var: f64,
    theta: &[[f64; 2]],
    mode: impl Fn(f64) -> usize,
    c: usize,
    seed: u64,
) -> Example {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut u = Vec::with_capacity(n + 1);
    let mut y = vec![0.0];
    let mut modes = Vec::with_capacity(n);
    for _ in 0..n {
        let x: f64 = rng.random_range(lo..hi);
        let m = mode(x);
        u.push(x);
        y.push(theta[m][0] * x + theta[m][1] + gauss(&mut rng, var));
        modes.push(m);
    }
    u.push(0.0);
    Example {
        data: Dataset::siso(u, y, None).expect("same lengths"),
        orders: RegressorSpec::new(0, 1, 1),
        theta: theta.iter().map(|t| t.to_vec()).collect(),
        modes,
        c,
    }
}

/// H1 (`ex_pwarx_1d_3modes.m`): three regions, modes 1 and 3 share
/// `theta = [1, 0.2]`; `u ~ U[-4, 4]`, N = 70, noise variance 0.01, c = 6.
/// Modes are numbered by region, so `theta[0] == theta[2]`.
pub fn h1(n: usize, seed: u64) -> Example {
    let th = [[1.0, 0.2], [-1.0, 2.0], [1.0, 0.2]];
    static_1d(
        n,
        -4.0,
        4.0,
        0.01,
        &th,
        |x| {
            if x <= -1.0 {
                0
            } else if x <= 2.0 {
                1
            } else {
                2
            }
        },
        6,
        seed,
    )
}

/// H2 (`ex_pwarx_1d_5modes.m`): five modes on `u ~ U[-4, 8]`, N = 100,
/// noise variance 0.01, c = 8.
pub fn h2(n: usize, seed: u64) -> Example {
    let th = [
        [1.0, 0.2],
        [-1.0, 2.0],
        [1.0, -1.0],
        [0.0, 2.0],
        [2.0, -10.0],
    ];
    let mode = |x: f64| {
        if x <= -1.0 {
            0
        } else if x <= 2.0 {
            1
        } else if x <= 4.0 {
            2
        } else if x <= 6.0 {
            3
        } else {
            4
        }
    };
    static_1d(n, -4.0, 8.0, 0.01, &th, mode, 8, seed)
}

/// H3 (`ex_pwarx_2d_3modes.m`): `x = [y(k-1), u(k-1)]`, `theta_1 = theta_3 =
/// [0.6, 0.3, 0]`, `theta_2 = [-0.6, -0.3, 0]`, regions split by
/// `x2 = -0.8 - 0.2 x1` and `x2 = 0.8 + 0.2 x1`; `u ~ U[-2, 2]`, N = 60,
/// `y(1) = 0.5`, noise variance 0.01, c = 6.
pub fn h3(n: usize, seed: u64) -> Example {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let th = [[0.6, 0.3, 0.0], [-0.6, -0.3, 0.0], [0.6, 0.3, 0.0]];
    let mut u = Vec::with_capacity(n + 1);
    let mut y = vec![0.5];
    let mut modes = Vec::with_capacity(n);
    for k in 0..n {
        let uk: f64 = rng.random_range(-2.0..2.0);
        u.push(uk);
        let (x1, x2) = (y[k], uk);
        let m = if 0.2 * x1 + x2 <= -0.8 {
            0
        } else if x2 <= 0.8 + 0.2 * x1 {
            1
        } else {
            2
        };
        modes.push(m);
        y.push(th[m][0] * x1 + th[m][1] * x2 + th[m][2] + gauss(&mut rng, 0.01));
    }
    u.push(0.0);
    Example {
        data: Dataset::siso(u, y, None).expect("same lengths"),
        orders: RegressorSpec::new(1, 1, 1),
        theta: th.iter().map(|t| t.to_vec()).collect(),
        modes,
        c: 6,
    }
}

/// H4 (`ex_cake1.m`): static PWA map on `[-1, 1]^2`, three wedges meeting
/// at the origin; N = 60 uniform points, noise variance 0.1, c = 6. As
/// PWARX: two inputs, `na = 0`, `nb = 1`.
pub fn h4(n: usize, seed: u64) -> Example {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let th = [[4.0, 2.0, 3.0], [-6.0, 6.0, -5.0], [4.0, -2.0, -2.0]];
    let s3 = 3f64.sqrt();
    let (mut u1, mut u2, mut y) = (
        Vec::with_capacity(n + 1),
        Vec::with_capacity(n + 1),
        vec![0.0],
    );
    let mut modes = Vec::with_capacity(n);
    for _ in 0..n {
        let (a, b): (f64, f64) = (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
        let m = if a <= -b.abs() / s3 {
            1
        } else if b >= 0.0 {
            0
        } else {
            2
        };
        u1.push(a);
        u2.push(b);
        modes.push(m);
        y.push(th[m][0] * a + th[m][1] * b + th[m][2] + gauss(&mut rng, 0.1));
    }
    u1.push(0.0);
    u2.push(0.0);
    let data = Dataset::new(
        vec![
            Signal {
                name: "u1".into(),
                values: u1,
            },
            Signal {
                name: "u2".into(),
                values: u2,
            },
        ],
        Signal {
            name: "y".into(),
            values: y,
        },
        None,
    )
    .expect("same lengths");
    Example {
        data,
        orders: RegressorSpec::new(0, 1, 2),
        theta: th.iter().map(|t| t.to_vec()).collect(),
        modes,
        c: 6,
    }
}

/// True mode of B1 at `phi = [y(k-1), u(k-1), 1]`.
pub fn b1_mode(y1: f64, u1: f64) -> usize {
    if 4.0 * y1 - u1 + 10.0 < 0.0 {
        0
    } else if 5.0 * y1 + u1 - 6.0 <= 0.0 {
        1
    } else {
        2
    }
}

/// B1, the classic three-mode PWARX (Ferrari-Trecate et al. 2003):
/// `theta = [-0.4, 1, 1.5]`, `[0.5, -1, -0.5]`, `[-0.3, 0.5, -1.7]`,
/// boundaries `[4, -1, 10] phi` and `[5, 1, -6] phi`; `u ~ U[-4, 4]`,
/// noise `U[-0.1, 0.1]`, `n` regressors.
pub fn b1(n: usize, seed: u64) -> Example {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let th = [[-0.4, 1.0, 1.5], [0.5, -1.0, -0.5], [-0.3, 0.5, -1.7]];
    let mut u = Vec::with_capacity(n + 1);
    let mut y = vec![0.0];
    let mut modes = Vec::with_capacity(n);
    for k in 0..n {
        let uk: f64 = rng.random_range(-4.0..4.0);
        u.push(uk);
        let m = b1_mode(y[k], uk);
        modes.push(m);
        let e: f64 = rng.random_range(-0.1..0.1);
        y.push(th[m][0] * y[k] + th[m][1] * uk + th[m][2] + e);
    }
    u.push(0.0);
    Example {
        data: Dataset::siso(u, y, None).expect("same lengths"),
        orders: RegressorSpec::new(1, 1, 1),
        theta: th.iter().map(|t| t.to_vec()).collect(),
        modes,
        c: 10,
    }
}
