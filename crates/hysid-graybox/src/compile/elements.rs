//! The elements (dry frictions, stops), checked and compiled.

use super::CompiledElement;
use super::problem::{InvalidGrayBox, Problem};
use crate::expr::Expression;
use crate::model::{Element, GrayBoxModel};
use std::collections::{BTreeMap, BTreeSet, HashMap};

/// The elements, checked: names, states, labels, one friction per velocity,
/// stop quantities of parameters only.
pub(super) fn compile_elements(
    m: &GrayBoxModel,
    mode_index: &BTreeMap<&str, usize>,
    state_of: &dyn Fn(&str, &str) -> Result<usize, InvalidGrayBox>,
    parametric: &dyn Fn(&str, &str) -> Result<Expression, InvalidGrayBox>,
    restitution_of: &dyn Fn(&str, &str) -> Result<Expression, InvalidGrayBox>,
) -> Result<Vec<CompiledElement>, InvalidGrayBox> {
    let labels = m.mode_names();
    let label_index: HashMap<&str, usize> = labels
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    let label_of = |l: &str| label_index[l];
    let mut elements = Vec::with_capacity(m.elements.len());
    let mut names = BTreeSet::new();
    let mut friction_on = BTreeSet::new();
    for e in &m.elements {
        let place = format!("element '{}'", e.name());
        if !names.insert(e.name()) {
            return Err(InvalidGrayBox::new(
                "elements",
                Some(e.name()),
                Problem::Duplicate(e.name().into()),
            ));
        }
        if mode_index.contains_key(e.mode()) {
            return Err(InvalidGrayBox::new(
                &place,
                Some(e.mode()),
                Problem::LabelIsMode(e.mode().into()),
            ));
        }
        elements.push(match e {
            Element::DryFriction { velocity, mode, .. } => {
                let v = state_of(&place, velocity)?;
                if !friction_on.insert(v) {
                    return Err(InvalidGrayBox::new(
                        &place,
                        Some(velocity),
                        Problem::TwoFrictions(velocity.clone()),
                    ));
                }
                CompiledElement::DryFriction {
                    velocity: v,
                    label: label_of(mode),
                }
            }
            Element::Stop {
                position,
                velocity,
                at,
                side,
                restitution,
                rest_speed,
                mode,
                ..
            } => CompiledElement::Stop {
                position: state_of(&place, position)?,
                velocity: state_of(&place, velocity)?,
                at: parametric(&format!("{place}, at"), at)?,
                sign: side.sign(),
                restitution: restitution_of(&format!("{place}, restitution"), restitution)?,
                rest_speed: rest_speed.max(0.0),
                label: label_of(mode),
            },
        });
    }
    Ok(elements)
}

/// Checks that no two stops on one position leave no position between
/// them at the file's values (`value_of`: an expression of the parameters
/// at their values): a `side = "min"` stop must lie below every
/// `side = "max"` stop on the same state.
pub(super) fn check_stops(
    m: &GrayBoxModel,
    elements: &[CompiledElement],
    value_of: &dyn Fn(&Expression) -> f64,
) -> Result<(), InvalidGrayBox> {
    // (element, position state, sign, position) of every stop.
    let stops: Vec<(&Element, usize, f64, f64)> = (m.elements.iter().zip(elements))
        .filter_map(|(e, c)| match c {
            CompiledElement::Stop {
                position, at, sign, ..
            } => Some((e, *position, *sign, value_of(at))),
            CompiledElement::DryFriction { .. } => None,
        })
        .collect();
    for &(below, state, _, at_least) in stops.iter().filter(|s| s.2 < 0.0) {
        for &(above, _, _, at_most) in stops.iter().filter(|s| s.2 > 0.0 && s.1 == state) {
            if let Element::Stop { at, .. } = above
                && at_least >= at_most
            {
                return Err(InvalidGrayBox::new(
                    format!("element '{}'", above.name()),
                    Some(at),
                    Problem::CrossedStops {
                        below: below.name().into(),
                        at_least,
                        above: above.name().into(),
                        at_most,
                    },
                ));
            }
        }
    }
    Ok(())
}
