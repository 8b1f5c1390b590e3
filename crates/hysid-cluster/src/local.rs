//! Step 1 of the procedure (Ferrari-Trecate et al., Automatica 2003,
//! section 3.1): local datasets, local least squares and feature vectors.
//!
//! For every sample `j` the local dataset `C_j` holds `j` and its `c - 1`
//! nearest neighbours in regressor space. On `C_j`:
//!
//! - `theta_j = (Phi_j' Phi_j)^-1 Phi_j' y_j` with `Phi_j = [X_Cj, 1]`;
//! - `sigma_j^2 = SSR_j / (c - n - 1)` and `V_j = sigma_j^2 (Phi_j' Phi_j)^-1`;
//! - `m_j` the mean of the regressors of `C_j`, `Q_j` their covariance
//!   (normalised by `c - 1`);
//! - feature vector `xi_j = [theta_j; m_j]` with `R_j = blkdiag(V_j, Q_j)`
//!   (`fv`), or `xi_j = theta_j` with `R_j = V_j` (`lpv`);
//! - confidence `w_j = 1 / sqrt((2 pi)^d det R_j)`, `d = dim xi_j`.
//!
//! **Degenerate local datasets.** HIT aborts when `V_j` or `Q_j` is not
//! invertible. Here they are regularised (and counted):
//!
//! - *noise-free fit* (`sigma_j^2` below the floor): `sigma_j^2` is raised
//!   to `max(eps var(y), 0.01 median_k sigma_k^2)`;
//! - *collinear regressors* (`Phi_j' Phi_j` with a squared Cholesky pivot
//!   below `1e-10` times its mean diagonal): the ridge
//!   `eps mean_diag(Phi_j' Phi_j) I` is added;
//! - *flat scatter* (`Q_j` with a squared pivot below the floor, e.g. all
//!   regressors equal in a saturation or a stuck phase): `Q_j` gets
//!   `max(eps tr(Sigma_x)/n, 0.01 median_k tr(Q_k)/n) I` added,
//!
//! with `eps` the `regularization` option. The floors relative to the
//! median local dataset keep degenerate local datasets from being trusted
//! millions of times more than ordinary ones.

use crate::Features;
use crate::knn::KdTree;
use hysid_estimation::dense;
use hysid_model::statistics::upper_median;
use rayon::prelude::*;

/// Counts of regularised local datasets.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Degeneracy {
    /// Local fits with (numerically) zero residual.
    pub noise_free: usize,
    /// Local datasets with collinear regressors (`Phi' Phi` singular).
    pub collinear: usize,
    /// Local datasets with a singular regressor scatter `Q_j`.
    pub flat_scatter: usize,
    /// Local datasets with at least one of the above.
    pub total: usize,
}

/// The feature vectors of all samples with their confidence.
#[derive(Debug, Clone)]
pub struct FeatureVectors {
    /// Number of samples.
    pub n_samples: usize,
    /// Size of the parameter block, `n + 1`.
    pub p: usize,
    /// Size of the mean block (`n` with `fv`, 0 with `lpv`).
    pub q: usize,
    /// `xi_j` rows (`p + q` columns), row-major.
    pub xi: Vec<f64>,
    /// `V_j^-1` blocks (`p x p` each), row-major.
    pub v_inv: Vec<f64>,
    /// `Q_j^-1` blocks (`q x q` each), row-major.
    pub q_inv: Vec<f64>,
    /// `ln w_j`, the log-confidence.
    pub log_w: Vec<f64>,
    /// Local parameter vectors `theta_j` (`p` each).
    pub theta: Vec<f64>,
    /// Local dataset members, `c` per sample (the sample itself first), as
    /// `u32`: the largest array at large N (`N c` entries), half the memory
    /// of `usize` indices. Records have fewer than 2^32 samples (checked by
    /// the back-end).
    pub members: Vec<u32>,
    /// Local dataset size `c`.
    pub c: usize,
    /// Regularised local datasets.
    pub degenerate: Degeneracy,
}

impl FeatureVectors {
    /// Dimension of `xi`.
    pub fn dim(&self) -> usize {
        self.p + self.q
    }

    /// `xi_j`.
    pub fn xi(&self, j: usize) -> &[f64] {
        let d = self.dim();
        &self.xi[j * d..(j + 1) * d]
    }

    /// Members of `C_j`.
    pub fn members(&self, j: usize) -> &[u32] {
        &self.members[j * self.c..(j + 1) * self.c]
    }

