//! Exact k-nearest-neighbour search in regressor space with a k-d tree
//! (Friedman, Bentley, Finkel, "An algorithm for finding best matches in
//! logarithmic expected time", ACM TOMS 3(3), 1977).
//!
//! The dimension is a run-time value (PWARX regressors have `na + nb m`
//! entries), and ties are broken by sample index, so the local datasets are
//! a deterministic function of the data. Duplicate points (frequent in
//! quantised, stiction-dominated records) are handled: a leaf whose points
//! all coincide is simply not split further.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

const LEAF: usize = 16;
/// Largest `k` kept in a sorted vector rather than a heap.
const SORTED_MAX: usize = 64;

#[derive(Debug, Clone)]
enum Node {
    Leaf {
        start: usize,
        end: usize,
    },
    Split {
        dim: usize,
        value: f64,
        left: usize,
        right: usize,
    },
}

/// A k-d tree over the rows of a point matrix (`n` points of dimension `d`,
/// stored row-major).
#[derive(Debug, Clone)]
pub struct KdTree<'a> {
    points: &'a [f64],
    d: usize,
    order: Vec<usize>,
    nodes: Vec<Node>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Candidate {
    dist: f64,
    index: usize,
}
impl Eq for Candidate {}
impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        self.dist
            .total_cmp(&other.dist)
            .then(self.index.cmp(&other.index))
    }
}

impl<'a> KdTree<'a> {
    /// Builds the tree over `points` (row-major, `d` columns, finite values).
    pub fn new(points: &'a [f64], d: usize) -> Self {
        let n = points.len().checked_div(d).unwrap_or(0);
        let mut t = KdTree {
            points,
            d,
            order: (0..n).collect(),
            nodes: Vec::new(),
        };
        if n > 0 {
            t.build(0, n);
        }
        t
    }

    fn coord(&self, i: usize, k: usize) -> f64 {
        self.points[i * self.d + k]
    }

    fn build(&mut self, start: usize, end: usize) -> usize {
        let id = self.nodes.len();
        self.nodes.push(Node::Leaf { start, end });
        if end - start <= LEAF {
            return id;
        }
        // Split on the dimension of largest spread, at the median.
        let (mut best, mut spread) = (0, 0.0);
        for k in 0..self.d {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for &i in &self.order[start..end] {
                let v = self.coord(i, k);
                lo = lo.min(v);
                hi = hi.max(v);
            }
            if hi - lo > spread {
                spread = hi - lo;
                best = k;
            }
        }
        if spread <= 0.0 {
            return id; // all points coincide
        }
        let mid = start + (end - start) / 2;
        let (pts, d) = (self.points, self.d);
        self.order[start..end].select_nth_unstable_by(mid - start, |&a, &b| {
            pts[a * d + best].total_cmp(&pts[b * d + best])
        });
        let value = self.coord(self.order[mid], best);
        let left = self.build(start, mid);
        let right = self.build(mid, end);
        self.nodes[id] = Node::Split {
            dim: best,
            value,
            left,
            right,
        };
        id
    }

    /// The point indices in the tree's leaf order: consecutive entries are
    /// close in space, so querying them in this order reuses the cache.
    pub fn leaf_order(&self) -> &[usize] {
        &self.order
    }

    /// The `k` nearest points to `q` (squared Euclidean distance, ties by
    /// index), nearest first, as indices into the point matrix.
    pub fn nearest(&self, q: &[f64], k: usize, out: &mut Vec<usize>) {
        out.clear();
        if self.nodes.is_empty() || k == 0 {
            return;
        }
        let mut best = Best::new(k);
        let mut off = vec![0.0; self.d];
        self.search(0, q, &mut best, 0.0, &mut off);
        out.extend(best.into_sorted().into_iter().map(|c| c.index));
    }

