//! `delta = auto`: a noise bound estimated from local affine fits (ours; the
//! paper takes delta as given).
//!
//! The noise standard deviation `sigma` of the modes is the median local
//! one of `hysid_estimation::noise::local_noise_sigma`. The bound is
//! `delta = 3 sigma` (covers 99.7 % of Gaussian noise and 1.73 times the
//! half-width of uniform noise, `sigma = b / sqrt 3`), floored at
//! `1e-6 std(y)` so that noise-free data get a positive bound.

use hysid_estimation::noise::{local_noise_sigma, noise_floor};
use hysid_model::regressors::Regressors;

/// Multiple of the estimated noise standard deviation used as delta.
pub const SIGMAS: f64 = 3.0;

/// The `auto` error bound: `max(3 sigma, 1e-6 std(y))`.
pub fn auto_delta(reg: &Regressors) -> f64 {
    (SIGMAS * local_noise_sigma(reg)).max(noise_floor(reg))
}