    /// `(xi_j - mu)' R_j^-1 (xi_j - mu)` (both blocks symmetric).
    #[inline]
    pub fn mahalanobis(&self, j: usize, mu: &[f64]) -> f64 {
        let (p, q) = (self.p, self.q);
        let x = self.xi(j);
        let a = &self.v_inv[j * p * p..(j + 1) * p * p];
        let mut s = 0.0;
        for r in 0..p {
            let dr = x[r] - mu[r];
            let mut t = 0.5 * a[r * p + r] * dr;
            for k in 0..r {
                t += a[r * p + k] * (x[k] - mu[k]);
            }
            s += dr * t;
        }
        if q > 0 {
            let b = &self.q_inv[j * q * q..(j + 1) * q * q];
            let (x, mu) = (&x[p..], &mu[p..]);
            for r in 0..q {
                let dr = x[r] - mu[r];
                let mut t = 0.5 * b[r * q + r] * dr;
                for k in 0..r {
                    t += b[r * q + k] * (x[k] - mu[k]);
                }
                s += dr * t;
            }
        }
        2.0 * s
    }
}

/// Largest regressor dimension supported (feature vectors live on the stack).
pub const MAX_DIM: usize = 31;

/// Inputs and outputs of [`local_fit`] for one local dataset.
struct FitArgs<'a> {
    x: &'a [f64],
    y: &'a [f64],
    /// The members of the local dataset.
    mem: &'a [u32],
    eps: f64,
    /// `Phi' Phi` (`p x p`; regularised on exit if collinear).
    g: &'a mut [f64],
    /// `theta_j` (`p`).
    th: &'a mut [f64],
    /// Local mean `m_j` (`n`).
    m: &'a mut [f64],
    /// Local scatter `Q_j` (`n x n`).
    s: &'a mut [f64],
    lchol: &'a mut [f64],
    scratch: &'a mut [f64],
}

/// [`local_fit`] with a compile-time dimension.
fn local_fit_n<const N: usize>(a: FitArgs<'_>) -> (bool, f64) {
    local_fit(N, a)
}

/// Local least squares, mean and scatter of one local dataset: returns
/// whether `Phi' Phi` was regularised (collinear) and `sigma_j^2`.
#[inline(always)]
fn local_fit(n: usize, a: FitArgs<'_>) -> (bool, f64) {
    let FitArgs {
        x,
        y,
        mem,
        eps,
        g,
        th,
        m,
        s,
        lchol,
        scratch,
    } = a;
    let p = n + 1;
    let c = mem.len();
    // Sums in local arrays (registers once the loops unroll), written out
    // afterwards; the additions are those of a direct accumulation.
    const P: usize = MAX_DIM + 1;
    let mut phi = [0.0; P];
    let mut gl = [[0.0; P]; P];
    let mut rhs = [0.0; P];
    for i in mem.iter().map(|&i| i as usize) {
        phi[..n].copy_from_slice(&x[i * n..(i + 1) * n]);
        phi[n] = 1.0;
        for r in 0..p {
            rhs[r] += phi[r] * y[i];
            for k in 0..=r {
                gl[r][k] += phi[r] * phi[k];
            }
        }
    }
    th.copy_from_slice(&rhs[..p]);
    for r in 0..p {
        for k in 0..=r {
            g[r * p + k] = gl[r][k];
            g[k * p + r] = gl[r][k];
        }
    }
    let l = &mut lchol[..p * p];
    l.copy_from_slice(g);
    let t = dense::mean_diag(g, p);
    let collinear =
        dense::regularised_cholesky(l, p, 1e-10, eps * t.max(f64::MIN_POSITIVE), scratch);
    if collinear {
        for r in 0..p {
            g[r * p + r] += eps * t.max(f64::MIN_POSITIVE);
        }
    }
    dense::cholesky_solve(l, p, th);
    let mut ssr = 0.0;
    let mut ml = [0.0; P];
    for i in mem.iter().map(|&i| i as usize) {
        let xi = &x[i * n..(i + 1) * n];
        let pred: f64 = xi.iter().zip(&th[..n]).map(|(a, b)| a * b).sum::<f64>() + th[n];
        ssr += (y[i] - pred).powi(2);
        for k in 0..n {
            ml[k] += xi[k];
        }
    }
    for v in &mut ml[..n] {
        *v /= c as f64;
    }
    m.copy_from_slice(&ml[..n]);
    let mut sl = [[0.0; P]; P];
    for i in mem.iter().map(|&i| i as usize) {
        let xi = &x[i * n..(i + 1) * n];
        for r in 0..n {
            for k in 0..n {
                sl[r][k] += (xi[r] - ml[r]) * (xi[k] - ml[k]);
            }
        }
    }
    for r in 0..n {
        for k in 0..n {
            s[r * n + k] = sl[r][k] / (c - 1) as f64;
        }
    }
    (collinear, ssr / (c - p) as f64)
}

