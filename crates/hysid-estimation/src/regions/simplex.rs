//! An exact solver of the MRLP restricted to a working set: the bounded-
//! variable primal simplex method (Dantzig; bounded variables after
//! Dantzig 1955 and Wagner 1958) applied to the LP dual of the MRLP.
//!
//! The MRLP (see [`crate::regions::working_set`]) is, with `u` the free score
//! parameters (the last mode's are fixed at 0, so `u` has
//! `k = (modes - 1)(p + 1)` entries) and one *term* `t = (r, j)` per point
//! `r` and other mode `j != y_r`,
//!
//! ```text
//! min_u  sum_t c_t max(0, 1 - a_t . u),   a_t . u = f_{y_r}(z_r) - f_j(z_r).
//! ```
//!
//! Its LP dual has only `k` equality rows:
//!
//! ```text
//! max_lambda  sum_t lambda_t   s.t.  sum_t lambda_t a_t = 0,  0 <= lambda_t <= c_t,
//! ```
//!
//! so a simplex basis is a `k x k` matrix (refactorised from scratch at every
//! pivot: no accumulated update error), `lambda = 0` is a feasible start, and
//! the simplex multipliers are the primal `u`: the reduced cost of term `t` is
//! `a_t . u - 1` (its margin minus one). The method stops when every term at
//! 0 has margin `>= 1`, every term at its bound `c_t` has margin `<= 1` and
//! every basic term has margin exactly 1: the optimality conditions of the
//! MRLP, so `u` is an optimum of the same LP that clarabel solves.
//!
//! Rank deficiency (e.g. a constant regressor column) is handled by `k`
//! artificial variables fixed at 0 that form the first basis; an
//! artificial still basic at the end sets its direction of `u` to 0.
//! Dantzig's rule over a cyclic window of the rows (partial pricing)
//! picks the entering term; after a run of degenerate
//! pivots Bland's rule (smallest index) takes over, which cannot cycle
//! (Bland, Math. Oper. Res. 2(2), 1977). Pivots are bounded; past the bound
//! the caller falls back to clarabel.
//!
//! Warm start: terms added to the working set enter at `lambda_t = 0`,
//! which keeps the current basis feasible, so each working-set round
//! continues from the previous optimum.
//!
//! A simplex returns a vertex of the optimal face, an interior-point solver
//! a point inside it. They coincide when the optimum is unique, which
//! [`Simplex::unique`] certifies; otherwise (e.g. separable modes, whose
//! zero-loss face is large) the caller keeps clarabel's solution, whose
//! boundaries sit inside the gaps between modes.

use crate::regions::problem::Prepared;

/// A margin within this of 1 counts as 1 (reduced-cost tolerance).
const REDUCED_TOL: f64 = 1e-9;
/// Smallest `|pivot|` accepted in the ratio test, relative to the largest
/// entry of the direction.
const PIVOT_TOL: f64 = 1e-9;
/// A basic dual value within this fraction of its bound counts as at the
/// bound in [`Simplex::unique`].
const UNIQUE_TOL: f64 = 1e-9;
/// Rows priced per pivot at least (partial pricing).
const PRICING_CHUNK: usize = 512;
/// Consecutive degenerate pivots before Bland's rule takes over.
const DEGENERATE_RUN: usize = 50;

/// Why the simplex gave up (the caller then uses clarabel).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum SimplexFailure {
    /// The pivot bound was reached.
    PivotLimit,
    /// The basis became numerically singular.
    Singular,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Var {
    /// Artificial `i`, fixed at 0.
    Art(usize),
    /// Term `t = r (modes - 1) + jj` (`jj`: index among the other modes).
    Term(usize),
}

const LOWER: u8 = 0;
const UPPER: u8 = 1;
const BASIC: u8 = 2;

/// Simplex state over all terms of a problem (only the terms of rows in
/// the working set are ever priced).
pub(crate) struct Simplex<'a> {
    prep: &'a Prepared,
    labels: &'a [usize],
    weight: &'a [f64],
    modes: usize,
    k: usize,
    basis: Vec<Var>,
    status: Vec<u8>,
    /// `sum_{t at upper} c_t a_t`.
    upper_sum: Vec<f64>,
    /// Current primal `u` (simplex multipliers).
    u: Vec<f64>,
    /// Pivots and bound flips done.
    pub(crate) pivots: u64,
    bland: bool,
    degenerate: usize,
    /// Where the last partial pricing scan stopped (index into the set).
    cursor: usize,
    // scratch
    lu: Vec<f64>,
    perm: Vec<usize>,
    col: Vec<f64>,
    xb: Vec<f64>,
    f: Vec<f64>,
}

