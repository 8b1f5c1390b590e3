//! Pieces shared by the model-file targets.

use hysid_core::model::Model;
use hysid_model::data::{Dataset, Signal};
use hysid_model::simulate::SimulationOptions;

/// A gray-box model that parses also simulates without a panic: 20 samples
/// of a zero input at 10 ms, when its step needs at most 100 sub-steps per
/// sample (a bound on the fuzzer's time, not on the model).
pub fn run_briefly(m: &Model) {
    let Model::GrayBox(g) = m else {
        return;
    };
    if !(g.internal_step >= 1e-4) || g.inputs.len() > 8 {
        return;
    }
    let n = 20;
    let signal = |name: String| Signal {
        name,
        values: vec![0.0; n],
    };
    let data = Dataset::new(
        (0..g.inputs.len()).map(|i| signal(format!("u{i}"))).collect(),
        signal("y".into()),
        Some(0.01),
    );
    if let Ok(data) = data {
        let _ = hysid_core::simulate::simulate(m, &data, SimulationOptions::default());
        let _ = hysid_core::simulate::predict(m, &data, SimulationOptions::default());
    }
}
