//! Polyhedra `{ z : A z <= b, A_eq z = b_eq }`: the regions of PWARX modes,
//! the invariants of hybrid-automaton modes and their guard sets. Equality
//! rows make a set lower-dimensional (for example the stop `y = 25`).

use serde::{Deserialize, Serialize};

/// Tolerance used for membership tests of equality rows and boundaries.
pub const MEMBERSHIP_TOL: f64 = 1e-9;

/// `{ z : a z <= b, a_eq z = b_eq }`, rows stored row-major. No rows means
/// the whole space.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Polyhedron {
    /// Inequality rows.
    #[serde(default)]
    pub a: Vec<Vec<f64>>,
    /// Inequality right-hand sides.
    #[serde(default)]
    pub b: Vec<f64>,
    /// Equality rows (a lower-dimensional set when non-empty).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub a_eq: Vec<Vec<f64>>,
    /// Equality right-hand sides.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub b_eq: Vec<f64>,
}

/// The violation up to which `z` belongs to a set
/// ([`Polyhedron::contains`]): [`MEMBERSHIP_TOL`] times `1 + max |z_i|`.
pub fn membership_tolerance(z: &[f64]) -> f64 {
    let scale = 1.0 + z.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    MEMBERSHIP_TOL * scale
}

fn dot(a: &[f64], z: &[f64]) -> f64 {
    a.iter().zip(z).map(|(p, q)| p * q).sum()
}

fn norm(a: &[f64]) -> f64 {
    a.iter()
        .map(|v| v * v)
        .sum::<f64>()
        .sqrt()
        .max(f64::MIN_POSITIVE)
}

/// A malformed [`Polyhedron`] ([`Polyhedron::validate`]); rows count from
/// 1, the inequality rows first.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PolyhedronError {
    /// `a` and `b` (or `a_eq` and `b_eq`) of different lengths.
    #[error("a and b have different numbers of rows")]
    RowCount,
    /// A row of the wrong length.
    #[error("row {row} has {len} entries, expected {dim}")]
    RowLength {
        /// Row number.
        row: usize,
        /// Its entries.
        len: usize,
        /// The dimension.
        dim: usize,
    },
    /// A row with NaN or an infinity.
    #[error("row {row} has a non-finite entry")]
    NonFiniteRow {
        /// Row number.
        row: usize,
    },
    /// A right-hand side with NaN or an infinity.
    #[error("a right-hand side is not finite")]
    NonFiniteRhs,
}

impl Polyhedron {
    /// The whole space.
    pub fn everything() -> Self {
        Self::default()
    }

    /// The half-spaces `a z <= b`.
    pub fn from_inequalities(a: Vec<Vec<f64>>, b: Vec<f64>) -> Self {
        Self {
            a,
            b,
            ..Self::default()
        }
    }

    /// True when it has equality rows (it then has no volume).
    pub fn is_lower_dimensional(&self) -> bool {
        !self.a_eq.is_empty()
    }

    /// Checks that every row has `dim` entries and all numbers are finite.
    pub fn validate(&self, dim: usize) -> Result<(), PolyhedronError> {
        if self.a.len() != self.b.len() || self.a_eq.len() != self.b_eq.len() {
            return Err(PolyhedronError::RowCount);
        }
        for (i, row) in self.a.iter().chain(&self.a_eq).enumerate() {
            if row.len() != dim {
                return Err(PolyhedronError::RowLength {
                    row: i + 1,
                    len: row.len(),
                    dim,
                });
            }
            if row.iter().any(|v| !v.is_finite()) {
                return Err(PolyhedronError::NonFiniteRow { row: i + 1 });
            }
        }
        if self.b.iter().chain(&self.b_eq).any(|v| !v.is_finite()) {
            return Err(PolyhedronError::NonFiniteRhs);
        }
        Ok(())
    }

    /// Largest Euclidean distance by which `z` violates a row (0 inside).
    /// Inequality rows count `(a_i z - b_i)+ / |a_i|`, equality rows
    /// `|a_i z - b_i| / |a_i|`.
    pub fn violation(&self, z: &[f64]) -> f64 {
        let ineq = self
            .a
            .iter()
            .zip(&self.b)
            .map(|(r, b)| ((dot(r, z) - b) / norm(r)).max(0.0));
        let eq = self
            .a_eq
            .iter()
            .zip(&self.b_eq)
            .map(|(r, b)| ((dot(r, z) - b) / norm(r)).abs());
        ineq.chain(eq).fold(0.0, f64::max)
    }