impl<'a> Simplex<'a> {
    /// All terms at 0, the artificials basic.
    pub(crate) fn new(
        prep: &'a Prepared,
        labels: &'a [usize],
        weight: &'a [f64],
        modes: usize,
    ) -> Self {
        let k = (modes - 1) * (prep.p + 1);
        Simplex {
            prep,
            labels,
            weight,
            modes,
            k,
            basis: (0..k).map(Var::Art).collect(),
            status: vec![LOWER; prep.n * (modes - 1)],
            upper_sum: vec![0.0; k],
            u: vec![0.0; k],
            pivots: 0,
            bland: false,
            degenerate: 0,
            cursor: 0,
            lu: vec![0.0; k * k],
            perm: vec![0; k],
            col: vec![0.0; k],
            xb: vec![0.0; k],
            f: vec![0.0; modes],
        }
    }

    /// The other mode of term `t` and its row.
    fn term(&self, t: usize) -> (usize, usize) {
        let m1 = self.modes - 1;
        let (r, jj) = (t / m1, t % m1);
        let y = self.labels[r];
        (r, if jj < y { jj } else { jj + 1 })
    }

    /// Writes `s a_t` into `out` (adds when `add`).
    fn column(&self, t: usize, s: f64, out: &mut [f64], add: bool) {
        let b = self.prep.p + 1;
        let (r, j) = self.term(t);
        let y = self.labels[r];
        let z = self.prep.row(r);
        if !add {
            out.iter_mut().for_each(|v| *v = 0.0);
        }
        for (blk, sign) in [(y, s), (j, -s)] {
            if blk < self.modes - 1 {
                let o = &mut out[blk * b..(blk + 1) * b];
                for (ov, zv) in o.iter_mut().zip(z) {
                    *ov += sign * zv;
                }
                o[b - 1] -= sign;
            }
        }
    }

    /// Upper bound `c_t` of term `t`.
    fn cap(&self, t: usize) -> f64 {
        self.weight[self.labels[t / (self.modes - 1)]]
    }

