//! The pick-and-place protocol with the `physical` back-end: decimate by 10,
//! identify on rows 0..5000, validate on rows 5000..6001 with warm-up 10.
//!
//! `cargo run --release -p hysid-physical --example physical_pick_and_place [-- OUT_DIR [KEY=VALUE..]]`
//! (`KEY=VALUE`: `physical` options; `model=` defaults to
//! `models/pick-and-place/head.toml`)
//! (environment: `PHYS_SEED=N`, `PHYS_FIX_STOP=1` to fix the lower stop at 25 mm)
//!
//! Prints the fitted parameters, the fit time, `fit_sim` on both records and
//! the simulation throughput; writes `OUT_DIR/physical_traces.csv` (measured
//! and simulated output, mode) and `OUT_DIR/physical_model.json` when
//! `OUT_DIR` is given.

use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_model::data::{DataSelection, RowRange};
use hysid_model::regressors::RegressorSpec;
use hysid_physical::Physical;
use std::path::Path;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out_dir = args.first().cloned();
    let head = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/pick-and-place");
    // The built-in head unless the options name another model.
    let mut sets: Vec<String> = args.iter().skip(1).cloned().collect();
    if !sets.iter().any(|s| s.starts_with("model=")) {
        sets.insert(0, format!("model={}", head.join("head.toml").display()));
    }
    let root = head.join("headdata_1v6.mat");
    let sel = |rows: RowRange| DataSelection {
        decimate: 10,
        rows,
        ..DataSelection::default()
    };
    let ident = hysid_io::load(
        &root,
        &sel(RowRange {
            start: Some(0),
            end: Some(5000),
        }),
    )?;
    let valid = hysid_io::load(
        &root,
        &sel(RowRange {
            start: Some(5000),
            end: Some(6001),
        }),
    )?;
    // With `PHYS_FIX_STOP=1`, the lower stop is fixed at the paper's 25 mm
    // (a `[fixed]` prior); by default every non-fixed parameter is fitted.
    let mut priors = Priors::default();
    if std::env::var_os("PHYS_FIX_STOP").is_some() {
        priors.fixed.insert("y_low".into(), 25.0);
    }
    let seed: u64 = std::env::var("PHYS_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    println!(
        "seed {seed}, priors: {}",
        if priors.fixed.is_empty() {
            "none"
        } else {
            "[fixed] y_low = 25"
        }
    );
    let problem = Problem {
        data: &ident,
        orders: RegressorSpec::new(2, 2, 1),
        priors: &priors,
        priors_origin: None,
    };
    let t0 = Instant::now();
    let model = Physical.run(&problem, &Settings::parse(&sets)?, &RunContext::quiet(seed))?;
    let fit_seconds = t0.elapsed().as_secs_f64();
    let Model::Mechanical(m) = &model else {
        unreachable!()
    };
    println!(
        "fit time: {fit_seconds:.2} s ({} simulations)",
        m.info.diagnostics.method["evaluations"]
    );
    println!(
        "final cost (MSE, identification): {:.5}",
        m.info.diagnostics.method["cost"]
    );
    for p in &m.parameters {
        let d = &m.info.diagnostics.method["parameters"].get(&p.name);
        let se = d
            .and_then(|d| d["std_error"].as_f64())
            .map(|s| format!("± {s:.4}"))
            .unwrap_or_else(|| {
                if p.fixed {
                    "(fixed)".into()
                } else {
                    "(zero local sensitivity)".into()
                }
            });
        println!(
            "  {:6} = {:>12.4} {se:>14}  {:18} bounds [{}, {}]",
            p.name, p.value, p.unit, p.bounds[0], p.bounds[1]
        );
    }
    let (ri, _, _) = hysid_core::simulate::validate(&model, &ident, 10)?;
    let (rv, sim, _) = hysid_core::simulate::validate(&model, &valid, 10)?;
    println!(
        "fit_sim identification (rows 0..5000, warm-up 10): {:.2} %",
        ri.fit_sim
    );
    println!(
        "fit_sim validation (rows 5000..6001, warm-up 10): {:.2} %  rmse {:.3}",
        rv.fit_sim, rv.rmse_sim
    );
    println!("fit_pred validation: {:.2} %", rv.fit_pred);
    // The bridge: per-mode ARX(2,2) form at the data's rate.
    let pw = hysid_physical::bridge::to_pwarx(m, ident.ts.unwrap_or(0.0025));
    println!("per-mode ARX(2,2) form, theta = [a1, a2, b1, b2, c]:");
    for q in &pw.modes {
        let t: Vec<String> = q.theta.iter().map(|v| format!("{v:.6}")).collect();
        println!(
            "  {:14} [{}]",
            q.name.clone().unwrap_or_default(),
            t.join(", ")
        );
    }
    // Throughput: simulate the identification record repeatedly (the
    // model's gray-box form, translated and compiled at every run).
    let reps = 50;
    let t1 = Instant::now();
    for _ in 0..reps {
        hysid_core::simulate::simulate(&model, &ident, Default::default())?;
    }
    let dt = t1.elapsed().as_secs_f64();
    println!(
        "simulation throughput: {:.0} output samples/s at 400 Hz ({:.3} ms per 5000-sample record)",
        (reps * ident.len()) as f64 / dt,
        1e3 * dt / reps as f64
    );
    if let Some(dir) = out_dir {
        std::fs::create_dir_all(&dir)?;
        hysid_io::save_model(&model, &Path::new(&dir).join("physical_model.json"))?;
        let names = model.mode_names();
        let mut s = String::from("t,u,y_measured,y_simulated,mode\n");
        for k in 0..valid.len() {
            let t = (5000 + k) as f64 * valid.ts.unwrap_or(0.0025);
            let mode = sim.modes[k].map(|q| names[q].clone()).unwrap_or_default();
            s.push_str(&format!(
                "{t:.4},{},{},{:.5},{mode}\n",
                valid.u(0)[k],
                valid.y()[k],
                sim.y[k]
            ));
        }
        std::fs::write(Path::new(&dir).join("physical_traces.csv"), s)?;
        println!("wrote {dir}/physical_model.json and {dir}/physical_traces.csv");
    }
    Ok(())
}
