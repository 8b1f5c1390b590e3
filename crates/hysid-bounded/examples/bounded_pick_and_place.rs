//! The pick-and-place protocol (`docs/cli.md`)
//! with a delta sweep: decimate by 10 without a filter, identify on rows
//! 0..5000, validate on rows 5000..6001 with warm-up 10, PWARX na = nb = 2.
//!
//! `cargo run --release -p hysid-bounded --example bounded_pick_and_place [delta ...] [ls] [seed=N]`
//! (`ls`: least-squares refit instead of the Chebyshev LP)
//! prints the sweep as a Markdown table (the one in `docs/bounded.md`).

use hysid_bounded::sweep::{best, delta_sweep, table};
use hysid_bounded::{BoundedOptions, noise};
use hysid_core::backend::{Problem, RunContext};
use hysid_core::priors::Priors;
use hysid_io::load;
use hysid_model::data::{DataSelection, RowRange};
use hysid_model::regressors::RegressorSpec;
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../models/pick-and-place/headdata_1v6.mat");
    let sel = |rows: &str| DataSelection {
        decimate: 10,
        rows: rows.parse().unwrap_or(RowRange::default()),
        ..Default::default()
    };
    let ident = load(&path, &sel("0..5000"))?;
    let valid = load(&path, &sel("5000..6001"))?;
    let orders = RegressorSpec::new(2, 2, 1);
    let priors = Priors::default();
    let problem = Problem {
        data: &ident,
        orders,
        priors: &priors,
        priors_origin: None,
    };
    let args: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let deltas = if args.is_empty() {
        vec![0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0]
    } else {
        args
    };
    let reg = orders.build(&ident)?;
    let auto = noise::auto_delta(&reg);
    println!(
        "identification rows: {}, validation rows: {}, delta=auto would be {auto:.4}",
        ident.len(),
        valid.len()
    );
    let t = Instant::now();
    let seed: u64 = std::env::args()
        .find_map(|a| a.strip_prefix("seed=").and_then(|v| v.parse().ok()))
        .unwrap_or(1);
    let mut options = BoundedOptions::default();
    if std::env::args().any(|a| a == "ls") {
        options.refit = hysid_bounded::Refit::Ls;
    }
    println!("options: {options:?}");
    let points = delta_sweep(
        &problem,
        &valid,
        10,
        &deltas,
        &options,
        &RunContext::quiet(seed),
    )?;
    println!(
        "sweep of {} bounds in {:.1} s (seed {seed})\n",
        deltas.len(),
        t.elapsed().as_secs_f64()
    );
    print!("{}", table(&points));
    println!(
        "\n| delta | greedy modes | merged | dropped | rounds | max residual per mode |\n|---|---|---|---|---|---|"
    );
    for p in &points {
        if let Some(m) = &p.model {
            let d = &m.info().diagnostics.method;
            println!(
                "| {} | {} | {} | {} | {} | {} |",
                p.delta,
                d["greedy_modes"],
                d["merged"],
                d["dropped"],
                d["rounds"],
                d["max_residual"]
            );
        }
    }
    if let Some(i) = best(&points) {
        let p = &points[i];
        println!(
            "\nbest fit_sim: {:.2} % at delta = {} with {} modes",
            p.fit_sim.unwrap_or(f64::NAN),
            p.delta,
            p.modes
        );
        if let Some(m) = &p.model {
            for (k, mode) in m.info().diagnostics.method.iter() {
                println!("  {k}: {mode}");
            }
        }
    }
    Ok(())
}