    /// Membership with tolerance [`MEMBERSHIP_TOL`] (relative to |z|).
    pub fn contains(&self, z: &[f64]) -> bool {
        self.violation(z) <= membership_tolerance(z)
    }

    /// The first point of the segment `z0 -> z1` that lies in the set, as the
    /// fraction `s` in `[0, 1]`, or `None`. The set is convex and the segment
    /// affine in `s`, so every row is a linear condition in `s` and the
    /// answer is exact: it is how guard crossings are located within a step.
    pub fn first_hit_on_segment(&self, z0: &[f64], z1: &[f64]) -> Option<f64> {
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        let scale = 1.0 + z0.iter().chain(z1).fold(0.0f64, |m, v| m.max(v.abs()));
        let tol = MEMBERSHIP_TOL * scale;
        // Rows as  alpha + beta * s  <= 0  (inequalities), = 0 (equalities).
        for (r, b) in self.a.iter().zip(&self.b) {
            let n = norm(r);
            let alpha = (dot(r, z0) - b) / n - tol;
            let beta = (dot(r, z1) - dot(r, z0)) / n;
            if beta.abs() < f64::EPSILON * (1.0 + alpha.abs()) {
                if alpha > 0.0 {
                    return None;
                }
            } else if beta > 0.0 {
                hi = hi.min(-alpha / beta);
            } else {
                lo = lo.max(-alpha / beta);
            }
        }
        for (r, b) in self.a_eq.iter().zip(&self.b_eq) {
            let n = norm(r);
            let alpha = (dot(r, z0) - b) / n;
            let beta = (dot(r, z1) - dot(r, z0)) / n;
            if beta.abs() <= tol {
                if alpha.abs() > tol {
                    return None;
                }
            } else {
                let s = -alpha / beta;
                let ds = tol / beta.abs();
                lo = lo.max(s - ds);
                hi = hi.min(s + ds);
            }
        }
        (lo <= hi).then_some(lo)
    }

    /// The set in new coordinates `z = m + D w` (`D` diagonal, entries `d`):
    /// `{ w : (A D) w <= b - A m }`. Used to express regions found on
    /// standardised data in original units (with `w` the original
    /// coordinates, pass the inverse map).
    pub fn affine_preimage(&self, m: &[f64], d: &[f64]) -> Self {
        let map = |rows: &[Vec<f64>], rhs: &[f64]| -> (Vec<Vec<f64>>, Vec<f64>) {
            rows.iter()
                .zip(rhs)
                .map(|(r, b)| {
                    let nr: Vec<f64> = r.iter().zip(d).map(|(a, di)| a * di).collect();
                    (nr, b - dot(r, m))
                })
                .unzip()
        };
        let (a, b) = map(&self.a, &self.b);
        let (a_eq, b_eq) = map(&self.a_eq, &self.b_eq);
        Self { a, b, a_eq, b_eq }
    }
}

/// The argmax partition of affine scores `f_i = c_i . x + c_i0` (rows
/// `[c_i; c_i0]`): region `i` is `{x : f_i(x) >= f_j(x) for all j != i}`,
/// one row `(c_j - c_i) x <= c_i0 - c_j0` per other mode `j`, in mode order.
/// The rows of `i` against `j` and of `j` against `i` are exact negatives
/// of each other in floating point. The regions cover the space.
pub fn argmax_regions(scores: &[Vec<f64>]) -> Vec<Polyhedron> {
    let s = scores.len();
    (0..s)
        .map(|i| {
            let d = scores[i].len().saturating_sub(1);
            let mut a = Vec::with_capacity(s.saturating_sub(1));
            let mut b = Vec::with_capacity(s.saturating_sub(1));
            for j in (0..s).filter(|&j| j != i) {
                a.push((0..d).map(|k| scores[j][k] - scores[i][k]).collect());
                b.push(scores[i][d] - scores[j][d]);
            }
            Polyhedron::from_inequalities(a, b)
        })
        .collect()
}

