//! The initial-state rule and the states it estimates, checked, and the
//! output map the measured rule reads the state through.

use super::problem::{InvalidGrayBox, Problem};
use super::{CompiledInitial, CompiledMode, EstimatedState};
use crate::model::{DEFAULT_SAMPLES, Estimates, GrayBoxInitialState, GrayBoxModel};
use std::collections::BTreeMap;

/// The initial-state rule and the states it estimates, checked: known
/// states and modes, finite values, bounds with low <= high, no state both
/// measured and estimated.
pub(super) fn initial_rule(
    m: &GrayBoxModel,
    state_of: &dyn Fn(&str, &str) -> Result<usize, InvalidGrayBox>,
    mode_of: &dyn Fn(&str, &str) -> Result<usize, InvalidGrayBox>,
) -> Result<(CompiledInitial, Vec<EstimatedState>), InvalidGrayBox> {
    let place = "initial_state";
    let values = |given: &BTreeMap<String, f64>| -> Result<Vec<f64>, InvalidGrayBox> {
        let mut x = vec![0.0; m.states.len()];
        for (s, v) in given {
            if !v.is_finite() {
                return Err(InvalidGrayBox::new(
                    place,
                    Some(s),
                    Problem::NotFinite(s.clone()),
                ));
            }
            x[state_of(place, s)?] = *v;
        }
        Ok(x)
    };
    let mode = |q: &Option<String>| q.as_deref().map(|q| mode_of(place, q)).transpose();
    let warmup = |samples: usize| match samples {
        0 => Err(InvalidGrayBox::new(
            place,
            Some("samples"),
            Problem::NoWarmup,
        )),
        n => Ok(n),
    };
    // A given rule's warm-up without an estimate would be read by nothing.
    if let GrayBoxInitialState::Given {
        samples: Some(_),
        estimate,
        ..
    } = &m.initial_state
        && estimate.is_empty()
    {
        return Err(InvalidGrayBox::new(
            place,
            Some("samples"),
            Problem::WarmupWithoutEstimate,
        ));
    }
    let no_estimate = Estimates::new();
    let (rule, estimate, given, measured) = match &m.initial_state {
        GrayBoxInitialState::Given {
            values: v,
            mode: q,
            estimate,
            samples,
        } => (
            CompiledInitial::Given {
                x: values(v)?,
                mode: mode(q)?,
                samples: warmup(samples.unwrap_or(DEFAULT_SAMPLES))?,
            },
            estimate,
            v,
            vec![],
        ),
        GrayBoxInitialState::Measured {
            samples,
            position,
            velocity,
            velocity_tol,
            values: v,
            mode: q,
            estimate,
        } => (
            CompiledInitial::Measured {
                samples: warmup(*samples)?,
                position: state_of(place, position)?,
                velocity: velocity
                    .as_deref()
                    .map(|s| state_of(place, s))
                    .transpose()?,
                velocity_tol: velocity_tol.max(0.0),
                x: values(v)?,
                mode: mode(q)?,
            },
            estimate,
            v,
            std::iter::once(position).chain(velocity).collect(),
        ),
        GrayBoxInitialState::Steady { values: v, mode: q } => (
            CompiledInitial::Steady {
                x: values(v)?,
                mode: mode(q)?,
            },
            &no_estimate,
            v,
            vec![],
        ),
    };
    let mut estimates = Vec::with_capacity(estimate.len());
    for (name, &[lo, hi]) in estimate {
        let place = "initial_state, estimate";
        let state = state_of(place, name)?;
        if !(lo <= hi && (hi - lo).is_finite()) {
            return Err(InvalidGrayBox::new(
                place,
                Some(name),
                Problem::EstimateBounds(name.clone()),
            ));
        }
        if measured.contains(&name) {
            return Err(InvalidGrayBox::new(
                place,
                Some(name),
                Problem::MeasuredAndEstimated(name.clone()),
            ));
        }
        let start = match given.get(name) {
            Some(&value) if !(lo..=hi).contains(&value) => {
                return Err(InvalidGrayBox::new(
                    place,
                    Some(name),
                    Problem::EstimateStart {
                        name: name.clone(),
                        value,
                        low: lo,
                        high: hi,
                    },
                ));
            }
            Some(&value) => value,
            None => 0.5 * (lo + hi),
        };
        estimates.push(EstimatedState {
            state,
            name: name.clone(),
            bounds: [lo, hi],
            start,
        });
    }
    Ok((rule, estimates))
}

/// With the measured rule, the output map of every mode must be affine in
/// the position state ([`crate::expr::Expression::affine_in`]): the
/// state is read from the output through its inverse.
pub(super) fn check_sensor(
    m: &GrayBoxModel,
    initial: &CompiledInitial,
    modes: &[CompiledMode],
) -> Result<(), InvalidGrayBox> {
    let CompiledInitial::Measured { position, .. } = initial else {
        return Ok(());
    };
    if modes.iter().all(|q| q.output.affine_in(*position as u32)) {
        return Ok(());
    }
    let output = &m.outputs[0];
    Err(InvalidGrayBox::new(
        "initial_state",
        Some(&output.value),
        Problem::NotAffine {
            output: output.name.clone(),
            value: output.value.clone(),
            state: m.states[*position].clone(),
        },
    ))
}
