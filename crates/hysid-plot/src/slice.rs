//! Two-dimensional slices of polyhedra, for drawing the regions of a PWARX
//! model in a plane of two regressor coordinates.
//!
//! The plane is `z = z0 + u e_i + v e_j`: coordinates `i` and `j` vary, every
//! other coordinate is held at its value in `z0` (for example its mean over
//! the data). A row `a z <= b` becomes the half-plane
//! `a_i u + a_j v <= b - sum_{k != i, j} a_k z0_k`; the slice inside a
//! bounding box is then the box clipped by every half-plane
//! (Sutherland–Hodgman), which is exact for convex sets. Equality rows make a
//! line or a point, so a lower-dimensional set is returned as a segment or a
//! point rather than a polygon.

use hysid_model::geometry::Polyhedron;

/// A plotting window `[x_min, x_max] x [y_min, y_max]` in the two chosen
/// coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Smallest value of the horizontal coordinate.
    pub x_min: f64,
    /// Largest value of the horizontal coordinate.
    pub x_max: f64,
    /// Smallest value of the vertical coordinate.
    pub y_min: f64,
    /// Largest value of the vertical coordinate.
    pub y_max: f64,
}

impl Bounds {
    /// True when all four numbers are finite and the box has positive width
    /// and height.
    pub fn is_valid(&self) -> bool {
        [self.x_min, self.x_max, self.y_min, self.y_max]
            .iter()
            .all(|v| v.is_finite())
            && self.x_max > self.x_min
            && self.y_max > self.y_min
    }

    /// Length scale of the box (its larger side), used for tolerances.
    pub fn scale(&self) -> f64 {
        (self.x_max - self.x_min).max(self.y_max - self.y_min)
    }

    /// The four corners, counter-clockwise from `(x_min, y_min)`.
    pub fn corners(&self) -> Vec<[f64; 2]> {
        vec![
            [self.x_min, self.y_min],
            [self.x_max, self.y_min],
            [self.x_max, self.y_max],
            [self.x_min, self.y_max],
        ]
    }

    fn half_planes(&self) -> [HalfPlane; 4] {
        [
            HalfPlane::new(-1.0, 0.0, -self.x_min),
            HalfPlane::new(1.0, 0.0, self.x_max),
            HalfPlane::new(0.0, -1.0, -self.y_min),
            HalfPlane::new(0.0, 1.0, self.y_max),
        ]
    }
}

/// The half-plane `a[0] u + a[1] v <= b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfPlane {
    /// Normal (not necessarily unit).
    pub a: [f64; 2],
    /// Offset.
    pub b: f64,
}

impl HalfPlane {
    /// `a0 u + a1 v <= b`.
    pub fn new(a0: f64, a1: f64, b: f64) -> Self {
        Self { a: [a0, a1], b }
    }

    /// `a p - b`: negative inside, positive outside.
    pub fn value(&self, p: [f64; 2]) -> f64 {
        self.a[0] * p[0] + self.a[1] * p[1] - self.b
    }

    /// Signed Euclidean distance of `p` outside the boundary line (negative
    /// inside).
    pub fn distance(&self, p: [f64; 2]) -> f64 {
        self.value(p) / self.a[0].hypot(self.a[1]).max(f64::MIN_POSITIVE)
    }
}

/// What is left of a set in the plotting plane and window.
#[derive(Debug, Clone, PartialEq)]
pub enum Slice2 {
    /// The set does not meet the window in this plane.
    Empty,
    /// A single point (for example two equality rows).
    Point([f64; 2]),
    /// A segment (one equality row, or a polygon of no area).
    Segment([f64; 2], [f64; 2]),
    /// A convex polygon with positive area, vertices counter-clockwise.
    Polygon(Vec<[f64; 2]>),
}

impl Slice2 {
    /// True for [`Slice2::Empty`].
    pub fn is_empty(&self) -> bool {
        matches!(self, Slice2::Empty)
    }

    /// Every vertex of the slice (none when empty).
    pub fn vertices(&self) -> Vec<[f64; 2]> {
        match self {
            Slice2::Empty => vec![],
            Slice2::Point(p) => vec![*p],
            Slice2::Segment(p, q) => vec![*p, *q],
            Slice2::Polygon(v) => v.clone(),
        }
    }
}