    /// LU factorisation with partial pivoting of the basis matrix (column
    /// `i` is the `i`-th basic variable's column); false if singular.
    fn factor(&mut self) -> bool {
        let k = self.k;
        let mut lu = std::mem::take(&mut self.lu);
        let mut col = std::mem::take(&mut self.col);
        for (i, v) in self.basis.clone().into_iter().enumerate() {
            match v {
                Var::Art(a) => {
                    col.iter_mut().for_each(|c| *c = 0.0);
                    col[a] = 1.0;
                }
                Var::Term(t) => self.column(t, 1.0, &mut col, false),
            }
            for r in 0..k {
                lu[r * k + i] = col[r];
            }
        }
        self.col = col;
        let scale = lu.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1.0);
        for (i, p) in self.perm.iter_mut().enumerate() {
            *p = i;
        }
        for c in 0..k {
            let (mut best, mut piv) = (0.0, c);
            for r in c..k {
                let v = lu[r * k + c].abs();
                if v > best {
                    best = v;
                    piv = r;
                }
            }
            if best <= 1e-13 * scale {
                self.lu = lu;
                return false;
            }
            if piv != c {
                for q in 0..k {
                    lu.swap(c * k + q, piv * k + q);
                }
                self.perm.swap(c, piv);
            }
            let d = lu[c * k + c];
            for r in c + 1..k {
                let m = lu[r * k + c] / d;
                lu[r * k + c] = m;
                if m != 0.0 {
                    for q in c + 1..k {
                        lu[r * k + q] -= m * lu[c * k + q];
                    }
                }
            }
        }
        self.lu = lu;
        true
    }

    /// Solves `B x = b` in place.
    fn solve(&self, b: &mut [f64]) {
        let k = self.k;
        let lu = &self.lu;
        let pb: Vec<f64> = self.perm.iter().map(|&i| b[i]).collect();
        b.copy_from_slice(&pb);
        for r in 0..k {
            let mut s = b[r];
            for q in 0..r {
                s -= lu[r * k + q] * b[q];
            }
            b[r] = s;
        }
        for r in (0..k).rev() {
            let mut s = b[r];
            for q in r + 1..k {
                s -= lu[r * k + q] * b[q];
            }
            b[r] = s / lu[r * k + r];
        }
    }

    /// Solves `B' x = b` in place.
    fn solve_transposed(&self, b: &mut [f64]) {
        let k = self.k;
        let lu = &self.lu;
        // B = P' L U, so B' x = b is U' L' (P x) = b.
        for r in 0..k {
            let mut s = b[r];
            for q in 0..r {
                s -= lu[q * k + r] * b[q];
            }
            b[r] = s / lu[r * k + r];
        }
        for r in (0..k).rev() {
            let mut s = b[r];
            for q in r + 1..k {
                s -= lu[q * k + r] * b[q];
            }
            b[r] = s;
        }
        let mut x = vec![0.0; k];
        for (i, &p) in self.perm.iter().enumerate() {
            x[p] = b[i];
        }
        b.copy_from_slice(&x);
    }

    /// Margins `a_t . u` of the terms of row `r`, into `self.f` as scores.
    /// The pricing's inner loop: for the usual few regressor columns the
    /// sums are unrolled at compile time, in the same order.
    fn scores(&mut self, r: usize) {
        let z = self.prep.row(r);
        let f = &mut self.f[..self.modes - 1];
        match z.len() {
            1 => mode_scores::<1>(z, &self.u, f),
            2 => mode_scores::<2>(z, &self.u, f),
            3 => mode_scores::<3>(z, &self.u, f),
            4 => mode_scores::<4>(z, &self.u, f),
            5 => mode_scores::<5>(z, &self.u, f),
            6 => mode_scores::<6>(z, &self.u, f),
            _ => {
                for (fi, v) in f.iter_mut().zip(self.u.chunks_exact(z.len() + 1)) {
                    *fi = score(z, v);
                }
            }
        }
        self.f[self.modes - 1] = 0.0;
    }

    /// The current primal solution as per-mode `[w; g]` blocks.
    pub(crate) fn blocks(&self) -> Vec<Vec<f64>> {
        let b = self.prep.p + 1;
        let mut out: Vec<Vec<f64>> = self.u.chunks(b).map(<[f64]>::to_vec).collect();
        out.push(vec![0.0; b]);
        out
    }

    /// Runs the simplex over the terms of the rows `set` until optimal
    /// there, with at most `max_pivots` pivots in total.
    ///
    /// A numerical kernel kept in one piece: pricing, the ratio test and the
    /// pivot update act on one factorised basis and read as one simplex
    /// iteration.
    pub(crate) fn optimise(
        &mut self,
        set: &[usize],
        max_pivots: u64,
    ) -> Result<(), SimplexFailure> {
        let k = self.k;
        let m1 = self.modes - 1;
        loop {
            if !self.factor() {
                return Err(SimplexFailure::Singular);
            }
            // u: B' u = 1 on basic terms, 0 on artificials.
            let mut u: Vec<f64> = self
                .basis
                .iter()
                .map(|v| if matches!(v, Var::Term(_)) { 1.0 } else { 0.0 })
                .collect();
            self.solve_transposed(&mut u);
            self.u = u;
            // Pricing: partial (Dantzig's rule over at least PRICING_CHUNK
            // rows from where the last scan stopped, continuing until a
            // candidate is found); optimality is only declared after a scan
            // of every row found none. Bland's rule scans from the first row.
            let mut enter: Option<(usize, f64)> = None;
            let len = set.len();
            let mut pos = if self.bland || len == 0 {
                0
            } else {
                self.cursor % len
            };
            let mut scanned = 0;
            'rows: while scanned < len {
                let r = set[pos];
                scanned += 1;
                pos = if pos + 1 == len { 0 } else { pos + 1 };
                self.scores(r);
                let y = self.labels[r];
                for jj in 0..m1 {
                    let t = r * m1 + jj;
                    let st = self.status[t];
                    if st == BASIC {
                        continue;
                    }
                    let j = if jj < y { jj } else { jj + 1 };
                    let m = self.f[y] - self.f[j];
                    let viol = if st == LOWER { 1.0 - m } else { m - 1.0 };
                    if viol > REDUCED_TOL && enter.is_none_or(|(_, v)| viol > v) {
                        enter = Some((t, viol));
                        if self.bland {
                            break 'rows;
                        }
                    }
                }
                if enter.is_some() && scanned >= PRICING_CHUNK {
                    break;
                }
            }
            self.cursor = pos;
            let Some((q, _)) = enter else {
                return Ok(());
            };
            if self.pivots >= max_pivots {
                return Err(SimplexFailure::PivotLimit);
            }
            self.pivots += 1;
            // Basic values: B x_B = -upper_sum.
            let mut xb: Vec<f64> = self.upper_sum.iter().map(|v| -v).collect();
            self.solve(&mut xb);
            self.xb.copy_from_slice(&xb);
            let sigma = if self.status[q] == LOWER { 1.0 } else { -1.0 };
            let mut delta = vec![0.0; k];
            self.column(q, sigma, &mut delta, false);
            self.solve(&mut delta);
            let dmax = delta.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let tol = PIVOT_TOL * dmax.max(1.0);
            let cap_q = self.cap(q);
            let mut theta = cap_q;
            let mut leave: Option<usize> = None;
            for i in 0..k {
                let d = delta[i];
                if d.abs() <= tol {
                    continue;
                }
                let (lo, hi) = match self.basis[i] {
                    Var::Art(_) => (0.0, 0.0),
                    Var::Term(t) => (0.0, self.cap(t)),
                };
                let x = self.xb[i];
                let th = if d > 0.0 { (x - lo) / d } else { (hi - x) / -d }.max(0.0);
                let better = match leave {
                    None => th < theta,
                    Some(l) => {
                        th < theta
                            || (th == theta
                                && if self.bland {
                                    self.var_index(self.basis[i]) < self.var_index(self.basis[l])
                                } else {
                                    d.abs() > delta[l].abs()
                                })
                    }
                };
                if better {
                    theta = th;
                    leave = Some(i);
                }
            }
            if theta <= 1e-12 {
                self.degenerate += 1;
                if self.degenerate > DEGENERATE_RUN {
                    self.bland = true;
                }
            } else {
                self.degenerate = 0;
            }
            let mut col = vec![0.0; k];
            match leave {
                None => {
                    // Bound flip of the entering term.
                    let sign = if self.status[q] == LOWER { 1.0 } else { -1.0 };
                    self.column(q, sign * cap_q, &mut col, false);
                    for (a, b) in self.upper_sum.iter_mut().zip(&col) {
                        *a += b;
                    }
                    self.status[q] = if self.status[q] == LOWER {
                        UPPER
                    } else {
                        LOWER
                    };
                }
                Some(i) => {
                    if self.status[q] == UPPER {
                        self.column(q, -cap_q, &mut col, false);
                        for (a, b) in self.upper_sum.iter_mut().zip(&col) {
                            *a += b;
                        }
                    }
                    if let Var::Term(t) = self.basis[i] {
                        if delta[i] > 0.0 {
                            self.status[t] = LOWER;
                        } else {
                            self.status[t] = UPPER;
                            let c = self.cap(t);
                            self.column(t, c, &mut col, false);
                            for (a, b) in self.upper_sum.iter_mut().zip(&col) {
                                *a += b;
                            }
                        }
                    }
                    self.status[q] = BASIC;
                    self.basis[i] = Var::Term(q);
                }
            }
            if self.pivots.is_multiple_of(64) {
                self.recompute_upper_sum(set);
            }
        }
    }

    /// Whether the current optimum `u` is the only optimum: every basic
    /// variable is a term strictly between its bounds (a non-degenerate
    /// dual solution). Complementary slackness then forces `a_t . u = 1`
    /// for the `k` basic terms, `k` independent equations, on every primal
    /// optimum. Degenerate cases (separable modes, where the whole optimal
    /// face has zero loss, or rank-deficient data) return false.
    pub(crate) fn unique(&mut self) -> bool {
        if !self.factor() {
            return false;
        }
        let mut xb: Vec<f64> = self.upper_sum.iter().map(|v| -v).collect();
        self.solve(&mut xb);
        self.basis.iter().zip(&xb).all(|(v, &x)| match *v {
            Var::Art(_) => false,
            Var::Term(t) => {
                let c = self.cap(t);
                x > UNIQUE_TOL * c && x < (1.0 - UNIQUE_TOL) * c
            }
        })
    }

    /// Order for Bland's rule: artificials first, then terms by index.
    fn var_index(&self, v: Var) -> usize {
        match v {
            Var::Art(a) => a,
            Var::Term(t) => self.k + t,
        }
    }

    /// `upper_sum` from scratch (removes drift of the incremental updates);
    /// only terms of the rows `set` can be away from 0.
    fn recompute_upper_sum(&mut self, set: &[usize]) {
        let m1 = self.modes - 1;
        let mut sum = vec![0.0; self.k];
        for &r in set {
            for t in r * m1..(r + 1) * m1 {
                if self.status[t] == UPPER {
                    let c = self.cap(t);
                    self.column(t, c, &mut sum, true);
                }
            }
        }
        self.upper_sum = sum;
    }
}

/// `w . z - g` for the scores `v = [w; g]`.
fn score(z: &[f64], v: &[f64]) -> f64 {
    z.iter().zip(v).map(|(a, c)| a * c).sum::<f64>() - v[z.len()]
}

/// [`score`] of every block of `u` into `f`, for `P` columns.
fn mode_scores<const P: usize>(z: &[f64], u: &[f64], f: &mut [f64]) {
    let z = &z[..P];
    for (fi, v) in f.iter_mut().zip(u.chunks_exact(P + 1)) {
        *fi = score(z, &v[..P + 1]);
    }
}
