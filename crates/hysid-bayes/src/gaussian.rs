//! The exact posterior of a Gaussian prior under Gaussian noise.
//!
//! With `theta ~ N(m, P)` and `y = phi' theta + e`, `e ~ N(0, sigma^2)`,
//! the predictive pdf of `y` is `N(phi' m, phi' P phi + sigma^2)` and the
//! posterior after `y` is Gaussian again (the recursive least-squares or
//! Kalman update). This is what the particle approximation approximates
//! when the prior is not truncated; it serves as `posterior = gaussian`
//! and as the reference of the particle cloud in the tests.

use crate::prior::ModePrior;
use nalgebra::{DMatrix, DVector};

/// `ln sqrt(2 pi)`.
pub(crate) const LN_SQRT_2PI: f64 = 0.918_938_533_204_672_8;

/// A Gaussian pdf of one mode's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct GaussianPosterior {
    /// Mean.
    pub mean: DVector<f64>,
    /// Covariance.
    pub cov: DMatrix<f64>,
}

impl GaussianPosterior {
    /// The prior itself (its bounds are not represented).
    pub fn from_prior(prior: &ModePrior) -> Self {
        Self {
            mean: prior.mean.clone(),
            cov: prior.cov.clone(),
        }
    }

    /// `ln p(y | phi)`, the log predictive density, with `phi = [x; 1]`.
    pub fn log_predictive(&self, phi: &DVector<f64>, y: f64, sigma: f64) -> f64 {
        let (r, s2) = self.innovation(phi, y, sigma);
        -LN_SQRT_2PI - 0.5 * s2.ln() - 0.5 * r * r / s2
    }

    /// Bayes' rule with the sample `(phi, y)`.
    pub fn update(&mut self, phi: &DVector<f64>, y: f64, sigma: f64) {
        let (r, s2) = self.innovation(phi, y, sigma);
        let pphi = &self.cov * phi;
        self.mean.axpy(r / s2, &pphi, 1.0);
        self.cov.ger(-1.0 / s2, &pphi, &pphi, 1.0);
        // Keep the covariance exactly symmetric against rounding.
        let sym = 0.5 * (&self.cov + self.cov.transpose());
        self.cov = sym;
    }

    /// Residual `y - phi' m` and its variance `phi' P phi + sigma^2`.
    fn innovation(&self, phi: &DVector<f64>, y: f64, sigma: f64) -> (f64, f64) {
        let r = y - phi.dot(&self.mean);
        let s2 = (phi.dot(&(&self.cov * phi)) + sigma * sigma).max(f64::MIN_POSITIVE);
        (r, s2)
    }
}
