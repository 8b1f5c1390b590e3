//! A model file laid over its base (`extends`): any two TOML texts, the
//! base and the extending file, separated by a line `%%%`, give a merged
//! document or an error; a merged document that reads as a model writes
//! JSON that reads back to the same model, and a gray-box one simulates.
#![no_main]

use hysid_core::model::Model;
use hysid_graybox::extends::extend;
use libfuzzer_sys::fuzz_target;

#[path = "models.rs"]
mod models;

/// A TOML text as the document `extend` takes.
fn document(text: &str) -> Option<serde_json::Value> {
    let table: toml::Table = text.parse().ok()?;
    serde_json::to_value(table).ok()
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Some((base, own)) = text.split_once("\n%%%\n") else {
        return;
    };
    let (Some(base), Some(own)) = (document(base), document(own)) else {
        return;
    };
    let Ok(merged) = extend(base, own) else {
        return;
    };
    let Ok(m) = serde_json::from_value::<Model>(merged) else {
        return;
    };
    if m.validate().is_ok() {
        let again =
            Model::from_json(&m.to_json(), "again.json").expect("a model's own JSON reads back");
        assert_eq!(m, again);
        models::run_briefly(&m);
    }
});
