//! The measured pick-and-place record with the ARX(2,2) baseline: the
//! founding paper's Fig. 7 layout on real data (validation rows 5000..6001,
//! decimated by 10, warm-up 10), plus the regressor plane y(k-1), u(k-1) of the
//! identification rows.
//!
//! ```text
//! cargo run -p hysid --example plot_pick_and_place -- docs/figures/gallery
//! ```

use std::path::PathBuf;

use hysid_arx::Arx;
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_core::simulate::validate;
use hysid_estimation::pwarx::Pwarx;
use hysid_io::load;
use hysid_model::data::{DataSelection, RowRange};
use hysid_model::regressors::RegressorSpec;
use hysid_plot::{RegionFigure, SimulationFigure};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir: PathBuf = std::env::args()
        .nth(1)
        .ok_or("usage: pick_and_place OUTPUT_DIR")?
        .into();
    std::fs::create_dir_all(&dir)?;
    let file = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../models/pick-and-place/headdata_1v6.mat");
    let rows = |start, end| DataSelection {
        decimate: 10,
        rows: RowRange {
            start: Some(start),
            end: Some(end),
        },
        ..DataSelection::default()
    };
    let ident = load(&file, &rows(0, 5000))?;
    let valid = load(&file, &rows(5000, 6001))?;
    let priors = Priors::default();
    let problem = Problem {
        data: &ident,
        orders: RegressorSpec::new(2, 2, 1),
        priors: &priors,
        priors_origin: None,
    };
    let model = Pwarx(Arx).run(&problem, &Settings::default(), &RunContext::quiet(1))?;
    let (report, sim, _pred) = validate(&model, &valid, 10)?;

    let fig = SimulationFigure::from_dataset(
        "Pick-and-place head, validation rows 5000..6001: ARX(2,2) baseline",
        &valid,
        5000,
        "head position y [mm]",
        "motor drive u [-]",
    )
    .with_simulation(
        format!("ARX(2,2) simulation (fit_sim {:.1} %)", report.fit_sim),
        &sim,
    )
    .with_warmup(10);
    hysid_plot::simulation_plot(&dir.join("pick_and_place_arx.svg"), &fig)?;

    let Model::Pwarx(pwarx) = &model else {
        return Err("the arx back-end returns a PWARX model".into());
    };
    let regs = model_spec_regressors(pwarx, &ident)?;
    let labels = vec![Some(0); regs.len()];
    let mut regions = RegionFigure::from_model(
        "Pick-and-place head, identification rows: regressors y(k-1), u(k-1)",
        pwarx,
        &regs,
        labels,
        (0, 2),
        &["mm", "mm", "-", "-"],
    );
    regions.mode_names = vec!["ARX (one region: everything)".into()];
    hysid_plot::regions_plot(&dir.join("pick_and_place_regressors.svg"), &regions)?;

    println!(
        "fit_sim {:.2} %, fit_pred {:.2} %; wrote 2 figures to {}",
        report.fit_sim,
        report.fit_pred,
        dir.display()
    );
    Ok(())
}

fn model_spec_regressors(
    m: &hysid_model::model::PwarxModel,
    data: &hysid_model::data::Dataset,
) -> Result<hysid_model::regressors::Regressors, Box<dyn std::error::Error>> {
    Ok(m.spec().build(data)?)
}
