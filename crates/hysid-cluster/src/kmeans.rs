//! Step 2 of the procedure: clustering the feature vectors.
//!
//! **Weighted K-means** (Ferrari-Trecate et al., Automatica 2003, section
//! 3.2; HIT `hit_kmeans.m`, adapted from NetLab): minimises
//! `J = sum_i sum_{j in D_i} (xi_j - mu_i)' R_j^-1 (xi_j - mu_i)`.
//! Each sweep assigns every `xi_j` to the centre of least distance and
//! moves the centres to `mu_i = (sum_{j in D_i} R_j^-1)^-1 sum_{j in D_i} R_j^-1 xi_j`.
//! It stops when `max |delta mu| < 1e-4` and `|delta J| < 1e-4`, or after
//! `max_iter` sweeps. HIT's initialisation cuts a random permutation of
//! the points into `s` blocks and takes the same weighted mean per block;
//! `plusplus` seeds the centres instead with k-means++ (Arthur and
//! Vassilvitskii, SODA 2007) on the same distance. The restart of least
//! cost is kept. An empty cluster keeps its centre (it is discarded later).
//!
//! **Single linkage** (HIT `'SL'`): agglomerative clustering on the plain
//! Euclidean distance between feature vectors, by Prim's minimum spanning
//! tree, cut at a distance threshold or into a given number of clusters.

use crate::local::FeatureVectors;
use hysid_core::backend::Deadline;
use hysid_estimation::dense;
use rand::Rng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

/// Initialisation of the K-means centres.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KmeansInit {
    /// HIT: weighted means of `s` random blocks of the points.
    Blocks,
    /// k-means++ seeding on the weighted distance.
    PlusPlus,
}

/// Outcome of clustering.
#[derive(Debug, Clone, PartialEq)]
pub struct Clusters {
    /// Cluster of every feature vector.
    pub labels: Vec<usize>,
    /// Number of clusters (some may be empty).
    pub count: usize,
    /// Cost of the kept run (K-means), 0 for single linkage.
    pub cost: f64,
    /// Cost of every restart, in order.
    pub restart_costs: Vec<f64>,
    /// Sweeps of the kept run.
    pub iterations: usize,
    /// True when the kept run met the stopping rule before `max_iter`.
    pub converged: bool,
}

/// Per-cluster sums of the centre update: `sum R_j^-1` (blocks) and
/// `sum R_j^-1 xi_j`.
struct Sums<'a> {
    sa: &'a mut [f64],
    sb: &'a mut [f64],
    rhs: &'a mut [f64],
    count: &'a mut [usize],
}

impl Sums<'_> {
    /// Adds point `j` to cluster `i`, block sizes `p` and `q`.
    #[inline(always)]
    fn add(&mut self, f: &FeatureVectors, av: &[f64], j: usize, i: usize, p: usize, q: usize) {
        let d = p + q;
        self.count[i] += 1;
        for (a, b) in self.sa[i * p * p..(i + 1) * p * p]
            .iter_mut()
            .zip(&f.v_inv[j * p * p..(j + 1) * p * p])
        {
            *a += b;
        }
        for (a, b) in self.sb[i * q * q..(i + 1) * q * q]
            .iter_mut()
            .zip(&f.q_inv[j * q * q..(j + 1) * q * q])
        {
            *a += b;
        }
        for (a, b) in self.rhs[i * d..(i + 1) * d]
            .iter_mut()
            .zip(&av[j * d..(j + 1) * d])
        {
            *a += b;
        }
    }

    /// All points, in the order of `members` (with `labels[k]` the cluster
    /// of `members[k]`) or of the labels; `P`, `Q` compile-time sizes.
    fn accumulate<const P: usize, const Q: usize>(
        &mut self,
        f: &FeatureVectors,
        av: &[f64],
        labels: &[usize],
        members: Option<&[usize]>,
    ) {
        match members {
            Some(order) => {
                for (k, &j) in order.iter().enumerate() {
                    self.add(f, av, j, labels[k], P, Q);
                }
            }
            None => {
                for (j, &i) in labels.iter().enumerate() {
                    self.add(f, av, j, i, P, Q);
                }
            }
        }
    }

    /// [`Self::accumulate`] for run-time sizes.
    fn accumulate_any(
        &mut self,
        f: &FeatureVectors,
        av: &[f64],
        labels: &[usize],
        members: Option<&[usize]>,
    ) {
        let (p, q) = (f.p, f.q);
        match members {
            Some(order) => {
                for (k, &j) in order.iter().enumerate() {
                    self.add(f, av, j, labels[k], p, q);
                }
            }
            None => {
                for (j, &i) in labels.iter().enumerate() {
                    self.add(f, av, j, i, p, q);
                }
            }
        }
    }
}

