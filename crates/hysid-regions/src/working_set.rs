//! The multicategory hinge programs (MRLP and Weston-Watkins MSVM) and the
//! exact working-set scheme that solves them.
//!
//! Both minimise `R(w) + sum_r sum_{j != y_r} c_r max(0, 1 - (f_{y_r}(z_r) - f_j(z_r)))`
//! with affine scores `f_i(z) = w_i . z - g_i`; `R = 0` for MRLP and
//! `R = 1/2 sum_i |w_i|^2` for MSVM. Write `F_S` for the objective restricted
//! to a subset `S` of the points. If `u*` minimises `F_S` and every point
//! outside `S` has zero loss at `u*`, then for every `u`,
//! `F(u) >= F_S(u) >= F_S(u*) = F(u*)` (losses are nonnegative), so `u*`
//! minimises the full objective `F`. The scheme grows `S` by the points with
//! non-zero loss until none is left outside, so it returns an optimum of the
//! full program (to the solver's tolerance), not an approximation.

use crate::solver::{self, Context, Program, Triplets};
use crate::{Prepared, RegionError, RegionMethod, RegionOptions, SolveStats};
use clarabel::solver::SupportedConeT::{NonnegativeConeT, ZeroConeT};

/// Margin below which a point outside the working set counts as having a
/// non-zero loss and is added (slightly below 1 so that points sitting on
/// the margin of the current optimum, to solver accuracy, are not re-added
/// forever; their loss is at most this slack times their weight).
const MARGIN_TOL: f64 = 1e-7;
/// Bound on the working-set rounds; past it the full program is solved.
const MAX_ROUNDS: usize = 40;
/// Points per mode in the first working set (evenly spaced by index), per
/// unknown of a mode's score.
const INITIAL_PER_MODE_FACTOR: usize = 5;
/// Points whose softmax margin (log-odds against the best other mode) is
/// below this join the first working set.
const SOFTMAX_BAND: f64 = 2.0;

/// Per mode `[w (p); g]` and statistics.
pub(crate) fn solve(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    opts: &RegionOptions,
) -> Result<(Vec<Vec<f64>>, SolveStats), RegionError> {
    let (method, quadratic): (&'static str, bool) = match opts.method {
        RegionMethod::Msvm => ("msvm", true),
        _ => ("mrlp", false),
    };
    // Slack weights per mode.
    let weight: Vec<f64> = prep
        .counts
        .iter()
        .map(|&c| {
            if quadratic {
                opts.svm_c * prep.n as f64 / (modes as f64 * c as f64)
            } else {
                1.0 / c as f64
            }
        })
        .collect();

    let mut stats = SolveStats::default();
    let mut in_set = vec![false; prep.n];
    let mut set = initial_set(prep, labels, modes, &mut stats)?;
    for &r in &set {
        in_set[r] = true;
    }
    let mut round = 0;
    loop {
        round += 1;
        let full = round > MAX_ROUNDS;
        if full {
            set = (0..prep.n).collect();
        }
        let ctx = Context {
            method,
            points: set.len(),
            round,
        };
        let prog = program(prep, labels, modes, &weight, quadratic, &set);
        let sol = solver::solve(prog, &ctx)?;
        stats.solves += 1;
        stats.solver_iterations += u64::from(sol.iterations);
        stats.working_points = set.len();
        let mut blocks: Vec<Vec<f64>> = sol.x[..modes * (prep.p + 1)]
            .chunks(prep.p + 1)
            .map(<[f64]>::to_vec)
            .collect();
        // The normalised entries are 0 by a ZeroCone row; clarabel returns
        // them to ~1e-20, store them exactly.
        if quadratic {
            blocks[modes - 1][prep.p] = 0.0;
        } else {
            blocks[modes - 1].iter_mut().for_each(|v| *v = 0.0);
        }
        if full {
            return Ok((blocks, stats));
        }
        let before = set.len();
        let mut f = vec![0.0; modes];
        for r in 0..prep.n {
            if in_set[r] {
                continue;
            }
            let z = prep.row(r);
            for (i, fi) in f.iter_mut().enumerate() {
                let v = &blocks[i];
                *fi = z.iter().zip(v).map(|(a, b)| a * b).sum::<f64>() - v[prep.p];
            }
            let own = f[labels[r]];
            let worst = f
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != labels[r])
                .map(|(_, &v)| v)
                .fold(f64::NEG_INFINITY, f64::max);
            if own - worst < 1.0 - MARGIN_TOL {
                in_set[r] = true;
                set.push(r);
            }
        }
        if set.len() == before {
            return Ok((blocks, stats));
        }
        // Keep row order independent of the discovery order.
        set.sort_unstable();
    }
}