    /// [`Self::nearest`], given `seed`: any points, typically the answer
    /// for a nearby query. The `k`-th smallest seed distance to `q` bounds
    /// the distance of the answer's farthest point when `k` distinct
    /// points are within it, so the search only visits cells within that
    /// bound, collects every point within it and selects the `k` nearest at
    /// the end, instead of keeping a running list. The answer is the same
    /// as without a seed (ties by index); when fewer than `k` points turn
    /// out to be within the bound, the plain search runs.
    pub fn nearest_seeded(
        &self,
        q: &[f64],
        k: usize,
        seed: &[usize],
        scratch: &mut Scratch,
        out: &mut Vec<usize>,
    ) {
        out.clear();
        if self.nodes.is_empty() || k == 0 {
            return;
        }
        // Bound: the k-th smallest seed distance. Whatever the seeds (even
        // repeated), if at least k points lie within the bound the answer
        // is among them; otherwise the plain search is used.
        let cand = &mut scratch.cand;
        cand.clear();
        cand.extend(
            seed.iter()
                .map(|&i| key(Self::dist(&self.points[i * self.d..(i + 1) * self.d], q), i)),
        );
        if cand.len() < k {
            self.nearest(q, k, out);
            return;
        }
        let bound = if cand.len() == k {
            cand.iter().copied().max().unwrap_or(0)
        } else {
            *cand.select_nth_unstable(k - 1).1
        } >> 64;
        let bound = f64::from_bits(bound as u64);
        cand.clear();
        scratch.off.clear();
        scratch.off.resize(self.d, 0.0);
        self.collect(0, q, bound, 0.0, &mut scratch.off, cand);
        // The seed points are within the bound, unless rounding of the cell
        // distances pruned some: with fewer than k, search afresh.
        if cand.len() < k {
            self.nearest(q, k, out);
            return;
        }
        cand.select_nth_unstable(k - 1);
        cand.truncate(k);
        cand.sort_unstable();
        out.extend(cand.iter().map(|&c| (c as u64) as usize));
    }

    /// Every point within squared distance `bound` of `q`, into `cand`
    /// (cells pruned as in [`Self::search`]).
    fn collect(
        &self,
        node: usize,
        q: &[f64],
        bound: f64,
        rd: f64,
        off: &mut [f64],
        cand: &mut Vec<u128>,
    ) {
        match self.nodes[node] {
            Node::Leaf { start, end } => {
                for &i in &self.order[start..end] {
                    let dist = Self::dist(&self.points[i * self.d..(i + 1) * self.d], q);
                    if dist <= bound {
                        cand.push(key(dist, i));
                    }
                }
            }
            Node::Split {
                dim,
                value,
                left,
                right,
            } => {
                let diff = q[dim] - value;
                let (near, far) = if diff < 0.0 {
                    (left, right)
                } else {
                    (right, left)
                };
                self.collect(near, q, bound, rd, off, cand);
                let old = off[dim];
                let far_rd = rd - old * old + diff * diff;
                if far_rd <= bound {
                    off[dim] = diff;
                    self.collect(far, q, bound, far_rd, off, cand);
                    off[dim] = old;
                }
            }
        }
    }

    /// Squared Euclidean distance (one formula for every caller, so a point
    /// offered twice gets the same bits).
    #[inline]
    fn dist(row: &[f64], q: &[f64]) -> f64 {
        row.iter().zip(q).map(|(a, b)| (a - b) * (a - b)).sum()
    }

    /// Descends near child first; `rd` is the squared distance from `q` to
    /// the node's cell and `off` its per-coordinate offsets (Arya and
    /// Mount's incremental distance), which prunes far cells tighter than
    /// the distance to the splitting plane alone.
    fn search(&self, node: usize, q: &[f64], best: &mut Best, rd: f64, off: &mut [f64]) {
        match self.nodes[node] {
            Node::Leaf { start, end } => {
                for &i in &self.order[start..end] {
                    let row = &self.points[i * self.d..(i + 1) * self.d];
                    best.offer(Candidate {
                        dist: Self::dist(row, q),
                        index: i,
                    });
                }
            }
            Node::Split {
                dim,
                value,
                left,
                right,
            } => {
                let diff = q[dim] - value;
                let (near, far) = if diff < 0.0 {
                    (left, right)
                } else {
                    (right, left)
                };
                self.search(near, q, best, rd, off);
                // Points equal to the split value may sit on either side.
                let old = off[dim];
                let far_rd = rd - old * old + diff * diff;
                if best.accepts(far_rd) {
                    off[dim] = diff;
                    self.search(far, q, best, far_rd, off);
                    off[dim] = old;
                }
            }
        }
    }
}