/// Why a polyhedron could not be sliced.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SliceError {
    /// The polyhedron is malformed for the dimension of `z0`.
    #[error("invalid polyhedron: {0}")]
    InvalidPolyhedron(hysid_model::geometry::PolyhedronError),
    /// The two axes are equal or out of range.
    #[error("axes ({0}, {1}) are not two distinct coordinates below the dimension {2}")]
    InvalidAxes(usize, usize, usize),
    /// `z0` has a non-finite entry.
    #[error("the fixed point has a non-finite entry")]
    NonFinitePoint,
    /// The window is not a finite box of positive size.
    #[error("the plotting window is not a finite box of positive size")]
    InvalidBounds,
}

/// Relative tolerance of the slicing, times the window scale.
pub const SLICE_TOL: f64 = 1e-9;

/// Restricts the rows of `poly` to the plane through `z0` spanned by
/// coordinates `axes.0` and `axes.1`.
///
/// Returns the inequality half-planes, the equality lines (as half-planes
/// read with `=`), or `None` when a row that does not involve the two axes
/// is violated at `z0` (the slice is then empty).
fn restrict(
    poly: &Polyhedron,
    z0: &[f64],
    axes: (usize, usize),
    tol: f64,
) -> Option<(Vec<HalfPlane>, Vec<HalfPlane>)> {
    let (i, j) = axes;
    let project = |row: &[f64], b: f64| -> HalfPlane {
        let rest: f64 = row
            .iter()
            .zip(z0)
            .enumerate()
            .filter(|(k, _)| *k != i && *k != j)
            .map(|(_, (a, z))| a * z)
            .sum();
        HalfPlane::new(row[i], row[j], b - rest)
    };
    let mut ineq = Vec::new();
    for (row, &b) in poly.a.iter().zip(&poly.b) {
        let h = project(row, b);
        let full_norm = row.iter().map(|v| v * v).sum::<f64>().sqrt();
        let plane_norm = h.a[0].hypot(h.a[1]);
        if plane_norm <= 1e-12 * full_norm.max(f64::MIN_POSITIVE) || plane_norm == 0.0 {
            // Constant in the plane: either always true or always false.
            if -h.b > tol * full_norm.max(1.0) {
                return None;
            }
        } else {
            ineq.push(h);
        }
    }
    let mut eq = Vec::new();
    for (row, &b) in poly.a_eq.iter().zip(&poly.b_eq) {
        let h = project(row, b);
        let full_norm = row.iter().map(|v| v * v).sum::<f64>().sqrt();
        let plane_norm = h.a[0].hypot(h.a[1]);
        if plane_norm <= 1e-12 * full_norm.max(f64::MIN_POSITIVE) || plane_norm == 0.0 {
            if h.b.abs() > tol * full_norm.max(1.0) {
                return None;
            }
        } else {
            eq.push(h);
        }
    }
    Some((ineq, eq))
}

/// Clips the convex polygon `poly` by the half-plane `h` (one step of
/// Sutherland–Hodgman).
pub fn clip_polygon(poly: &[[f64; 2]], h: &HalfPlane) -> Vec<[f64; 2]> {
    let n = poly.len();
    let mut out = Vec::with_capacity(n + 1);
    for k in 0..n {
        let p = poly[k];
        let q = poly[(k + 1) % n];
        let fp = h.value(p);
        let fq = h.value(q);
        let p_in = fp <= 0.0;
        let q_in = fq <= 0.0;
        if p_in {
            out.push(p);
        }
        if p_in != q_in {
            let t = fp / (fp - fq);
            let t = t.clamp(0.0, 1.0);
            out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
        }
    }
    out
}

/// Twice the signed area of a polygon (positive when counter-clockwise).
pub fn signed_area2(poly: &[[f64; 2]]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|k| {
            let p = poly[k];
            let q = poly[(k + 1) % n];
            p[0] * q[1] - q[0] * p[1]
        })
        .sum()
}

/// Removes consecutive vertices closer than `tol` (and a closing duplicate).
fn dedup(poly: Vec<[f64; 2]>, tol: f64) -> Vec<[f64; 2]> {
    let mut out: Vec<[f64; 2]> = Vec::with_capacity(poly.len());
    for p in poly {
        if out
            .last()
            .is_none_or(|q| (p[0] - q[0]).hypot(p[1] - q[1]) > tol)
        {
            out.push(p);
        }
    }
    while out.len() > 1 {
        let (f, l) = (out[0], out[out.len() - 1]);
        if (f[0] - l[0]).hypot(f[1] - l[1]) <= tol {
            out.pop();
        } else {
            break;
        }
    }
    out
}

