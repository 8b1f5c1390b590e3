//! The exact sensitivities of a gray-box run beside central differences:
//! the positioning axis of `models/examples/positioning-axis.toml` (dry
//! friction that sticks at every reversal), driven by random steps, from
//! its measured start; per parameter, the norm of the output's derivative
//! and its distance to central differences, then the time of a run with
//! and without the sensitivities.
//!
//! `cargo bench -p hysid-graybox --bench sensitivities`

use hysid_graybox::simulate::{run, run_from, run_with_sensitivities};
use hysid_graybox::{CompiledModel, GrayBoxModel};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use std::time::Instant;

fn main() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../models/examples/positioning-axis.toml"
    );
    // Read as the library reads a model file: the document resolved by
    // `extends::read`, then deserialized without its `kind` tag.
    let mut document = hysid_graybox::extends::read(std::path::Path::new(path))
        .expect("the example model")
        .value;
    document.as_object_mut().expect("a table").remove("kind");
    let m: GrayBoxModel = serde_json::from_value(document).expect("a gray-box model");
    let c = CompiledModel::new(&m).expect("a valid model");
    let values = m.values();
    // Random steps of the drive's voltage, and the axis's own output.
    let ex = Excitation {
        n: 2001,
        hold: 50,
        low: -2.0,
        high: 2.0,
        ts: Some(0.01),
        inputs: 1,
    };
    let u = ex.generate(1).remove(0);
    let silent = Dataset::siso(u.clone(), vec![0.0; ex.n], ex.ts).expect("a record");
    let y = run(&c, &values, &silent).expect("a run").y;
    let data = Dataset::siso(u, y, ex.ts).expect("a record");

    let with = run_with_sensitivities(&c, &values, &[], &data).expect("a run");
    let s = with.sensitivities.expect("sensitivities");
    println!("{} samples, {} events", ex.n, with.events);
    println!("parameter   |dy/dθ|        |exact - central differences| / |dy/dθ|");
    for (j, p) in m.parameters.iter().enumerate() {
        let exact: Vec<f64> = s.dy.chunks(s.columns).map(|row| row[j]).collect();
        let h = 1e-6 * values[j].abs().max(1e-3);
        let (mut up, mut down) = (values.clone(), values.clone());
        up[j] += h;
        down[j] -= h;
        let (yu, yd) = (
            run_from(&c, &up, &[], &data).expect("a run").y,
            run_from(&c, &down, &[], &data).expect("a run").y,
        );
        let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
        let size = norm(&mut exact.iter().copied());
        let gap = norm(
            &mut exact
                .iter()
                .zip(yu.iter().zip(&yd))
                .map(|(e, (a, b))| e - (a - b) / (2.0 * h)),
        );
        println!(
            "{:<10} {size:>12.4e}   {:.1e}",
            p.name,
            gap / size.max(1e-300)
        );
    }

    let time = |f: &dyn Fn()| {
        let t0 = Instant::now();
        for _ in 0..20 {
            f();
        }
        t0.elapsed().as_secs_f64() / 20.0 * 1e3
    };
    let plain = time(&|| {
        run_from(&c, &values, &[], &data).expect("a run");
    });
    let sensitive = time(&|| {
        run_with_sensitivities(&c, &values, &[], &data).expect("a run");
    });
    println!(
        "one run: {plain:.2} ms; with the sensitivities in {} parameters: {sensitive:.2} ms",
        values.len()
    );
}
