//! Renders every hysid-plot figure from synthetic data into a directory.
//!
//! ```text
//! cargo run -p hysid-plot --example gallery -- docs/figures/gallery
//! ```
//!
//! The data come from a three-mode PWARX system with regressor
//! `x = [y(k-1), y(k-2), u(k-1)]`, sampled at `Ts = 2.5 ms` (the mounting-head
//! record decimated by 10). The "identified" model is the true one with
//! perturbed parameters and shrunken regions, so that the figures show
//! simulation errors, mode mismatches and holes in the partition. The sweep
//! numbers are made up to show the layout; they are not measurements.

use std::path::PathBuf;

use hysid_model::geometry::Polyhedron;
use hysid_model::metrics::fit;
use hysid_plot::{
    Bounds, ModeFigure, ModeSequence, RegionFigure, Series, SimulationFigure, SweepFigure,
    SweepPanel, SweepSeries, mode_sequence_plot, regions_plot, simulation_plot, sweep_plot,
    time_axis,
};

/// A small deterministic generator (xorshift64*), enough for test signals.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Parameters `[a1, a2, b1, c]` of `y(k) = a1 y(k-1) + a2 y(k-2) + b1 u(k-1) + c`.
type Params = [[f64; 4]; 3];

const TRUE_PARAMS: Params = [
    [1.5, -0.7, 0.5, 0.0],
    [1.2, -0.5, 0.8, 0.1],
    [1.0, -0.3, 0.3, 0.2],
];

/// The true switching rule on `x = [y(k-1), y(k-2), u(k-1)]`.
fn true_mode(x: &[f64; 3]) -> usize {
    if x[0] <= 0.0 {
        0
    } else if x[2] <= 0.5 {
        1
    } else {
        2
    }
}

/// Regions of the "identified" model: the true ones shrunk, leaving holes,
/// with one row coupling y(k-1) and y(k-2).
fn identified_regions() -> Vec<Polyhedron> {
    vec![
        Polyhedron::from_inequalities(vec![vec![1.0, 0.0, 0.0]], vec![-0.08]),
        Polyhedron::from_inequalities(
            vec![
                vec![-1.0, 0.0, 0.0],
                vec![0.0, 0.0, 1.0],
                vec![1.0, 0.3, 0.0],
            ],
            vec![-0.05, 0.42, 3.6],
        ),
        Polyhedron::from_inequalities(
            vec![vec![-1.0, 0.0, 0.0], vec![0.0, 0.0, -1.0]],
            vec![-0.12, -0.58],
        ),
    ]
}

