//! Named physical parameters of the models declared by their physics.

use serde::{Deserialize, Deserializer, Serialize, de};
use std::collections::BTreeMap;

/// A named physical parameter of a model declared by its physics (a
/// mechanical or gray-box model), with unit, value and bounds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhysicalParameter {
    /// Name used by the model's elements or expressions and by priors
    /// (`[fixed]`, `[bounds]`, `[[tie]]`).
    pub name: String,
    /// Unit, as text (e.g. `1/s^2`, `mm/s^2`).
    #[serde(default)]
    pub unit: String,
    /// Value: nominal in a declared model, fitted in an identified one.
    pub value: f64,
    /// Admissible range `[low, high]` (search box of the fit).
    #[serde(deserialize_with = "exact_bounds")]
    pub bounds: [f64; 2],
    /// Known exactly: never fitted.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub fixed: bool,
    /// What it is.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub doc: String,
}

/// Reads bounds `[low, high]`: exactly two numbers. Serde reads a
/// fixed-size array entry by entry, and the `toml` crate leaves the
/// entries after the second unread (`[0, 1, 2]` would read as `[0, 1]`);
/// this reader refuses them. For `#[serde(deserialize_with)]`.
pub fn exact_bounds<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    <[f64; 2]>::try_from(v.as_slice())
        .map_err(|_| de::Error::invalid_length(v.len(), &"bounds [low, high]: 2 numbers"))
}

/// [`exact_bounds`] for each entry of a table of bounds by name.
pub fn exact_bounds_by_name<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<BTreeMap<String, [f64; 2]>, D::Error> {
    #[derive(Deserialize)]
    struct Exact(#[serde(deserialize_with = "exact_bounds")] [f64; 2]);
    let table = BTreeMap::<String, Exact>::deserialize(d)?;
    Ok(table.into_iter().map(|(k, Exact(b))| (k, b)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, Deserialize)]
    struct Box {
        #[serde(deserialize_with = "exact_bounds")]
        b: [f64; 2],
        #[serde(default, deserialize_with = "exact_bounds_by_name")]
        named: BTreeMap<String, [f64; 2]>,
    }

    /// Two numbers read; one or three refused, in TOML as in JSON, in a
    /// field and in a table by name.
    #[test]
    fn bounds_are_exactly_two_numbers() {
        let b: Box = toml::from_str("b = [0, 1.5]\nnamed = { x = [-1, 1] }").unwrap();
        assert_eq!((b.b, b.named["x"]), ([0.0, 1.5], [-1.0, 1.0]));
        for text in [
            "b = [0, 1, 2]",
            "b = [0]",
            "b = [0, 1]\nnamed = { x = [0, 1, 2] }",
        ] {
            let e = toml::from_str::<Box>(text).unwrap_err().to_string();
            assert!(
                e.contains("expected bounds [low, high]: 2 numbers"),
                "{text}: {e}"
            );
        }
        for text in [
            r#"{"b": [0, 1, 2]}"#,
            r#"{"b": [0, 1], "named": {"x": [3]}}"#,
        ] {
            assert!(serde_json::from_str::<Box>(text).is_err(), "{text}");
        }
    }
}
