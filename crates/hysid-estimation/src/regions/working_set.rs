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

use crate::conic::{Cone, Program, Triplets};
use crate::regions::options::{RegionError, RegionMethod, RegionOptions, SolveStats};
use crate::regions::problem::{Context, Prepared};
use crate::regions::simplex::Simplex;
use hysid_core::backend::Deadline;
use std::collections::HashMap;
use std::collections::hash_map::Entry;

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
/// below this join the first working set of clarabel.
const SOFTMAX_BAND: f64 = 2.0;
/// Points whose margin under the scaled softmax scores is below this join
/// the first working set (the program's hinge is active below 1).
const SCALED_BAND: f64 = 2.0;
/// Largest number of points the softmax of the first working set is fitted on.
const SOFTMAX_SAMPLE: usize = 1000;
/// Search interval of the log scale factor of the softmax scores.
const SCALE_LN_RANGE: (f64, f64) = (-12.0, 16.0);
/// The MRLP goes to the simplex of [`crate::regions::simplex`] when it has at most
/// this many free score parameters (the basis is refactorised at every
/// pivot, `O(k^3)`); above, and for the MSVM QP, clarabel solves it.
const SIMPLEX_MAX_UNKNOWNS: usize = 48;
/// Pivot bound of the simplex, per term of the whole program.
const SIMPLEX_PIVOTS_PER_TERM: usize = 4;
/// Golden-section steps (the interval shrinks by 0.618 per step).
const GOLDEN_STEPS: usize = 60;

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

    if opts.deadline.passed() {
        return softmax_instead(prep, labels, modes, SolveStats::default());
    }
    let mut certified = None;
    if !quadratic && (modes - 1) * (prep.p + 1) <= SIMPLEX_MAX_UNKNOWNS {
        let mut stats = SolveStats::default();
        // A failed softmax on the sample only costs the fast path.
        if let Ok(set) = scaled_softmax_set(prep, labels, modes, &weight, quadratic, &mut stats) {
            match solve_simplex(
                prep,
                labels,
                modes,
                &weight,
                set,
                &opts.deadline,
                &mut stats,
            ) {
                SimplexOutcome::Kept(blocks) => return Ok((blocks, stats)),
                SimplexOutcome::Degenerate { set } => certified = Some(set),
                SimplexOutcome::GaveUp => {}
            }
        }
    }
    // The QP, large MRLPs, and MRLPs whose optimum is not unique (the
    // interior-point solution is kept there: see `crate::regions::simplex`).
    // Where the simplex reached the optimum, its working set holds every
    // point with a non-zero loss there, and clarabel starts from it.
    let mut stats = SolveStats::default();
    let set = match certified {
        Some(set) => set,
        None => initial_set(prep, labels, modes, &mut stats)?,
    };
    let solved = solve_clarabel(
        prep,
        labels,
        modes,
        &weight,
        (method, quadratic),
        set,
        &opts.deadline,
        stats.clone(),
    );
    match solved {
        Err(RegionError::TimeLimit { .. }) => softmax_instead(prep, labels, modes, stats),
        other => other,
    }
}

/// When the time budget leaves no room for the program: the softmax
/// partition (also complete), marked [`SolveStats::cut_short`].
fn softmax_instead(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    mut stats: SolveStats,
) -> Result<(Vec<Vec<f64>>, SolveStats), RegionError> {
    let (blocks, steps) = crate::regions::softmax::fit(
        prep,
        labels,
        modes,
        &crate::regions::options::SoftmaxSettings::default(),
    )?;
    stats.newton_steps = steps;
    stats.cut_short = true;
    Ok((blocks, stats))
}

/// Points outside the set (`in_set` false) whose margin under the scores
/// `blocks` is below `1 - MARGIN_TOL`: they have a non-zero loss.
fn violators(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    blocks: &[Vec<f64>],
    in_set: &[bool],
) -> Vec<usize> {
    let mut out = Vec::new();
    let mut f = vec![0.0; modes];
    for r in 0..prep.n {
        if in_set[r] {
            continue;
        }
        let z = prep.row(r);
        for (fi, v) in f.iter_mut().zip(blocks) {
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
            out.push(r);
        }
    }
    out
}

/// How [`solve_simplex`] ended.
enum SimplexOutcome {
    /// Scores to keep: the unique optimum, or past the deadline the last
    /// round's.
    Kept(Vec<Vec<f64>>),
    /// An optimum that is not certified unique, reached on working set
    /// `set`: every point outside it has zero loss there.
    Degenerate { set: Vec<usize> },
    /// The pivot bound or a singular basis.
    GaveUp,
}