/// First working set: the points near the boundaries of a softmax fit
/// (margin below [`SOFTMAX_BAND`]), which predicts the hinge-active points
/// of the LP/QP well, plus up to `INITIAL_PER_MODE_FACTOR (p + 1)` points of
/// each mode evenly spaced in row order. Deterministic; it only affects the
/// speed, not the optimum (the loop adds every point with non-zero loss).
fn initial_set(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    stats: &mut SolveStats,
) -> Result<Vec<usize>, RegionError> {
    let (wg, steps) = crate::softmax::fit(prep, labels, modes)?;
    stats.newton_steps = steps;
    let per_mode = INITIAL_PER_MODE_FACTOR * (prep.p + 1);
    let mut seen = vec![0usize; modes];
    let mut set = Vec::new();
    let mut f = vec![0.0; modes];
    for (r, &l) in labels.iter().enumerate() {
        let c = prep.counts[l];
        // take point number k of mode l when floor(k * per_mode / c) advances
        let k = seen[l];
        seen[l] += 1;
        let stride = c <= per_mode || (k * per_mode) / c != ((k + 1) * per_mode) / c;
        let z = prep.row(r);
        for (i, fi) in f.iter_mut().enumerate() {
            let v = &wg[i];
            *fi = z.iter().zip(v).map(|(a, b)| a * b).sum::<f64>() - v[prep.p];
        }
        let worst = f
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != l)
            .map(|(_, &v)| v)
            .fold(f64::NEG_INFINITY, f64::max);
        if stride || f[l] - worst < SOFTMAX_BAND {
            set.push(r);
        }
    }
    Ok(set)
}