/// Centre update `mu_i = (sum R_j^-1)^-1 sum R_j^-1 xi_j` for every cluster
/// with members; others keep their centre. `av` holds `R_j^-1 xi_j`.
fn update_centres(
    f: &FeatureVectors,
    av: &[f64],
    labels: &[usize],
    members: Option<&[usize]>,
    centres: &mut [f64],
    s: usize,
) {
    let (p, q) = (f.p, f.q);
    let d = p + q;
    let mut sa = vec![0.0; s * p * p];
    let mut sb = vec![0.0; s * q * q];
    let mut rhs = vec![0.0; s * d];
    let mut count = vec![0usize; s];
    let mut sums = Sums {
        sa: &mut sa,
        sb: &mut sb,
        rhs: &mut rhs,
        count: &mut count,
    };
    // Common sizes get unrolled additions (same order, same sums).
    match (p, q) {
        (2, 0) => sums.accumulate::<2, 0>(f, av, labels, members),
        (2, 1) => sums.accumulate::<2, 1>(f, av, labels, members),
        (3, 0) => sums.accumulate::<3, 0>(f, av, labels, members),
        (3, 2) => sums.accumulate::<3, 2>(f, av, labels, members),
        (4, 0) => sums.accumulate::<4, 0>(f, av, labels, members),
        (4, 3) => sums.accumulate::<4, 3>(f, av, labels, members),
        _ => sums.accumulate_any(f, av, labels, members),
    }
    let mut scratch = vec![0.0; p.max(q) * p.max(q)];
    for i in 0..s {
        if count[i] == 0 {
            continue;
        }
        let a = &mut sa[i * p * p..(i + 1) * p * p];
        let t = dense::mean_diag(a, p).max(f64::MIN_POSITIVE);
        dense::regularised_cholesky(a, p, 1e-14, 1e-14 * t, &mut scratch);
        let mu = &mut centres[i * d..(i + 1) * d];
        mu[..p].copy_from_slice(&rhs[i * d..i * d + p]);
        dense::cholesky_solve(a, p, &mut mu[..p]);
        if q > 0 {
            let b = &mut sb[i * q * q..(i + 1) * q * q];
            let t = dense::mean_diag(b, q).max(f64::MIN_POSITIVE);
            dense::regularised_cholesky(b, q, 1e-14, 1e-14 * t, &mut scratch);
            mu[p..].copy_from_slice(&rhs[i * d + p..(i + 1) * d]);
            dense::cholesky_solve(b, q, &mut mu[p..]);
        }
    }
}

/// `R_j^-1 xi_j` for every `j`.
fn weighted_features(f: &FeatureVectors) -> Vec<f64> {
    let (p, q) = (f.p, f.q);
    let d = p + q;
    let mut av = vec![0.0; f.n_samples * d];
    for j in 0..f.n_samples {
        let x = f.xi(j);
        let a = &f.v_inv[j * p * p..(j + 1) * p * p];
        for r in 0..p {
            av[j * d + r] = (0..p).map(|k| a[r * p + k] * x[k]).sum();
        }
        let b = &f.q_inv[j * q * q..(j + 1) * q * q];
        for r in 0..q {
            av[j * d + p + r] = (0..q).map(|k| b[r * q + k] * x[p + k]).sum();
        }
    }
    av
}

/// Adds `(x - mu)' A (x - mu) / 2` over the lower triangle of the `P x P`
/// block `a` to `s`, in the order of [`FeatureVectors::mahalanobis`] (so the
/// sums are bit-identical); `P` is a compile-time size so that the loops
/// unroll.
#[inline(always)]
fn half_quad<const P: usize>(a: &[f64], x: &[f64], mu: &[f64], mut s: f64) -> f64 {
    let (a, x, mu) = (&a[..P * P], &x[..P], &mu[..P]);
    for r in 0..P {
        let dr = x[r] - mu[r];
        let mut t = 0.5 * a[r * P + r] * dr;
        for k in 0..r {
            t += a[r * P + k] * (x[k] - mu[k]);
        }
        s += dr * t;
    }
    s
}