/// The MRLP by the dual simplex of [`crate::regions::simplex`], warm-started from
/// round to round. The caller uses clarabel when the simplex gives up or
/// the optimum is not unique. Past `deadline`, the scores of the last round.
fn solve_simplex(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    weight: &[f64],
    mut set: Vec<usize>,
    deadline: &Deadline,
    stats: &mut SolveStats,
) -> SimplexOutcome {
    let mut in_set = vec![false; prep.n];
    for &r in &set {
        in_set[r] = true;
    }
    let k = (modes - 1) * (prep.p + 1);
    // Generous: a few pivots per term of the whole problem.
    let max_pivots = (SIMPLEX_PIVOTS_PER_TERM * (prep.n * (modes - 1) + k)) as u64;
    let mut sx = Simplex::new(prep, labels, weight, modes);
    let mut round = 0;
    loop {
        round += 1;
        if round > MAX_ROUNDS && set.len() < prep.n {
            set = (0..prep.n).collect();
            in_set.iter_mut().for_each(|v| *v = true);
        }
        if sx.optimise(&set, max_pivots).is_err() {
            return SimplexOutcome::GaveUp;
        }
        stats.solves += 1;
        stats.solver_iterations = sx.pivots;
        stats.working_points = set.len();
        let blocks = sx.blocks();
        let new = violators(prep, labels, modes, &blocks, &in_set);
        if new.is_empty() {
            return if sx.unique() {
                SimplexOutcome::Kept(blocks)
            } else {
                SimplexOutcome::Degenerate { set }
            };
        }
        if deadline.passed() {
            stats.cut_short = true;
            return SimplexOutcome::Kept(blocks);
        }
        for &r in &new {
            in_set[r] = true;
        }
        set.extend_from_slice(&new);
        set.sort_unstable();
    }
}

/// The working-set rounds with clarabel solving each restricted program;
/// past `deadline`, the scores of the last round.
#[allow(clippy::too_many_arguments)]
fn solve_clarabel(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    weight: &[f64],
    (method, quadratic): (&'static str, bool),
    mut set: Vec<usize>,
    deadline: &Deadline,
    mut stats: SolveStats,
) -> Result<(Vec<Vec<f64>>, SolveStats), RegionError> {
    let mut in_set = vec![false; prep.n];
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
            deadline: deadline.clone(),
        };
        let prog = program(prep, labels, modes, weight, quadratic, &set);
        let sol = crate::regions::problem::solve_in_context(prog, &ctx)?;
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
        let new = violators(prep, labels, modes, &blocks, &in_set);
        if new.is_empty() {
            return Ok((blocks, stats));
        }
        if deadline.passed() {
            stats.cut_short = true;
            return Ok((blocks, stats));
        }
        for &r in &new {
            in_set[r] = true;
        }
        set.extend_from_slice(&new);
        // Keep row order independent of the discovery order.
        set.sort_unstable();
    }
}