/// Reusable buffers of [`KdTree::nearest_seeded`].
#[derive(Debug, Clone, Default)]
pub struct Scratch {
    cand: Vec<u128>,
    off: Vec<f64>,
}

/// Sort key of a candidate: the bits of its squared distance (finite and
/// `>= +0`, so the bits order as the values, as `total_cmp` does), then its
/// index; one integer comparison orders as [`Candidate`] does.
#[inline]
fn key(dist: f64, index: usize) -> u128 {
    (u128::from(dist.to_bits()) << 64) | index as u128
}

/// The best `k` candidates so far: a sorted vector for small `k` (an
/// insertion moves at most `k` entries, cheaper than heap upkeep and the
/// final sort for small `k`), a max-heap for large `k`.
enum Best {
    Sorted(Vec<Candidate>, usize),
    Heap(BinaryHeap<Candidate>, usize),
}

impl Best {
    fn new(k: usize) -> Self {
        if k <= SORTED_MAX {
            Best::Sorted(Vec::with_capacity(k + 1), k)
        } else {
            Best::Heap(BinaryHeap::with_capacity(k + 1), k)
        }
    }

    /// Could a point at squared distance `bound` still enter?
    #[inline]
    fn accepts(&self, bound: f64) -> bool {
        match self {
            Best::Sorted(v, k) => v.len() < *k || bound <= v[k - 1].dist,
            Best::Heap(h, k) => h.len() < *k || bound <= h.peek().map_or(f64::INFINITY, |c| c.dist),
        }
    }

    #[inline]
    fn offer(&mut self, c: Candidate) {
        match self {
            Best::Sorted(v, k) => {
                if v.len() == *k {
                    if c >= v[*k - 1] {
                        return;
                    }
                    v.pop();
                }
                let pos = v.partition_point(|b| *b < c);
                v.insert(pos, c);
            }
            Best::Heap(h, k) => {
                if h.len() < *k {
                    h.push(c);
                } else if h.peek().is_some_and(|top| c < *top) {
                    h.pop();
                    h.push(c);
                }
            }
        }
    }

    fn into_sorted(self) -> Vec<Candidate> {
        match self {
            Best::Sorted(v, _) => v,
            Best::Heap(h, _) => h.into_sorted_vec(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute(points: &[f64], d: usize, q: &[f64], k: usize) -> Vec<usize> {
        let n = points.len() / d;
        let mut c: Vec<Candidate> = (0..n)
            .map(|i| Candidate {
                dist: points[i * d..(i + 1) * d]
                    .iter()
                    .zip(q)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum(),
                index: i,
            })
            .collect();
        c.sort();
        c.truncate(k);
        c.into_iter().map(|c| c.index).collect()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Seeds (any points, repeated or not) never change the answer.
        #[test]
        fn seeds_do_not_change_the_answer(d in 1usize..4, n in 1usize..200, k in 1usize..60, seed in any::<u64>()) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let pts: Vec<f64> = (0..n * d).map(|_| (rng.random_range(0..6) as f64) * 0.5).collect();
            let t = KdTree::new(&pts, d);
            let mut out = Vec::new();
            for i in 0..n.min(20) {
                let q = &pts[i * d..(i + 1) * d];
                let seeds: Vec<usize> = (0..rng.random_range(0..2 * k)).map(|_| rng.random_range(0..n)).collect();
                let mut scratch = Scratch::default();
                t.nearest_seeded(q, k, &seeds, &mut scratch, &mut out);
                prop_assert_eq!(&out, &brute(&pts, d, q, k));
            }
        }

        /// The tree returns exactly the brute-force neighbours, duplicates
        /// and ties included (coordinates on a coarse grid make many ties).
        #[test]
        fn matches_brute_force(d in 1usize..5, n in 1usize..300, k in 1usize..60, seed in any::<u64>()) {
            use rand::{Rng, SeedableRng};
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let pts: Vec<f64> = (0..n * d).map(|_| (rng.random_range(0..6) as f64) * 0.5).collect();
            let t = KdTree::new(&pts, d);
            let mut out = Vec::new();
            for i in 0..n.min(20) {
                let q = &pts[i * d..(i + 1) * d];
                t.nearest(q, k, &mut out);
                prop_assert_eq!(&out, &brute(&pts, d, q, k));
            }
        }
    }
}
