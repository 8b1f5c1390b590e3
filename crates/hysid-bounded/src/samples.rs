//! The regression data of the bounded-error problem: rows `phi_k = [x_k; 1]`
//! and targets `y_k`, stored row-major for the inner loops of the thermal
//! relaxation.

use hysid_model::regressors::Regressors;

/// `phi_k` rows (row-major, `p` columns, constant last) and targets `y_k`.
#[derive(Debug, Clone, PartialEq)]
pub struct Samples {
    /// Number of parameters `p = dim + 1`.
    pub p: usize,
    /// Row-major regression matrix, `n * p` entries.
    pub phi: Vec<f64>,
    /// Targets.
    pub y: Vec<f64>,
    /// `1 / std` of each regressor column (0 for a constant column), for
    /// distances in standardised regressor space.
    pub inv_std: Vec<f64>,
}

impl Samples {
    /// From regressors built by `hysid_core` (constant column appended).
    pub fn from_regressors(reg: &Regressors) -> Self {
        let (n, d) = reg.x.shape();
        let p = d + 1;
        let mut phi = Vec::with_capacity(n * p);
        for k in 0..n {
            for j in 0..d {
                phi.push(reg.x[(k, j)]);
            }
            phi.push(1.0);
        }
        Self::new(p, phi, reg.y.iter().copied().collect())
    }

    /// From a row-major `phi` (constant column last) and targets.
    pub fn new(p: usize, phi: Vec<f64>, y: Vec<f64>) -> Self {
        let n = y.len();
        let d = p.saturating_sub(1);
        let mut mean = vec![0.0; d];
        let mut var = vec![0.0; d];
        for k in 0..n {
            for j in 0..d {
                mean[j] += phi[k * p + j] / n as f64;
            }
        }
        for k in 0..n {
            for j in 0..d {
                var[j] += (phi[k * p + j] - mean[j]).powi(2) / n as f64;
            }
        }
        let inv_std = var
            .iter()
            .map(|v| {
                if v.sqrt() > 1e-12 {
                    1.0 / v.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        Self { p, phi, y, inv_std }
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.y.len()
    }

    /// True when there is no sample.
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }

    /// `phi_k`.
    pub fn row(&self, k: usize) -> &[f64] {
        &self.phi[k * self.p..(k + 1) * self.p]
    }

    /// Residual `y_k - phi_k' theta`.
    pub fn residual(&self, k: usize, theta: &[f64]) -> f64 {
        self.y[k] - dot(self.row(k), theta)
    }

    /// Indices among `idx` whose residual is within `delta` of zero.
    pub fn satisfied(&self, idx: &[usize], theta: &[f64], delta: f64) -> Vec<usize> {
        idx.iter()
            .copied()
            .filter(|&k| self.residual(k, theta).abs() <= delta)
            .collect()
    }
}

/// Dot product.
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
