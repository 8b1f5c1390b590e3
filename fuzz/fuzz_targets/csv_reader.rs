//! CSV reader: any bytes give a dataset or a `DataError`, never a panic.
#![no_main]

mod common;

use hysid_io::{DataFormat, load_bytes};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let (sel, file) = common::split(data);
    if let Ok(d) = load_bytes(file, DataFormat::Csv, Path::new("fuzz.csv"), &sel) {
        assert!(!d.is_empty());
        assert!(d.y().iter().all(|v| v.is_finite()));
    }
});
