//! Dense least squares on nalgebra types, computed with faer.
//!
//! faer is used only here, so a faer upgrade touches one module. All
//! solutions come from a thin SVD with a relative rank cut-off, so
//! collinear regressors give the minimum-norm solution instead of garbage
//! or a crash.

use nalgebra::{DMatrix, DVector, DVectorView};
use std::borrow::Cow;

/// A least-squares solution.
#[derive(Debug, Clone, PartialEq)]
pub struct LeastSquares {
    /// Minimiser of `|Phi theta - y|` (minimum norm when rank deficient).
    pub theta: DVector<f64>,
    /// Numerical rank of `Phi`.
    pub rank: usize,
    /// Residual sum of squares.
    pub rss: f64,
}

/// Failures of the dense kernels (only on non-finite input or when the SVD
/// does not converge).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinalgError {
    /// Input has NaN or infinite entries.
    #[error("matrix has non-finite entries")]
    NonFinite,
    /// Shapes do not agree.
    #[error("shape mismatch: {0}")]
    Shape(String),
    /// The SVD did not converge.
    #[error("singular value decomposition did not converge")]
    NoConvergence,
    /// The equality constraints `E theta = f` have no solution.
    #[error("the equality constraints are inconsistent (residual {0:.3e})")]
    InconsistentConstraints(f64),
}

/// A thin SVD `A = U diag(s) V'` with its numerical rank. `U` stays in
/// faer's storage (it is as tall as `A`); `V` is small.
struct ThinSvd {
    svd: Option<faer::linalg::solvers::Svd<f64>>,
    s: Vec<f64>,
    v: DMatrix<f64>,
    rank: usize,
}

impl ThinSvd {
    /// Left singular vector `i`: borrowed from faer's column-major `U`,
    /// copied only if its column were strided.
    fn u_column(&self, i: usize) -> Cow<'_, [f64]> {
        let Some(svd) = &self.svd else {
            return Cow::Owned(Vec::new());
        };
        let column = svd.U().col(i);
        match column.try_as_col_major() {
            Some(contiguous) => Cow::Borrowed(contiguous.as_slice()),
            None => Cow::Owned(column.iter().copied().collect()),
        }
    }
}

fn thin_svd(a: &DMatrix<f64>) -> Result<ThinSvd, LinalgError> {
    if a.iter().any(|v| !v.is_finite()) {
        return Err(LinalgError::NonFinite);
    }
    let (m, n) = a.shape();
    if m == 0 || n == 0 {
        return Ok(ThinSvd {
            svd: None,
            s: vec![],
            v: DMatrix::zeros(n, 0),
            rank: 0,
        });
    }
    // nalgebra stores a DMatrix column-major and contiguous, as faer reads it.
    let fa = faer::MatRef::from_column_major_slice(a.as_slice(), m, n);
    let svd = fa.thin_svd().map_err(|_| LinalgError::NoConvergence)?;
    let v = svd.V();
    let v = DMatrix::from_fn(v.nrows(), v.ncols(), |i, j| v[(i, j)]);
    let s: Vec<f64> = svd.S().column_vector().iter().copied().collect();
    let smax = s.iter().fold(0.0f64, |x, &y| x.max(y));
    let tol = (m.max(n) as f64) * f64::EPSILON * smax;
    let rank = s.iter().filter(|&&x| x > tol && x > 0.0).count();
    Ok(ThinSvd {
        svd: Some(svd),
        s,
        v,
        rank,
    })
}

/// Solves `min |Phi theta - y|`.
pub fn lstsq(phi: &DMatrix<f64>, y: &DVector<f64>) -> Result<LeastSquares, LinalgError> {
    if phi.nrows() != y.len() {
        return Err(LinalgError::Shape(format!(
            "{} rows, {} targets",
            phi.nrows(),
            y.len()
        )));
    }
    if y.iter().any(|v| !v.is_finite()) {
        return Err(LinalgError::NonFinite);
    }
    let svd = thin_svd(phi)?;
    let mut theta = DVector::zeros(phi.ncols());
    for i in 0..svd.rank {
        let u = svd.u_column(i);
        let coef = DVectorView::from_slice(&u, u.len()).dot(y) / svd.s[i];
        theta.axpy(coef, &svd.v.column(i), 1.0);
    }
    let rss = (phi * &theta - y).norm_squared();
    Ok(LeastSquares {
        theta,
        rank: svd.rank,
        rss,
    })
}

/// Solves `min sum_k w_k (y_k - phi_k theta)^2` with `w_k >= 0`.
pub fn weighted_lstsq(
    phi: &DMatrix<f64>,
    y: &DVector<f64>,
    w: &[f64],
) -> Result<LeastSquares, LinalgError> {
    if w.len() != y.len() || w.iter().any(|v| !v.is_finite() || *v < 0.0) {
        return Err(LinalgError::Shape(
            "weights must be finite, non-negative, one per row".into(),
        ));
    }
    let mut p = phi.clone();
    let mut t = y.clone();
    for (k, &wk) in w.iter().enumerate() {
        let s = wk.sqrt();
        p.row_mut(k).scale_mut(s);
        t[k] *= s;
    }
    let mut sol = lstsq(&p, &t)?;
    sol.rss = (phi * &sol.theta - y)
        .component_mul(&(phi * &sol.theta - y))
        .dot(&DVector::from_column_slice(w));
    Ok(sol)
}

