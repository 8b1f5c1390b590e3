//! Pairwise proximal support vector classification (Fung and Mangasarian,
//! "Proximal support vector machine classifiers", KDD 2001), HIT's default
//! region estimator, in closed form and deterministic.
//!
//! For modes `i < j`, with `E = [Z, -1]` over the points of both modes,
//! `D = diag(+1 for mode i, -1 for mode j)` and class-balancing weights
//! `Omega = diag(n_ij / (2 n_k))` (each mode gets half the total weight),
//! `(I / nu + E' Omega E) [w; g] = E' Omega D 1` with `nu = 1e6`.
//! Region `i` keeps `w.z - g >= 0` against every `j`, so regions are
//! intersections of pairwise half-spaces and may leave holes.

use crate::regions::options::RegionError;
use crate::regions::problem::Prepared;
use hysid_model::geometry::Polyhedron;
use nalgebra::{DMatrix, DVector};

/// Fung and Mangasarian's `nu` as used by HIT.
pub const NU: f64 = 1e6;

/// One region per mode in original units.
pub(crate) fn regions(
    prep: &Prepared,
    labels: &[usize],
    modes: usize,
    d: usize,
) -> Result<Vec<Polyhedron>, RegionError> {
    let p = prep.p;
    // rows[i] collects (normal in original units, rhs) for region i.
    let mut rows: Vec<(Vec<Vec<f64>>, Vec<f64>)> = vec![(Vec::new(), Vec::new()); modes];
    for i in 0..modes {
        for j in i + 1..modes {
            let total = (prep.counts[i] + prep.counts[j]) as f64;
            let wi = total / (2.0 * prep.counts[i] as f64);
            let wj = total / (2.0 * prep.counts[j] as f64);
            let mut m = DMatrix::<f64>::identity(p + 1, p + 1) / NU;
            let mut rhs = DVector::<f64>::zeros(p + 1);
            let mut e = vec![0.0; p + 1];
            for (r, &l) in labels.iter().enumerate() {
                let (omega, sign) = if l == i {
                    (wi, 1.0)
                } else if l == j {
                    (wj, -1.0)
                } else {
                    continue;
                };
                e[..p].copy_from_slice(prep.row(r));
                e[p] = -1.0;
                for a in 0..=p {
                    rhs[a] += omega * sign * e[a];
                    for b in a..=p {
                        m[(a, b)] += omega * e[a] * e[b];
                    }
                }
            }
            for a in 0..=p {
                for b in 0..a {
                    m[(a, b)] = m[(b, a)];
                }
            }
            let sol = m
                .cholesky()
                .map(|c| c.solve(&rhs))
                .ok_or(RegionError::Singular {
                    method: "psvc",
                    i,
                    j,
                })?;
            if sol.iter().any(|v| !v.is_finite()) {
                return Err(RegionError::Singular {
                    method: "psvc",
                    i,
                    j,
                });
            }
            // h(z) = w.z - g; in original units h = c.x + c0.
            let mut c = vec![0.0; d];
            let mut c0 = -sol[p];
            for k in 0..p {
                let ck = sol[k] / prep.scale[k];
                c[prep.cols[k]] = ck;
                c0 -= ck * prep.mean[k];
            }
            // region i: h >= 0  <=>  -c.x <= c0 ; region j: h <= 0 <=> c.x <= -c0
            // `0.0 - v` rather than `-v`: no negative zeros in unused columns.
            rows[i].0.push(c.iter().map(|v| 0.0 - v).collect());
            rows[i].1.push(c0);
            rows[j].0.push(c);
            rows[j].1.push(0.0 - c0);
        }
    }
    Ok(rows
        .into_iter()
        .map(|(a, b)| Polyhedron::from_inequalities(a, b))
        .collect())
}
