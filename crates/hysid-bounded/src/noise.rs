//! `delta = auto`: a noise bound estimated from local affine fits (ours; the
//! paper takes delta as given).
//!
//! Around up to [`CENTRES`] samples (evenly spaced in the record), the
//! `LOCAL = 3p` nearest samples in standardised regressor space are fitted by
//! least squares and the local noise level `sigma_c^2 = RSS / (LOCAL - p)`
//! is computed. Most local neighbourhoods lie inside one mode, so the median
//! of `sigma_c` estimates the noise standard deviation `sigma` of the modes.
//! The bound is `delta = 3 sigma` (covers 99.7 % of Gaussian noise and
//! 1.73 times the half-width of uniform noise, `sigma = b / sqrt 3`),
//! floored at `1e-6 std(y)` so that noise-free data get a positive bound.

use crate::refit::least_squares;
use crate::samples::Samples;

/// Centres of local fits (at most).
pub const CENTRES: usize = 400;
/// Multiple of the estimated noise standard deviation used as delta.
pub const SIGMAS: f64 = 3.0;

/// Local noise standard deviation estimate (median over centres).
pub fn noise_sigma(s: &Samples) -> f64 {
    let n = s.len();
    let p = s.p;
    let d = p - 1;
    let local = (3 * p).min(n);
    if local <= p {
        return 0.0;
    }
    let inv = &s.inv_std;
    let centres = CENTRES.min(n);
    let mut sig = Vec::with_capacity(centres);
    let mut dist: Vec<(f64, usize)> = Vec::with_capacity(n);
    for c in 0..centres {
        let k0 = c * n / centres;
        dist.clear();
        dist.extend((0..n).map(|k| {
            let dd: f64 = (0..d)
                .map(|j| ((s.row(k)[j] - s.row(k0)[j]) * inv[j]).powi(2))
                .sum();
            (dd, k)
        }));
        dist.select_nth_unstable_by(local - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let idx: Vec<usize> = dist[..local].iter().map(|&(_, k)| k).collect();
        if let Some(theta) = least_squares(s, &idx) {
            let rss: f64 = idx.iter().map(|&k| s.residual(k, &theta).powi(2)).sum();
            sig.push((rss / (local - p) as f64).sqrt());
        }
    }
    if sig.is_empty() {
        return 0.0;
    }
    let mid = sig.len() / 2;
    *sig.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
}

/// The `auto` error bound: `max(3 sigma, 1e-6 std(y))`.
pub fn auto_delta(s: &Samples) -> f64 {
    let n = s.len().max(1) as f64;
    let my = s.y.iter().sum::<f64>() / n;
    let sy = (s.y.iter().map(|v| (v - my).powi(2)).sum::<f64>() / n).sqrt();
    (SIGMAS * noise_sigma(s))
        .max(1e-6 * sy)
        .max(f64::MIN_POSITIVE)
}