/// Samples per parallel task of pass 1 of [`feature_vectors`]: a run of
/// the tree's leaf order.
const PASS1_RUN: usize = 1024;

/// Runs computed before their results are copied to the samples' places.
const PASS1_RUNS_PER_WAVE: usize = 16;

/// Pass 1 of [`feature_vectors`] on one run of samples: the local datasets,
/// their least squares and scatter, in the run's order.
struct LocalFits {
    members: Vec<u32>,
    theta: Vec<f64>,
    gram: Vec<f64>,
    mean: Vec<f64>,
    scatter: Vec<f64>,
    collinear: Vec<bool>,
    sigma2: Vec<f64>,
}

impl LocalFits {
    /// The local fits of the samples `run` (consecutive in the tree's leaf
    /// order), reusing one set of scratch buffers for all of them.
    fn of_run(
        tree: &KdTree,
        x: &[f64],
        n: usize,
        y: &[f64],
        c: usize,
        eps: f64,
        run: &[usize],
    ) -> Self {
        let (len, p) = (run.len(), n + 1);
        let mut f = LocalFits {
            members: vec![0; len * c],
            theta: vec![0.0; len * p],
            gram: vec![0.0; len * p * p],
            mean: vec![0.0; len * n],
            scatter: vec![0.0; len * n * n],
            collinear: vec![false; len],
            sigma2: vec![0.0; len],
        };
        let mut nb = Vec::with_capacity(c);
        let mut scratch = vec![0.0; p * p];
        let mut lchol = vec![0.0; p * p];
        let mut prev: Vec<usize> = Vec::with_capacity(c);
        let mut knn_scratch = crate::knn::Scratch::default();
        for (i, &j) in run.iter().enumerate() {
            // The previous query is a spatial neighbour: its neighbours bound
            // the search (same answer, most cells pruned).
            tree.nearest_seeded(&x[j * n..(j + 1) * n], c, &prev, &mut knn_scratch, &mut nb);
            prev.clear();
            prev.extend_from_slice(&nb);
            // C_j contains j itself (with many duplicates it may not be among
            // the c nearest by the index tie-break): put it first.
            if let Some(pos) = nb.iter().position(|&k| k == j) {
                nb.remove(pos);
            } else {
                nb.pop();
            }
            let mem = &mut f.members[i * c..(i + 1) * c];
            mem[0] = j as u32;
            for (m, &k) in mem[1..].iter_mut().zip(&nb) {
                *m = k as u32;
            }
            let args = FitArgs {
                x,
                y,
                mem: &f.members[i * c..(i + 1) * c],
                eps,
                g: &mut f.gram[i * p * p..(i + 1) * p * p],
                th: &mut f.theta[i * p..(i + 1) * p],
                m: &mut f.mean[i * n..(i + 1) * n],
                s: &mut f.scatter[i * n * n..(i + 1) * n * n],
                lchol: &mut lchol,
                scratch: &mut scratch,
            };
            // Common regressor dimensions get unrolled loops (same operations).
            let (col, s2) = match n {
                1 => local_fit_n::<1>(args),
                2 => local_fit_n::<2>(args),
                3 => local_fit_n::<3>(args),
                4 => local_fit_n::<4>(args),
                _ => local_fit(n, args),
            };
            f.collinear[i] = col;
            f.sigma2[i] = s2;
        }
        f
    }
}

