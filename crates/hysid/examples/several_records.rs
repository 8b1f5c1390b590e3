//! One model from several records of one system, through the library API
//! (the program does the same with `hysid identify a.csv b.csv ...` and
//! `hysid validate MODEL c.csv d.csv`).
//!
//! Three records of the coupled drives (`models/examples/coupled-drives.toml`)
//! are simulated from rest with binary inputs of amplitudes 0.5, 1 and
//! 1.5 V, joined into one dataset, and the model's five parameters fitted
//! on all three; on the record of amplitude 1 alone the input's exponent
//! `pw` cannot be seen. Each record is then scored on its own and all
//! together.
//!
//! Run: `cargo run --release -p hysid --example several_records`

use hysid::identify::Identify;
use hysid_core::model::Model;
use hysid_core::simulate::{simulate, validate};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use hysid_model::simulate::SimulationOptions;
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let file = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../models/examples/coupled-drives.toml")
        .canonicalize()?;
    let mut truth = Model::load(&file)?;
    if let Model::GrayBox(m) = &mut truth {
        for (name, value) in [
            ("k", 2.2),
            ("tm", 0.17),
            ("wn", 20.0),
            ("z", 0.15),
            ("pw", 1.8),
        ] {
            let i = m.parameter_index(name).ok_or("no such parameter")?;
            m.parameters[i].value = value;
        }
    }
    let ts = 0.02;
    let mut records = Vec::new();
    for (amplitude, seed) in [(0.5, 11), (1.0, 12), (1.5, 13)] {
        let levels = Excitation {
            n: 300,
            hold: 4,
            low: -1.0,
            high: 1.0,
            ts: Some(ts),
            inputs: 1,
        }
        .generate(seed)
        .remove(0);
        let u: Vec<f64> = levels.iter().map(|v| amplitude * v.signum()).collect();
        let input = Dataset::siso(u.clone(), vec![0.0; u.len()], Some(ts))?;
        let y = simulate(&truth, &input, SimulationOptions::default())?.y;
        records.push(Dataset::siso(u, y, Some(ts))?);
    }
    let joined = Dataset::join(&records)?;
    let registry = hysid::registry();
    let fit = |data: &Dataset| -> Result<Model, Box<dyn std::error::Error>> {
        let request = Identify::new("physical", data)
            .set("model", &file.display().to_string())
            .seed(1);
        Ok(request.run(&registry)?.model)
    };
    for (what, data) in [
        ("three records", &joined),
        ("the record of 1 V", &records[1]),
    ] {
        let model = fit(data)?;
        let Model::GrayBox(m) = &model else {
            return Err("not a gray-box model".into());
        };
        let values: Vec<String> = m
            .parameters
            .iter()
            .map(|p| format!("{} = {:.4}", p.name, p.value))
            .collect();
        println!("fitted on {what}: {}", values.join(", "));
        if let Some(unseen) = m.info.diagnostics.method.get("zero_sensitivity") {
            println!("  parameters the rows cannot see: {unseen}");
        }
        let (report, _, _) = validate(&model, &joined, 4)?;
        for (i, r) in report.records.iter().enumerate() {
            println!("  record {}: fit_sim {:.2} %", i + 1, r.fit_sim);
        }
        println!("  all three: fit_sim {:.2} %", report.fit_sim);
    }
    Ok(())
}
