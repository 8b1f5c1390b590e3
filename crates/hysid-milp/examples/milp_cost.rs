//! The cost of the exact programs against the record length: B1 (three
//! modes, uniform noise 0.1) with N = 10 to 30 samples, the l1 program with
//! the true mode count and the fewest-modes program with delta = 0.11 (just
//! above the noise), seed 1. Figures in docs/milp.md.
//!
//! Run: cargo run --release -p hysid-milp --example milp_cost

use hysid_core::backend::RunContext;
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::{Pwarx, PwarxMethod as _};
use hysid_milp::Milp;
use hysid_testkit::Noise;
use std::time::Instant;

fn main() {
    let registry = hysid_core::backend::Registry::new().with(Pwarx(Milp));
    let milp = registry.require(Milp::NAME).expect("registered");
    println!("| N | program | wall | nodes | proven optimal | modes | largest parameter error |");
    println!("|---|---|---|---|---|---|---|");
    for n in [10, 15, 20, 25, 30] {
        let b = hysid_testkit::b1(n + 1, 4.0, Noise::Uniform(0.1), 1);
        for (program, modes, set) in [
            ("l1, 3 modes", Some(3), vec![]),
            ("fewest modes, delta = 0.11", None, vec!["delta=0.11"]),
        ] {
            let priors = Priors {
                modes,
                ..Priors::default()
            };
            let settings = Settings::parse(&set).expect("valid options");
            let start = Instant::now();
            let result = milp.run(&b.problem(&priors), &settings, &RunContext::quiet(1));
            let wall = start.elapsed().as_secs_f64();
            match result {
                Ok(Model::Pwarx(m)) => {
                    let d = &m.info.diagnostics.method;
                    let error = if m.modes.len() == 3 {
                        format!("{:.3}", b.recovery(&m).1)
                    } else {
                        "-".into()
                    };
                    println!(
                        "| {n} | {program} | {wall:.3} s | {} | {} | {} | {error} |",
                        d["nodes"],
                        d["proven_optimal"],
                        m.modes.len()
                    );
                }
                Ok(_) => {
                    println!("| {n} | {program} | {wall:.3} s | - | - | - | not a PWARX model |")
                }
                Err(e) => println!("| {n} | {program} | {wall:.3} s | - | - | - | {e} |"),
            }
        }
    }
}