/// Affine scores whose [`argmax_regions`] are `regions` (in `dim`
/// coordinates), mode 0's scores zero, when `regions` have that layout:
/// two or more regions of inequality rows only, region `i`'s row for mode
/// `j` at position `j` (`j < i`) or `j - 1`, each the difference of two
/// scores to a relative `1e-9`. `None` for any other partition.
pub fn argmax_scores(regions: &[Polyhedron], dim: usize) -> Option<Vec<Vec<f64>>> {
    let s = regions.len();
    let layout = |r: &Polyhedron| {
        r.a_eq.is_empty()
            && r.a.len() == s - 1
            && r.b.len() == s - 1
            && r.a.iter().all(|row| row.len() == dim)
    };
    if s < 2 || !regions.iter().all(layout) {
        return None;
    }
    let mut scores = vec![vec![0.0; dim + 1]];
    for (row, b) in regions[0].a.iter().zip(&regions[0].b) {
        let mut c = row.clone();
        c.push(-b);
        scores.push(c);
    }
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-9 * (1.0 + x.abs().max(y.abs()));
    let rebuilt = argmax_regions(&scores);
    let agrees = regions.iter().zip(&rebuilt).all(|(r, q)| {
        let rows = r.a.iter().flatten().zip(q.a.iter().flatten());
        rows.chain(r.b.iter().zip(&q.b)).all(|(x, y)| close(*x, *y))
    });
    agrees.then_some(scores)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn unit_box() -> Polyhedron {
        Polyhedron::from_inequalities(
            vec![
                vec![1.0, 0.0],
                vec![-1.0, 0.0],
                vec![0.0, 1.0],
                vec![0.0, -1.0],
            ],
            vec![1.0, 0.0, 1.0, 0.0],
        )
    }

    #[test]
    fn membership_and_violation() {
        let p = unit_box();
        assert!(p.contains(&[0.5, 0.5]));
        assert!(p.contains(&[1.0, 0.0]));
        assert!(!p.contains(&[1.5, 0.5]));
        assert!((p.violation(&[3.0, 0.5]) - 2.0).abs() < 1e-12);
        assert!(Polyhedron::everything().contains(&[1e9, -3.0]));
    }

    #[test]
    fn segment_hits_lower_dimensional_guard() {
        // y = 25 with v >= 0, z = [y, v]
        let g = Polyhedron {
            a: vec![vec![0.0, -1.0]],
            b: vec![0.0],
            a_eq: vec![vec![1.0, 0.0]],
            b_eq: vec![25.0],
        };
        let s = g.first_hit_on_segment(&[20.0, 2.0], &[30.0, 2.0]).unwrap();
        assert!((s - 0.5).abs() < 1e-6);
        assert!(g.first_hit_on_segment(&[20.0, 2.0], &[24.0, 2.0]).is_none());
        assert!(
            g.first_hit_on_segment(&[20.0, -2.0], &[30.0, -2.0])
                .is_none()
        );
    }

    proptest! {
        #[test]
        fn segment_hit_point_is_in_the_set(x0 in -3.0f64..3.0, y0 in -3.0f64..3.0, x1 in -3.0f64..3.0, y1 in -3.0f64..3.0) {
            let p = unit_box();
            let (z0, z1) = ([x0, y0], [x1, y1]);
            match p.first_hit_on_segment(&z0, &z1) {
                Some(s) => {
                    let z = [x0 + s * (x1 - x0), y0 + s * (y1 - y0)];
                    prop_assert!(p.violation(&z) < 1e-6);
                }
                None => {
                    for i in 1..=50 {
                        let s = i as f64 / 50.0;
                        let z = [x0 + s * (x1 - x0), y0 + s * (y1 - y0)];
                        prop_assert!(p.violation(&z) > 0.0);
                    }
                }
            }
        }

        #[test]
        fn affine_preimage_preserves_membership(m0 in -2.0f64..2.0, d0 in 0.1f64..3.0, w0 in -2.0f64..2.0, w1 in -2.0f64..2.0) {
            let p = unit_box();
            let (m, d) = ([m0, -m0], [d0, 1.0 / d0]);
            let q = p.affine_preimage(&m, &d);
            let z = [m[0] + d[0] * w0, m[1] + d[1] * w1];
            // Inside and outside alike; only points within rounding of the
            // threshold may fall on either side of it.
            let v = p.violation(&z);
            prop_assert!((v > 1e-9) == (q.violation(&[w0, w1]) > 1e-9) || (1e-10..1e-8).contains(&v));
        }
    }
}
