//! Trimmed re-estimation of the mode parameters on the samples of their
//! regions, the stage between a PWARX back-end's `fit` and the
//! simulation-error refinement ([`crate::pwarx::refine`]) when the option `trim`
//! is set.
//!
//! A back-end's regions are estimated from its own mode assignment, and a
//! few samples near a boundary fall in a region whose mode did not
//! generate them. Where the modes are discontinuous across the boundary,
//! such a sample's residual in its region's mode is of the size of the
//! jump, not of the noise, and ordinary least squares on the region's
//! samples is pulled by it (the mixed points of Ferrari-Trecate et al.,
//! Automatica 39(2), 2003, section 3, which their confidence weights only
//! down-weight). This stage estimates every mode again from the samples its
//! region holds (the rule of [`region_of`], the simulator's), leaving out
//! those whose residual exceeds `trim` robust standard deviations of the
//! mode:
//!
//! ```text
//! keep k in region i  <=>  |y(k) - theta_i . [x(k); 1]| <= trim * max(s_i, s_min)
//! s_i = 1.4826 * median_{k in region i} |y(k) - theta_i . [x(k); 1]|
//! ```
//!
//! (the median absolute deviation, scaled to the standard deviation of
//! Gaussian errors: Hampel, JASA 69, 1974; the rejection rule of Hampel et
//! al., *Robust Statistics*, 1986, section 1.4), then least squares under
//! the priors on the samples kept ([`constrained::fit_modes_on`]: ties,
//! fixed values, equalities and bounds hold as in the back-end's fit). The
//! residuals of the new parameters give the next round's samples, from the
//! back-end's parameters on, until the samples kept no longer change, for
//! at most [`MAX_ROUNDS`] rounds. The regions are not changed.
//!
//! A fit whose trimming converged at the same cutoff is returned as it
//! came: its parameters are the rule's fixed point (their inliers are the
//! samples they were estimated on), so another pass would estimate them
//! again bit for bit and only lose the record of its rounds. A back-end
//! that trims as a step of its own (`cluster` on a clustering sample)
//! is thus not trimmed twice.

use crate::constrained::{self, Parametrisation};
use crate::pwarx::assemble::PwarxFit;
use crate::pwarx::failure::PwarxFailure;
use crate::pwarx::prepare::PwarxData;
use hysid_core::backend::IdentifyError;
use hysid_model::model::{PwarxMode, Trimming, TrimmingStatus, region_of};
use hysid_model::regressors::Regressors;
use hysid_model::statistics::{MAD_TO_SIGMA, median};

/// Bound on the least-squares rounds.
pub const MAX_ROUNDS: usize = 20;
/// `fit` with its ordinary modes' parameters estimated again on the samples
/// of their regions, residuals beyond `cutoff` robust standard deviations
/// left out (see the module doc); the outcome in `fit.trimming`. With
/// `None`, `fit` unchanged. `cutoff` is the checked option `trim` (finite
/// and positive).
pub fn trim<D>(
    data: &PwarxData<'_>,
    mut fit: PwarxFit<D>,
    cutoff: Option<f64>,
) -> Result<PwarxFit<D>, IdentifyError> {
    let Some(cutoff) = cutoff else {
        return Ok(fit);
    };
    if fit
        .trimming
        .as_ref()
        .is_some_and(|t| t.cutoff == cutoff && t.status == TrimmingStatus::Converged)
    {
        return Ok(fit);
    }
    let par = Parametrisation::from_priors(data.priors(), &data.spec, fit.modes.len())
        .map_err(|e| data.prior_error(e))?;
    let reg = data.ordinary_regressors();
    let floor = rounding_floor(&reg);
    let members = region_members(&fit.modes, &reg);
    let mut thetas: Vec<Vec<f64>> = fit.modes.iter().map(|m| m.theta.clone()).collect();
    let mut used: Option<Vec<Vec<usize>>> = None;
    let mut status = TrimmingStatus::RoundLimit;
    let mut rounds = 0;
    while rounds < MAX_ROUNDS {
        let kept = inliers(&reg, &members, &thetas, cutoff, floor);
        if used.as_ref() == Some(&kept) {
            status = TrimmingStatus::Converged;
            break;
        }
        if kept.iter().any(|rows| rows.len() < par.n_params()) {
            status = TrimmingStatus::TooFewSamples;
            break;
        }
        thetas = constrained::fit_modes_on(&par, &reg, &kept)
            .map_err(|e| IdentifyError::failed(PwarxFailure::Trim(e)))?;
        used = Some(kept);
        rounds += 1;
    }
    let left_out = match &used {
        Some(kept) => members
            .iter()
            .zip(kept)
            .map(|(all, k)| all.len() - k.len())
            .collect(),
        None => vec![0; members.len()],
    };
    for (mode, theta) in fit.modes.iter_mut().zip(thetas) {
        mode.theta = theta;
    }
    fit.trimming = Some(Trimming {
        cutoff,
        rounds,
        left_out,
        status,
    });
    Ok(fit)
}

