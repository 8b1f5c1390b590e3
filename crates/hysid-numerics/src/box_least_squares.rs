//! Linear least squares, unconstrained and in a box: `argmin |A x - b|^2`
//! over `lo <= x <= hi`, the subproblem of a Levenberg-Marquardt step whose
//! unknowns have bounds ([`crate::least_squares::Residuals`]).
//!
//! The box is solved by an active-set method in the manner of Stark and
//! Parker's bounded-variable least squares (*Computational Statistics*
//! 10, 1995, 129-141): from the unconstrained solution clipped into the
//! box, the coordinates it clipped held at their bounds, the free ones are
//! solved again with the held ones fixed; a solution that leaves the box is
//! followed only as far as the box allows, holding the coordinate that
//! stops it; a feasible one frees the held coordinate whose bound most
//! resists the descent (its multiplier of the wrong sign), until none
//! does. Where the unconstrained solution lies in the box it is the
//! answer, unchanged.

use nalgebra::{DMatrix, DVector};

/// `argmin |design x - rhs|^2` by Householder QR (`design` has full column
/// rank); `None` when its triangle is singular.
pub fn unconstrained(design: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Vec<f64>> {
    let qr = design.clone().qr();
    let x = qr.r().solve_upper_triangular(&(qr.q().transpose() * rhs))?;
    Some(x.iter().copied().collect())
}

/// Where a coordinate stands in the active set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Free,
    Lower,
    Upper,
}

/// The side of the box `[lo, hi]` that `v` lies beyond; `Free` inside it.
fn side_of(v: f64, [lo, hi]: [f64; 2]) -> Side {
    if v < lo {
        Side::Lower
    } else if v > hi {
        Side::Upper
    } else {
        Side::Free
    }
}

/// `argmin |design x - rhs|^2` over `bounds[j][0] <= x_j <= bounds[j][1]`
/// (`design` of full column rank, every `lo <= hi`; see the module doc).
/// `None` when a solve is singular. After `3 n + 3` active-set changes
/// (rounding can make a coordinate enter and leave) the feasible point
/// reached is returned.
pub fn in_box(design: &DMatrix<f64>, rhs: &DVector<f64>, bounds: &[[f64; 2]]) -> Option<Vec<f64>> {
    let n = design.ncols();
    let start = unconstrained(design, rhs)?;
    let mut side: Vec<Side> = start
        .iter()
        .zip(bounds)
        .map(|(&v, &bound)| side_of(v, bound))
        .collect();
    if side.iter().all(|s| *s == Side::Free) {
        return Some(start);
    }
    let mut x: Vec<f64> = start
        .iter()
        .zip(bounds)
        .map(|(v, [lo, hi])| v.clamp(*lo, *hi))
        .collect();
    for _ in 0..3 * n + 3 {
        let free: Vec<usize> = (0..n).filter(|&j| side[j] == Side::Free).collect();
        if !free.is_empty() {
            let z = solve_free(design, rhs, &free, &x)?;
            if let Some((j, s)) = advance_towards(&mut x, &free, &z, bounds) {
                side[j] = s;
                continue;
            }
        }
        match most_resisting(design, rhs, &x, &side) {
            Some(j) => side[j] = Side::Free,
            None => break,
        }
    }
    Some(x)
}

/// The least-squares values of the `free` coordinates with the others
/// held at their values in `x`.
fn solve_free(
    design: &DMatrix<f64>,
    rhs: &DVector<f64>,
    free: &[usize],
    x: &[f64],
) -> Option<Vec<f64>> {
    let mut target = rhs.clone();
    for (j, &v) in x.iter().enumerate() {
        if !free.contains(&j) && v != 0.0 {
            target.axpy(-v, &design.column(j), 1.0);
        }
    }
    unconstrained(&design.select_columns(free), &target)
}

/// Moves the `free` coordinates of `x` towards their solution `z` as far
/// as the box allows; the coordinate that stops the move short of `z`, put
/// onto its bound, and that bound's side.
fn advance_towards(
    x: &mut [f64],
    free: &[usize],
    z: &[f64],
    bounds: &[[f64; 2]],
) -> Option<(usize, Side)> {
    let mut alpha = 1.0;
    let mut stop = None;
    for (&j, &target) in free.iter().zip(z) {
        let [lo, hi] = bounds[j];
        let (bound, s) = match side_of(target, bounds[j]) {
            Side::Free => continue,
            Side::Lower => (lo, Side::Lower),
            Side::Upper => (hi, Side::Upper),
        };
        let t = (x[j] - bound) / (x[j] - target);
        if t < alpha {
            alpha = t;
            stop = Some((j, s, bound));
        }
    }
    for (&j, &target) in free.iter().zip(z) {
        x[j] += alpha * (target - x[j]);
        x[j] = x[j].clamp(bounds[j][0], bounds[j][1]);
    }
    let (j, s, bound) = stop?;
    x[j] = bound;
    Some((j, s))
}

