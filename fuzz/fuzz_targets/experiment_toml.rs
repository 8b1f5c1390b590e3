//! Experiment TOML reader: any text gives a checked experiment or an
//! `ExperimentError`; a parsed experiment expands into jobs or an error.
#![no_main]

use hysid::compare::Experiment;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(e) = Experiment::from_toml(text, "fuzz.toml") {
        let _ = e.jobs();
    }
});
