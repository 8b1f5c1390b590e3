//! Per-mode parameter estimation on a set of samples: the Chebyshev
//! (l-infinity, minimax) fit as a linear programme on clarabel, which
//! certifies `|y_k - phi_k' theta| <= t` with the smallest `t`, and the
//! least-squares fit (`refit = ls`).
//!
//! The Chebyshev (minimax) LP:
//! variables `[theta (p); t; w (p-1)]`, minimise `t + eps * sum_j s_j w_j`
//! subject to `phi_k' theta - t <= y_k`, `-phi_k' theta - t <= -y_k` and
//! `|theta_j| <= w_j` for the slopes. The tiny l1 term (`eps = 1e-6`, slopes
//! weighted by the RMS `s_j` of their regressor so that it is in output
//! units) only breaks ties between minimax solutions: on a constant-output
//! segment `y = y_sat` every `theta` with `phi' theta = y_sat` is exact, and
//! the tie-break selects `[0 .. 0 y_sat]` (ours, not in the paper).

use crate::samples::Samples;
use hysid_estimation::conic::{self, Cone, Program, Settings, Triplets};
use hysid_estimation::constrained::{ModeSamples, Parametrisation, Slot, fit_modes};
use hysid_estimation::linalg;
use nalgebra::{DMatrix, DVector};

/// Weight of the slope l1 tie-break, relative to the minimax error.
pub const TIE_BREAK: f64 = 1e-6;

/// A Chebyshev fit: parameters and the largest absolute residual on the
/// fitted samples (computed from `theta`, not read from the solver).
#[derive(Debug, Clone, PartialEq)]
pub struct ChebyshevFit {
    /// Parameters.
    pub theta: Vec<f64>,
    /// `max_k |y_k - phi_k' theta|` over the fitted samples.
    pub max_residual: f64,
}

/// Largest absolute residual of `theta` on `idx`.
pub fn max_residual(s: &Samples, idx: &[usize], theta: &[f64]) -> f64 {
    idx.iter()
        .map(|&k| s.residual(k, theta).abs())
        .fold(0.0, f64::max)
}

/// Initial working set of [`chebyshev`], in multiples of `p`.
pub const WORKING_FACTOR: usize = 10;
/// Bound on the working-set rounds of [`chebyshev`].
pub const WORKING_ROUNDS: usize = 50;

