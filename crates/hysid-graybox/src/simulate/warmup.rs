//! The states an initial-state rule leaves unknown, estimated from the
//! record's warm-up outputs alone.

use super::initial::state_solve;
use super::runs::run_from;
use crate::compile::CompiledModel;
use hysid_model::data::{Dataset, RowRange};
use hysid_model::simulate::SimError;
use hysid_numerics::budget::Deadline;
use hysid_numerics::least_squares::{CentralDifferences, Residuals, descend};

/// Iterations of the warm-up estimate's solver.
pub const ESTIMATE_ITERATIONS: usize = 100;

/// The finite-difference step of the warm-up estimate, in box-normalised
/// coordinates.
const STATE_DIFFERENCE: f64 = 1e-7;

/// The states [`CompiledModel::estimates`] lists, estimated from the
/// outputs of `data`'s warm-up alone (its first
/// [`crate::compile::CompiledInitial::warmup`] samples; the rows after it
/// are not read): the values within their bounds that minimise the sum of
/// squared differences between the measured and the simulated outputs
/// over the warm-up, from the rule's starting guesses, by
/// [`descend`] (Levenberg-Marquardt) on central differences in box-normalised
/// coordinates (steps projected onto the bounds). Empty when the rule estimates
/// nothing.
pub fn estimate(m: &CompiledModel, values: &[f64], data: &Dataset) -> Result<Vec<f64>, SimError> {
    if m.estimates.is_empty() {
        return Ok(Vec::new());
    }
    let window = warmup_window(m, data)?;
    let to_values = |z: &[f64]| -> Vec<f64> {
        m.estimates
            .iter()
            .zip(z)
            .map(|(e, z)| e.bounds[0] + (e.bounds[1] - e.bounds[0]) * z.clamp(0.0, 1.0))
            .collect()
    };
    let residuals = |z: &[f64]| -> Option<Vec<f64>> {
        let r = run_from(m, values, &to_values(z), &window).ok()?;
        let e: Vec<f64> = window.y().iter().zip(&r.y).map(|(a, b)| a - b).collect();
        e.iter().all(|v| v.is_finite()).then_some(e)
    };
    let z0: Vec<f64> = m
        .estimates
        .iter()
        .map(|e| {
            let [lo, hi] = e.bounds;
            if hi > lo {
                (e.start - lo) / (hi - lo)
            } else {
                0.5
            }
        })
        .collect();
    let unit = vec![[0.0, 1.0]; z0.len()];
    let problem = Residuals::new(
        residuals,
        z0.len(),
        Some(&unit),
        CentralDifferences {
            step: STATE_DIFFERENCE,
        },
    );
    let settings = state_solve(ESTIMATE_ITERATIONS);
    let descent = descend(&problem, z0.clone(), &settings, &Deadline::none());
    let z = match descent.v {
        Some(z) => z,
        // No step from the guess: a flat spot of the warm-up's cost (a
        // state a held friction or a dead zone hides). The descents from a
        // quarter and three quarters of the bounds are tried; the lowest
        // cost is kept, the guess among equals.
        None => {
            FLAT_SPOT_STARTS
                .iter()
                .map(|&q| {
                    let start = vec![q; unit.len()];
                    let d = descend(&problem, start.clone(), &settings, &Deadline::none());
                    (d.cost_after, d.v.unwrap_or(start))
                })
                .fold((descent.cost_after, z0), |best, (cost, z)| {
                    if cost < best.0 { (cost, z) } else { best }
                })
                .1
        }
    };
    Ok(to_values(&z))
}

/// Which of the estimated states (`estimated`, as [`estimate`] gave
/// them) the warm-up does not show: moving one by the estimate's finite
/// difference either way, within its bounds, leaves every simulated
/// output of the warm-up as it was (a state a held friction or a dead
/// zone hides there). The record does not determine such a state: its
/// value is where the estimate stopped (the guess, or a point of a flat
/// stretch).
pub fn unseen(
    m: &CompiledModel,
    values: &[f64],
    data: &Dataset,
    estimated: &[f64],
) -> Result<Vec<bool>, SimError> {
    let window = warmup_window(m, data)?;
    let outputs = |states: &[f64]| run_from(m, values, states, &window).ok().map(|r| r.y);
    let at = outputs(estimated);
    Ok(m.estimates
        .iter()
        .enumerate()
        .map(|(i, e)| {
            let step = STATE_DIFFERENCE * (e.bounds[1] - e.bounds[0]);
            let moved = |delta: f64| {
                let mut states = estimated.to_vec();
                states[i] = (states[i] + delta).clamp(e.bounds[0], e.bounds[1]);
                outputs(&states)
            };
            at.is_some() && step > 0.0 && moved(step) == at && moved(-step) == at
        })
        .collect())
}

/// The warm-up of `data` whose outputs estimate the unknown states: its
/// first [`crate::compile::CompiledInitial::warmup`] samples (an error
/// where the record is shorter).
fn warmup_window(m: &CompiledModel, data: &Dataset) -> Result<Dataset, SimError> {
    let w = m.initial.warmup().unwrap_or(1);
    if data.len() < w {
        return Err(SimError::TooShort {
            samples: data.len(),
            needed: w,
        });
    }
    data.slice(RowRange {
        start: Some(0),
        end: Some(w),
    })
    .map_err(|e| SimError::InitialState(e.to_string()))
}

/// Where [`estimate`] starts again, in box-normalised coordinates, when
/// the guess is a flat spot of the warm-up's cost.
const FLAT_SPOT_STARTS: [f64; 2] = [0.25, 0.75];