/// [`assign`] for blocks of compile-time sizes `P` (parameters) and `Q`
/// (local mean).
fn assign_fixed<const P: usize, const Q: usize>(
    f: &FeatureVectors,
    centres: &[f64],
    s: usize,
    labels: &mut [usize],
) -> (f64, bool) {
    let d = P + Q;
    let mut cost = 0.0;
    let mut changed = false;
    for (j, l) in labels.iter_mut().enumerate() {
        let x = &f.xi[j * d..(j + 1) * d];
        let a = &f.v_inv[j * P * P..(j + 1) * P * P];
        let b = &f.q_inv[j * Q * Q..(j + 1) * Q * Q];
        let (mut best, mut bi) = (f64::INFINITY, 0);
        for i in 0..s {
            let mu = &centres[i * d..(i + 1) * d];
            let mut v = half_quad::<P>(a, x, mu, 0.0);
            if Q > 0 {
                v = half_quad::<Q>(b, &x[P..], &mu[P..], v);
            }
            let v = 2.0 * v;
            if v < best {
                best = v;
                bi = i;
            }
        }
        changed |= *l != bi;
        *l = bi;
        cost += best;
    }
    (cost, changed)
}

/// Assigns every point to its nearest centre; returns the cost and whether
/// any label changed.
fn assign(f: &FeatureVectors, centres: &[f64], s: usize, labels: &mut [usize]) -> (f64, bool) {
    // Common PWARX sizes (p = n + 1, q = n with `fv`, 0 with `lpv`) get an
    // unrolled distance; the result is the same as the generic loop's.
    match (f.p, f.q) {
        (2, 0) => return assign_fixed::<2, 0>(f, centres, s, labels),
        (2, 1) => return assign_fixed::<2, 1>(f, centres, s, labels),
        (3, 0) => return assign_fixed::<3, 0>(f, centres, s, labels),
        (3, 2) => return assign_fixed::<3, 2>(f, centres, s, labels),
        (4, 0) => return assign_fixed::<4, 0>(f, centres, s, labels),
        (4, 3) => return assign_fixed::<4, 3>(f, centres, s, labels),
        (5, 0) => return assign_fixed::<5, 0>(f, centres, s, labels),
        (5, 4) => return assign_fixed::<5, 4>(f, centres, s, labels),
        _ => {}
    }
    let d = f.dim();
    let mut cost = 0.0;
    let mut changed = false;
    for (j, l) in labels.iter_mut().enumerate() {
        let (mut best, mut bi) = (f64::INFINITY, 0);
        for i in 0..s {
            let v = f.mahalanobis(j, &centres[i * d..(i + 1) * d]);
            if v < best {
                best = v;
                bi = i;
            }
        }
        changed |= *l != bi;
        *l = bi;
        cost += best;
    }
    (cost, changed)
}

/// Weighted K-means with `restarts` seeded restarts (at least one).
pub fn weighted_kmeans(
    f: &FeatureVectors,
    s: usize,
    restarts: usize,
    max_iter: usize,
    init: KmeansInit,
    rng: &mut ChaCha8Rng,
) -> Clusters {
    weighted_kmeans_until(f, s, restarts, max_iter, init, rng, &Deadline::none())
}

/// [`weighted_kmeans`] that starts no restart after `deadline` (the first
/// always runs); `restart_costs` of the result lists the restarts run.
///
/// The initial centres of every restart are drawn first, in restart order,
/// from `rng`; the sweeps of the restarts then run in parallel (rayon).
/// The restart of least cost is kept, the first of equal costs, so the
/// result is the same for any thread count.
pub fn weighted_kmeans_until(
    f: &FeatureVectors,
    s: usize,
    restarts: usize,
    max_iter: usize,
    init: KmeansInit,
    rng: &mut ChaCha8Rng,
    deadline: &Deadline,
) -> Clusters {
    let av = weighted_features(f);
    // Drawn in restart order, none after the deadline: a restart's draws
    // do not depend on whether later ones are drawn.
    let starts: Vec<Vec<f64>> = (0..restarts.max(1))
        .map_while(|r| {
            deadline
                .admits(r)
                .then(|| initial_centres(f, &av, s, init, rng))
        })
        .collect();
    let runs: Vec<Option<Clusters>> = starts
        .into_par_iter()
        .enumerate()
        .map(|(r, centres)| {
            deadline
                .admits(r)
                .then(|| sweeps(f, &av, s, max_iter, centres))
        })
        .collect();
    let runs: Vec<Clusters> = runs.into_iter().map_while(|run| run).collect();
    let restart_costs: Vec<f64> = runs.iter().map(|run| run.cost).collect();
    let mut best = runs
        .into_iter()
        .reduce(|best, run| if run.cost < best.cost { run } else { best })
        .expect("the first restart always runs");
    best.restart_costs = restart_costs;
    best
}

