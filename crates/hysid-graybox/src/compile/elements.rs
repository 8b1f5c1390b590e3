//! The elements (dry frictions, stops), checked and compiled.

use super::problem::{InvalidGrayBox, Problem};
use super::{CompiledElement, ModeLabels};
use crate::expr::Expression;
use crate::model::{Element, GrayBoxModel};
use std::collections::{BTreeMap, BTreeSet, HashMap};

/// The elements, checked: names, states, labels, one friction per velocity,
/// stop quantities of parameters only.
pub(super) fn compile_elements(
    m: &GrayBoxModel,
    labels: &LabelIndex,
    state_of: &dyn Fn(&str, &str) -> Result<usize, InvalidGrayBox>,
    parametric: &dyn Fn(&str, &str) -> Result<Expression, InvalidGrayBox>,
    restitution_of: &dyn Fn(&str, &str) -> Result<Expression, InvalidGrayBox>,
) -> Result<Vec<CompiledElement>, InvalidGrayBox> {
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
                    label: labels.of(mode),
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
                label: labels.of(mode),
            },
        });
    }
    Ok(elements)
}

/// Every mode label of a run ([`GrayBoxModel::mode_names`]) by its index.
pub(super) struct LabelIndex(HashMap<String, usize>);

impl LabelIndex {
    pub(super) fn of_model(m: &GrayBoxModel) -> Self {
        LabelIndex(
            (m.mode_names().into_iter().enumerate())
                .map(|(i, l)| (l, i))
                .collect(),
        )
    }

    /// The index of `label`, one of the model's (`mode_names` lists them
    /// all; 0 for another).
    fn of(&self, label: &str) -> usize {
        self.0.get(label).copied().unwrap_or_default()
    }
}

/// The mode labels of a run's samples, checked: an element's label (its
/// own `mode` or a mode's `element_modes`) is no mode's name or label, an
/// `element_modes` entry names an element, and a mode's label that is
/// another mode's name is that mode's label too.
pub(super) fn mode_labels(
    m: &GrayBoxModel,
    mode_index: &BTreeMap<&str, usize>,
    labels: &LabelIndex,
) -> Result<ModeLabels, InvalidGrayBox> {
    let modes: BTreeSet<&str> = (m.modes.iter())
        .flat_map(|q| [q.name.as_str(), q.label()])
        .collect();
    let own_label = |place: String, label: &str| {
        if label.is_empty() {
            return Err(InvalidGrayBox::new(place, None, Problem::EmptyLabel));
        }
        if modes.contains(label) {
            return Err(InvalidGrayBox::new(
                place,
                Some(label),
                Problem::LabelIsMode(label.into()),
            ));
        }
        Ok(())
    };
    for e in &m.elements {
        own_label(format!("element '{}'", e.name()), e.mode())?;
    }
    for q in &m.modes {
        if q.label().is_empty() {
            let place = format!("mode '{}'", q.name);
            return Err(InvalidGrayBox::new(place, None, Problem::EmptyLabel));
        }
        if let Some(&other) = mode_index.get(q.label())
            && m.modes[other].label() != q.label()
        {
            return Err(InvalidGrayBox::new(
                format!("mode '{}'", q.name),
                Some(q.label()),
                Problem::LabelOfOtherMode {
                    label: q.label().into(),
                    labelled: m.modes[other].label().into(),
                },
            ));
        }
        for (element, label) in &q.element_modes {
            let place = format!("mode '{}', element_modes", q.name);
            if !m.elements.iter().any(|e| e.name() == element) {
                return Err(InvalidGrayBox::new(
                    place,
                    Some(element),
                    Problem::UnknownElement(element.clone()),
                ));
            }
            own_label(place, label)?;
        }
    }
    Ok(ModeLabels {
        mode: m.modes.iter().map(|q| labels.of(q.label())).collect(),
        held: m
            .modes
            .iter()
            .map(|q| {
                m.elements
                    .iter()
                    .map(|e| labels.of(q.element_modes.get(e.name()).map_or(e.mode(), |l| l)))
                    .collect()
            })
            .collect(),
    })
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
