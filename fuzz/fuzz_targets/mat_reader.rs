//! MAT reader: any bytes give a dataset or a `DataError`, never a panic of
//! our code (panics inside `matrw` are guarded by the reader; see common.rs).
#![no_main]

mod common;

use hysid_io::{DataFormat, load_bytes};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    common::tolerate_matrw_panics();
    let (sel, file) = common::split(data);
    if let Ok(d) = load_bytes(file, DataFormat::Mat, Path::new("fuzz.mat"), &sel) {
        assert!(!d.is_empty());
        assert!(d.y().iter().all(|v| v.is_finite()));
    }
});