/// The initial centres of one restart (`s` rows of the feature dimension).
fn initial_centres(
    f: &FeatureVectors,
    av: &[f64],
    s: usize,
    init: KmeansInit,
    rng: &mut ChaCha8Rng,
) -> Vec<f64> {
    let n = f.n_samples;
    let d = f.dim();
    let mut centres = vec![0.0; s * d];
    match init {
        KmeansInit::Blocks => {
            let mut perm: Vec<usize> = (0..n).collect();
            perm.shuffle(rng);
            let block = (n / s).max(1);
            let block_labels: Vec<usize> = (0..n).map(|k| (k / block).min(s - 1)).collect();
            update_centres(f, av, &block_labels, Some(&perm), &mut centres, s);
        }
        KmeansInit::PlusPlus => {
            let first = rng.random_range(0..n);
            centres[..d].copy_from_slice(f.xi(first));
            let mut dmin: Vec<f64> = (0..n).map(|j| f.mahalanobis(j, &centres[..d])).collect();
            for i in 1..s {
                let total: f64 = dmin.iter().sum();
                let pick = if total > 0.0 && total.is_finite() {
                    let mut r = rng.random::<f64>() * total;
                    let mut k = n - 1;
                    for (j, &v) in dmin.iter().enumerate() {
                        if r < v {
                            k = j;
                            break;
                        }
                        r -= v;
                    }
                    k
                } else {
                    rng.random_range(0..n)
                };
                centres[i * d..(i + 1) * d].copy_from_slice(f.xi(pick));
                for (j, m) in dmin.iter_mut().enumerate() {
                    *m = m.min(f.mahalanobis(j, &centres[i * d..(i + 1) * d]));
                }
            }
        }
    }
    centres
}

/// The sweeps of one restart from `centres`, until the stopping rule or
/// `max_iter` sweeps.
fn sweeps(
    f: &FeatureVectors,
    av: &[f64],
    s: usize,
    max_iter: usize,
    mut centres: Vec<f64>,
) -> Clusters {
    let mut labels = vec![0usize; f.n_samples];
    let mut old_cost = f64::INFINITY;
    let mut iterations = 0;
    let mut converged = false;
    let mut final_cost = None;
    let mut old = vec![0.0; centres.len()];
    for it in 0..max_iter.max(1) {
        iterations = it + 1;
        let (cost, changed) = assign(f, &centres, s, &mut labels);
        if it > 0 && !changed {
            // Same labels as the sweep before: the update would give the
            // same centres again (a fixed point, which the rule below
            // would stop at one or two sweeps later with these centres and
            // labels), so stop now.
            converged = true;
            final_cost = Some(cost);
            break;
        }
        old.copy_from_slice(&centres);
        update_centres(f, av, &labels, None, &mut centres, s);
        let shift = old
            .iter()
            .zip(&centres)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        if it > 0 && shift < 1e-4 && (cost - old_cost).abs() < 1e-4 {
            converged = true;
            break;
        }
        old_cost = cost;
    }
    let cost = match final_cost {
        Some(c) => c,
        None => assign(f, &centres, s, &mut labels).0,
    };
    Clusters {
        labels,
        count: s,
        cost,
        restart_costs: vec![],
        iterations,
        converged,
    }
}