/// Builds the LP (MRLP) or QP (MSVM) on the points `set`.
///
/// Variables: per mode `[w_i (p); g_i]`, then per point of the set and per
/// other mode one slack. Rows: the normalisation in `ZeroConeT` first (MRLP:
/// `w_last = 0, g_last = 0`, removing the invariance to adding a common
/// affine function; MSVM: `g_last = 0` only, as its regulariser fixes the
/// normals), then `-(w_i - w_j).z + (g_i - g_j) - y <= -1` and `-y <= 0` in
/// `NonnegativeConeT`.
fn program(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    weight: &[f64],
    quadratic: bool,
    set: &[usize],
) -> Program {
    let p = prep.p;
    let nw = modes * (p + 1);
    let ns = set.len() * (modes - 1);
    let n = nw + ns;
    let mut q = vec![0.0; n];
    let mut pt = Triplets::default();
    if quadratic {
        for i in 0..modes {
            for k in 0..p {
                pt.push(i * (p + 1) + k, i * (p + 1) + k, 1.0);
            }
        }
    }
    let mut a = Triplets::default();
    let mut b = Vec::new();
    let last = (modes - 1) * (p + 1);
    let fixed: Vec<usize> = if quadratic {
        vec![last + p]
    } else {
        (last..last + p + 1).collect()
    };
    for &v in &fixed {
        a.push(b.len(), v, 1.0);
        b.push(0.0);
    }
    let zero_rows = b.len();
    let mut slack = nw;
    for &r in set {
        let i = labels[r];
        let z = prep.row(r);
        for j in (0..modes).filter(|&j| j != i) {
            let row = b.len();
            for (k, &zk) in z.iter().enumerate() {
                a.push(row, i * (p + 1) + k, -zk);
                a.push(row, j * (p + 1) + k, zk);
            }
            a.push(row, i * (p + 1) + p, 1.0);
            a.push(row, j * (p + 1) + p, -1.0);
            a.push(row, slack, -1.0);
            b.push(-1.0);
            q[slack] = weight[i];
            slack += 1;
        }
    }
    for v in nw..n {
        a.push(b.len(), v, -1.0);
        b.push(0.0);
    }
    let nonneg = b.len() - zero_rows;
    Program {
        p: pt,
        q,
        a,
        b,
        cones: vec![ZeroConeT(zero_rows), NonnegativeConeT(nonneg)],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};

    /// Full objective `R(w) + sum c_r hinge` of per-mode blocks.
    fn objective(
        prep: &Prepared,
        labels: &[usize],
        weight: &[f64],
        quadratic: bool,
        wg: &[Vec<f64>],
    ) -> f64 {
        let p = prep.p;
        let mut total = 0.0;
        if quadratic {
            total += 0.5
                * wg.iter()
                    .map(|v| v[..p].iter().map(|a| a * a).sum::<f64>())
                    .sum::<f64>();
        }
        for (r, &i) in labels.iter().enumerate() {
            let z = prep.row(r);
            let f = |v: &Vec<f64>| z.iter().zip(v).map(|(a, b)| a * b).sum::<f64>() - v[p];
            for j in (0..wg.len()).filter(|&j| j != i) {
                total += weight[i] * (1.0 - (f(&wg[i]) - f(&wg[j]))).max(0.0);
            }
        }
        total
    }

    /// The working-set optimum has the objective of the LP/QP on all points.
    #[test]
    fn working_set_reaches_the_full_optimum() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let n = 600;
        let mut x = DMatrix::zeros(n, 2);
        let mut labels = Vec::new();
        for r in 0..n {
            let (a, b): (f64, f64) = (rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
            x[(r, 0)] = a;
            x[(r, 1)] = b;
            let mut l = if a < -0.3 {
                0
            } else if b < 0.2 {
                1
            } else {
                2
            };
            if rng.random::<f64>() < 0.05 {
                l = (l + 1) % 3;
            }
            labels.push(l);
        }
        for method in [RegionMethod::Mrlp, RegionMethod::Msvm] {
            let opts = RegionOptions {
                method,
                ..RegionOptions::default()
            };
            let prep = crate::prepare(&x, &labels, 3, &opts).unwrap();
            let quadratic = method == RegionMethod::Msvm;
            let weight: Vec<f64> = prep
                .counts
                .iter()
                .map(|&c| {
                    if quadratic {
                        n as f64 / (3.0 * c as f64)
                    } else {
                        1.0 / c as f64
                    }
                })
                .collect();
            let (wg, stats) = solve(&prep, &labels, 3, &opts).unwrap();
            assert!(
                stats.working_points < n,
                "{method}: the working set should be a subset"
            );
            let all: Vec<usize> = (0..n).collect();
            let ctx = Context {
                method: "test",
                points: n,
                round: 1,
            };
            let full =
                solver::solve(program(&prep, &labels, 3, &weight, quadratic, &all), &ctx).unwrap();
            let full_blocks: Vec<Vec<f64>> = full.x[..3 * (prep.p + 1)]
                .chunks(prep.p + 1)
                .map(<[f64]>::to_vec)
                .collect();
            let a = objective(&prep, &labels, &weight, quadratic, &wg);
            let b = objective(&prep, &labels, &weight, quadratic, &full_blocks);
            assert!(
                (a - b).abs() <= 1e-6 * (1.0 + b.abs()),
                "{method}: working set {a} vs full {b}"
            );
        }
    }
}
