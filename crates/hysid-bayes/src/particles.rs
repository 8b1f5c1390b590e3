//! A mode's parameter pdf as a weighted particle cloud.
//!
//! `p_i(theta) ~ sum_j w_j delta(theta - theta_j)` with `sum_j w_j = 1`
//! (weights kept as logarithms). The predictive density of a sample is
//! `sum_j w_j N(y; phi' theta_j, sigma^2)`; Bayes' rule multiplies every
//! weight by its likelihood and normalises. When the effective sample size
//! `1 / sum_j w_j^2` falls below a fraction of the particles, the cloud is
//! resampled (systematic resampling) and moved by the kernel shrinkage of
//! Liu and West (2001): `theta <- a theta + (1 - a) theta_bar + h L e`
//! with `a = sqrt(1 - h^2)`, `L L'` the weighted covariance and `e`
//! standard normal, which keeps the cloud's mean and covariance while
//! giving back the diversity resampling removes. Fixed parameters have no
//! variance and so never move; moved particles are clamped into the
//! bounds. When too few particles carry the weight to estimate a
//! covariance (effective sample size below `2p` for `p` parameters), the
//! kernel takes the covariance of the Gaussian approximation of the
//! posterior instead (ours: with the small noise levels of real records a
//! single particle can take all the weight, and a zero covariance would
//! freeze the cloud there for good).

use crate::gaussian::LN_SQRT_2PI;
use crate::prior::{ModePrior, sqrt_psd};
use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// Draws of the prior outside its bounds are redrawn at most this often
/// before they are clamped into them.
pub const MAX_REDRAWS: usize = 100;

/// A weighted particle cloud.
#[derive(Debug, Clone, PartialEq)]
pub struct ParticleCloud {
    /// Parameters per particle.
    pub dim: usize,
    /// Particles, row-major (`n * dim`).
    pub theta: Vec<f64>,
    /// Normalised log weights.
    pub log_w: Vec<f64>,
}

impl ParticleCloud {
    /// `n` equally weighted draws of the prior, redrawn (at most
    /// [`MAX_REDRAWS`] times) while outside its bounds, then clamped.
    pub fn draw(prior: &ModePrior, n: usize, rng: &mut ChaCha8Rng) -> Self {
        let dim = prior.dim();
        let l = sqrt_psd(&prior.cov);
        let mut theta = Vec::with_capacity(n * dim);
        for _ in 0..n {
            let mut t = gaussian_draw(&prior.mean, &l, rng);
            for _ in 0..MAX_REDRAWS {
                if prior.admits(t.as_slice()) {
                    break;
                }
                t = gaussian_draw(&prior.mean, &l, rng);
            }
            prior.clamp(t.as_mut_slice());
            theta.extend(t.iter());
        }
        Self::equally_weighted(dim, theta)
    }

