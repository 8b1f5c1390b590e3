//! Simulation throughput of the positioning axis and cascaded tanks
//! examples, on records of their own response. Run with
//! `cargo bench -p hysid-graybox --bench simulate`. The mounting head
//! against the hand-written reference simulator: `cargo bench -p
//! hysid-physical --bench simulators`.

use hysid_graybox::{CompiledModel, GrayBoxModel};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use std::path::Path;

fn main() {
    divan::main();
}

/// The gray-box model of the file at `path` (from the repository's root).
fn read_gray_box(path: &str) -> GrayBoxModel {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let text = std::fs::read_to_string(root.join(path)).unwrap();
    let mut table: toml::Table = text.parse().unwrap();
    table.remove("kind");
    toml::Value::Table(table).try_into().unwrap()
}

/// The positioning axis (`models/examples/positioning-axis.toml`, its file
/// values) on 25 000 samples at 1 kHz of its own response to random drive
/// levels held 0.2 s, the size of the EMPS benchmark's estimation record:
/// the free run and the segmented run of the `physical` back-end's swarm
/// (segments of 100 samples, each from the measured position and a
/// centred slope).
fn axis() -> (CompiledModel, Vec<f64>, Dataset) {
    own_response(
        "models/examples/positioning-axis.toml",
        Excitation {
            n: 25_000,
            hold: 200,
            low: -2.0,
            high: 2.0,
            ts: Some(0.001),
            inputs: 1,
        },
    )
}

/// The model of the file at `path` (its file values) and a record of its
/// own response to the excitation `ex` (seed 1).
fn own_response(path: &str, ex: Excitation) -> (CompiledModel, Vec<f64>, Dataset) {
    let m = read_gray_box(path);
    let u = ex.generate(1).remove(0);
    let c = CompiledModel::new(&m).unwrap();
    let values = m.values();
    let zeros = Dataset::siso(u.clone(), vec![0.0; u.len()], ex.ts).unwrap();
    let y = hysid_graybox::simulate::run(&c, &values, &zeros).unwrap().y;
    (c, values, Dataset::siso(u, y, ex.ts).unwrap())
}

#[divan::bench(sample_count = 100)]
fn positioning_axis(bencher: divan::Bencher) {
    let (c, values, data) = axis();
    bencher.bench(|| hysid_graybox::simulate::run(&c, &values, &data).unwrap());
}

/// The free run as a fit's residuals read it: the outputs alone.
#[divan::bench(sample_count = 100)]
fn positioning_axis_outputs(bencher: divan::Bencher) {
    let (c, values, data) = axis();
    bencher.bench(|| hysid_graybox::simulate::outputs_from(&c, &values, &[], &data).unwrap());
}

#[divan::bench(sample_count = 100)]
fn positioning_axis_segmented(bencher: divan::Bencher) {
    let (c, values, data) = axis();
    let (y, ts) = (data.y(), 0.001);
    let slope = |s: usize| (y[(s + 1).min(y.len() - 1)] - y[s.saturating_sub(1)]) / (2.0 * ts);
    bencher.bench(|| {
        hysid_graybox::simulate::segmented(&c, &values, &[], &data, 100, &slope).unwrap()
    });
}

/// The cascaded tanks (`models/examples/cascaded-tanks.toml`, its file
/// values) on 1 024 samples at 4 s of its own response to its "Try:"
/// excitation, the size of the benchmark's records: Torricelli outflows
/// and overflow guards, no closed form, every stage on the expression
/// tapes.
fn tanks() -> (CompiledModel, Vec<f64>, Dataset) {
    own_response(
        "models/examples/cascaded-tanks.toml",
        Excitation {
            n: 1024,
            hold: 50,
            low: 0.0,
            high: 10.0,
            ts: Some(4.0),
            inputs: 1,
        },
    )
}

/// The tanks' free run as a fit reads it (the upper level given).
#[divan::bench(sample_count = 100)]
fn cascaded_tanks(bencher: divan::Bencher) {
    let (c, values, data) = tanks();
    bencher.bench(|| hysid_graybox::simulate::outputs_from(&c, &values, &[5.0], &data).unwrap());
}

/// The same run with the forward sensitivities in the parameters and the
/// upper level (the exact Jacobian of one Levenberg-Marquardt step): every
/// stage's partial derivatives read from the tapes in reverse mode.
#[divan::bench(sample_count = 50)]
fn cascaded_tanks_sensitivities(bencher: divan::Bencher) {
    let (c, values, data) = tanks();
    bencher.bench(|| {
        hysid_graybox::simulate::run_with_sensitivities(&c, &values, &[5.0], &data).unwrap()
    });
}