/// The rows of `reg` in each mode's region, by [`region_of`].
fn region_members(modes: &[PwarxMode], reg: &Regressors) -> Vec<Vec<usize>> {
    let mut members = vec![Vec::new(); modes.len()];
    let mut x = vec![0.0; reg.x.ncols()];
    for k in 0..reg.len() {
        for (j, v) in x.iter_mut().enumerate() {
            *v = reg.x[(k, j)];
        }
        members[region_of(modes.iter().map(|m| &m.region), &x).mode].push(k);
    }
    members
}

/// The rows of each mode's region whose residual under `thetas` is within
/// `cutoff` robust standard deviations of the mode, each at least `floor`
/// (see the module doc).
fn inliers(
    reg: &Regressors,
    members: &[Vec<usize>],
    thetas: &[Vec<f64>],
    cutoff: f64,
    floor: f64,
) -> Vec<Vec<usize>> {
    members
        .iter()
        .zip(thetas)
        .map(|(rows, theta)| {
            let residuals: Vec<f64> = rows.iter().map(|&k| residual(reg, k, theta)).collect();
            let limit = cutoff * robust_sigma(&residuals).max(floor);
            rows.iter()
                .zip(&residuals)
                .filter(|(_, r)| r.abs() <= limit)
                .map(|(&k, _)| k)
                .collect()
        })
        .collect()
}

/// `y(k) - theta . [x(k); 1]`.
fn residual(reg: &Regressors, k: usize, theta: &[f64]) -> f64 {
    let d = reg.x.ncols();
    let prediction: f64 = (0..d).map(|j| theta[j] * reg.x[(k, j)]).sum::<f64>() + theta[d];
    reg.y[k] - prediction
}

/// [`MAD_TO_SIGMA`] times the median absolute residual (0 for none).
fn robust_sigma(residuals: &[f64]) -> f64 {
    let mut a: Vec<f64> = residuals.iter().map(|r| r.abs()).collect();
    MAD_TO_SIGMA * median(&mut a).unwrap_or(0.0)
}

