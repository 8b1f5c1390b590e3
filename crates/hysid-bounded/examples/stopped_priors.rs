//! The bounded back-end on the stopped head of `hysid-testkit` (two
//! ordinary modes, both stops reached), with and without the priors
//! (`docs/priors.md`). Prints the mode accuracy of the classification of the
//! identification rows (saturation modes included, infeasible rows wrong)
//! and the FIT on a fresh validation record.
//!
//! `cargo run -p hysid-bounded --example stopped_priors -- [N] [NOISE] [DELTA] [SEED]`

use hysid_bounded::Bounded;
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_core::simulate::validate;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::metrics::mode_accuracy;
use hysid_model::regressors::RegressorSpec;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, d: f64| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(d);
    let n = arg(0, 1500.0) as usize;
    let noise = arg(1, 0.05);
    let delta = arg(2, 0.2);
    let seed = arg(3, 1.0) as u64;
    let id = hysid_testkit::stopped_head(n, 60, noise, seed);
    let val = hysid_testkit::stopped_head(1000, 60, noise, seed + 100);
    let full = id.priors();
    let modes_only = Priors {
        modes: full.modes,
        ..Default::default()
    };
    let set = [format!("delta={delta}")];
    let set: Vec<&str> = set.iter().map(String::as_str).collect();
    println!(
        "| priors | modes | fit_sim % | fit_pred % | mode accuracy (identification rows) | CPU s |"
    );
    println!("|---|---|---|---|---|---|");
    for (name, pri) in [
        ("none", Priors::default()),
        ("modes = 4", modes_only),
        ("modes = 4 + both stops", full),
    ] {
        let problem = Problem {
            data: &id.data,
            orders: RegressorSpec::new(2, 1, 1),
            priors: &pri,
            priors_origin: None,
        };
        let t = std::time::Instant::now();
        let m = match Pwarx(Bounded).run(
            &problem,
            &Settings::parse(&set).expect("settings"),
            &RunContext::quiet(seed),
        ) {
            Ok(m) => m,
            Err(e) => {
                println!("| {name} | error: {e} | | | | |");
                continue;
            }
        };
        let cpu = t.elapsed().as_secs_f64();
        // Classification accuracy on the identification record (infeasible
        // rows count as wrong).
        let opts = hysid_bounded::BoundedOptions {
            delta: hysid_bounded::Delta::Value(delta),
            ..Default::default()
        };
        let cl =
            Bounded::classify_all(&problem, &opts, &RunContext::quiet(seed)).expect("classifies");
        let wrong = 99;
        let rows: Vec<usize> = cl.row_labels().iter().map(|l| l.unwrap_or(wrong)).collect();
        let id_acc = mode_accuracy(&id.row_modes(), &rows).unwrap().accuracy;
        let (rep, _, _) = validate(&m, &val.data, 2).expect("validates");
        let modes = m.info().diagnostics.method["modes_found"].clone();
        if std::env::var("VERBOSE").is_ok() {
            eprintln!("{name}: {:?}", m.info().diagnostics);
            if let hysid_core::model::Model::HybridAutomaton(a) = &m {
                for q in &a.modes {
                    eprintln!(
                        "  {} a0={:?} b0={:?} f0={}",
                        q.name, q.flow.a[0], q.flow.b[0], q.flow.f[0]
                    );
                }
            }
        }
        println!(
            "| {name} | {modes} | {:.2} | {:.2} | {id_acc:.4} | {cpu:.1} |",
            rep.fit_sim, rep.fit_pred
        );
    }
}
