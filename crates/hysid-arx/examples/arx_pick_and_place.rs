//! The ARX baseline on the pick-and-place benchmark protocol, through the
//! library API (the CLI does the same with `hysid identify` / `validate`).
//!
//! Run: `cargo run --release -p hysid-arx --example arx_pick_and_place`

use hysid_arx::Arx;
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_core::simulate::validate;
use hysid_estimation::pwarx::Pwarx;
use hysid_io::load;
use hysid_model::data::DataSelection;
use hysid_model::regressors::RegressorSpec;
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let file =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/pick-and-place/headdata_1v6.mat");
    let select = |rows: &str| DataSelection {
        decimate: 10,
        rows: rows.parse().unwrap(),
        ..Default::default()
    };
    let ident = load(&file, &select("0..5000"))?;
    let valid = load(&file, &select("5000..6001"))?;
    println!("{:>4} {:>4} {:>9} {:>9}", "na", "nb", "fit_sim", "fit_pred");
    for (na, nb) in [(1, 1), (2, 2), (3, 3), (4, 4)] {
        let problem = Problem {
            data: &ident,
            orders: RegressorSpec::new(na, nb, 1),
            priors: &Priors::default(),
            priors_origin: None,
        };
        let model = Pwarx(Arx).run(&problem, &Settings::default(), &RunContext::quiet(0))?;
        let (report, _, _) = validate(&model, &valid, 10)?;
        println!(
            "{na:>4} {nb:>4} {:>8.2}% {:>8.2}%",
            report.fit_sim, report.fit_pred
        );
    }
    Ok(())
}
