//! The prior pdf `p_i(theta)` of a mode's parameters.
//!
//! Black-box prior (ours; the paper leaves the black-box prior to the
//! user): on the standardised problem (every regressor and the output with
//! zero mean and unit standard deviation) the parameters `beta` are
//! Gaussian around the affine least-squares fit `beta_LS` of all ordinary
//! samples, `N(beta_LS, prior_std^2 I)`. In data units this is
//! `theta ~ N(theta_LS, prior_std^2 T T')`, with `theta = T beta + t` the
//! change of units. `[fixed]` priors condition this Gaussian on the fixed
//! values; `[bounds]` truncate it (particles only).

use hysid_estimation::constrained::{Parametrisation, Slot};
use hysid_estimation::linalg;
use hysid_model::data::AffineScale;
use hysid_model::regressors::Regressors;
use nalgebra::{DMatrix, DVector};

/// The prior of one mode: a Gaussian on the free parameters given the
/// fixed ones, truncated to box bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct ModePrior {
    /// Mean of all `p` parameters (fixed ones at their values).
    pub mean: DVector<f64>,
    /// Covariance of all `p` parameters (zero rows and columns for the
    /// fixed ones).
    pub cov: DMatrix<f64>,
    /// Lower bound of every parameter (`-inf` when none; the value when
    /// fixed).
    pub lower: Vec<f64>,
    /// Upper bound of every parameter.
    pub upper: Vec<f64>,
}

impl ModePrior {
    /// Parameters per mode.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Whether some parameter has a finite bound it is not fixed at.
    pub fn is_truncated(&self) -> bool {
        self.lower
            .iter()
            .zip(&self.upper)
            .any(|(l, u)| l != u && (l.is_finite() || u.is_finite()))
    }

    /// `theta` clamped into the bounds.
    pub fn clamp(&self, theta: &mut [f64]) {
        for (j, t) in theta.iter_mut().enumerate() {
            *t = t.clamp(self.lower[j], self.upper[j]);
        }
    }

    /// Whether `theta` lies within the bounds.
    pub fn admits(&self, theta: &[f64]) -> bool {
        theta
            .iter()
            .enumerate()
            .all(|(j, t)| (self.lower[j]..=self.upper[j]).contains(t))
    }
}

/// The black-box prior of every mode (module doc), under the `[fixed]`
/// and `[bounds]` priors of `par`. `None` when the affine fit fails.
pub fn black_box_priors(
    reg: &Regressors,
    par: &Parametrisation,
    prior_std: f64,
) -> Option<Vec<ModePrior>> {
    let (mean, cov) = affine_fit_spread(reg, prior_std)?;
    (0..par.modes())
        .map(|i| condition(&mean, &cov, par, i))
        .collect()
}

/// `theta_LS` and `prior_std^2 T T'` in data units.
fn affine_fit_spread(reg: &Regressors, prior_std: f64) -> Option<(DVector<f64>, DMatrix<f64>)> {
    let d = reg.x.ncols();
    let theta = linalg::lstsq(&reg.phi(), &reg.y).ok()?.theta;
    if !theta.iter().all(|v| v.is_finite()) {
        return None;
    }
    let sy = AffineScale::of(reg.y.as_slice()).std;
    // theta_j = beta_j sy / sx_j; c = ybar + sy beta_0 - sum_j theta_j xbar_j.
    let mut t = DMatrix::zeros(d + 1, d + 1);
    for j in 0..d {
        let x = AffineScale::of(reg.x.column(j).as_slice());
        let scale = sy / x.std;
        t[(j, j)] = scale;
        t[(d, j)] = -scale * x.mean;
    }
    t[(d, d)] = sy;
    let cov = &t * t.transpose() * (prior_std * prior_std);
    Some((theta, cov))
}

/// The Gaussian `N(mean, cov)` conditioned on the fixed parameters of mode
/// `mode`, with that mode's bounds.
fn condition(
    mean: &DVector<f64>,
    cov: &DMatrix<f64>,
    par: &Parametrisation,
    mode: usize,
) -> Option<ModePrior> {
    let p = mean.len();
    let mut lower = vec![f64::NEG_INFINITY; p];
    let mut upper = vec![f64::INFINITY; p];
    let mut fixed = Vec::new();
    let mut free = Vec::new();
    for j in 0..p {
        match par.slot(mode, j) {
            Slot::Fixed(x) => {
                fixed.push((j, x));
                lower[j] = x;
                upper[j] = x;
            }
            Slot::Free(v) => {
                free.push(j);
                (lower[j], upper[j]) = par.free_bounds(v);
            }
        }
    }
    let mut m = mean.clone();
    let mut c = cov.clone();
    if !fixed.is_empty() {
        let sel = |rows: &[usize], cols: &[usize]| {
            DMatrix::from_fn(rows.len(), cols.len(), |a, b| cov[(rows[a], cols[b])])
        };
        let xi: Vec<usize> = fixed.iter().map(|&(j, _)| j).collect();
        let gap = DVector::from_iterator(xi.len(), fixed.iter().map(|&(j, x)| x - mean[j]));
        let pxx_inv = linalg::pinv(&sel(&xi, &xi)).ok()?;
        let pfx = sel(&free, &xi);
        let shift = &pfx * &pxx_inv * gap;
        let pff = sel(&free, &free) - &pfx * &pxx_inv * pfx.transpose();
        m = DVector::zeros(p);
        c = DMatrix::zeros(p, p);
        for (a, &j) in free.iter().enumerate() {
            m[j] = mean[j] + shift[a];
            for (b, &k) in free.iter().enumerate() {
                c[(j, k)] = 0.5 * (pff[(a, b)] + pff[(b, a)]);
            }
        }
        for &(j, x) in &fixed {
            m[j] = x;
        }
    }
    Some(ModePrior {
        mean: m,
        cov: c,
        lower,
        upper,
    })
}

/// A square root `L` with `L L' = cov` of a symmetric positive
/// semidefinite matrix (eigenvalues below zero, from rounding, count as
/// zero), so that `mean + L e` with standard normal `e` has covariance
/// `cov` even when `cov` is singular.
pub fn sqrt_psd(cov: &DMatrix<f64>) -> DMatrix<f64> {
    let eig = cov.clone().symmetric_eigen();
    let mut l = eig.eigenvectors;
    for (k, lambda) in eig.eigenvalues.iter().enumerate() {
        let s = lambda.max(0.0).sqrt();
        l.column_mut(k).scale_mut(s);
    }
    l
}
