//! The noise level of a PWARX record, estimated from local affine fits.
//!
//! Around up to [`CENTRES`] samples (evenly spaced in the record), the
//! `3p` nearest samples in standardised regressor space (`p = dim + 1`
//! parameters) are fitted by least squares and the local noise level
//! `sigma_c^2 = RSS / (3p - p)` is computed. Most local neighbourhoods lie
//! inside one mode, so the median of `sigma_c` estimates the standard
//! deviation of the equation noise of the modes. This is the local step of
//! the clustering procedure (Ferrari-Trecate et al. 2003) used as an
//! estimator; the bounded-error and Bayesian back-ends start from it when
//! their noise level is not given.

use crate::linalg;
use hysid_model::regressors::Regressors;
use hysid_model::statistics::upper_median;
use nalgebra::{DMatrix, DVector};

/// Centres of local fits (at most).
pub const CENTRES: usize = 400;

/// The median local noise standard deviation; 0 when no local fit is
/// possible (fewer than `3p` samples or every fit failed).
pub fn local_noise_sigma(reg: &Regressors) -> f64 {
    let (n, d) = reg.x.shape();
    let p = d + 1;
    let local = (3 * p).min(n);
    if local <= p {
        return 0.0;
    }
    let inv_std = inverse_column_std(&reg.x);
    let centres = CENTRES.min(n);
    let mut sigmas = Vec::with_capacity(centres);
    let mut dist: Vec<(f64, usize)> = Vec::with_capacity(n);
    for c in 0..centres {
        let k0 = c * n / centres;
        dist.clear();
        dist.extend((0..n).map(|k| {
            let dd: f64 = (0..d)
                .map(|j| ((reg.x[(k, j)] - reg.x[(k0, j)]) * inv_std[j]).powi(2))
                .sum();
            (dd, k)
        }));
        dist.select_nth_unstable_by(local - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        if let Some(rss) = local_rss(reg, &dist[..local]) {
            sigmas.push((rss / (local - p) as f64).sqrt());
        }
    }
    upper_median(&mut sigmas).unwrap_or(0.0)
}

/// The smallest noise level a record is given, `1e-6 std(y)` (population
/// standard deviation, at least the smallest positive number): noise-free
/// records keep positive bounds and finite densities.
pub fn noise_floor(reg: &Regressors) -> f64 {
    let n = reg.y.len().max(1) as f64;
    let mean = reg.y.iter().sum::<f64>() / n;
    let std = (reg.y.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
    (1e-6 * std).max(f64::MIN_POSITIVE)
}

/// `1 / std` of every column (population standard deviation; 0 for a
/// constant column).
fn inverse_column_std(x: &DMatrix<f64>) -> Vec<f64> {
    let n = x.nrows().max(1) as f64;
    (0..x.ncols())
        .map(|j| {
            let col = x.column(j);
            let mean = col.iter().sum::<f64>() / n;
            let sd = (col.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
            if sd > 1e-12 { 1.0 / sd } else { 0.0 }
        })
        .collect()
}

/// Residual sum of squares of the affine least-squares fit on `rows`
/// (`(distance, row)` pairs); `None` when the fit fails or is not finite.
fn local_rss(reg: &Regressors, rows: &[(f64, usize)]) -> Option<f64> {
    let d = reg.x.ncols();
    let phi = DMatrix::from_fn(rows.len(), d + 1, |r, j| {
        if j < d { reg.x[(rows[r].1, j)] } else { 1.0 }
    });
    let y = DVector::from_iterator(rows.len(), rows.iter().map(|&(_, k)| reg.y[k]));
    let sol = linalg::lstsq(&phi, &y).ok()?;
    if !sol.theta.iter().all(|v| v.is_finite()) {
        return None;
    }
    let res = &y - &phi * &sol.theta;
    Some(res.norm_squared())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two affine modes with uniform noise of half-width 0.3 (standard
    /// deviation 0.3 / sqrt 3): the estimate lies within 20 % of it.
    #[test]
    fn estimates_the_noise_of_a_two_mode_record() {
        let n = 2000;
        let (inputs, errors) = (hysid_testkit::uniform(n, 1), hysid_testkit::uniform(n, 2));
        let x = DMatrix::from_fn(n, 1, |_, _| 0.0);
        let mut reg = Regressors {
            x,
            y: DVector::zeros(n),
            samples: (0..n).collect(),
        };
        for k in 0..n {
            let u = 2.0 * inputs[k];
            let e = 0.3 * errors[k];
            reg.x[(k, 0)] = u;
            reg.y[k] = if u < 0.0 { 1.0 + 2.0 * u } else { 1.0 - u } + e;
        }
        let sigma = local_noise_sigma(&reg);
        let truth = 0.3 / 3f64.sqrt();
        assert!(
            (sigma / truth - 1.0).abs() < 0.2,
            "sigma {sigma} vs {truth}"
        );
    }

    #[test]
    fn too_few_samples_give_zero() {
        let reg = Regressors {
            x: DMatrix::from_row_slice(2, 1, &[0.0, 1.0]),
            y: DVector::from_vec(vec![0.0, 1.0]),
            samples: vec![0, 1],
        };
        assert_eq!(local_noise_sigma(&reg), 0.0);
    }
}