/// Moore-Penrose pseudo-inverse.
pub fn pinv(a: &DMatrix<f64>) -> Result<DMatrix<f64>, LinalgError> {
    let svd = thin_svd(a)?;
    let mut p = DMatrix::zeros(a.ncols(), a.nrows());
    for i in 0..svd.rank {
        let u = svd.u_column(i);
        p += (svd.v.column(i) * DVectorView::from_slice(&u, u.len()).transpose()) / svd.s[i];
    }
    Ok(p)
}

/// An orthonormal basis of the null space of `a` (columns).
pub fn null_space(a: &DMatrix<f64>) -> Result<DMatrix<f64>, LinalgError> {
    let n = a.ncols();
    if a.nrows() == 0 {
        return Ok(DMatrix::identity(n, n));
    }
    // Pad to a square matrix so the thin SVD returns all n right vectors.
    let mut sq = DMatrix::zeros(a.nrows().max(n), n);
    sq.view_mut((0, 0), a.shape()).copy_from(a);
    let svd = thin_svd(&sq)?;
    let cols: Vec<usize> = (svd.rank..n).collect();
    Ok(svd.v.select_columns(&cols))
}

/// Solves `min |Phi theta - y|` subject to `E theta = f` exactly, by the
/// null-space method: `theta = theta_p + N z` with `E theta_p = f` and
/// `N` a basis of `ker E` (Golub & Van Loan, Matrix Computations, 6.2).
pub fn lstsq_equality(
    phi: &DMatrix<f64>,
    y: &DVector<f64>,
    e: &DMatrix<f64>,
    f: &DVector<f64>,
) -> Result<LeastSquares, LinalgError> {
    if e.nrows() == 0 {
        return lstsq(phi, y);
    }
    if e.ncols() != phi.ncols() || e.nrows() != f.len() {
        return Err(LinalgError::Shape(
            "constraints do not match the parameters".into(),
        ));
    }
    let theta_p = pinv(e)? * f;
    let res = (e * &theta_p - f).amax();
    if res > 1e-9 * (1.0 + f.amax()) {
        return Err(LinalgError::InconsistentConstraints(res));
    }
    let n = null_space(e)?;
    let rank_e = phi.ncols() - n.ncols();
    if n.ncols() == 0 {
        let rss = (phi * &theta_p - y).norm_squared();
        return Ok(LeastSquares {
            theta: theta_p,
            rank: rank_e,
            rss,
        });
    }
    let reduced = lstsq(&(phi * &n), &(y - phi * &theta_p))?;
    let theta = theta_p + &n * reduced.theta;
    let rss = (phi * &theta - y).norm_squared();
    Ok(LeastSquares {
        theta,
        rank: reduced.rank + rank_e,
        rss,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn collinear_columns_give_minimum_norm() {
        let phi = DMatrix::from_row_slice(3, 2, &[1.0, 1.0, 2.0, 2.0, 3.0, 3.0]);
        let y = DVector::from_vec(vec![2.0, 4.0, 6.0]);
        let s = lstsq(&phi, &y).unwrap();
        assert_eq!(s.rank, 1);
        assert!((s.theta[0] - 1.0).abs() < 1e-12 && (s.theta[1] - 1.0).abs() < 1e-12);
        assert!(lstsq(&DMatrix::from_element(2, 1, f64::NAN), &DVector::zeros(2)).is_err());
    }

    #[test]
    fn equality_constraints_hold_exactly() {
        let phi = DMatrix::from_row_slice(
            4,
            3,
            &[1.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 2.0, -1.0, 1.0],
        );
        let y = DVector::from_vec(vec![1.0, 2.0, 3.0, 0.5]);
        let e = DMatrix::from_row_slice(1, 3, &[1.0, -1.0, 0.0]); // theta0 = theta1
        let f = DVector::from_vec(vec![0.0]);
        let s = lstsq_equality(&phi, &y, &e, &f).unwrap();
        assert!((s.theta[0] - s.theta[1]).abs() < 1e-12);
        let bad = DMatrix::from_row_slice(2, 3, &[1.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
        assert!(lstsq_equality(&phi, &y, &bad, &DVector::from_vec(vec![0.0, 1.0])).is_err());
    }

    /// A matrix of 4 to 12 rows and 1 to 3 columns, entries in [-10, 10).
    fn matrix() -> impl Strategy<Value = DMatrix<f64>> {
        (4usize..=12, 1usize..=3).prop_flat_map(|(rows, cols)| {
            proptest::collection::vec(-10.0f64..10.0, rows * cols)
                .prop_map(move |v| DMatrix::from_vec(rows, cols, v))
        })
    }

    proptest! {
        /// The normal equations hold at the solution: Phi' (Phi theta - y) = 0.
        #[test]
        fn normal_equations(phi in matrix(), seed in any::<u64>()) {
            let y = DVector::from_fn(phi.nrows(), |i, _| ((seed >> (i % 60)) & 7) as f64 - 3.0);
            let s = lstsq(&phi, &y).unwrap();
            let g = phi.transpose() * (&phi * &s.theta - &y);
            prop_assert!(g.amax() < 1e-8 * (1.0 + phi.norm() * phi.norm() * (1.0 + s.theta.amax())));
        }
    }
}
