//! The integration tests of this crate, as one test binary.

mod ball;
mod delay;
mod examples;
mod head;
mod initial;
mod limits;
mod real_systems;
mod sensitivities;
mod transitions;

use serde::de::DeserializeOwned;

/// The model of the TOML text `text`, read as the library reads a model
/// file: into a `serde_json::Value` first (`hysid_graybox::extends`), then
/// [`from_value`].
pub(crate) fn from_toml<T: DeserializeOwned>(text: &str, kind: Option<&str>) -> T {
    from_value(toml::from_str(text).unwrap(), kind)
}

/// The model of a model file's document `value` (`extends::read` gives
/// one) without its `kind` tag, which, when `kind` is given, must be
/// `kind`. Every test reads its models through this one deserializer.
pub(crate) fn from_value<T: DeserializeOwned>(
    mut value: serde_json::Value,
    kind: Option<&str>,
) -> T {
    let tag = value.as_object_mut().unwrap().remove("kind");
    if let Some(kind) = kind {
        assert_eq!(tag.as_ref().and_then(|t| t.as_str()), Some(kind));
    }
    serde_json::from_value(value).unwrap()
}

/// A file of the repository (`path` from its root), as text.
pub(crate) fn repository_file(path: &str) -> String {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    std::fs::read_to_string(format!("{root}/{path}")).unwrap()
}
