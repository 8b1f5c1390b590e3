//! The exact Jacobian of the fit's objective (the runs' forward
//! sensitivities, assembled over records and carried to the search's
//! coordinates through ties and bounds) against central differences of
//! the objective's own residuals; and the fit's use of it.

use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_graybox::{GrayBoxInitialState, GrayBoxModel};
use hysid_model::data::Dataset;
use hysid_model::excitation::Excitation;
use hysid_model::regressors::RegressorSpec;
use hysid_physical::objective::Objective;
use hysid_physical::{GrayBoxTarget, ParameterMap, Physical};
use nalgebra::DMatrix;

/// Two lags in cascade with a sensor gain and offset, the upstream state
/// estimated per record, the parameters all free.
const CASCADE: &str = r#"
kind = "gray_box"
format = 1
internal_step = 0.025
states = ["x1", "x2"]
inputs = ["u"]
outputs = [{ name = "y", value = "c*x2 + off" }]
initial_state = { from = "measured", position = "x2", estimate = { x1 = [-5.0, 5.0] } }
parameters = [
    { name = "a", value = 1.0, bounds = [0.2, 4.0] },
    { name = "b", value = 2.0, bounds = [0.2, 4.0] },
    { name = "c", value = 1.0, bounds = [0.5, 2.0] },
    { name = "off", value = 0.0, bounds = [-2.0, 2.0] },
]

[[modes]]
name = "only"
flow = { x1 = "-a*x1 + u", x2 = "b*(x1 - x2)" }
"#;

fn parse(text: &str) -> GrayBoxModel {
    match Model::from_toml(text, "test.toml").unwrap() {
        Model::GrayBox(m) => m,
        other => panic!("kind {}", other.kind()),
    }
}

/// A record of the model's own output from `(x1, x2)`, input from `seed`.
fn record(m: &GrayBoxModel, x1: f64, x2: f64, n: usize, seed: u64) -> Dataset {
    let mut truth = m.clone();
    truth.initial_state = GrayBoxInitialState::Given {
        values: [("x1".to_string(), x1), ("x2".to_string(), x2)].into(),
        mode: None,
        estimate: Default::default(),
        samples: None,
    };
    let ex = Excitation {
        n,
        hold: 9,
        low: -1.0,
        high: 1.5,
        ts: Some(0.05),
        inputs: 1,
    };
    let u = ex.generate(seed).remove(0);
    let silent = Dataset::siso(u.clone(), vec![0.0; n], ex.ts).unwrap();
    let y = hysid_graybox::simulate(&truth, &silent, Default::default())
        .unwrap()
        .y;
    Dataset::siso(u, y, ex.ts).unwrap()
}

/// Central differences of the objective's residuals in `z`.
fn differences(objective: &Objective, z: &[f64]) -> DMatrix<f64> {
    let columns: Vec<Vec<f64>> = (0..z.len())
        .map(|j| {
            let h = 1e-6;
            let (mut up, mut down) = (z.to_vec(), z.to_vec());
            up[j] += h;
            down[j] -= h;
            let (rp, rm) = (
                objective.residuals(&up).unwrap(),
                objective.residuals(&down).unwrap(),
            );
            rp.iter()
                .zip(&rm)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect()
        })
        .collect();
    DMatrix::from_fn(columns[0].len(), z.len(), |i, j| columns[j][i])
}

/// Two records (each with its own estimated `x1`), `a` and `b` tied: the
/// exact Jacobian of the free-run and of the segmented residuals equals
/// central differences to 1e-6 of its size, column by column.
#[test]
fn the_objectives_exact_jacobian_is_its_residuals_derivative() {
    let m = parse(CASCADE);
    let records = [record(&m, 1.4, 0.2, 140, 1), record(&m, -0.9, 0.6, 120, 2)];
    let target = GrayBoxTarget::new(m).unwrap();
    let priors = Priors::from_toml("[[tie]]\nparams = [\"a\", \"b\"]\n", "test").unwrap();
    let map = ParameterMap::new(&target, &priors, records.len()).unwrap();
    // a = b, c, off, and x1 of each record.
    assert_eq!(map.dim(), 5);
    let z = [0.3, 0.55, 0.4, 0.6, 0.35];
    for segment in [0, 20] {
        let objective = Objective {
            segment,
            velocity_tol: 0.0,
            model: &target,
            records: &records,
            map: &map,
        };
        let exact = objective.jacobian(&z).expect("an exact Jacobian");
        let fd = differences(&objective, &z);
        assert_eq!(exact.shape(), fd.shape());
        for j in 0..z.len() {
            let error = (exact.column(j) - fd.column(j)).norm();
            assert!(
                error <= 1e-6 * fd.column(j).norm(),
                "segment {segment}, column {j}: {error:e} against {:e}",
                fd.column(j).norm()
            );
        }
    }
}

/// The fit of a gray-box model reports the exact Jacobian by default and
/// central differences when told; both recover the parameters of a
/// noise-free record, the exact one in fewer simulations.
#[test]
fn the_fit_uses_the_exact_jacobian_unless_told() {
    let text = CASCADE;
    let mut truth = parse(text);
    for (p, v) in truth.parameters.iter_mut().zip([0.7, 2.6, 1.3, -0.4]) {
        p.value = v;
    }
    let data = record(&truth, 1.9, -0.4, 240, 3);
    let file = std::env::temp_dir().join(format!("hysid-jacobian-{}.toml", std::process::id()));
    std::fs::write(&file, text).unwrap();
    let problem = Problem {
        data: &data,
        orders: RegressorSpec::new(2, 2, 1),
        priors: &Priors::default(),
        priors_origin: None,
    };
    let fit = |exact: bool| {
        let model = format!("model={}", file.display());
        let exact = format!("exact_jacobian={exact}");
        let settings = Settings::parse(&[
            model.as_str(),
            exact.as_str(),
            "particles=8",
            "swarm_iters=8",
        ])
        .unwrap();
        match Physical
            .run(&problem, &settings, &RunContext::quiet(3))
            .unwrap()
        {
            Model::GrayBox(m) => m,
            other => panic!("kind {}", other.kind()),
        }
    };
    let (exact, differences) = (fit(true), fit(false));
    std::fs::remove_file(&file).unwrap();
    let evaluations = |m: &GrayBoxModel| m.info.diagnostics.method["evaluations"].as_u64().unwrap();
    for (m, kind) in [(&exact, "exact"), (&differences, "central_differences")] {
        assert_eq!(m.info.diagnostics.method["jacobian"], kind);
        for (p, want) in m.parameters.iter().zip([0.7, 2.6, 1.3, -0.4]) {
            assert!(
                (p.value - want).abs() <= 1e-4 * want.abs(),
                "{kind}: {} = {} against {want}",
                p.name,
                p.value
            );
        }
    }
    assert!(
        evaluations(&exact) < evaluations(&differences),
        "{} against {}",
        evaluations(&exact),
        evaluations(&differences)
    );
}