/// Chebyshev (minimax) fit on samples `idx`, by constraint generation: the
/// LP is solved on a working set (the `WORKING_FACTOR * p` samples of
/// largest least-squares residual), then the samples whose residual exceeds
/// the working set's minimax error are added (the worst ones first, at most
/// that many per round) until none does; the working-set optimum is then
/// optimal for all of `idx` (same objective, feasible everywhere). `None`
/// when the solver does not report `Solved`/`AlmostSolved` (callers then
/// keep their previous, already certified, parameters).
pub fn chebyshev(s: &Samples, idx: &[usize]) -> Option<ChebyshevFit> {
    let n = idx.len();
    let m = (WORKING_FACTOR * s.p).max(1);
    if n <= 2 * m {
        return chebyshev_lp(s, idx);
    }
    let start = least_squares(s, idx).unwrap_or_else(|| vec![0.0; s.p]);
    let mut by_r: Vec<(f64, usize)> = idx
        .iter()
        .map(|&k| (s.residual(k, &start).abs(), k))
        .collect();
    by_r.select_nth_unstable_by(m - 1, |a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut work: Vec<usize> = by_r[..m].iter().map(|&(_, k)| k).collect();
    let mut inside = vec![false; s.len()];
    for &k in &work {
        inside[k] = true;
    }
    for _ in 0..WORKING_ROUNDS {
        let fit = chebyshev_lp(s, &work)?;
        let t = fit.max_residual;
        let tol = 1e-9 * (1.0 + t);
        let mut viol: Vec<(f64, usize)> = idx
            .iter()
            .filter(|&&k| !inside[k])
            .filter_map(|&k| {
                let r = s.residual(k, &fit.theta).abs();
                (r > t + tol).then_some((r, k))
            })
            .collect();
        if viol.is_empty() {
            let max_residual = max_residual(s, idx, &fit.theta);
            return Some(ChebyshevFit {
                theta: fit.theta,
                max_residual,
            });
        }
        if viol.len() > m {
            viol.select_nth_unstable_by(m - 1, |a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            viol.truncate(m);
        }
        for &(_, k) in &viol {
            inside[k] = true;
            work.push(k);
        }
    }
    chebyshev_lp(s, idx)
}

/// The clarabel settings of the Chebyshev LPs: 200 iterations at most,
/// clarabel's default tolerances. A solve that fails (any status but
/// `Solved` and `AlmostSolved`, the policy of `hysid_estimation::conic`)
/// gives `None`.
fn lp_settings() -> Settings {
    Settings {
        max_iter: 200,
        ..Settings::default()
    }
}

/// The Chebyshev LP on all of `idx` at once.
fn chebyshev_lp(s: &Samples, idx: &[usize]) -> Option<ChebyshevFit> {
    let p = s.p;
    let n = idx.len();
    if n == 0 {
        return None;
    }
    let nslope = p - 1;
    let nvar = p + 1 + nslope;
    let t_col = p;
    // Scales of the slopes for the tie-break.
    let mut scale = vec![0.0; nslope];
    for &k in idx {
        for (j, sj) in scale.iter_mut().enumerate() {
            *sj += s.row(k)[j].powi(2);
        }
    }
    for sj in &mut scale {
        *sj = (*sj / n as f64).sqrt().max(1e-12);
    }
    let rows = 2 * n + 2 * nslope;
    let mut a = Triplets::default();
    let mut b = Vec::with_capacity(rows);
    for (r, &k) in idx.iter().enumerate() {
        let phi = s.row(k);
        for (j, &v) in phi.iter().enumerate() {
            a.push(2 * r, j, v);
            a.push(2 * r + 1, j, -v);
        }
        a.push(2 * r, t_col, -1.0);
        a.push(2 * r + 1, t_col, -1.0);
        b.push(s.y[k]);
        b.push(-s.y[k]);
    }
    for j in 0..nslope {
        let r = 2 * n + 2 * j;
        let w = p + 1 + j;
        a.push(r, j, 1.0);
        a.push(r, w, -1.0);
        a.push(r + 1, j, -1.0);
        a.push(r + 1, w, -1.0);
        b.extend([0.0, 0.0]);
    }
    let mut q = vec![0.0; nvar];
    q[t_col] = 1.0;
    for j in 0..nslope {
        q[p + 1 + j] = TIE_BREAK * scale[j];
    }
    let program = Program {
        p: Triplets::default(),
        q,
        a,
        b,
        cones: vec![Cone::Nonnegative(rows)],
    };
    let sol = conic::solve(program, &lp_settings()).ok()?;
    let theta: Vec<f64> = sol.x[..p].to_vec();
    if theta.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let max_residual = max_residual(s, idx, &theta);
    Some(ChebyshevFit {
        theta,
        max_residual,
    })
}

/// A joint Chebyshev fit of several modes: parameters of each mode and the
/// largest absolute residual over all fitted (mode, sample) pairs.
#[derive(Debug, Clone, PartialEq)]
pub struct JointFit {
    /// Parameters of each mode.
    pub thetas: Vec<Vec<f64>>,
    /// `max_i max_{k in group i} |y_k - phi_k' theta_i|`.
    pub max_residual: f64,
}

/// Largest absolute residual of `thetas` on their groups.
fn joint_max_residual(s: &Samples, groups: &[Vec<usize>], thetas: &[Vec<f64>]) -> f64 {
    groups
        .iter()
        .zip(thetas)
        .map(|(g, t)| max_residual(s, g, t))
        .fold(0.0, f64::max)
}

/// The Chebyshev (minimax) fit of all modes at once under a
/// parametrisation (`hysid_estimation::constrained::Parametrisation`): fixed
/// values substituted, tied parameters one shared variable, free variables
/// boxed by `bounds`. The LP (ours; the joint form of
/// the per-mode LP above, needed because ties couple the modes) has the
/// variables `[z; t; w]` and minimises `t + eps * sum_v s_v w_v` subject to
/// `|y_k - phi_k' theta_i(z)| <= t` for every sample k of group i,
/// `lo_v <= z_v <= hi_v` and `|z_v| <= w_v` for the free slope variables.
/// Solved by the same constraint generation as [`chebyshev`] over the
/// (mode, sample) pairs. `None` when clarabel does not solve it.
pub fn chebyshev_joint(
    s: &Samples,
    par: &Parametrisation,
    bounds: &[(f64, f64)],
    groups: &[Vec<usize>],
) -> Option<JointFit> {
    let pairs: Vec<(usize, usize)> = groups
        .iter()
        .enumerate()
        .flat_map(|(i, g)| g.iter().map(move |&k| (i, k)))
        .collect();
    let n = pairs.len();
    if n == 0 || groups.len() != par.modes() {
        return None;
    }
    let m = (WORKING_FACTOR * par.n_dof().max(1)).max(1);
    if n <= 2 * m {
        return chebyshev_joint_lp(s, par, bounds, &pairs);
    }
    let start =
        least_squares_joint(s, par, groups).unwrap_or_else(|| vec![vec![0.0; s.p]; groups.len()]);
    let mut by_r: Vec<(f64, usize)> = pairs
        .iter()
        .enumerate()
        .map(|(r, &(i, k))| (s.residual(k, &start[i]).abs(), r))
        .collect();
    by_r.select_nth_unstable_by(m - 1, |a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut inside = vec![false; n];
    let mut work: Vec<(usize, usize)> = Vec::new();
    for &(_, r) in &by_r[..m] {
        inside[r] = true;
        work.push(pairs[r]);
    }
    for _ in 0..WORKING_ROUNDS {
        let fit = chebyshev_joint_lp(s, par, bounds, &work)?;
        let t = fit.max_residual;
        let tol = 1e-9 * (1.0 + t);
        let mut viol: Vec<(f64, usize)> = (0..n)
            .filter(|&r| !inside[r])
            .filter_map(|r| {
                let (i, k) = pairs[r];
                let e = s.residual(k, &fit.thetas[i]).abs();
                (e > t + tol).then_some((e, r))
            })
            .collect();
        if viol.is_empty() {
            let max_residual = joint_max_residual(s, groups, &fit.thetas);
            return Some(JointFit {
                thetas: fit.thetas,
                max_residual,
            });
        }
        if viol.len() > m {
            viol.select_nth_unstable_by(m - 1, |a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            viol.truncate(m);
        }
        for &(_, r) in &viol {
            inside[r] = true;
            work.push(pairs[r]);
        }
    }
    chebyshev_joint_lp(s, par, bounds, &pairs)
}

/// The joint Chebyshev LP on the (mode, sample) pairs `work`; the returned
/// `max_residual` is over `work`.
fn chebyshev_joint_lp(
    s: &Samples,
    par: &Parametrisation,
    bounds: &[(f64, f64)],
    work: &[(usize, usize)],
) -> Option<JointFit> {
    let p = s.p;
    let nf = par.n_free();
    // The LP variables x: the free variables z = z0 + B x (B = I without
    // [[equality]] entries; with them, B spans the null space of the
    // equalities, so every LP point satisfies them).
    let (z0, basis) = par.affine();
    let nx = basis.ncols();
    let t_col = nx;
    // Free slope variables get a tie-break weight (RMS of their regressor
    // over the pairs they appear in).
    let mut sum_sq = vec![0.0; nf];
    let mut count = vec![0usize; nf];
    let mut is_slope = vec![false; nf];
    for &(i, k) in work {
        for j in 0..p - 1 {
            if let Slot::Free(v) = par.slot(i, j) {
                sum_sq[v] += s.row(k)[j].powi(2);
                count[v] += 1;
                is_slope[v] = true;
            }
        }
    }
    let slopes: Vec<usize> = (0..nf).filter(|&v| is_slope[v]).collect();
    let nvar = nx + 1 + slopes.len();
    let mut rows = Rows::default();
    let mut coef = vec![0.0; nf];
    // Row `a_z . z` in x: coefficients `B' a_z`, constant `a_z . z0`.
    let in_x = |a_z: &[f64]| -> (Vec<f64>, f64) {
        let cx = (0..nx)
            .map(|u| a_z.iter().enumerate().map(|(v, a)| a * basis[(v, u)]).sum())
            .collect();
        let c0 = a_z.iter().zip(&z0).map(|(a, z)| a * z).sum();
        (cx, c0)
    };
    for &(i, k) in work {
        coef.iter_mut().for_each(|c| *c = 0.0);
        let mut target = s.y[k];
        for (j, &x) in s.row(k).iter().enumerate() {
            match par.slot(i, j) {
                Slot::Free(v) => coef[v] += x,
                Slot::Fixed(c) => target -= c * x,
            }
        }
        let (cx, c0) = in_x(&coef);
        rows.abs_within(&cx, target - c0, t_col);
    }
    let unit = |v: usize| -> (Vec<f64>, f64) {
        let mut a = vec![0.0; nf];
        a[v] = 1.0;
        in_x(&a)
    };
    for (v, &(lo, hi)) in bounds.iter().enumerate() {
        if !(hi.is_finite() || lo.is_finite()) {
            continue;
        }
        let (cx, c0) = unit(v);
        if hi.is_finite() {
            rows.push(&cx, 1.0, None, hi - c0);
        }
        if lo.is_finite() {
            rows.push(&cx, -1.0, None, c0 - lo);
        }
    }
    let mut q = vec![0.0; nvar];
    q[t_col] = 1.0;
    for (w, &v) in slopes.iter().enumerate() {
        // |z_v| <= aux_w.
        let col = nx + 1 + w;
        let (cx, c0) = unit(v);
        rows.abs_within(&cx, -c0, col);
        let scale = (sum_sq[v] / count[v].max(1) as f64).sqrt().max(1e-12);
        q[col] = TIE_BREAK * scale;
    }
    let Rows { a, b } = rows;
    let program = Program {
        p: Triplets::default(),
        q,
        cones: vec![Cone::Nonnegative(b.len())],
        a,
        b,
    };
    let sol = conic::solve(program, &lp_settings()).ok()?;
    let x = &sol.x[..nx];
    if x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let mut z: Vec<f64> = (0..nf)
        .map(|v| z0[v] + (0..nx).map(|u| basis[(v, u)] * x[u]).sum::<f64>())
        .collect();
    par.clamp_to_bounds(&mut z);
    let thetas = par.thetas(&z);
    let mut max_residual: f64 = 0.0;
    for &(i, k) in work {
        max_residual = max_residual.max(s.residual(k, &thetas[i]).abs());
    }
    Some(JointFit {
        thetas,
        max_residual,
    })
}

/// Joint least squares of the modes with samples `groups` under `par`
/// (`hysid_estimation::constrained::fit_modes`).
pub fn least_squares_joint(
    s: &Samples,
    par: &Parametrisation,
    groups: &[Vec<usize>],
) -> Option<Vec<Vec<f64>>> {
    let d = s.p - 1;
    let data: Vec<(DMatrix<f64>, Vec<f64>)> = groups
        .iter()
        .map(|g| {
            (
                DMatrix::from_fn(g.len(), d, |r, j| s.row(g[r])[j]),
                g.iter().map(|&k| s.y[k]).collect(),
            )
        })
        .collect();
    let ms: Vec<ModeSamples<'_>> = data
        .iter()
        .map(|(phi, y)| ModeSamples {
            phi,
            y,
            weights: None,
        })
        .collect();
    let t = fit_modes(par, &ms).ok()?;
    t.iter().flatten().all(|v| v.is_finite()).then_some(t)
}

/// Least-squares fit on samples `idx` (minimum-norm when rank deficient).
pub fn least_squares(s: &Samples, idx: &[usize]) -> Option<Vec<f64>> {
    if idx.is_empty() {
        return None;
    }
    let p = s.p;
    let phi = DMatrix::from_fn(idx.len(), p, |r, j| s.row(idx[r])[j]);
    let y = DVector::from_iterator(idx.len(), idx.iter().map(|&k| s.y[k]));
    let sol = linalg::lstsq(&phi, &y).ok()?;
    let theta: Vec<f64> = sol.theta.iter().copied().collect();
    theta.iter().all(|v| v.is_finite()).then_some(theta)
}

/// Inequality rows `A x <= b` (a nonnegative cone).
#[derive(Default)]
struct Rows {
    a: Triplets,
    b: Vec<f64>,
}

impl Rows {
    /// The row `sign (cx . x) - x_t <= rhs` (without `x_t` when `t` is `None`).
    fn push(&mut self, cx: &[f64], sign: f64, t: Option<usize>, rhs: f64) {
        let r = self.b.len();
        for (u, &c) in cx.iter().enumerate() {
            self.a.push(r, u, sign * c);
        }
        if let Some(t) = t {
            self.a.push(r, t, -1.0);
        }
        self.b.push(rhs);
    }

    /// `|cx . x - rhs| <= x_t`, as two rows.
    fn abs_within(&mut self, cx: &[f64], rhs: f64, t: usize) {
        self.push(cx, 1.0, Some(t), rhs);
        self.push(cx, -1.0, Some(t), -rhs);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(rows: &[[f64; 2]], y: &[f64]) -> Samples {
        let mut phi = Vec::new();
        for r in rows {
            phi.extend([r[0], r[1], 1.0]);
        }
        Samples::new(3, phi, y.to_vec())
    }

    #[test]
    fn working_set_matches_the_full_lp() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let n = 500;
        let mut phi = Vec::new();
        let mut y = Vec::new();
        for _ in 0..n {
            let (a, b): (f64, f64) = (rng.random_range(-2.0..2.0), rng.random_range(-1.0..1.0));
            phi.extend([a, b, 1.0]);
            y.push(0.7 * a - 0.2 * b + 0.3 + rng.random_range(-0.1..0.1));
        }
        let s = Samples::new(3, phi, y);
        let idx: Vec<usize> = (0..n).collect();
        let ws = chebyshev(&s, &idx).unwrap();
        let full = chebyshev_lp(&s, &idx).unwrap();
        assert!(
            (ws.max_residual - full.max_residual).abs() < 1e-7,
            "{ws:?} {full:?}"
        );
    }

    #[test]
    fn joint_lp_matches_the_per_mode_lp_and_shares_ties() {
        use hysid_core::priors::Priors;
        use hysid_model::regressors::RegressorSpec;
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let n = 400;
        let mut phi = Vec::new();
        let mut y = Vec::new();
        for k in 0..n {
            let (a, b): (f64, f64) = (rng.random_range(-2.0..2.0), rng.random_range(-1.0..1.0));
            phi.extend([a, b, 1.0]);
            let bb = if k < n / 2 { -0.2 } else { 1.1 };
            y.push(0.7 * a + bb * b + 0.3 + rng.random_range(-0.1..0.1));
        }
        let s = Samples::new(3, phi, y);
        let all: Vec<usize> = (0..n).collect();
        // Free, one mode: the same minimax error as the per-mode LP (with
        // constraint generation: 400 pairs > 2 * 10 * 3).
        let free = Parametrisation::free(3, 1);
        let bounds = vec![(f64::NEG_INFINITY, f64::INFINITY); 3];
        let j = chebyshev_joint(&s, &free, &bounds, std::slice::from_ref(&all)).unwrap();
        let c = chebyshev(&s, &all).unwrap();
        assert!(
            (j.max_residual - c.max_residual).abs() < 1e-7,
            "{j:?} {c:?}"
        );
        // Two modes, a1 tied, c fixed: shared bitwise, fixed exact, and
        // within the noise bound (the truth is feasible).
        let pri = Priors::from_toml("[[tie]]\nparams = [\"a1\"]\n[fixed]\nc = 0.3\n", "p").unwrap();
        let par = Parametrisation::from_priors(&pri, &RegressorSpec::new(1, 1, 1), 2).unwrap();
        let bounds = vec![(f64::NEG_INFINITY, f64::INFINITY); par.n_free()];
        let groups = vec![(0..n / 2).collect(), (n / 2..n).collect()];
        let j = chebyshev_joint(&s, &par, &bounds, &groups).unwrap();
        assert_eq!(j.thetas[0][0].to_bits(), j.thetas[1][0].to_bits());
        assert_eq!(j.thetas[0][2], 0.3);
        assert_eq!(j.thetas[1][2], 0.3);
        assert!(j.max_residual <= 0.1 + 1e-9, "{j:?}");
    }

    #[test]
    fn chebyshev_is_minimax() {
        // y = x exactly except one point off by 0.3: minimax error 0.15.
        let s = samples(
            &[[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]],
            &[0.0, 1.0, 2.3, 3.0],
        );
        let f = chebyshev(&s, &[0, 1, 2, 3]).unwrap();
        assert!(
            f.max_residual < 0.15 + 1e-6 && f.max_residual > 0.15 - 1e-6,
            "{f:?}"
        );
    }

    #[test]
    fn constant_segment_gets_zero_slopes() {
        // y = 2 on points where y(k-1) = 2 too: theta = [0, 0, 2] and [1, 0, 0] are both exact.
        let s = samples(
            &[[2.0, 0.5], [2.0, -1.0], [2.0, 0.3], [2.0, 0.9]],
            &[2.0; 4],
        );
        let f = chebyshev(&s, &[0, 1, 2, 3]).unwrap();
        assert!(
            (f.theta[0]).abs() < 1e-6 && f.theta[1].abs() < 1e-6 && (f.theta[2] - 2.0).abs() < 1e-5,
            "{f:?}"
        );
    }
}
