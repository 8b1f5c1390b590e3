//! One module per subcommand.

pub mod compare;
pub mod identify;
pub mod methods;
pub mod simulate;
pub mod sweep;
pub mod validate;

/// Estimated initial states as `x1 = 2.5, x2 = -0.1` (shortest round-trip
/// form of each value).
pub(crate) fn states_text(states: &std::collections::BTreeMap<String, f64>) -> String {
    states
        .iter()
        .map(|(name, v)| format!("{name} = {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}