/// The two points of a vertex set farthest apart (a zero-area polygon is the
/// segment between them).
fn extremes(points: &[[f64; 2]]) -> ([f64; 2], [f64; 2], f64) {
    let mut best = (points[0], points[0], 0.0);
    for (k, p) in points.iter().enumerate() {
        for q in &points[k + 1..] {
            let d = (p[0] - q[0]).hypot(p[1] - q[1]);
            if d > best.2 {
                best = (*p, *q, d);
            }
        }
    }
    best
}

/// Clips the line `{p : h.a p = h.b}` by the half-planes, returning the
/// parameter interval along its direction.
fn clip_line(line: &HalfPlane, cuts: &[HalfPlane], tol: f64) -> Slice2 {
    let n2 = line.a[0] * line.a[0] + line.a[1] * line.a[1];
    // Foot point of the origin on the line and a unit direction.
    let p0 = [line.a[0] * line.b / n2, line.a[1] * line.b / n2];
    let len = n2.sqrt();
    let d = [-line.a[1] / len, line.a[0] / len];
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for h in cuts {
        // h.a (p0 + s d) <= h.b  <=>  alpha + beta s <= 0
        let alpha = h.value(p0);
        let beta = h.a[0] * d[0] + h.a[1] * d[1];
        let hn = h.a[0].hypot(h.a[1]);
        if beta.abs() <= 1e-12 * hn {
            if alpha > tol * hn {
                return Slice2::Empty;
            }
        } else if beta > 0.0 {
            hi = hi.min(-alpha / beta);
        } else {
            lo = lo.max(-alpha / beta);
        }
    }
    if !(lo.is_finite() && hi.is_finite()) || lo > hi + tol {
        return Slice2::Empty;
    }
    let at = |s: f64| [p0[0] + s * d[0], p0[1] + s * d[1]];
    if hi - lo <= tol {
        Slice2::Point(at(0.5 * (lo + hi)))
    } else {
        Slice2::Segment(at(lo), at(hi))
    }
}