fn simulate(
    u: &[f64],
    params: &Params,
    rule: &dyn Fn(&[f64; 3]) -> Option<usize>,
) -> (Vec<f64>, Vec<Option<usize>>) {
    let mut y = vec![0.0; u.len()];
    let mut modes = vec![None; u.len()];
    for k in 2..u.len() {
        let x = [y[k - 1], y[k - 2], u[k - 1]];
        let m = rule(&x);
        // Outside every region the last mode is kept (a simple, common choice).
        let used = m.or(modes[k - 1]).unwrap_or(0);
        let p = params[used];
        y[k] = p[0] * x[0] + p[1] * x[1] + p[2] * x[2] + p[3];
        modes[k] = m;
    }
    (y, modes)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir: PathBuf = std::env::args()
        .nth(1)
        .ok_or("usage: gallery OUTPUT_DIR")?
        .into();
    std::fs::create_dir_all(&dir)?;

    // Random steps held for 20..60 samples, as in the paper's excitation.
    let n = 1000;
    let mut rng = Rng(0x5EED_1234_ABCD_0001);
    let mut u = Vec::with_capacity(n);
    while u.len() < n {
        let level = 2.0 * rng.uniform() - 1.0;
        let hold = 20 + (rng.uniform() * 40.0) as usize;
        u.extend(std::iter::repeat_n(level, hold));
    }
    u.truncate(n);
    let (y_true, modes_true) = simulate(&u, &TRUE_PARAMS, &|x| Some(true_mode(x)));
    let noise: Vec<f64> = (0..n).map(|_| 0.03 * (rng.uniform() - 0.5)).collect();
    let measured: Vec<f64> = y_true.iter().zip(&noise).map(|(y, e)| y + e).collect();

    let mut id_params = TRUE_PARAMS;
    id_params[1][2] = 0.72;
    id_params[2][3] = 0.26;
    let regions = identified_regions();
    let rule_id = |x: &[f64; 3]| regions.iter().position(|r| r.contains(x));
    let (y_pwarx, modes_id) = simulate(&u, &id_params, &rule_id);
    // A linear ARX(2,1) stand-in: mode 2 everywhere.
    let (y_arx, _) = simulate(&u, &TRUE_PARAMS, &|_| Some(1));

    let (time, time_label) = time_axis(n, Some(0.0025), 0);
    let warm = 10;
    let fit_of = |yhat: &[f64]| fit(&measured[warm..], &yhat[warm..]);
    let sim = SimulationFigure {
        title: "Free-run simulation on validation data (synthetic 3-mode PWARX)".into(),
        time: time.clone(),
        time_label: time_label.clone(),
        output_label: "position y [mm]".into(),
        measured: Series::new("measured", measured.clone()),
        simulated: vec![
            Series::new(
                format!("PWARX, 3 modes (FIT {:.1} %)", fit_of(&y_pwarx)),
                y_pwarx.clone(),
            ),
            Series::new(
                format!("ARX(2,1) (FIT {:.1} %)", fit_of(&y_arx)),
                y_arx.clone(),
            ),
        ],
        input_label: "input u [-]".into(),
        inputs: vec![Series::new("input u", u.clone())],
        warm_ups: vec![(time[0], time[warm])],
        record_starts: Vec::new(),
    };
    simulation_plot(&dir.join("simulation.svg"), &sim)?;

    // The first two samples have no regressor, hence no mode.
    let modes = ModeFigure {
        title: "Active mode: true versus identified (synthetic)".into(),
        time: time[2..].to_vec(),
        time_label: time_label.clone(),
        sequences: vec![
            ModeSequence::new("true", modes_true[2..].to_vec()),
            ModeSequence::new("identified", modes_id[2..].to_vec()),
        ],
        mode_names: vec![],
        mark_mismatch: true,
    };
    mode_sequence_plot(&dir.join("modes.svg"), &modes)?;

    let points: Vec<Vec<f64>> = (2..n)
        .map(|k| vec![measured[k - 1], measured[k - 2], u[k - 1]])
        .collect();
    let labels: Vec<Option<usize>> = points
        .iter()
        .map(|x| Some(true_mode(&[x[0], x[1], x[2]])))
        .collect();
    let mean_y2 = points.iter().map(|p| p[1]).sum::<f64>() / points.len() as f64;
    let names = vec![
        "y(k-1)".to_string(),
        "y(k-2)".to_string(),
        "u(k-1)".to_string(),
    ];
    let region_fig = RegionFigure {
        title: "Classified regressors and identified regions (synthetic)".into(),
        x_label: "y(k-1) [mm]".into(),
        y_label: "u(k-1) [-]".into(),
        axes: (0, 2),
        fixed: vec![0.0, mean_y2, 0.0],
        coordinate_names: names,
        points,
        labels,
        regions: regions.clone(),
        mode_names: vec![],
        bounds: None,
        notes: vec![],
    };
    regions_plot(&dir.join("regions.svg"), &region_fig)?;
    // The same with an explicit window and a lower-dimensional region (a stop
    // at y(k-1) = 2.4 mm, for example a mechanical end stop).
    let mut stop = Polyhedron::from_inequalities(vec![vec![0.0, 0.0, 1.0]], vec![0.8]);
    stop.a_eq = vec![vec![1.0, 0.0, 0.0]];
    stop.b_eq = vec![2.4];
    let mut with_stop = region_fig.clone();
    with_stop.title = "Regions with a lower-dimensional stop mode (synthetic)".into();
    with_stop.regions.push(stop);
    with_stop.mode_names = vec![
        "mode 1".into(),
        "mode 2".into(),
        "mode 3".into(),
        "stop y(k-1) = 2.4".into(),
    ];
    with_stop.bounds = Some(Bounds {
        x_min: -3.0,
        x_max: 3.0,
        y_min: -1.2,
        y_max: 1.2,
    });
    regions_plot(&dir.join("regions_stop.svg"), &with_stop)?;

    let c = vec![15.0, 25.0, 35.0, 45.0, 55.0, 65.0, 75.0];
    let sweep_c = SweepFigure {
        title: "FIT versus cluster size c (illustrative numbers)".into(),
        x_label: "cluster size c [-]".into(),
        panels: vec![SweepPanel {
            y_label: "fit_sim [%]".into(),
            series: vec![
                SweepSeries::new(
                    "2 modes, na = 2, nb = 1",
                    c.clone(),
                    vec![62.0, 70.5, 76.1, 78.3, 79.0, 78.2, 77.5],
                ),
                SweepSeries::new(
                    "2 modes, na = 2, nb = 2",
                    c.clone(),
                    vec![60.2, 72.4, 78.8, 80.1, 81.3, f64::NAN, 80.0],
                ),
                SweepSeries::new(
                    "3 modes, na = 2, nb = 2",
                    c.clone(),
                    vec![55.0, 74.0, 82.5, 81.0, 79.5, 78.0, 76.0],
                ),
            ],
            integer_y: false,
        }],
        log_x: false,
    };
    sweep_plot(&dir.join("sweep_c.svg"), &sweep_c)?;

    let delta = vec![0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0];
    let sweep_delta = SweepFigure {
        title: "Bounded error: FIT and mode count versus delta (illustrative numbers)".into(),
        x_label: "error bound delta [mm]".into(),
        panels: vec![
            SweepPanel {
                y_label: "fit_sim [%]".into(),
                series: vec![SweepSeries::new(
                    "bounded",
                    delta.clone(),
                    vec![40.0, 66.0, 79.0, 83.0, 80.0, 73.0, 71.0],
                )],
                integer_y: false,
            },
            SweepPanel {
                y_label: "modes [-]".into(),
                series: vec![SweepSeries::new(
                    "bounded",
                    delta.clone(),
                    vec![14.0, 9.0, 5.0, 3.0, 2.0, 1.0, 1.0],
                )],
                integer_y: true,
            },
        ],
        log_x: true,
    };
    sweep_plot(&dir.join("sweep_delta.svg"), &sweep_delta)?;
    println!("wrote 6 figures to {}", dir.display());
    Ok(())
}
