//! The simulator the `physical` back-end fits with, on the mounting head
//! written as a gray-box model, against the hand-written mechanical
//! simulator the gray-box form is tested against, in the same run. Run with
//! `cargo bench -p hysid-physical --bench simulators`; the gray-box head
//! also with its forward sensitivities.
//!
//! Data: the pick-and-place record, rows 0..5000 after decimating by 10
//! (12.5 s at 400 Hz, 10 sub-steps per sample); parameters: the fitted
//! head (`models/pick-and-place/head-fitted.json`). Output samples per
//! second are 5000 divided by the time of one run.

use hysid_core::model::Model;
use hysid_graybox::{CompiledModel, GrayBoxInitialState, GrayBoxModel};
use hysid_mechanical::{MechanicalInitialState, MechanicalModel};
use hysid_model::data::{DataSelection, Dataset, RowRange};
use std::path::{Path, PathBuf};

fn main() {
    divan::main();
}

fn at_root(path: &str) -> PathBuf {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(path)
}

fn record() -> Dataset {
    let sel = DataSelection {
        decimate: 10,
        rows: RowRange {
            start: Some(0),
            end: Some(5000),
        },
        ..DataSelection::default()
    };
    hysid_io::load(&at_root("models/pick-and-place/headdata_1v6.mat"), &sel).unwrap()
}

fn fitted() -> MechanicalModel {
    match Model::load(&at_root("models/pick-and-place/head-fitted.json")).unwrap() {
        Model::Mechanical(m) => m,
        other => panic!("head-fitted.json is a {} model", other.kind()),
    }
}

/// The gray-box head with the fitted head's parameters and initial rule.
fn gray_box(m: &MechanicalModel) -> GrayBoxModel {
    let mut g = match Model::load(&at_root("models/pick-and-place/head-graybox.toml")).unwrap() {
        Model::GrayBox(g) => g,
        other => panic!("head-graybox.toml is a {} model", other.kind()),
    };
    for p in &mut g.parameters {
        p.value = m.parameters[m.parameter_index(&p.name).unwrap()].value;
    }
    if let (
        GrayBoxInitialState::Measured { velocity_tol, .. },
        MechanicalInitialState::Measured {
            velocity_tol: tol, ..
        },
    ) = (&mut g.initial_state, &m.initial_state)
    {
        *velocity_tol = *tol;
    }
    g
}

#[divan::bench(sample_count = 200)]
fn mechanical_head(bencher: divan::Bencher) {
    let data = record();
    let m = fitted();
    let values = m.values();
    bencher.bench(|| hysid_mechanical::simulate::run(&m, &values, &data).unwrap());
}

#[divan::bench(sample_count = 200)]
fn gray_box_head(bencher: divan::Bencher) {
    let data = record();
    let g = gray_box(&fitted());
    let c = CompiledModel::new(&g).unwrap();
    let values = g.values();
    bencher.bench(|| hysid_graybox::simulate::run(&c, &values, &data).unwrap());
}

/// The same run with the forward sensitivities in its 12 parameters (the
/// exact Jacobian of one Levenberg-Marquardt step; central differences
/// take 24 runs).
#[divan::bench(sample_count = 100)]
fn gray_box_head_sensitivities(bencher: divan::Bencher) {
    let data = record();
    let g = gray_box(&fitted());
    let c = CompiledModel::new(&g).unwrap();
    let values = g.values();
    bencher.bench(|| {
        hysid_graybox::simulate::run_with_sensitivities(&c, &values, &[], &data).unwrap()
    });
}
