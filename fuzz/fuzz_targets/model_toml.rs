//! Model TOML reader: any text gives a valid model or a `ModelError`; a
//! model that parses writes to JSON that parses to the same model.
#![no_main]

use hysid_core::model::Model;
use libfuzzer_sys::fuzz_target;

#[path = "models.rs"]
mod models;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(m) = Model::from_toml(text, "fuzz.toml") {
        let again =
            Model::from_json(&m.to_json(), "again.json").expect("a model's own JSON reads back");
        assert_eq!(m, again);
        models::run_briefly(&m);
    }
});
