//! CPU time (user + system, from `/proc/self/stat`, Linux only) of the
//! `bounded` back-end on B1 for growing N: a measure that, unlike wall
//! time, is not inflated by other processes sharing the cores.
//!
//! `taskset -c 0 cargo run --release -p hysid-bounded --example cpu_time [regions=METHOD]`

use hysid_bounded::{Bounded, BoundedOptions, Delta};
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::regressors::RegressorSpec;
use std::time::Instant;

/// User + system CPU seconds of this process.
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    // Fields after the command name (which is in parentheses).
    let rest = stat.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    // utime and stime are fields 14 and 15 of the full line: 11 and 12 here.
    (ticks(11) + ticks(12)) / 100.0
}

fn main() {
    let reps = 5;
    println!(
        "| N | classify CPU s | identify CPU s | identify wall s | modes |\n|---|---|---|---|---|"
    );
    for n in [1000, 2000, 4000, 8000, 16000] {
        let g = hysid_testkit::b1(n, 4.0, hysid_testkit::Noise::Uniform(0.1), 1);
        let pri = Priors::default();
        let problem = Problem {
            data: &g.data,
            orders: RegressorSpec::new(1, 1, 1),
            priors: &pri,
            priors_origin: None,
        };
        let opts = BoundedOptions {
            delta: Delta::Value(0.1),
            ..Default::default()
        };
        let settings = Settings::parse(&["delta=0.1"]).unwrap();
        let c0 = cpu_seconds();
        let mut modes = 0;
        for _ in 0..reps {
            modes = Bounded::classify(&problem, &opts, &RunContext::quiet(1))
                .unwrap()
                .0
                .thetas
                .len();
        }
        let c1 = cpu_seconds();
        let w = Instant::now();
        for _ in 0..reps {
            Pwarx(Bounded)
                .run(&problem, &settings, &RunContext::quiet(1))
                .unwrap();
        }
        let wall = w.elapsed().as_secs_f64() / reps as f64;
        let c2 = cpu_seconds();
        println!(
            "| {n} | {:.3} | {:.3} | {wall:.3} | {modes} |",
            (c1 - c0) / reps as f64,
            (c2 - c1) / reps as f64
        );
    }
}
