//! Which regions share a facet (HIT's `idmodes.adjacences`), needed by the
//! mixed-point reattribution of the clustering procedure, which only moves a
//! point to an adjacent mode.

use crate::conic::{Cone, Program, Triplets};
use crate::regions::options::RegionError;
use crate::regions::problem::Context;
use hysid_core::backend::Deadline;
use hysid_model::geometry::Polyhedron;

/// Symmetric adjacency matrix of a pairwise partition inside the box
/// `[lo, hi]`: `adj[i][j]` is true when regions `i` and `j` share a facet
/// of positive (d-1)-dimensional size inside the box.
///
/// The regions must have the pairwise layout produced by [`crate::regions::estimate`]
/// and [`crate::regions::argmax_regions`]: region `i` has `s - 1` rows, the row for
/// mode `j` at position `j` (if `j < i`) or `j - 1`, and it is the negative
/// of region `j`'s row for `i`. For each pair one LP (clarabel) finds the
/// largest `t` such that a point `x` in the box lies on their common
/// hyperplane with every other row of both regions satisfied with
/// Euclidean slack `t`; the pair is adjacent when `t > 1e-9 (1 + box size)`.
// Symmetric fill of `adj[i][j]` and `adj[j][i]` needs both indices.
#[allow(clippy::needless_range_loop)]
pub fn adjacency(
    regions: &[Polyhedron],
    lo: &[f64],
    hi: &[f64],
) -> Result<Vec<Vec<bool>>, RegionError> {
    let s = regions.len();
    let d = lo.len();
    if hi.len() != d {
        return Err(RegionError::Shape(format!(
            "box bounds of lengths {} and {}",
            d,
            hi.len()
        )));
    }
    if lo
        .iter()
        .zip(hi)
        .any(|(l, h)| !(l.is_finite() && h.is_finite() && l <= h))
    {
        return Err(RegionError::Shape(
            "box bounds must be finite with lo <= hi".into(),
        ));
    }
    for (i, r) in regions.iter().enumerate() {
        if r.a.len() != s - 1 || r.b.len() != s - 1 || r.a.iter().any(|row| row.len() != d) {
            return Err(RegionError::Shape(format!(
                "region {i} does not have the pairwise layout ({} rows of length {d} expected)",
                s - 1
            )));
        }
    }
    let pos = |i: usize, j: usize| if j < i { j } else { j - 1 };
    let norm = |a: &[f64]| a.iter().map(|v| v * v).sum::<f64>().sqrt();
    let size = lo
        .iter()
        .zip(hi)
        .map(|(l, h)| (h - l).abs())
        .fold(0.0, f64::max)
        + lo.iter().chain(hi).fold(0.0f64, |m, v| m.max(v.abs()));
    let mut adj = vec![vec![false; s]; s];
    for i in 0..s {
        for j in i + 1..s {
            let h = &regions[i].a[pos(i, j)];
            if norm(h) == 0.0 {
                continue;
            }
            // variables [x (d); t]; minimise -t
            let mut q = vec![0.0; d + 1];
            q[d] = -1.0;
            let mut a = Triplets::default();
            let mut b = Vec::new();
            for (k, &v) in h.iter().enumerate() {
                a.push(0, k, v);
            }
            b.push(regions[i].b[pos(i, j)]);
            let others = (0..s)
                .filter(|&k| k != j && k != i)
                .map(|k| (i, pos(i, k)))
                .chain((0..s).filter(|&k| k != i && k != j).map(|k| (j, pos(j, k))));
            for (reg, row) in others {
                let r = &regions[reg].a[row];
                let n = norm(r);
                let at = b.len();
                for (k, &v) in r.iter().enumerate() {
                    a.push(at, k, v);
                }
                a.push(at, d, n);
                b.push(regions[reg].b[row]);
            }
            for k in 0..d {
                let at = b.len();
                a.push(at, k, 1.0);
                b.push(hi[k]);
                a.push(at + 1, k, -1.0);
                b.push(-lo[k]);
            }
            let at = b.len();
            a.push(at, d, 1.0);
            b.push(1.0);
            let rows = b.len();
            let prog = Program {
                p: Triplets::default(),
                q,
                a,
                b,
                cones: vec![Cone::Zero(1), Cone::Nonnegative(rows - 1)],
            };
            let ctx = Context {
                method: "adjacency",
                points: 0,
                round: 1,
                deadline: Deadline::none(),
            };
            let (variables, rows) = (prog.variables(), prog.rows());
            match crate::regions::problem::solve_program(prog) {
                Ok(sol) => {
                    let t = sol.x[d];
                    adj[i][j] = t > 1e-9 * (1.0 + size);
                    adj[j][i] = adj[i][j];
                }
                // No point on the common hyperplane (or none the LP can
                // bound): the pair shares no facet.
                Err(e) if e.is_certificate() => {}
                Err(e) => return Err(RegionError::from_solve(e, &ctx, variables, rows)),
            }
        }
    }
    Ok(adj)
}