/// First working set of the simplex, from a cheap classifier whose scale is
/// matched to the program's:
///
/// 1. a softmax fit ([`crate::regions::softmax`]) on at most [`SOFTMAX_SAMPLE`]
///    points, evenly spaced in row order within each mode (every mode is
///    present, so the fit is well posed);
/// 2. the softmax scores are multiplied by the factor `a > 0` that minimises
///    the program's own objective (hinge terms and, for MSVM, the
///    regulariser) on that sample, by golden-section search on `ln a` (the
///    objective is convex in `a`, so unimodal in `ln a`): the softmax
///    boundaries are about right but its margins are in other units;
/// 3. the set is every point whose scaled margin (own score minus the best
///    other) is below [`SCALED_BAND`], i.e. the points the LP/QP will
///    probably find hinge-active, plus up to `INITIAL_PER_MODE_FACTOR (p + 1)`
///    points of each mode evenly spaced in row order.
///
/// Deterministic; it only affects the speed, not the optimum (the rounds add
/// every point with non-zero loss).
fn scaled_softmax_set(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    weight: &[f64],
    quadratic: bool,
    stats: &mut SolveStats,
) -> Result<Vec<usize>, RegionError> {
    let p = prep.p;
    // 1. Stratified sample and softmax fit on it.
    let sample = stratified(labels, &prep.counts, SOFTMAX_SAMPLE / modes.max(1));
    let (sub, sub_labels) = subsample(prep, labels, modes, &sample);
    let (wg, steps) = crate::regions::softmax::fit(
        &sub,
        &sub_labels,
        modes,
        &crate::regions::options::SoftmaxSettings::default(),
    )?;
    stats.newton_steps = steps;
    let score = |z: &[f64], f: &mut [f64]| {
        for (fi, v) in f.iter_mut().zip(&wg) {
            *fi = z.iter().zip(v).map(|(a, b)| a * b).sum::<f64>() - v[p];
        }
    };
    // 2. Scale: margins f_y - f_j of the sample, each hinge term weighted
    // as in the program, scaled up from the sample to the whole mode.
    let mut terms: Vec<(f64, f64)> = Vec::with_capacity(sample.len() * (modes - 1));
    let mut f = vec![0.0; modes];
    for &r in &sample {
        let l = labels[r];
        score(prep.row(r), &mut f);
        let w = weight[l] * prep.counts[l] as f64 / sub.counts[l] as f64;
        for j in (0..modes).filter(|&j| j != l) {
            terms.push((f[l] - f[j], w));
        }
    }
    let norm2: f64 = if quadratic {
        wg.iter()
            .map(|v| v[..p].iter().map(|a| a * a).sum::<f64>())
            .sum()
    } else {
        0.0
    };
    let objective = |t: f64| -> f64 {
        let a = t.exp();
        let hinge: f64 = terms.iter().map(|&(m, w)| w * (1.0 - a * m).max(0.0)).sum();
        hinge + 0.5 * a * a * norm2
    };
    let a = golden_section(objective, SCALE_LN_RANGE.0, SCALE_LN_RANGE.1).exp();
    // 3. Points of small scaled margin, plus the evenly spaced ones.
    let scaled: Vec<Vec<f64>> = wg
        .iter()
        .map(|v| v.iter().map(|x| a * x).collect())
        .collect();
    Ok(small_margin(prep, labels, modes, &scaled, SCALED_BAND))
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
    let (wg, steps) = crate::regions::softmax::fit(
        prep,
        labels,
        modes,
        &crate::regions::options::SoftmaxSettings::default(),
    )?;
    stats.newton_steps = steps;
    Ok(small_margin(prep, labels, modes, &wg, SOFTMAX_BAND))
}

/// Rows whose margin under the scores `wg` is below `band`, plus up to
/// `INITIAL_PER_MODE_FACTOR (p + 1)` rows of each mode evenly spaced in row
/// order.
fn small_margin(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    wg: &[Vec<f64>],
    band: f64,
) -> Vec<usize> {
    let p = prep.p;
    let per_mode = INITIAL_PER_MODE_FACTOR * (p + 1);
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
        for (fi, v) in f.iter_mut().zip(wg) {
            *fi = z.iter().zip(v).map(|(a, b)| a * b).sum::<f64>() - v[p];
        }
        let worst = f
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != l)
            .map(|(_, &v)| v)
            .fold(f64::NEG_INFINITY, f64::max);
        if stride || f[l] - worst < band {
            set.push(r);
        }
    }
    set
}

/// The rows `sample` of `prep` as a problem of their own, with their labels.
fn subsample(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    sample: &[usize],
) -> (Prepared, Vec<usize>) {
    let mut counts = vec![0usize; modes];
    for &r in sample {
        counts[labels[r]] += 1;
    }
    let sub = Prepared {
        z: sample
            .iter()
            .flat_map(|&r| prep.row(r).iter().copied())
            .collect(),
        n: sample.len(),
        p: prep.p,
        cols: prep.cols.clone(),
        mean: prep.mean.clone(),
        scale: prep.scale.clone(),
        counts,
    };
    (sub, sample.iter().map(|&r| labels[r]).collect())
}

/// Up to `per_mode` rows of every mode, evenly spaced in row order (all rows
/// of a mode with fewer), in increasing row order.
fn stratified(labels: &[usize], counts: &[usize], per_mode: usize) -> Vec<usize> {
    let per_mode = per_mode.max(1);
    let mut seen = vec![0usize; counts.len()];
    let mut out = Vec::new();
    for (r, &l) in labels.iter().enumerate() {
        let c = counts[l];
        let k = seen[l];
        seen[l] += 1;
        if c <= per_mode || (k * per_mode) / c != ((k + 1) * per_mode) / c {
            out.push(r);
        }
    }
    out
}

/// Minimiser of a unimodal `g` on `[lo, hi]` by golden-section search
/// (Kiefer 1953), [`GOLDEN_STEPS`] steps.
fn golden_section(g: impl Fn(f64) -> f64, lo: f64, hi: f64) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (lo, hi);
    let mut x1 = b - r * (b - a);
    let mut x2 = a + r * (b - a);
    let (mut g1, mut g2) = (g(x1), g(x2));
    for _ in 0..GOLDEN_STEPS {
        if g1 <= g2 {
            b = x2;
            x2 = x1;
            g2 = g1;
            x1 = b - r * (b - a);
            g1 = g(x1);
        } else {
            a = x1;
            x1 = x2;
            g1 = g2;
            x2 = a + r * (b - a);
            g2 = g(x2);
        }
    }
    if g1 <= g2 { x1 } else { x2 }
}

