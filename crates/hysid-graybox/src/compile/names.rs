//! The model's header, sizes and names: the format version and the
//! internal step, the limits, the modes by name, every definition name and
//! the slot of every name.

use super::problem::{InvalidGrayBox, Problem};
use super::{MAX_DEFINITIONS, MAX_ELEMENTS, MAX_MODE_DEFINITIONS, MAX_MODES};
use crate::expr::Function;
use crate::model::{FORMAT_VERSION, GrayBoxModel};
use std::collections::{BTreeMap, HashMap, HashSet};

/// The format version and the internal step.
pub(super) fn check_header(m: &GrayBoxModel) -> Result<(), InvalidGrayBox> {
    if m.format != FORMAT_VERSION {
        return Err(InvalidGrayBox::new(
            "format",
            Some("format"),
            Problem::Version(m.format),
        ));
    }
    if !(m.internal_step > 0.0 && m.internal_step.is_finite()) {
        return Err(InvalidGrayBox::new(
            "internal_step",
            Some("internal_step"),
            Problem::InternalStep,
        ));
    }
    Ok(())
}

/// The limits on definitions, modes and elements ([`MAX_DEFINITIONS`],
/// [`MAX_MODES`], [`MAX_ELEMENTS`], [`MAX_MODE_DEFINITIONS`]), checked
/// before any is compiled.
pub(super) fn check_sizes(m: &GrayBoxModel, definitions: usize) -> Result<(), InvalidGrayBox> {
    for (what, count, limit) in [
        ("definitions", definitions, MAX_DEFINITIONS),
        ("modes", m.modes.len(), MAX_MODES),
        ("elements", m.elements.len(), MAX_ELEMENTS),
    ] {
        if count > limit {
            return Err(InvalidGrayBox::new(
                what,
                None,
                Problem::TooMany { what, count, limit },
            ));
        }
    }
    let own = m.modes.iter().filter(|q| !q.definitions.is_empty()).count();
    if own * definitions > MAX_MODE_DEFINITIONS {
        return Err(InvalidGrayBox::new(
            "modes",
            None,
            Problem::ModeDefinitions {
                modes: own,
                definitions,
            },
        ));
    }
    Ok(())
}

/// The modes by name, checked: at least one input, one output, at least
/// one mode, modes named by identifiers, none twice.
pub(super) fn mode_index(m: &GrayBoxModel) -> Result<BTreeMap<&str, usize>, InvalidGrayBox> {
    if m.inputs.is_empty() {
        return Err(InvalidGrayBox::new(
            "inputs",
            Some("inputs"),
            Problem::NoInput,
        ));
    }
    if m.outputs.len() != 1 {
        return Err(InvalidGrayBox::new(
            "outputs",
            None,
            Problem::Outputs(m.outputs.len()),
        ));
    }
    if m.modes.is_empty() {
        return Err(InvalidGrayBox::new("modes", None, Problem::NoMode));
    }
    let mut index = BTreeMap::new();
    for (i, q) in m.modes.iter().enumerate() {
        if !is_identifier(&q.name) {
            return Err(InvalidGrayBox::new(
                "modes",
                Some(&q.name),
                Problem::BadName(q.name.clone()),
            ));
        }
        if index.insert(q.name.as_str(), i).is_some() {
            return Err(InvalidGrayBox::new(
                "modes",
                Some(&q.name),
                Problem::Duplicate(q.name.clone()),
            ));
        }
    }
    Ok(index)
}

/// Every definition name: the model's, then those only modes give, in the
/// order the modes first give them.
pub(super) fn definition_names(m: &GrayBoxModel) -> Vec<&String> {
    let mut names: Vec<&String> = m.definitions.keys().collect();
    let mut seen: HashSet<&String> = names.iter().copied().collect();
    for q in &m.modes {
        for d in q.definitions.keys() {
            if seen.insert(d) {
                names.push(d);
            }
        }
    }
    names
}

/// The slot of every state, input, parameter and definition
/// (`definitions`, as [`definition_names`] lists them), in that order;
/// checks names and parameters.
pub(super) fn symbol_table<'m>(
    m: &'m GrayBoxModel,
    definitions: &[&'m String],
) -> Result<HashMap<&'m str, usize>, InvalidGrayBox> {
    let mut table = HashMap::with_capacity(
        m.states.len() + m.inputs.len() + m.parameters.len() + definitions.len(),
    );
    let mut slot = 0;
    let mut add = |what: &str, name: &'m str| -> Result<(), InvalidGrayBox> {
        if !is_identifier(name) {
            return Err(InvalidGrayBox::new(
                what,
                Some(name),
                Problem::BadName(name.into()),
            ));
        }
        if let Some(first) = table.insert(name, slot) {
            let (nx, ni) = (m.states.len(), m.inputs.len());
            let kind = match first {
                s if s < nx => "a state",
                s if s < nx + ni => "an input",
                s if s < nx + ni + m.parameters.len() => "a parameter",
                _ => "a definition",
            };
            let problem = Problem::Taken {
                name: name.into(),
                kind,
            };
            return Err(InvalidGrayBox::new(what, Some(name), problem));
        }
        slot += 1;
        Ok(())
    };
    for s in &m.states {
        add("states", s)?;
    }
    for s in &m.inputs {
        add("inputs", s)?;
    }
    for p in &m.parameters {
        add("parameters", &p.name)?;
        let [lo, hi] = p.bounds;
        // A finite width too: the fit's coordinates run over `hi - lo`.
        if !(p.value.is_finite() && lo <= p.value && p.value <= hi && (hi - lo).is_finite()) {
            return Err(InvalidGrayBox::new(
                "parameters",
                Some(&p.name),
                Problem::Parameter {
                    name: p.name.clone(),
                    value: p.value,
                    low: lo,
                    high: hi,
                },
            ));
        }
    }
    for d in definitions {
        add("definitions", d)?;
    }
    Ok(table)
}

/// Whether `name` can name a state, an input, a parameter, a definition or
/// a mode: a letter or `_`, then letters, digits or `_`, and not the name
/// of a function or a boolean.
pub fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
        && Function::ALL.iter().all(|f| f.name() != name)
        && !matches!(name, "true" | "false")
}
