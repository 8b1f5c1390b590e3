//! Tiny dense kernels on row-major `p x p` slices (p is the regressor
//! dimension plus one, rarely above 10): Cholesky factorisation, solves,
//! inverse and log-determinant, for `cluster`'s local datasets. They are
//! called once or twice per local dataset, so they avoid allocation; larger
//! problems go through [`crate::linalg`] (faer).
//!
//! Why not faer's `Llt` here: factor and solve one right-hand side take
//! 57 / 125 / 258 / 542 ns here against 395 / 575 / 625 / 1046 ns with faer
//! for p = 3 / 5 / 8 / 12 (medians, `cargo bench -p hysid-estimation
//! --bench dense`, docs/performance-cluster.md): with one factorisation
//! per local dataset, faer would add about 3.6 ms to the 47 ms of a
//! B1 record of 8000 samples.

/// Cholesky factorisation in place (lower triangle of `a` becomes `L`,
/// `a = L L^T`). Returns the smallest squared pivot `L_kk^2`, or `None` when
/// a pivot is not positive (the matrix is not numerically positive
/// definite).
pub fn cholesky(a: &mut [f64], p: usize) -> Option<f64> {
    let mut min_pivot = f64::INFINITY;
    for j in 0..p {
        let mut d = a[j * p + j];
        for k in 0..j {
            d -= a[j * p + k] * a[j * p + k];
        }
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        min_pivot = min_pivot.min(d);
        let ljj = d.sqrt();
        a[j * p + j] = ljj;
        for i in j + 1..p {
            let mut s = a[i * p + j];
            for k in 0..j {
                s -= a[i * p + k] * a[j * p + k];
            }
            a[i * p + j] = s / ljj;
        }
    }
    Some(min_pivot)
}

/// Solves `L L^T x = b` in place of `b`, `l` from [`cholesky`].
pub fn cholesky_solve(l: &[f64], p: usize, b: &mut [f64]) {
    for i in 0..p {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * p + k] * b[k];
        }
        b[i] = s / l[i * p + i];
    }
    for i in (0..p).rev() {
        let mut s = b[i];
        for k in i + 1..p {
            s -= l[k * p + i] * b[k];
        }
        b[i] = s / l[i * p + i];
    }
}

/// `log det(L L^T)`.
pub fn cholesky_log_det(l: &[f64], p: usize) -> f64 {
    (0..p).map(|i| 2.0 * l[i * p + i].ln()).sum()
}

/// Inverse of `L L^T` written to `out` (full, symmetric).
pub fn cholesky_inverse(l: &[f64], p: usize, out: &mut [f64], col: &mut [f64]) {
    for j in 0..p {
        col.iter_mut().for_each(|v| *v = 0.0);
        col[j] = 1.0;
        cholesky_solve(l, p, col);
        for i in 0..p {
            out[i * p + j] = col[i];
        }
    }
}

/// Mean of the diagonal.
pub fn mean_diag(a: &[f64], p: usize) -> f64 {
    if p == 0 {
        return 0.0;
    }
    (0..p).map(|i| a[i * p + i]).sum::<f64>() / p as f64
}

/// A symmetric positive semi-definite matrix made safely invertible: the
/// Cholesky factor of `a` if its smallest squared pivot is at least
/// `rel * mean_diag(a)` and at least `floor`, else of `a + floor I`
/// (`floor > 0`). Returns `true` when the ridge was needed. The factor
/// replaces `a`; `scratch` holds a copy.
pub fn regularised_cholesky(
    a: &mut [f64],
    p: usize,
    rel: f64,
    floor: f64,
    scratch: &mut [f64],
) -> bool {
    if p == 0 {
        return false;
    }
    scratch[..p * p].copy_from_slice(&a[..p * p]);
    let t = mean_diag(a, p);
    if let Some(piv) = cholesky(a, p)
        && piv >= rel * t
        && piv >= floor
    {
        return false;
    }
    a[..p * p].copy_from_slice(&scratch[..p * p]);
    for i in 0..p {
        a[i * p + i] += floor;
    }
    if cholesky(a, p).is_none() {
        // Not finite or wildly indefinite: fall back to the ridge alone.
        a.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..p {
            a[i * p + i] = floor.sqrt();
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_and_inverts_spd() {
        let a = [4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0];
        let mut l = a;
        assert!(cholesky(&mut l, 3).is_some());
        let mut inv = [0.0; 9];
        let mut col = [0.0; 3];
        cholesky_inverse(&l, 3, &mut inv, &mut col);
        for i in 0..3 {
            for j in 0..3 {
                let v: f64 = (0..3).map(|k| a[i * 3 + k] * inv[k * 3 + j]).sum();
                assert!((v - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        let det = 4.0 * (5.0 * 3.0 - 1.0) - 2.0 * (2.0 * 3.0 - 0.6) + 0.6 * (2.0 - 5.0 * 0.6);
        assert!((cholesky_log_det(&l, 3) - f64::ln(det)).abs() < 1e-12);
    }

    #[test]
    fn singular_matrix_gets_the_ridge() {
        let mut a = [1.0, 1.0, 1.0, 1.0];
        let mut s = [0.0; 4];
        assert!(regularised_cholesky(&mut a, 2, 1e-10, 1e-6, &mut s));
        assert!(a.iter().all(|v| v.is_finite()));
        let mut b = [1.0, 1.0];
        let mut z = [0.0; 4];
        let mut g = [1.0, 1.0, 1.0, 1.0];
        assert!(regularised_cholesky(&mut g, 2, 1e-10, 1e-6, &mut z));
        cholesky_solve(&g, 2, &mut b);
        assert!(b.iter().all(|v| v.is_finite()));
    }
}