/// The slice of `poly` in the plane through `z0` spanned by coordinates
/// `axes = (i, j)`, inside the window `bounds`.
///
/// `z0` has the dimension of the polyhedron; its entries at `i` and `j` are
/// ignored. A full-dimensional region gives a polygon (possibly the whole
/// window), a region touching the plane only along an edge gives a segment,
/// an equality row gives a segment or a point, and a region missing the plane
/// or the window gives [`Slice2::Empty`].
pub fn slice_polyhedron(
    poly: &Polyhedron,
    z0: &[f64],
    axes: (usize, usize),
    bounds: Bounds,
) -> Result<Slice2, SliceError> {
    let dim = z0.len();
    let (i, j) = axes;
    if i == j || i >= dim || j >= dim {
        return Err(SliceError::InvalidAxes(i, j, dim));
    }
    poly.validate(dim).map_err(SliceError::InvalidPolyhedron)?;
    if z0
        .iter()
        .enumerate()
        .any(|(k, v)| k != i && k != j && !v.is_finite())
    {
        return Err(SliceError::NonFinitePoint);
    }
    if !bounds.is_valid() {
        return Err(SliceError::InvalidBounds);
    }
    let tol = SLICE_TOL * bounds.scale().max(1.0);
    let Some((ineq, eq)) = restrict(poly, z0, axes, tol) else {
        return Ok(Slice2::Empty);
    };
    let mut cuts: Vec<HalfPlane> = bounds.half_planes().to_vec();
    cuts.extend(ineq.iter().copied());

    if let Some(first) = eq.first() {
        // A point when a second, independent equality exists.
        let second = eq.iter().skip(1).find(|h| {
            let det = first.a[0] * h.a[1] - first.a[1] * h.a[0];
            det.abs() > 1e-9 * first.a[0].hypot(first.a[1]) * h.a[0].hypot(h.a[1])
        });
        if let Some(second) = second {
            let det = first.a[0] * second.a[1] - first.a[1] * second.a[0];
            let p = [
                (first.b * second.a[1] - first.a[1] * second.b) / det,
                (first.a[0] * second.b - first.b * second.a[0]) / det,
            ];
            let ok_eq = eq.iter().all(|h| h.distance(p).abs() <= tol);
            let ok_in = cuts.iter().all(|h| h.distance(p) <= tol);
            return Ok(if ok_eq && ok_in && p[0].is_finite() && p[1].is_finite() {
                Slice2::Point(p)
            } else {
                Slice2::Empty
            });
        }
        // Parallel equalities: all must be the same line.
        let s = clip_line(first, &cuts, tol);
        let on_all = s
            .vertices()
            .iter()
            .all(|p| eq.iter().all(|h| h.distance(*p).abs() <= tol));
        let s = if on_all { s } else { Slice2::Empty };
        return Ok(s);
    }

    let mut poly2 = bounds.corners();
    for h in &ineq {
        poly2 = clip_polygon(&poly2, h);
        if poly2.is_empty() {
            return Ok(Slice2::Empty);
        }
    }
    let poly2 = dedup(poly2, tol);
    match poly2.len() {
        0 => Ok(Slice2::Empty),
        1 => Ok(Slice2::Point(poly2[0])),
        _ => {
            let (p, q, d) = extremes(&poly2);
            let area2 = signed_area2(&poly2).abs();
            // Area below tol * diameter: a sliver drawn as a segment.
            if poly2.len() == 2 || area2 <= 2.0 * tol * d.max(tol) {
                if d <= tol {
                    Ok(Slice2::Point(p))
                } else {
                    Ok(Slice2::Segment(p, q))
                }
            } else {
                Ok(Slice2::Polygon(poly2))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn unit_box() -> Bounds {
        Bounds {
            x_min: -1.0,
            x_max: 1.0,
            y_min: -1.0,
            y_max: 1.0,
        }
    }

    fn box3(lo: [f64; 3], hi: [f64; 3]) -> Polyhedron {
        let mut a = Vec::new();
        let mut b = Vec::new();
        for k in 0..3 {
            let mut r = vec![0.0; 3];
            r[k] = 1.0;
            a.push(r.clone());
            b.push(hi[k]);
            r[k] = -1.0;
            a.push(r);
            b.push(-lo[k]);
        }
        Polyhedron::from_inequalities(a, b)
    }

    fn same_set(a: &[[f64; 2]], b: &[[f64; 2]], tol: f64) -> bool {
        a.len() == b.len()
            && a.iter().all(|p| {
                b.iter()
                    .any(|q| (p[0] - q[0]).abs() <= tol && (p[1] - q[1]).abs() <= tol)
            })
    }

    #[test]
    fn whole_space_is_the_window() {
        let s = slice_polyhedron(&Polyhedron::everything(), &[0.0, 0.0], (0, 1), unit_box());
        assert_eq!(s.unwrap(), Slice2::Polygon(unit_box().corners()));
    }

    #[test]
    fn half_plane_cuts_the_window_in_two() {
        // x + y <= 0 in the unit box: the triangle below the anti-diagonal.
        let p = Polyhedron::from_inequalities(vec![vec![1.0, 1.0]], vec![0.0]);
        let Slice2::Polygon(v) = slice_polyhedron(&p, &[0.0, 0.0], (0, 1), unit_box()).unwrap()
        else {
            panic!("expected a polygon");
        };
        assert!(same_set(
            &v,
            &[[-1.0, -1.0], [1.0, -1.0], [-1.0, 1.0]],
            1e-12
        ));
        assert!((signed_area2(&v) - 4.0).abs() < 1e-12, "area 2 of 4");
    }

    #[test]
    fn other_coordinates_are_held_fixed() {
        // z2 <= 0.5 with z2 fixed at 1: empty; fixed at 0: everything.
        let p = box3([-0.5, -0.5, -1.0], [0.5, 0.5, 0.5]);
        let e = slice_polyhedron(&p, &[0.0, 0.0, 1.0], (0, 1), unit_box()).unwrap();
        assert_eq!(e, Slice2::Empty);
        let Slice2::Polygon(v) =
            slice_polyhedron(&p, &[9.0, 9.0, 0.0], (0, 1), unit_box()).unwrap()
        else {
            panic!("expected a polygon");
        };
        assert!(same_set(
            &v,
            &[[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]],
            1e-12
        ));
        // A coupled row x0 + x2 <= 0 with x2 = 0.25 becomes x0 <= -0.25.
        let c = Polyhedron::from_inequalities(vec![vec![1.0, 0.0, 1.0]], vec![0.0]);
        let Slice2::Polygon(v) =
            slice_polyhedron(&c, &[0.0, 0.0, 0.25], (0, 1), unit_box()).unwrap()
        else {
            panic!("expected a polygon");
        };
        assert!(v.iter().all(|p| p[0] <= -0.25 + 1e-12));
        assert!(v.iter().any(|p| (p[0] + 0.25).abs() < 1e-12));
    }

    #[test]
    fn axes_can_be_any_pair_in_any_order() {
        let p = box3([-0.2, -0.3, -0.4], [0.2, 0.3, 0.4]);
        let Slice2::Polygon(v) = slice_polyhedron(&p, &[0.0; 3], (2, 0), unit_box()).unwrap()
        else {
            panic!("expected a polygon");
        };
        // Horizontal is z2 (half-width 0.4), vertical is z0 (0.2).
        assert!(same_set(
            &v,
            &[[-0.4, -0.2], [0.4, -0.2], [0.4, 0.2], [-0.4, 0.2]],
            1e-12
        ));
    }

    #[test]
    fn equality_gives_a_segment_and_two_give_a_point() {
        // The stop y = 0.25 as a_eq, and x <= 0.
        let mut p = Polyhedron::from_inequalities(vec![vec![1.0, 0.0]], vec![0.0]);
        p.a_eq = vec![vec![0.0, 1.0]];
        p.b_eq = vec![0.25];
        let s = slice_polyhedron(&p, &[0.0, 0.0], (0, 1), unit_box()).unwrap();
        let Slice2::Segment(a, b) = s else {
            panic!("expected a segment, got {s:?}");
        };
        assert!(same_set(&[a, b], &[[-1.0, 0.25], [0.0, 0.25]], 1e-12));
        p.a_eq.push(vec![1.0, 1.0]);
        p.b_eq.push(0.0);
        let s = slice_polyhedron(&p, &[0.0, 0.0], (0, 1), unit_box()).unwrap();
        match s {
            Slice2::Point(q) => assert!((q[0] + 0.25).abs() < 1e-12 && (q[1] - 0.25).abs() < 1e-12),
            other => panic!("expected a point, got {other:?}"),
        }
        // The point x = 0.5 violates x <= 0.
        p.b_eq[1] = 0.75;
        assert_eq!(
            slice_polyhedron(&p, &[0.0, 0.0], (0, 1), unit_box()).unwrap(),
            Slice2::Empty
        );
    }

    #[test]
    fn flat_inequalities_give_a_segment_and_disjoint_ones_nothing() {
        // 0 <= x <= 0 written as two inequalities.
        let p =
            Polyhedron::from_inequalities(vec![vec![1.0, 0.0], vec![-1.0, 0.0]], vec![0.0, 0.0]);
        match slice_polyhedron(&p, &[0.0, 0.0], (0, 1), unit_box()).unwrap() {
            Slice2::Segment(a, b) => {
                assert!(a[0].abs() < 1e-12 && b[0].abs() < 1e-12);
                assert!((a[1] - b[1]).abs() > 1.99);
            }
            other => panic!("expected a segment, got {other:?}"),
        }
        let q =
            Polyhedron::from_inequalities(vec![vec![1.0, 0.0], vec![-1.0, 0.0]], vec![-0.5, -0.5]);
        assert_eq!(
            slice_polyhedron(&q, &[0.0, 0.0], (0, 1), unit_box()).unwrap(),
            Slice2::Empty
        );
        // Outside the window.
        let r = Polyhedron::from_inequalities(vec![vec![-1.0, 0.0]], vec![-5.0]);
        assert_eq!(
            slice_polyhedron(&r, &[0.0, 0.0], (0, 1), unit_box()).unwrap(),
            Slice2::Empty
        );
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let p = Polyhedron::from_inequalities(vec![vec![1.0, f64::NAN]], vec![0.0]);
        assert!(slice_polyhedron(&p, &[0.0, 0.0], (0, 1), unit_box()).is_err());
        let q = Polyhedron::from_inequalities(vec![vec![1.0, 0.0, 0.0]], vec![0.0]);
        assert!(slice_polyhedron(&q, &[0.0, 0.0], (0, 1), unit_box()).is_err());
        assert!(
            slice_polyhedron(&Polyhedron::everything(), &[0.0, 0.0], (1, 1), unit_box()).is_err()
        );
        assert!(
            slice_polyhedron(&Polyhedron::everything(), &[0.0, 0.0], (0, 2), unit_box()).is_err()
        );
        let mut b = unit_box();
        b.x_max = f64::INFINITY;
        assert!(slice_polyhedron(&Polyhedron::everything(), &[0.0, 0.0], (0, 1), b).is_err());
        assert!(
            slice_polyhedron(
                &Polyhedron::everything(),
                &[0.0, 0.0, f64::NAN],
                (0, 1),
                unit_box()
            )
            .is_err()
        );
    }

    fn row3() -> impl Strategy<Value = (Vec<f64>, f64)> {
        (proptest::collection::vec(-3.0f64..3.0, 3), -2.0f64..2.0)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Every vertex of the slice satisfies every half-plane (of the
        /// polyhedron at the fixed coordinate, and of the window) within
        /// tolerance, and lies in the polyhedron as a point of R^3.
        #[test]
        fn vertices_satisfy_all_half_planes(
            rows in proptest::collection::vec(row3(), 0..7),
            z2 in -1.0f64..1.0,
            lo in -3.0f64..0.0,
            w in 0.1f64..4.0,
        ) {
            let (a, b): (Vec<Vec<f64>>, Vec<f64>) = rows.into_iter().unzip();
            let poly = Polyhedron::from_inequalities(a, b);
            let bounds = Bounds { x_min: lo, x_max: lo + w, y_min: lo - 0.5, y_max: lo + 2.0 * w };
            let s = slice_polyhedron(&poly, &[0.0, 0.0, z2], (0, 1), bounds).unwrap();
            let tol = 1e-7 * (1.0 + bounds.scale());
            for p in s.vertices() {
                prop_assert!(p[0] >= bounds.x_min - tol && p[0] <= bounds.x_max + tol);
                prop_assert!(p[1] >= bounds.y_min - tol && p[1] <= bounds.y_max + tol);
                prop_assert!(poly.violation(&[p[0], p[1], z2]) <= tol, "vertex {p:?} violates {poly:?}");
            }
            if let Slice2::Polygon(v) = &s {
                prop_assert!(v.len() >= 3);
                prop_assert!(signed_area2(v) > 0.0, "counter-clockwise");
            }
        }

        /// Slicing an axis-aligned box in any plane of R^3 gives that box's
        /// rectangle (clipped to the window), or nothing when the fixed
        /// coordinate is outside it.
        #[test]
        fn box_slice_of_a_box_is_the_box(
            lo in proptest::collection::vec(-2.0f64..0.0, 3),
            size in proptest::collection::vec(0.05f64..2.0, 3),
            fixed in -2.5f64..2.5,
            swap in any::<bool>(),
        ) {
            let hi: Vec<f64> = lo.iter().zip(&size).map(|(l, s)| l + s).collect();
            let p = box3([lo[0], lo[1], lo[2]], [hi[0], hi[1], hi[2]]);
            let axes = if swap { (1, 0) } else { (0, 1) };
            let window = Bounds { x_min: -3.0, x_max: 3.0, y_min: -3.0, y_max: 3.0 };
            let s = slice_polyhedron(&p, &[0.0, 0.0, fixed], axes, window).unwrap();
            if fixed < lo[2] - 1e-9 || fixed > hi[2] + 1e-9 {
                prop_assert_eq!(s, Slice2::Empty);
            } else {
                let (u, v) = (axes.0, axes.1);
                let expect = [[lo[u], lo[v]], [hi[u], lo[v]], [hi[u], hi[v]], [lo[u], hi[v]]];
                let Slice2::Polygon(got) = s else { panic!("expected a polygon") };
                prop_assert!(same_set(&got, &expect, 1e-9), "{got:?} vs {expect:?}");
            }
            // A box window equal to the box itself gives the box back.
            let own = Bounds { x_min: lo[axes.0], x_max: hi[axes.0], y_min: lo[axes.1], y_max: hi[axes.1] };
            let s = slice_polyhedron(&p, &[0.0, 0.0, 0.5 * (lo[2] + hi[2])], axes, own).unwrap();
            let Slice2::Polygon(got) = s else { panic!("expected a polygon") };
            prop_assert!(same_set(&got, &own.corners(), 1e-9));
        }
    }
}
