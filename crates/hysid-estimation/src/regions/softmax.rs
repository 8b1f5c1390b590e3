//! Multinomial logistic regression (softmax) with a small ridge, by damped
//! Newton: the fast complete-partition estimator (PARC-style, Bemporad 2023,
//! uses a multinomial-logistic separator for its partition). The regions are
//! the argmax of the fitted affine scores, so they cover the space exactly.
//!
//! Objective, with mode-balancing weights `omega_r = N / (s |F_{y_r}|)`
//! (or `omega_r = 1` with `SoftmaxSettings::balanced` off) and the ridge
//! `lambda` of `SoftmaxSettings::ridge`:
//! `(1/N) sum_r omega_r (log sum_j exp f_j(z_r) - f_{y_r}(z_r)) + (lambda/2) sum_i |w_i|^2`,
//! `f_i(z) = w_i . z - g_i`, the last mode's score fixed at 0 (the softmax is
//! invariant to adding a common affine function). Strictly convex in the
//! normals and, with every mode present, in the offsets, so the minimiser is
//! unique; Newton with backtracking converges globally.
//!
//! `exp` and `log` are the pure-Rust ones of the `libm` crate: glibc's
//! dispatch to an AVX/FMA variant, which was up to 14 times slower per call
//! when it followed the clustering steps (`docs/performance-cluster.md`).

use crate::regions::options::{RegionError, SoftmaxSettings};
use crate::regions::problem::Prepared;
use nalgebra::{DMatrix, DVector};

/// Newton iteration bound.
const MAX_NEWTON: usize = 100;
/// Stop when the Newton decrement squared falls below this.
const DECREMENT_TOL: f64 = 1e-12;

/// Per mode `[w (p); g]` (last mode all zeros) and the number of Newton steps.
///
/// A numerical kernel kept in one piece: the objective, gradient, Hessian
/// and line search share the score and probability buffers of one Newton
/// iteration, and splitting them would pass those buffers through every call.
pub(crate) fn fit(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    settings: &SoftmaxSettings,
) -> Result<(Vec<Vec<f64>>, usize), RegionError> {
    let p = prep.p;
    let b = p + 1; // block size
    let k = (modes - 1) * b; // free unknowns
    let n = prep.n;
    let omega: Vec<f64> = prep
        .counts
        .iter()
        .map(|&c| {
            if settings.balanced {
                n as f64 / (modes as f64 * c as f64)
            } else {
                1.0
            }
        })
        .collect();
    let inv_n = 1.0 / n as f64;
    let ridge_weight = settings.ridge;
    // theta: blocks [w_i; g_i] for i < modes - 1; score f_i = w.z - g.
    let mut theta = DVector::<f64>::zeros(k);
    if let Some(start) = settings.start.as_ref().filter(|s| s.len() == modes) {
        warm_start(prep, start, &mut theta);
    }
    let mut phi = vec![0.0; b];
    let mut f = vec![0.0; modes];
    let mut prob = vec![0.0; modes];

    let scores = |theta: &DVector<f64>, z: &[f64], f: &mut [f64]| {
        for (fi, t) in f.iter_mut().zip(theta.as_slice().chunks(b)) {
            *fi = z.iter().zip(t).map(|(a, c)| a * c).sum::<f64>() - t[p];
        }
        f[modes - 1] = 0.0;
    };
    let objective = |theta: &DVector<f64>, f: &mut [f64]| -> f64 {
        let mut loss = 0.0;
        for r in 0..n {
            scores(theta, prep.row(r), f);
            let m = f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let lse = m + libm::log(f.iter().map(|v| libm::exp(v - m)).sum::<f64>());
            loss += omega[labels[r]] * (lse - f[labels[r]]);
        }
        let mut ridge = 0.0;
        for i in 0..modes - 1 {
            ridge += theta.as_slice()[i * b..i * b + p]
                .iter()
                .map(|v| v * v)
                .sum::<f64>();
        }
        loss * inv_n + 0.5 * ridge_weight * ridge
    };

    let mut current = objective(&theta, &mut f);
    // Per-point outer products phi phi' (upper triangle, row-major b x b)
    // are accumulated per mode pair into `blocks_h`, then spread into `hess`.
    let pairs = (modes - 1) * modes / 2;
    let mut blocks_h = vec![0.0; pairs * b * b];
    let mut outer = vec![0.0; b * b];
    for it in 0..MAX_NEWTON {
        let mut grad = DVector::<f64>::zeros(k);
        blocks_h.iter_mut().for_each(|v| *v = 0.0);
        for r in 0..n {
            let z = prep.row(r);
            scores(&theta, z, &mut f);
            let m = f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let mut sum = 0.0;
            for (pi, fi) in prob.iter_mut().zip(&f) {
                *pi = libm::exp(fi - m);
                sum += *pi;
            }
            for pi in prob.iter_mut() {
                *pi /= sum;
            }
            phi[..p].copy_from_slice(z);
            phi[p] = -1.0;
            for a in 0..b {
                for c in a..b {
                    outer[a * b + c] = phi[a] * phi[c];
                }
            }
            let w = omega[labels[r]] * inv_n;
            let mut pair = 0;
            for i in 0..modes - 1 {
                let resid = prob[i] - if labels[r] == i { 1.0 } else { 0.0 };
                let g = &mut grad.as_mut_slice()[i * b..(i + 1) * b];
                for (ga, pa) in g.iter_mut().zip(&phi) {
                    *ga += w * resid * pa;
                }
                for j in i..modes - 1 {
                    let h = w * (if i == j { prob[i] } else { 0.0 } - prob[i] * prob[j]);
                    let blk = &mut blocks_h[pair * b * b..(pair + 1) * b * b];
                    for a in 0..b {
                        for c in a..b {
                            blk[a * b + c] += h * outer[a * b + c];
                        }
                    }
                    pair += 1;
                }
            }
        }
        let mut hess = DMatrix::<f64>::zeros(k, k);
        let mut pair = 0;
        for i in 0..modes - 1 {
            for j in i..modes - 1 {
                let blk = &blocks_h[pair * b * b..(pair + 1) * b * b];
                for a in 0..b {
                    for c in a..b {
                        let v = blk[a * b + c];
                        hess[(i * b + a, j * b + c)] = v;
                        hess[(i * b + c, j * b + a)] = v;
                        hess[(j * b + a, i * b + c)] = v;
                        hess[(j * b + c, i * b + a)] = v;
                    }
                }
                pair += 1;
            }
        }
        for i in 0..modes - 1 {
            for a in 0..p {
                grad[i * b + a] += ridge_weight * theta[i * b + a];
                hess[(i * b + a, i * b + a)] += ridge_weight;
            }
        }
        // A tiny diagonal shift keeps the offsets' block positive definite
        // when a mode's probabilities saturate (separable data).
        for a in 0..k {
            hess[(a, a)] += 1e-12;
        }
        let step = hess
            .cholesky()
            .map(|c| c.solve(&grad))
            .ok_or(RegionError::Singular {
                method: "softmax",
                i: 0,
                j: modes - 1,
            })?;
        let decrement = grad.dot(&step);
        if !decrement.is_finite() {
            return Err(RegionError::Singular {
                method: "softmax",
                i: 0,
                j: modes - 1,
            });
        }
        if decrement < DECREMENT_TOL {
            return Ok((blocks(&theta, modes, b), it));
        }
        // Backtracking (Armijo) line search.
        let mut t = 1.0;
        let mut accepted = false;
        for _ in 0..40 {
            let cand = &theta - t * &step;
            let val = objective(&cand, &mut f);
            if val <= current - 0.25 * t * decrement {
                theta = cand;
                current = val;
                accepted = true;
                break;
            }
            t *= 0.5;
        }
        if !accepted {
            // No descent possible at double precision: at the optimum.
            return Ok((blocks(&theta, modes, b), it));
        }
    }
    Ok((blocks(&theta, modes, b), MAX_NEWTON))
}