/// The distinct points of `set` (same mode, same regressor), each once in
/// order of first appearance, with how many points of `set` it stands for.
/// Identical points have identical hinge terms, so one term weighted by
/// their number is the same program with the same optimal set; an
/// interior-point solver converges on it in fewer, cheaper iterations
/// (duplicates make the KKT system nearly singular: a saturated output
/// under a held input repeats its regressor).
fn distinct_points(prep: &Prepared, labels: &[usize], set: &[usize]) -> Vec<(usize, f64)> {
    let mut first: HashMap<(usize, Vec<u64>), usize> = HashMap::with_capacity(set.len());
    let mut points: Vec<(usize, f64)> = Vec::with_capacity(set.len());
    for &r in set {
        let key = (labels[r], prep.row(r).iter().map(|v| v.to_bits()).collect());
        match first.entry(key) {
            Entry::Occupied(k) => points[*k.get()].1 += 1.0,
            Entry::Vacant(v) => {
                v.insert(points.len());
                points.push((r, 1.0));
            }
        }
    }
    points
}

/// Builds the LP (MRLP) or QP (MSVM) on the points `set`, identical points
/// merged ([`distinct_points`]).
///
/// Variables: per mode `[w_i (p); g_i]`, then per distinct point of the set
/// and per other mode one slack, weighted by the point's multiplicity.
/// Rows: the normalisation in `ZeroConeT` first (MRLP: `w_last = 0,
/// g_last = 0`, removing the invariance to adding a common affine
/// function; MSVM: `g_last = 0` only, as its regulariser fixes the
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
    let points = distinct_points(prep, labels, set);
    let ns = points.len() * (modes - 1);
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
    for &(r, count) in &points {
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
            q[slack] = weight[i] * count;
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
        cones: vec![Cone::Zero(zero_rows), Cone::Nonnegative(nonneg)],
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
            let prep = crate::regions::problem::prepare(&x, &labels, 3, &opts).unwrap();
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
                deadline: hysid_core::backend::Deadline::none(),
            };
            let full = crate::regions::problem::solve_in_context(
                program(&prep, &labels, 3, &weight, quadratic, &all),
                &ctx,
            )
            .unwrap();
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

    /// Identical points of one mode become one term weighted by their
    /// number; the same regressor in two modes stays two terms. The merged
    /// program has the optimum of the program with every point: the
    /// simplex, which keeps every term, reaches the same objective.
    #[test]
    fn identical_points_are_one_weighted_term() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let n = 240;
        let mut x = DMatrix::zeros(n, 2);
        let mut labels = Vec::with_capacity(n);
        for r in 0..n {
            // Every third row repeats a saturated point of mode 0; a fifth
            // of those carry mode 1 instead (an overlap at the same point).
            let (a, b, l) = if r % 3 == 0 {
                (1.5, -0.5, usize::from(r % 5 == 0))
            } else {
                let (a, b): (f64, f64) = (rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
                (a, b, usize::from(a + 0.3 * b > 0.1))
            };
            x[(r, 0)] = a;
            x[(r, 1)] = b;
            labels.push(l);
        }
        let opts = RegionOptions::default();
        let prep = crate::regions::problem::prepare(&x, &labels, 2, &opts).unwrap();
        let all: Vec<usize> = (0..n).collect();
        let points = distinct_points(&prep, &labels, &all);
        let saturated = |l: usize| (0..n).filter(|r| r % 3 == 0 && labels[*r] == l).count();
        assert_eq!(points.len(), n - n / 3 + 2);
        assert_eq!(points[0], (0, saturated(1) as f64));
        assert_eq!(points[1], (1, 1.0));
        assert_eq!(points[2], (2, 1.0));
        assert_eq!(points[3], (3, saturated(0) as f64));
        assert_eq!(points.iter().map(|p| p.1).sum::<f64>(), n as f64);

        let weight: Vec<f64> = prep.counts.iter().map(|&c| 1.0 / c as f64).collect();
        let merged = clarabel_full(&prep, &labels, 2, &weight);
        let mut sx = Simplex::new(&prep, &labels, &weight, 2);
        sx.optimise(&all, 1_000_000).unwrap();
        let exact = objective(&prep, &labels, &weight, false, &sx.blocks());
        assert!(
            (merged - exact).abs() <= 1e-6 * (1.0 + exact),
            "merged program {merged} vs every term {exact}"
        );
    }

    /// Objective of the clarabel solve of the MRLP on all points.
    fn clarabel_full(prep: &Prepared, labels: &[usize], modes: usize, weight: &[f64]) -> f64 {
        let all: Vec<usize> = (0..prep.n).collect();
        let ctx = Context {
            method: "test",
            points: prep.n,
            round: 1,
            deadline: hysid_core::backend::Deadline::none(),
        };
        let full = crate::regions::problem::solve_in_context(
            program(prep, labels, modes, weight, false, &all),
            &ctx,
        )
        .unwrap();
        let blocks: Vec<Vec<f64>> = full.x[..modes * (prep.p + 1)]
            .chunks(prep.p + 1)
            .map(<[f64]>::to_vec)
            .collect();
        objective(prep, labels, weight, false, &blocks)
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]
        /// The simplex working-set MRLP reaches the objective of clarabel on
        /// the full LP, and so does the region step's `solve`: random modes,
        /// dimensions, label noise (non-separable data) and duplicated
        /// points (degenerate vertices).
        #[test]
        fn simplex_matches_the_full_lp(
            modes in 2usize..5,
            d in 1usize..4,
            n in 20usize..300,
            flip in 0.0f64..0.3,
            dup in proptest::prelude::any::<bool>(),
            seed in proptest::prelude::any::<u64>(),
        ) {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let centres: Vec<Vec<f64>> = (0..modes)
                .map(|_| (0..d).map(|_| rng.random_range(-3.0..3.0)).collect())
                .collect();
            let mut x = DMatrix::zeros(n, d);
            let mut labels = Vec::with_capacity(n);
            for r in 0..n {
                if dup && r % 3 == 2 {
                    for k in 0..d {
                        x[(r, k)] = x[(r - 1, k)];
                    }
                } else {
                    for k in 0..d {
                        x[(r, k)] = (rng.random_range(-4.0f64..4.0) * 4.0).round() / 4.0;
                    }
                }
                let row: Vec<f64> = (0..d).map(|k| x[(r, k)]).collect();
                let mut l = (0..modes)
                    .min_by(|&a, &b| {
                        let da: f64 = row.iter().zip(&centres[a]).map(|(u, v)| (u - v) * (u - v)).sum();
                        let db: f64 = row.iter().zip(&centres[b]).map(|(u, v)| (u - v) * (u - v)).sum();
                        da.total_cmp(&db)
                    })
                    .unwrap();
                if r < modes {
                    l = r; // every mode present
                } else if rng.random::<f64>() < flip {
                    l = rng.random_range(0..modes);
                }
                labels.push(l);
            }
            let opts = RegionOptions::default();
            let prep = crate::regions::problem::prepare(&x, &labels, modes, &opts).unwrap();
            let weight: Vec<f64> = prep.counts.iter().map(|&c| 1.0 / c as f64).collect();
            let mut stats = SolveStats::default();
            let set = scaled_softmax_set(&prep, &labels, modes, &weight, false, &mut stats).unwrap();
            // The optimum the simplex's working-set rounds reach, unique or
            // not: where it is not, on the final working set, which holds
            // every point with a non-zero loss.
            let none = hysid_core::backend::Deadline::none();
            let blocks = match solve_simplex(&prep, &labels, modes, &weight, set, &none, &mut stats) {
                SimplexOutcome::Kept(blocks) => blocks,
                SimplexOutcome::Degenerate { set } => {
                    let mut sx = Simplex::new(&prep, &labels, &weight, modes);
                    sx.optimise(&set, 1_000_000).expect("the simplex finishes on its final set");
                    sx.blocks()
                }
                SimplexOutcome::GaveUp => {
                    return Err(proptest::test_runner::TestCaseError::fail("the simplex gave up"));
                }
            };
            let a = objective(&prep, &labels, &weight, false, &blocks);
            let b = clarabel_full(&prep, &labels, modes, &weight);
            proptest::prop_assert!(
                (a - b).abs() <= 1e-6 * (1.0 + b.abs()),
                "simplex {} vs clarabel {}", a, b
            );
            // The region step's own path (the simplex, or clarabel where
            // the simplex's optimum is not unique) reaches it too.
            let (scores, _) = solve(&prep, &labels, modes, &opts).unwrap();
            let c = objective(&prep, &labels, &weight, false, &scores);
            proptest::prop_assert!(
                (c - b).abs() <= 1e-6 * (1.0 + b.abs()),
                "solve {} vs clarabel {}", c, b
            );
        }
    }
}