/// The smallest robust standard deviation a mode is given (`s_min`): a few
/// rounding errors of the record's largest target, so that a noise-free
/// mode keeps the samples it fits to rounding.
fn rounding_floor(reg: &Regressors) -> f64 {
    let scale = reg.y.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    1e3 * f64::EPSILON * scale
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constrained::PriorConflict;
    use crate::pwarx;
    use hysid_core::backend::Problem;
    use hysid_core::priors::Priors;
    use hysid_model::data::Dataset;
    use hysid_model::geometry::Polyhedron;
    use hysid_model::regressors::RegressorSpec;
    use hysid_testkit::uniform;
    use proptest::prelude::*;

    /// `y(k) = b u(k-1) + c`: mode 0 where `u(k-1) <= 0`, mode 1 where
    /// `u(k-1) > 0`, with a jump of 2 at the boundary.
    const TRUTH: [[f64; 2]; 2] = [[1.0, 1.0], [1.0, -1.0]];

    /// Where the fit's regions put the boundary: the samples with
    /// `0 < u(k-1) <= SHIFT` lie in mode 0's region but were generated by
    /// mode 1.
    const SHIFT: f64 = 0.1;

    /// The record of the true modes, noise uniform in `[-noise, noise]`.
    fn record(n: usize, noise: f64, seed: u64) -> Dataset {
        let u = uniform(n, seed);
        let e = uniform(n, seed + 1);
        let mut y = vec![0.0; n];
        for k in 1..n {
            let t = TRUTH[usize::from(u[k - 1] > 0.0)];
            y[k] = t[0] * u[k - 1] + t[1] + noise * e[k];
        }
        Dataset::siso(u, y, None).unwrap()
    }

    /// The fit a back-end might return: parameters `thetas`, the boundary
    /// at [`SHIFT`] instead of 0.
    fn shifted_fit(thetas: Vec<Vec<f64>>) -> PwarxFit<()> {
        let regions = [
            Polyhedron::from_inequalities(vec![vec![1.0]], vec![SHIFT]),
            Polyhedron::from_inequalities(vec![vec![-1.0]], vec![-SHIFT]),
        ];
        PwarxFit::complete(PwarxMode::unnamed(thetas, regions), ())
    }

    /// `data` under `priors`, prepared for the stage (orders 0 and 1).
    fn prepared<'a>(data: &'a Dataset, priors: &'a Priors) -> PwarxData<'a> {
        let problem = Problem {
            data,
            orders: RegressorSpec::new(0, 1, 1),
            priors,
            priors_origin: None,
        };
        pwarx::prepare(&problem, "test").unwrap()
    }

    fn truth() -> Vec<Vec<f64>> {
        TRUTH.iter().map(|t| t.to_vec()).collect()
    }

    fn largest_error(fit: &PwarxFit<()>) -> f64 {
        fit.modes
            .iter()
            .zip(TRUTH)
            .flat_map(|(m, t)| m.theta.iter().zip(t).map(|(g, w)| (g - w).abs()))
            .fold(0.0, f64::max)
    }

    /// With the boundary misplaced, least squares on the regions' samples
    /// (a cutoff no residual reaches) is pulled by the samples of the wrong
    /// mode; trimmed at 3 robust standard deviations, those samples are
    /// left out, and the estimate is that of the noise alone.
    #[test]
    fn samples_of_the_wrong_mode_are_left_out() {
        let data = record(2000, 0.02, 5);
        let priors = Priors::default();
        let prepared = prepared(&data, &priors);
        let wrong: usize = data.u(0)[..1999]
            .iter()
            .filter(|&&u| u > 0.0 && u <= SHIFT)
            .count();
        assert!(wrong > 50, "{wrong} samples in the misplaced strip");

        let plain = trim(&prepared, shifted_fit(truth()), Some(1e9)).unwrap();
        assert_eq!(plain.trimming.as_ref().unwrap().left_out, vec![0, 0]);
        assert!(largest_error(&plain) > 0.05, "{:?}", plain.modes);

        let trimmed = trim(&prepared, shifted_fit(truth()), Some(3.0)).unwrap();
        let t = trimmed.trimming.clone().unwrap();
        assert_eq!(t.status, TrimmingStatus::Converged, "{t:?}");
        assert!(t.rounds >= 1 && t.rounds < MAX_ROUNDS, "{t:?}");
        assert!(
            t.left_out[0] >= wrong && t.left_out[0] <= wrong + 20,
            "{t:?}, {wrong} wrong"
        );
        assert!(t.left_out[1] <= 20, "{t:?}");
        assert!(largest_error(&trimmed) < 0.005, "{:?}", trimmed.modes);
        assert_eq!(
            trimmed.modes[0].region,
            shifted_fit(truth()).modes[0].region
        );
    }

    /// A converged trimming is the rule's fixed point: trimmed again at
    /// the same cutoff, its parameters come back bit for bit in one round.
    /// So a fit that carries that record is returned as it came, its
    /// rounds kept; at another cutoff the stage runs again.
    #[test]
    fn a_converged_trimming_is_not_repeated() {
        // A tight cutoff on uniform noise: the samples kept shrink over
        // several rounds before they settle.
        let data = record(2000, 0.02, 4);
        let priors = Priors::default();
        let prepared = prepared(&data, &priors);
        let trimmed = trim(&prepared, shifted_fit(truth()), Some(1.0)).unwrap();
        let first = trimmed.trimming.clone().unwrap();
        assert_eq!(first.status, TrimmingStatus::Converged, "{first:?}");
        assert!(first.rounds >= 2, "{first:?}");
        let thetas = |f: &PwarxFit<()>| -> Vec<Vec<f64>> {
            f.modes.iter().map(|m| m.theta.clone()).collect()
        };

        let mut unrecorded = trimmed.clone();
        unrecorded.trimming = None;
        let rerun = trim(&prepared, unrecorded, Some(1.0)).unwrap();
        assert_eq!(thetas(&rerun), thetas(&trimmed));
        assert_eq!(rerun.trimming.as_ref().unwrap().rounds, 1);

        let again = trim(&prepared, trimmed.clone(), Some(1.0)).unwrap();
        assert_eq!(thetas(&again), thetas(&trimmed));
        assert_eq!(again.trimming, Some(first));

        let other = trim(&prepared, trimmed, Some(3.0)).unwrap();
        assert_eq!(other.trimming.unwrap().cutoff, 3.0);
    }

    /// A noise-free record keeps every sample its region's mode generated:
    /// the rounding floor of the scale.
    #[test]
    fn noise_free_modes_are_recovered_exactly() {
        let data = record(500, 0.0, 9);
        let priors = Priors::default();
        let prepared = prepared(&data, &priors);
        let start = vec![vec![0.9, 1.2], vec![1.1, -0.8]];
        let fit = trim(&prepared, shifted_fit(start), Some(3.0)).unwrap();
        assert!(largest_error(&fit) < 1e-9, "{:?}", fit.modes);
        assert_eq!(fit.trimming.unwrap().left_out[1], 0);
    }

    /// No cutoff: the fit is returned as it came, with no record.
    #[test]
    fn no_cutoff_leaves_the_fit_alone() {
        let data = record(100, 0.02, 3);
        let priors = Priors::default();
        let prepared = prepared(&data, &priors);
        let start = vec![vec![0.5, 0.5], vec![2.0, 0.0]];
        let fit = trim(&prepared, shifted_fit(start.clone()), None).unwrap();
        assert!(fit.trimming.is_none());
        assert_eq!(fit.modes[0].theta, start[0]);
    }

    /// A mode whose region holds fewer samples than it has parameters keeps
    /// the back-end's estimate, and the record says why.
    #[test]
    fn too_few_samples_keep_the_fit() {
        let data = record(2, 0.02, 3);
        let priors = Priors::default();
        let prepared = prepared(&data, &priors);
        let fit = trim(&prepared, shifted_fit(truth()), Some(3.0)).unwrap();
        let t = fit.trimming.unwrap();
        assert_eq!((t.status, t.rounds), (TrimmingStatus::TooFewSamples, 0));
        assert_eq!(fit.modes[0].theta, truth()[0]);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 32, ..ProptestConfig::default() })]

        /// Random ties, fixed values, bounds and equalities: after the
        /// trimmed re-estimation they hold to 1e-9 (ties and fixed values
        /// bit for bit).
        #[test]
        fn priors_hold_after_trimming(
            with_tie in any::<bool>(),
            fixed_c in prop::option::of(-1.5f64..1.5),
            lo in 0.0f64..1.5,
            width in 0.05f64..1.0,
            value in -1.0f64..2.0,
            eq_c in -1.0f64..1.0,
            cutoff in 1.5f64..6.0,
            seed in 0u64..1000,
        ) {
            let constraints = crate::fixtures::ConstraintPriors {
                terms: &[("b1", 1.0)],
                eq_c,
                value,
                lo,
                width,
                tied: with_tie.then_some("b1"),
                fixed_c,
            };
            let priors = constraints.priors();
            let data = record(300, 0.05, seed);
            let prepared = prepared(&data, &priors);
            let par = match Parametrisation::from_priors(&priors, &prepared.spec, 2) {
                Ok(par) => par,
                // No b1 inside its bounds satisfies the equality and fixed c.
                Err(PriorConflict::OutsideBounds) => return Ok(()),
                Err(e) => return Err(TestCaseError::fail(e.to_string())),
            };
            let start = match par.project(&truth()) {
                Ok(t) => t,
                Err(_) => return Ok(()), // bounds and equality without a common point
            };
            let fit = trim(&prepared, shifted_fit(start), Some(cutoff)).unwrap();
            prop_assert!(fit.trimming.is_some());
            let thetas: Vec<Vec<f64>> = fit.modes.iter().map(|m| m.theta.clone()).collect();
            let broken = constraints.broken(&prepared.spec.param_names(), &thetas);
            prop_assert!(broken.is_none(), "{}", broken.unwrap_or_default());
        }
    }
}