/// Builds the local datasets and feature vectors of the regression problem
/// `y_k = theta' [x_k; 1]` (`x` row-major with `n` columns). Requires
/// `n + 2 <= c <= N` and `n <= MAX_DIM` (checked by the caller).
///
/// Pass 1 (`LocalFits`) runs in parallel; each run reuses one set of
/// scratch buffers for every local dataset.
pub fn feature_vectors(
    x: &[f64],
    n: usize,
    y: &[f64],
    c: usize,
    features: Features,
    eps: f64,
) -> FeatureVectors {
    let big_n = y.len();
    let p = n + 1;
    let q = if features == Features::Fv { n } else { 0 };
    let tree = KdTree::new(x, n);
    let mut members = vec![0u32; big_n * c];
    let mut theta = vec![0.0; big_n * p];
    let mut gram = vec![0.0; big_n * p * p];
    let mut scatter = vec![0.0; big_n * n * n];
    let mut sigma2 = vec![0.0; big_n];
    let mut mean = vec![0.0; big_n * n];
    let mut degenerate = Degeneracy::default();
    let mut collinear = vec![false; big_n];
    // Pass 1: neighbours, local least squares, local scatter, in parallel
    // over runs of the tree's leaf order (neighbouring queries share cache
    // lines and seed each other's search), a wave of runs at a time so the
    // runs' buffers stay small. Every result is stored at the sample's own
    // index, so neither the order nor the thread count changes any value.
    for wave in tree.leaf_order().chunks(PASS1_RUN * PASS1_RUNS_PER_WAVE) {
        let fits: Vec<LocalFits> = wave
            .par_chunks(PASS1_RUN)
            .map(|run| LocalFits::of_run(&tree, x, n, y, c, eps, run))
            .collect();
        for (run, f) in wave.chunks(PASS1_RUN).zip(&fits) {
            for (i, &j) in run.iter().enumerate() {
                members[j * c..(j + 1) * c].copy_from_slice(&f.members[i * c..(i + 1) * c]);
                theta[j * p..(j + 1) * p].copy_from_slice(&f.theta[i * p..(i + 1) * p]);
                gram[j * p * p..(j + 1) * p * p]
                    .copy_from_slice(&f.gram[i * p * p..(i + 1) * p * p]);
                mean[j * n..(j + 1) * n].copy_from_slice(&f.mean[i * n..(i + 1) * n]);
                scatter[j * n * n..(j + 1) * n * n]
                    .copy_from_slice(&f.scatter[i * n * n..(i + 1) * n * n]);
                collinear[j] = f.collinear[i];
                sigma2[j] = f.sigma2[i];
            }
        }
    }
    // Floors relative to the data and to the median local dataset.
    let var_y = {
        let my = y.iter().sum::<f64>() / big_n as f64;
        let v = y.iter().map(|v| (v - my).powi(2)).sum::<f64>() / big_n as f64;
        if v > 0.0 { v } else { 1.0 }
    };
    let tr_x = {
        let mut t = 0.0;
        for k in 0..n {
            let mk = (0..big_n).map(|j| x[j * n + k]).sum::<f64>() / big_n as f64;
            t += (0..big_n).map(|j| (x[j * n + k] - mk).powi(2)).sum::<f64>() / big_n as f64;
        }
        let t = t / n.max(1) as f64;
        if t > 0.0 { t } else { 1.0 }
    };
    let sigma_floor = (eps * var_y)
        .max(0.01 * upper_median(&mut sigma2.clone()).unwrap_or(0.0))
        .max(f64::MIN_POSITIVE);
    let scatter_floor = {
        let mut tr: Vec<f64> = (0..big_n)
            .map(|j| dense::mean_diag(&scatter[j * n * n..(j + 1) * n * n], n))
            .collect();
        (eps * tr_x)
            .max(0.01 * upper_median(&mut tr).unwrap_or(0.0))
            .max(f64::MIN_POSITIVE)
    };
    // Pass 2: regularise, invert, confidence.
    let d = p + q;
    let mut xi = vec![0.0; big_n * d];
    let mut v_inv = vec![0.0; big_n * p * p];
    let mut q_inv = vec![0.0; big_n * q * q];
    let mut log_w = vec![0.0; big_n];
    let mut qscratch = vec![0.0; n * n];
    let mut col = vec![0.0; n.max(1)];
    let mut lg = vec![0.0; p * p];
    let ln2pi = (2.0 * std::f64::consts::PI).ln();
    for j in 0..big_n {
        let mut any = collinear[j];
        if collinear[j] {
            degenerate.collinear += 1;
        }
        let s2 = if sigma2[j] < sigma_floor {
            degenerate.noise_free += 1;
            any = true;
            sigma_floor
        } else {
            sigma2[j]
        };
        let g = &gram[j * p * p..(j + 1) * p * p];
        let vi = &mut v_inv[j * p * p..(j + 1) * p * p];
        for k in 0..p * p {
            vi[k] = g[k] / s2;
        }
        lg.copy_from_slice(g);
        // log det V_j = p ln s2 - ln det G_j (G_j already regularised, so SPD).
        let ld_g = if dense::cholesky(&mut lg, p).is_some() {
            dense::cholesky_log_det(&lg, p)
        } else {
            0.0
        };
        let mut log_det_r = p as f64 * s2.ln() - ld_g;
        xi[j * d..j * d + p].copy_from_slice(&theta[j * p..(j + 1) * p]);
        if q > 0 {
            let mut lq = scatter[j * n * n..(j + 1) * n * n].to_vec();
            if dense::regularised_cholesky(&mut lq, n, 1e-10, scatter_floor, &mut qscratch) {
                degenerate.flat_scatter += 1;
                any = true;
            }
            log_det_r += dense::cholesky_log_det(&lq, n);
            dense::cholesky_inverse(&lq, n, &mut q_inv[j * n * n..(j + 1) * n * n], &mut col);
            xi[j * d + p..(j + 1) * d].copy_from_slice(&mean[j * n..(j + 1) * n]);
        }
        if any {
            degenerate.total += 1;
        }
        log_w[j] = -0.5 * (d as f64 * ln2pi + log_det_r);
    }
    FeatureVectors {
        n_samples: big_n,
        p,
        q,
        xi,
        v_inv,
        q_inv,
        log_w,
        theta,
        members,
        c,
        degenerate,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pass 1 runs in parallel over runs of 1024 samples: on 5000 samples
    /// (five runs) the feature vectors are bitwise the same with one thread
    /// and with three, and each sample's results are its own.
    #[test]
    fn the_same_with_any_thread_count() {
        use rand::{Rng, SeedableRng};
        let n = 2;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(99);
        let mut uniform = || rng.random::<f64>();
        let x: Vec<f64> = (0..5000 * n).map(|_| 4.0 * uniform() - 2.0).collect();
        let y: Vec<f64> = (0..5000)
            .map(|k| {
                let (a, b) = (x[k * n], x[k * n + 1]);
                (if a > b {
                    a - 2.0 * b
                } else {
                    0.5 * a + b + 1.0
                }) + 0.05 * uniform()
            })
            .collect();
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| feature_vectors(&x, n, &y, 20, Features::Fv, 1e-6))
        };
        let (one, three) = (run(1), run(3));
        assert_eq!(one.members, three.members);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for (a, b) in [
            (&one.xi, &three.xi),
            (&one.v_inv, &three.v_inv),
            (&one.q_inv, &three.q_inv),
            (&one.log_w, &three.log_w),
            (&one.theta, &three.theta),
        ] {
            assert_eq!(bits(a), bits(b));
        }
        assert_eq!(one.degenerate, three.degenerate);
        // Every result sits at its own sample: C_j starts with j, and theta_j
        // fits the members of C_j (its residuals are orthogonal to the
        // constant regressor: they sum to zero).
        for j in 0..5000 {
            let mem = one.members(j);
            assert_eq!(mem[0] as usize, j);
            let th = &one.theta[j * 3..(j + 1) * 3];
            let sum: f64 = mem
                .iter()
                .map(|&i| i as usize)
                .map(|i| y[i] - th[0] * x[i * n] - th[1] * x[i * n + 1] - th[2])
                .sum();
            assert!(sum.abs() < 1e-9, "sample {j}: residuals sum to {sum}");
        }
    }

    #[test]
    fn exact_local_fits_and_degenerate_counts() {
        // y = 2 x + 1 on a line: every local fit is exact (noise-free).
        let x: Vec<f64> = (0..50).map(|k| k as f64 / 10.0).collect();
        let y: Vec<f64> = x.iter().map(|v| 2.0 * v + 1.0).collect();
        let f = feature_vectors(&x, 1, &y, 5, Features::Fv, 1e-6);
        assert_eq!(f.dim(), 3);
        for j in 0..50 {
            assert!((f.theta[2 * j] - 2.0).abs() < 1e-6 && (f.theta[2 * j + 1] - 1.0).abs() < 1e-6);
            assert_eq!(f.members(j)[0] as usize, j);
            assert!(f.log_w[j].is_finite());
        }
        assert_eq!(f.degenerate.noise_free, 50);
        // Constant regressors and output (a stop): no abort, all counted.
        let x = vec![3.0; 40];
        let y = vec![1.0; 40];
        let f = feature_vectors(&x, 1, &y, 6, Features::Fv, 1e-6);
        assert_eq!(f.degenerate.total, 40);
        assert_eq!(f.degenerate.collinear, 40);
        assert_eq!(f.degenerate.flat_scatter, 40);
        assert!(
            f.xi.iter()
                .chain(&f.v_inv)
                .chain(&f.q_inv)
                .chain(&f.log_w)
                .all(|v| v.is_finite())
        );
    }
}