/// The held coordinate whose bound most resists the descent: at its lower
/// bound with the cost decreasing upwards, or at its upper bound with it
/// decreasing downwards, by more than rounding (`w = design^T (rhs -
/// design x)`, minus half the gradient).
fn most_resisting(
    design: &DMatrix<f64>,
    rhs: &DVector<f64>,
    x: &[f64],
    side: &[Side],
) -> Option<usize> {
    let residual = rhs - design * DVector::from_column_slice(x);
    let w = design.transpose() * &residual;
    let tolerance = 1e-12 * design.norm() * (residual.norm() + rhs.norm());
    (0..x.len())
        .filter_map(|j| {
            let pull = match side[j] {
                Side::Free => return None,
                Side::Lower => w[j],
                Side::Upper => -w[j],
            };
            (pull > tolerance).then_some((j, pull))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(j, _)| j)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn cost(a: &DMatrix<f64>, b: &DVector<f64>, x: &[f64]) -> f64 {
        (a * DVector::from_column_slice(x) - b).norm_squared()
    }

    /// The least cost over every pattern of coordinates held at a bound
    /// or left free whose solution stays in the box: the box's minimum,
    /// since the minimiser has one such pattern.
    fn by_every_pattern(a: &DMatrix<f64>, b: &DVector<f64>, bounds: &[[f64; 2]]) -> f64 {
        let n = a.ncols();
        let mut best = f64::INFINITY;
        for code in 0..3usize.pow(n as u32) {
            let mut x = vec![0.0; n];
            let mut free = Vec::new();
            let mut c = code;
            for j in 0..n {
                match c % 3 {
                    0 => free.push(j),
                    1 => x[j] = bounds[j][0],
                    _ => x[j] = bounds[j][1],
                }
                c /= 3;
            }
            if !free.is_empty() {
                let z = solve_free(a, b, &free, &x).unwrap();
                for (&j, v) in free.iter().zip(z) {
                    x[j] = v;
                }
            }
            if x.iter().zip(bounds).all(|(v, [lo, hi])| lo <= v && v <= hi) {
                best = best.min(cost(a, b, &x));
            }
        }
        best
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// On random problems of 1-5 unknowns with random boxes, the
        /// result lies in the box and its cost is the least of every
        /// pattern of held and free coordinates.
        #[test]
        fn the_box_solution_is_the_least_of_every_pattern(
            n in 1usize..=5,
            entries in proptest::collection::vec(-1.0f64..1.0, 40),
            rhs in proptest::collection::vec(-3.0f64..3.0, 8),
            corners in proptest::collection::vec((-1.0f64..1.0, 0.0f64..1.5), 5),
        ) {
            let m = n + 3;
            let a = DMatrix::from_fn(m, n, |i, j| entries[i * 5 + j] + if i == j { 1.5 } else { 0.0 });
            let b = DVector::from_column_slice(&rhs[..m]);
            let bounds: Vec<[f64; 2]> = corners[..n].iter().map(|&(lo, w)| [lo, lo + w]).collect();
            let x = in_box(&a, &b, &bounds).unwrap();
            for (v, [lo, hi]) in x.iter().zip(&bounds) {
                prop_assert!(lo <= v && v <= hi, "{} outside [{}, {}]", v, lo, hi);
            }
            let best = by_every_pattern(&a, &b, &bounds);
            let got = cost(&a, &b, &x);
            prop_assert!(got <= best * (1.0 + 1e-9) + 1e-12, "{} against {}", got, best);
        }
    }

    /// Inside the box the unconstrained solution comes back bit for bit;
    /// a box that cuts it off gives a lower cost than clipping it.
    #[test]
    fn inside_the_box_nothing_changes_and_outside_clipping_is_beaten() {
        let a = DMatrix::from_row_slice(3, 2, &[1.0, 0.9, 0.0, 1.0, 0.5, 0.2]);
        let b = DVector::from_column_slice(&[2.0, -1.0, 0.5]);
        let free = unconstrained(&a, &b).unwrap();
        let wide = [[-10.0, 10.0], [-10.0, 10.0]];
        assert_eq!(in_box(&a, &b, &wide).unwrap(), free);
        // The second coordinate wants to be negative; hold it at 0.
        assert!(free[1] < 0.0);
        let cut = [[-10.0, 10.0], [0.0, 10.0]];
        let x = in_box(&a, &b, &cut).unwrap();
        let clipped = [free[0], 0.0];
        assert_eq!(x[1], 0.0);
        assert!(cost(&a, &b, &x) < cost(&a, &b, &clipped));
    }
}
