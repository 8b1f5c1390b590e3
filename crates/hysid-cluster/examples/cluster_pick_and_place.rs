//! The founding experiment: the pick-and-place mounting head
//! (`models/pick-and-place/headdata_1v6.mat`), PWARX with na = nb = 2,
//! protocol of `docs/cli.md`: decimate by 10 (no filter),
//! identify on rows 0..5000, validate on rows 5000..6001 with a warm-up of
//! 10 samples; headline = free-run simulation FIT.
//!
//! Sweeps the local dataset size c and the mode count with
//! `hysid_cluster::sweep` and prints the FIT-versus-c table of
//! `docs/cluster.md`.
//!
//! ```text
//! cargo run --release -p hysid-cluster --example cluster_pick_and_place [-- FILE] [c,c,..] [s,s,..] [key=value ...]
//! ```

use hysid_cluster::{ClusterOptions, sweep};
use hysid_core::backend::{Problem, RunContext};
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_io::load;
use hysid_model::data::{DataSelection, RowRange};
use hysid_model::regressors::RegressorSpec;
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let file = args
        .iter()
        .find(|a| a.ends_with(".mat"))
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../models/pick-and-place/headdata_1v6.mat")
        });
    let list = |i: usize, default: &[usize]| -> Vec<usize> {
        args.iter()
            .filter(|a| !a.ends_with(".mat") && !a.contains('='))
            .nth(i)
            .map(|a| a.split(',').filter_map(|v| v.parse().ok()).collect())
            .unwrap_or_else(|| default.to_vec())
    };
    let cs = list(0, &[6, 10, 20, 40, 80, 120, 160, 240]);
    let modes = list(1, &[2, 3, 4]);
    let sets: Vec<&String> = args.iter().filter(|a| a.contains('=')).collect();
    let options: ClusterOptions = Settings::parse(&sets)
        .map_err(|e| e.to_string())?
        .resolve("cluster")?;
    let sel = |a, b| DataSelection {
        decimate: 10,
        rows: RowRange {
            start: Some(a),
            end: Some(b),
        },
        ..Default::default()
    };
    let ident = load(&file, &sel(0, 5000))?;
    let valid = load(&file, &sel(5000, 6001))?;
    let priors = Priors::default();
    let problem = Problem {
        data: &ident,
        orders: RegressorSpec::new(2, 2, 1),
        priors: &priors,
        priors_origin: None,
    };
    let t0 = std::time::Instant::now();
    let points = sweep(
        &problem,
        &valid,
        10,
        &cs,
        &modes,
        &options,
        &RunContext::quiet(1),
    );
    println!("| c | modes | modes found | fit_sim % | fit_pred % | coverage_sim |");
    println!("|---|---|---|---|---|---|");
    for p in &points {
        match (&p.report, &p.error) {
            (Some(r), _) => println!(
                "| {} | {} | {} | {:.1} | {:.2} | {:.3} |",
                p.c.map_or("-".into(), |c| c.to_string()),
                p.modes,
                p.modes_found.unwrap_or(0),
                r.fit_sim,
                r.fit_pred,
                r.coverage_sim
            ),
            (None, e) => println!(
                "| {} | {} | - | failed: {} | | |",
                p.c.map_or("-".into(), |c| c.to_string()),
                p.modes,
                e.as_deref().unwrap_or("?")
            ),
        }
    }
    let best = points
        .iter()
        .filter_map(|p| p.fit_sim.map(|f| (f, p)))
        .max_by(|a, b| a.0.total_cmp(&b.0));
    if let Some((f, p)) = best {
        println!(
            "best: c = {:?}, modes = {}: fit_sim = {f:.1} %",
            p.c, p.modes
        );
    }
    eprintln!(
        "{} identifications in {:.1} s",
        points.len(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
