//! Prior TOML reader: any text gives checked priors or a `PriorError`.
#![no_main]

use hysid_core::priors::Priors;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(p) = Priors::from_toml(text, "fuzz.toml") {
        let _ = p.kinds();
        assert!(p.check().is_ok());
    }
});