fn blocks(theta: &DVector<f64>, modes: usize, b: usize) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = theta.as_slice().chunks(b).map(<[f64]>::to_vec).collect();
    out.push(vec![0.0; b]);
    debug_assert_eq!(out.len(), modes);
    out
}

/// `theta` from scores `[c; c0]` in original units (`f = c.x + c0`), as
/// differences to the last mode's score: on the standardised selected
/// columns `z_k = (x_{cols_k} - mean_k) / scale_k`, `f = w.z - g` with
/// `w_k = c_{cols_k} scale_k` and `g = -c0 - sum_k c_{cols_k} mean_k`.
fn warm_start(prep: &Prepared, start: &[Vec<f64>], theta: &mut DVector<f64>) {
    let p = prep.p;
    let standardised = |c: &[f64]| -> Option<Vec<f64>> {
        let d = c.len().checked_sub(1)?;
        let mut wg = vec![0.0; p + 1];
        let mut g = -c[d];
        for (k, w) in wg.iter_mut().take(p).enumerate() {
            let ck = *c.get(prep.cols[k])?;
            *w = ck * prep.scale[k];
            g -= ck * prep.mean[k];
        }
        wg[p] = g;
        Some(wg)
    };
    let Some(blocks) = start
        .iter()
        .map(|c| standardised(c))
        .collect::<Option<Vec<_>>>()
        .filter(|b| b.iter().flatten().all(|v| v.is_finite()))
    else {
        return;
    };
    let last = &blocks[blocks.len() - 1];
    for (i, block) in blocks.iter().take(blocks.len() - 1).enumerate() {
        for j in 0..=p {
            theta[i * (p + 1) + j] = block[j] - last[j];
        }
    }
}