    /// The particles `theta` (row-major) with equal weights.
    pub fn equally_weighted(dim: usize, theta: Vec<f64>) -> Self {
        let n = theta.len() / dim.max(1);
        Self {
            dim,
            theta,
            log_w: vec![-(n.max(1) as f64).ln(); n],
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.log_w.len()
    }

    /// Whether the cloud has no particle.
    pub fn is_empty(&self) -> bool {
        self.log_w.is_empty()
    }

    /// Particle `j`.
    pub fn particle(&self, j: usize) -> &[f64] {
        &self.theta[j * self.dim..(j + 1) * self.dim]
    }

    /// The weights (summing to one).
    pub fn weights(&self) -> Vec<f64> {
        self.log_w.iter().map(|l| l.exp()).collect()
    }

    /// `ln N(y; phi' theta_j, sigma^2)` of every particle.
    fn log_likelihoods(&self, phi: &DVector<f64>, y: f64, sigma: f64) -> Vec<f64> {
        let c = -LN_SQRT_2PI - sigma.ln();
        (0..self.len())
            .map(|j| {
                let e = y - dot(self.particle(j), phi.as_slice());
                c - 0.5 * (e / sigma).powi(2)
            })
            .collect()
    }

    /// `ln p(y | phi)`, the log predictive density.
    pub fn log_predictive(&self, phi: &DVector<f64>, y: f64, sigma: f64) -> f64 {
        let ll = self.log_likelihoods(phi, y, sigma);
        log_sum_exp(self.log_w.iter().zip(&ll).map(|(w, l)| w + l))
    }

    /// Bayes' rule with the sample `(phi, y)`: weights times likelihoods,
    /// normalised.
    pub fn update(&mut self, phi: &DVector<f64>, y: f64, sigma: f64) {
        let ll = self.log_likelihoods(phi, y, sigma);
        for (w, l) in self.log_w.iter_mut().zip(&ll) {
            *w += l;
        }
        let total = log_sum_exp(self.log_w.iter().copied());
        for w in &mut self.log_w {
            *w -= total;
        }
    }

    /// `1 / sum_j w_j^2`.
    pub fn effective_sample_size(&self) -> f64 {
        1.0 / self.log_w.iter().map(|l| (2.0 * l).exp()).sum::<f64>()
    }

    /// The weighted mean.
    pub fn mean(&self) -> DVector<f64> {
        let mut m = DVector::zeros(self.dim);
        for (j, w) in self.weights().into_iter().enumerate() {
            for (k, t) in self.particle(j).iter().enumerate() {
                m[k] += w * t;
            }
        }
        m
    }

    /// The weighted covariance.
    pub fn covariance(&self) -> DMatrix<f64> {
        let m = self.mean();
        let mut c = DMatrix::zeros(self.dim, self.dim);
        for (j, w) in self.weights().into_iter().enumerate() {
            let d = DVector::from_iterator(
                self.dim,
                self.particle(j).iter().zip(m.iter()).map(|(t, m)| t - m),
            );
            c.ger(w, &d, &d, 1.0);
        }
        c
    }

    /// Systematic resampling, then the Liu-West move with bandwidth `h`
    /// (module doc), clamped into the prior's bounds. The weights become
    /// equal. `fallback` is the kernel covariance when the weight sits on
    /// fewer than `2p` effective particles.
    pub fn resample(
        &mut self,
        h: f64,
        prior: &ModePrior,
        fallback: &DMatrix<f64>,
        rng: &mut ChaCha8Rng,
    ) {
        let n = self.len();
        if n == 0 {
            return;
        }
        let mean = self.mean();
        let cov = if self.effective_sample_size() < 2.0 * self.dim as f64 {
            fallback.clone()
        } else {
            self.covariance()
        };
        let l = sqrt_psd(&cov);
        let a = (1.0 - h * h).max(0.0).sqrt();
        let picks = systematic(&self.weights(), rng.random::<f64>());
        let mut theta = Vec::with_capacity(n * self.dim);
        for &j in &picks {
            let e = DVector::from_fn(self.dim, |_, _| rng.sample::<f64, _>(StandardNormal));
            let jitter = &l * e;
            let mut t: Vec<f64> = (0..self.dim)
                .map(|k| a * self.particle(j)[k] + (1.0 - a) * mean[k] + h * jitter[k])
                .collect();
            prior.clamp(&mut t);
            theta.extend(t);
        }
        *self = Self::equally_weighted(self.dim, theta);
    }
}

/// `mean + L e` with standard normal `e`.
fn gaussian_draw(mean: &DVector<f64>, l: &DMatrix<f64>, rng: &mut ChaCha8Rng) -> DVector<f64> {
    let e = DVector::from_fn(mean.len(), |_, _| rng.sample::<f64, _>(StandardNormal));
    mean + l * e
}

/// Systematic resampling: particle `j` is picked once for every point
/// `(i + u) / n`, `i = 0..n`, in its cumulative-weight interval.
pub fn systematic(weights: &[f64], u: f64) -> Vec<usize> {
    let n = weights.len();
    let total: f64 = weights.iter().sum();
    let mut picks = Vec::with_capacity(n);
    let mut j = 0;
    let mut cum = weights.first().copied().unwrap_or(0.0) / total;
    for i in 0..n {
        let point = (i as f64 + u) / n as f64;
        while point > cum && j + 1 < n {
            j += 1;
            cum += weights[j] / total;
        }
        picks.push(j);
    }
    picks
}

/// `ln sum exp(v)`, stable; `-inf` for no term.
pub fn log_sum_exp(v: impl Iterator<Item = f64> + Clone) -> f64 {
    let max = v.clone().fold(f64::NEG_INFINITY, f64::max);
    if !max.is_finite() {
        return max;
    }
    max + v.map(|x| (x - max).exp()).sum::<f64>().ln()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
