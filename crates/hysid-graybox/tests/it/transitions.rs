//! Transitions at a sample instant: an input that jumps across two
//! thresholds passes through the mode between them, whatever the order in
//! which the file lists the transitions.

use crate::initial::model;
use hysid_graybox::simulate::run;
use hysid_graybox::{CompiledModel, GrayBoxModel};
use hysid_model::data::Dataset;
use proptest::prelude::*;

/// A first-order lag behind an input dead zone of half-width 0.5, as the
/// modes `dead`, `pos` and `neg`; `direct` lists the transitions between
/// `pos` and `neg` before those into `dead` or after them.
fn dead_zone(direct_first: bool) -> GrayBoxModel {
    let into_dead = r#"
[[transitions]]
from = "pos"
to = "dead"
guard = "u <= dz"

[[transitions]]
from = "neg"
to = "dead"
guard = "u >= -dz"
"#;
    let direct = r#"
[[transitions]]
from = "pos"
to = "neg"
guard = "u <= -dz"

[[transitions]]
from = "neg"
to = "pos"
guard = "u >= dz"
"#;
    let (first, second) = if direct_first {
        (direct, into_dead)
    } else {
        (into_dead, direct)
    };
    model(&format!(
        r#"
format = 1
internal_step = 0.01
states = ["x"]
inputs = ["u"]
outputs = [{{ name = "y", value = "x" }}]
initial_state = {{ from = "given", values = {{ x = 0 }} }}

[[parameters]]
name = "dz"
value = 0.5
bounds = [0.0, 1.0]

[definitions]
drive = "0"

[[modes]]
name = "dead"
flow = {{ x = "drive - x" }}
invariant = ["u <= dz", "u >= -dz"]

[[modes]]
name = "pos"
flow = {{ x = "drive - x" }}
invariant = ["u >= dz"]
definitions = {{ drive = "u - dz" }}

[[modes]]
name = "neg"
flow = {{ x = "drive - x" }}
invariant = ["u <= -dz"]
definitions = {{ drive = "u + dz" }}

[[transitions]]
from = "dead"
to = "pos"
guard = "u >= dz"

[[transitions]]
from = "dead"
to = "neg"
guard = "u <= -dz"
{first}{second}"#
    ))
}

proptest! {
    /// Inputs that jump between the zones, across both thresholds at
    /// once among them: both orders of the transitions run, to the same
    /// bits, and each sample's mode is the zone of the input that drove
    /// the sample before.
    #[test]
    fn an_input_jump_across_two_thresholds_passes_both(
        u in prop::collection::vec(prop::sample::select(vec![-2.0, -1.0, 0.0, 0.3, 1.0, 2.0]), 2..40),
    ) {
        let n = u.len();
        let data = Dataset::siso(u.clone(), vec![0.0; n], Some(0.1)).unwrap();
        let runs: Vec<_> = [true, false]
            .into_iter()
            .map(|direct_first| {
                let m = dead_zone(direct_first);
                run(&CompiledModel::new(&m).unwrap(), &m.values(), &data).unwrap()
            })
            .collect();
        let bits = |y: &[f64]| y.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        prop_assert_eq!(bits(&runs[0].y), bits(&runs[1].y));
        prop_assert_eq!(&runs[0].modes, &runs[1].modes);
        let zone = |v: f64| if v >= 0.5 { 1 } else if v <= -0.5 { 2 } else { 0 };
        for k in 1..n {
            prop_assert_eq!(runs[0].modes[k], Some(zone(u[k - 1])), "sample {}", k);
        }
    }
}

/// A guard that reads neither a state nor an input (parameters and
/// numbers only) never moves: the file is refused where it says so.
#[test]
fn a_guard_on_parameters_alone_is_refused() {
    let mut m = dead_zone(true);
    let guard = m.transitions.iter_mut().find(|t| t.guard == "u >= dz");
    guard.unwrap().guard = "dz >= 0.1".into();
    let e = m.validate().unwrap_err().to_string();
    assert!(
        e.contains("transition dead -> pos, guard")
            && e.contains("'dz >= 0.1' reads neither a state nor an input"),
        "{e}"
    );
}