/// Single linkage on the Euclidean distance between feature vectors: the
/// minimum spanning tree (Prim, O(N^2)) cut at edges longer than
/// `threshold`, or, without a threshold, at its `s - 1` longest edges.
/// Clusters are numbered by their first member.
pub fn single_linkage(f: &FeatureVectors, s: usize, threshold: Option<f64>) -> Clusters {
    let n = f.n_samples;
    let d = f.dim();
    let dist = |a: usize, b: usize| -> f64 {
        f.xi(a)
            .iter()
            .zip(f.xi(b))
            .map(|(x, y)| (x - y) * (x - y))
            .sum::<f64>()
            .sqrt()
    };
    let mut in_tree = vec![false; n];
    let mut best = vec![f64::INFINITY; n];
    let mut parent = vec![usize::MAX; n];
    let mut edges: Vec<(f64, usize, usize)> = Vec::with_capacity(n.saturating_sub(1));
    if n > 0 {
        let mut cur = 0;
        in_tree[0] = true;
        for _ in 1..n {
            let mut next = usize::MAX;
            let mut nd = f64::INFINITY;
            for j in 0..n {
                if in_tree[j] {
                    continue;
                }
                let v = dist(cur, j);
                if v < best[j] {
                    best[j] = v;
                    parent[j] = cur;
                }
                if best[j] < nd || next == usize::MAX {
                    nd = best[j];
                    next = j;
                }
            }
            in_tree[next] = true;
            edges.push((best[next], parent[next], next));
            cur = next;
        }
    }
    let _ = d;
    // Edges kept: all below the threshold, or all but the s - 1 longest.
    let mut order: Vec<usize> = (0..edges.len()).collect();
    order.sort_by(|&a, &b| edges[a].0.total_cmp(&edges[b].0).then(a.cmp(&b)));
    let keep: Vec<bool> = match threshold {
        Some(t) => edges.iter().map(|e| e.0 <= t).collect(),
        None => {
            let mut k = vec![true; edges.len()];
            for &e in order.iter().rev().take(s.saturating_sub(1)) {
                k[e] = false;
            }
            k
        }
    };
    // Union-find over kept edges.
    let mut root: Vec<usize> = (0..n).collect();
    fn find(r: &mut [usize], mut a: usize) -> usize {
        while r[a] != a {
            r[a] = r[r[a]];
            a = r[a];
        }
        a
    }
    for (e, &(_, a, b)) in edges.iter().enumerate() {
        if keep[e] {
            let (ra, rb) = (find(&mut root, a), find(&mut root, b));
            if ra != rb {
                root[ra.max(rb)] = ra.min(rb);
            }
        }
    }
    let mut id = vec![usize::MAX; n];
    let mut labels = vec![0; n];
    let mut count = 0;
    for (j, l) in labels.iter_mut().enumerate() {
        let r = find(&mut root, j);
        if id[r] == usize::MAX {
            id[r] = count;
            count += 1;
        }
        *l = id[r];
    }
    Clusters {
        labels,
        count,
        cost: 0.0,
        restart_costs: vec![],
        iterations: 0,
        converged: true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Features;
    use crate::local::feature_vectors;
    use rand::SeedableRng;

    /// The restarts run in parallel: with one thread and with three, the
    /// same restarts (costs bitwise), the same kept clustering; and the
    /// kept one is a restart of least cost.
    #[test]
    fn restarts_are_the_same_with_any_thread_count() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let n = 2;
        let x: Vec<f64> = (0..2000 * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let y: Vec<f64> = (0..2000)
            .map(|j| {
                let (a, b) = (x[j * n], x[j * n + 1]);
                (if a + b > 0.3 {
                    a - b
                } else {
                    0.5 * a + 2.0 * b + 1.0
                }) + 0.05 * rng.random::<f64>()
            })
            .collect();
        let f = feature_vectors(&x, n, &y, 12, Features::Fv, 1e-6);
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| {
                    let mut rng = ChaCha8Rng::seed_from_u64(3);
                    weighted_kmeans(&f, 3, 9, 100, KmeansInit::PlusPlus, &mut rng)
                })
        };
        let (one, three) = (run(1), run(3));
        let bits = |v: &[f64]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&one.restart_costs), bits(&three.restart_costs));
        assert_eq!(one.restart_costs.len(), 9);
        assert_eq!(one.labels, three.labels);
        assert_eq!(one.cost.to_bits(), three.cost.to_bits());
        let least = one
            .restart_costs
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        assert_eq!(one.cost, least);
    }

    /// The unrolled assignment gives the generic loop's labels and the very
    /// same cost bits, for every specialised block size and one generic.
    #[test]
    fn unrolled_assignment_matches_the_generic_distance() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for n in 1..=5 {
            for features in [Features::Fv, Features::Lpv] {
                let big_n = 120;
                let x: Vec<f64> = (0..big_n * n)
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect();
                let y: Vec<f64> = (0..big_n)
                    .map(|j| {
                        x[j * n] * if x[j * n] > 0.0 { 2.0 } else { -1.0 }
                            + rng.random::<f64>() * 0.1
                    })
                    .collect();
                let f = feature_vectors(&x, n, &y, n + 6, features, 1e-6);
                let d = f.dim();
                let s = 3;
                let centres: Vec<f64> = (0..s * d).map(|_| rng.random_range(-2.0..2.0)).collect();
                let mut labels = vec![0; big_n];
                let (cost, _) = assign(&f, &centres, s, &mut labels);
                let mut want_cost = 0.0;
                for (j, &label) in labels.iter().enumerate() {
                    let (mut best, mut bi) = (f64::INFINITY, 0);
                    for i in 0..s {
                        let v = f.mahalanobis(j, &centres[i * d..(i + 1) * d]);
                        if v < best {
                            best = v;
                            bi = i;
                        }
                    }
                    assert_eq!(label, bi, "n = {n}, {features:?}, point {j}");
                    want_cost += best;
                }
                assert_eq!(cost.to_bits(), want_cost.to_bits(), "n = {n}, {features:?}");
            }
        }
    }
}
