//! Cost of the `cluster` back-end on B1 (three-mode PWARX, na = nb = 1)
//! from N = 10^3 to 10^7, with the time of each stage, for
//! `docs/performance-cluster.md`. Above `cluster_points` samples (10^5 by
//! default) the stages before "end to end" run on the back-end's
//! clustering sample (every `ceil(N / cluster_points)`-th sample), as the
//! back-end does. The local datasets run in parallel (rayon;
//! `RAYON_NUM_THREADS=1` for one thread), the rest on one thread; every
//! stage is run with the back-end's default options (k-means++ seeding, 15 restarts, MRLP
//! regions), so the stage times add up to about the end-to-end time.
//!
//! ```text
//! cargo run --release -p hysid-cluster --example cluster_scaling [-- N N ... [c=K] [points=P] [reps=R] [svg=FILE]]
//! ```
//!
//! Each N is run `reps` times (default 1) and the fastest time of every
//! column is printed (the least disturbed by other load on the machine).
//! `points=P` sets `cluster_points` (0: cluster every sample); `svg=FILE`
//! draws the stage times against N on log-log axes.

use hysid_cluster::kmeans::{KmeansInit, weighted_kmeans};
use hysid_cluster::local::feature_vectors;
use hysid_cluster::{Cluster, ClusterOptions, Clustering, Features, procedure};
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_estimation::pwarx::Pwarx;
use hysid_model::data::Standardization;
use hysid_model::metrics::mode_accuracy;
use hysid_testkit::Noise;
use rand::SeedableRng;
use std::time::Instant;

fn fastest(v: Vec<f64>) -> f64 {
    v.into_iter().fold(f64::INFINITY, f64::min)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let ns: Vec<usize> = args.iter().filter_map(|a| a.parse().ok()).collect();
    // `c=K` fixes the local dataset size instead of the default rule.
    let fixed_c: Option<usize> = args
        .iter()
        .find_map(|a| a.strip_prefix("c=").and_then(|v| v.parse().ok()));
    let reps: usize = args
        .iter()
        .find_map(|a| a.strip_prefix("reps=").and_then(|v| v.parse().ok()))
        .unwrap_or(1)
        .max(1);
    let points: Option<usize> = args
        .iter()
        .find_map(|a| a.strip_prefix("points=").and_then(|v| v.parse().ok()));
    let svg: Option<String> = args
        .iter()
        .find_map(|a| a.strip_prefix("svg=").map(str::to_string));
    let ns = if ns.is_empty() {
        vec![1_000, 10_000, 100_000, 1_000_000]
    } else {
        ns
    };
    let defaults = ClusterOptions::default();
    let mut rows: Vec<[f64; 6]> = Vec::new();
    println!(
        "| N | clustered | c | local datasets + features (s) | K-means, {} restarts (s) | steps 1-5 total (s) | regions (s) | end to end (s) | end to end / (N log2 N) (ns) | cluster label accuracy | region mode accuracy |",
        defaults.restarts
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for n in ns {
        // `n` regressor rows of B1 (`u ~ U[-4, 4]`, noise `U[-0.1, 0.1]`).
        let ex = hysid_testkit::b1(n + 1, 4.0, Noise::Uniform(0.1), 1);
        let orders = ex.truth.spec();
        let truth_modes = ex.row_modes();
        let sc = Standardization::of(&ex.data);
        let reg = orders.build(&sc.apply(&ex.data)).unwrap();
        let d = orders.dim();
        // The back-end's clustering sample (all rows up to cluster_points).
        let points = points.unwrap_or(defaults.cluster_points);
        let stride = if points > 0 && reg.len() > points {
            reg.len().div_ceil(points)
        } else {
            1
        };
        let sample: Vec<usize> = (0..reg.len()).step_by(stride).collect();
        let x: Vec<f64> = sample
            .iter()
            .flat_map(|&r| (0..d).map(move |k| (r, k)))
            .map(|(r, k)| reg.x[(r, k)])
            .collect();
        let y: Vec<f64> = sample.iter().map(|&r| reg.y[r]).collect();
        let sample_x = reg.x.select_rows(&sample);
        let sample_truth: Vec<usize> = sample.iter().map(|&r| truth_modes[r]).collect();
        let c = fixed_c.unwrap_or_else(|| hysid_cluster::default_c(d, sample.len(), 3));
        let settings = procedure::Settings {
            c,
            modes: 3,
            features: defaults.features,
            clustering: Clustering::Kmeans,
            sl_distance: None,
            restarts: defaults.restarts,
            max_iter: defaults.max_iter,
            init: KmeansInit::PlusPlus,
            discard: defaults.discard,
            reattribute: defaults.reattribute,
            regularization: defaults.regularization,
            min_weight: defaults.min_weight,
            weights: defaults.weights,
            deadline: hysid_core::backend::Deadline::none(),
        };
        let mut pairs = vec![("cluster_points".to_string(), points.to_string())];
        if let Some(c) = fixed_c {
            pairs.push(("c".into(), c.to_string()));
        }
        let settings_all = Settings::from_pairs(pairs);
        let (mut tl, mut tk, mut tp, mut tr, mut ta) = (vec![], vec![], vec![], vec![], vec![]);
        let (mut acc_labels, mut acc) = (0.0, 0.0);
        for _ in 0..reps {
            let t = Instant::now();
            let f = feature_vectors(&x, d, &y, c, Features::Fv, defaults.regularization);
            tl.push(t.elapsed().as_secs_f64());
            eprintln!("N = {n}: local datasets {:.3} s", tl[tl.len() - 1]);
            let t = Instant::now();
            let _k = weighted_kmeans(
                &f,
                3,
                defaults.restarts,
                defaults.max_iter,
                KmeansInit::PlusPlus,
                &mut rand_chacha::ChaCha8Rng::seed_from_u64(1),
            );
            tk.push(t.elapsed().as_secs_f64());
            eprintln!("N = {n}: K-means {:.3} s", tk[tk.len() - 1]);
            let t = Instant::now();
            let fit = procedure::run(
                &x,
                d,
                &y,
                &settings,
                &mut rand_chacha::ChaCha8Rng::seed_from_u64(1),
            )
            .unwrap();
            tp.push(t.elapsed().as_secs_f64());
            eprintln!("N = {n}: steps 1-5 {:.3} s", tp[tp.len() - 1]);
            acc_labels = mode_accuracy(&sample_truth, &fit.labels).unwrap().accuracy;
            let t = Instant::now();
            let ropts = hysid_estimation::regions::RegionOptions {
                standardize: false,
                ..Default::default()
            };
            hysid_estimation::regions::estimate(&sample_x, &fit.labels, fit.theta.len(), &ropts)
                .unwrap();
            tr.push(t.elapsed().as_secs_f64());
            eprintln!("N = {n}: regions {:.3} s", tr[tr.len() - 1]);
            let priors = Priors {
                modes: Some(3),
                ..Default::default()
            };
            let problem = Problem {
                data: &ex.data,
                orders,
                priors: &priors,
                priors_origin: None,
            };
            let t = Instant::now();
            let m = Pwarx(Cluster)
                .run(&problem, &settings_all, &RunContext::quiet(1))
                .unwrap();
            ta.push(t.elapsed().as_secs_f64());
            let Model::Pwarx(p) = &m else { unreachable!() };
            let raw = orders.build(&ex.data).unwrap();
            let ident: Vec<usize> = (0..raw.len())
                .map(|r| {
                    p.mode_of(&raw.x.row(r).iter().copied().collect::<Vec<_>>())
                        .mode
                })
                .collect();
            acc = mode_accuracy(&truth_modes, &ident).unwrap().accuracy;
        }
        let t_all = fastest(ta);
        let row = [
            n as f64,
            fastest(tl),
            fastest(tk),
            fastest(tp),
            fastest(tr),
            t_all,
        ];
        println!(
            "| {n} | {} | {c} | {:.4} | {:.4} | {:.4} | {:.4} | {t_all:.4} | {:.1} | {acc_labels:.4} | {acc:.4} |",
            sample.len(),
            row[1],
            row[2],
            row[3],
            row[4],
            t_all * 1e9 / (n as f64 * (n as f64).log2())
        );
        rows.push(row);
    }
    if let Some(path) = svg {
        draw(&path, &rows).expect("drawing the figure");
    }
}

/// The stage times of `rows` (`[N, local, K-means, steps 1-5, regions, end
/// to end]`) against N, log-log.
fn draw(path: &str, rows: &[[f64; 6]]) -> Result<(), Box<dyn std::error::Error>> {
    use plotters::prelude::*;
    let root = SVGBackend::new(path, (720, 480)).into_drawing_area();
    root.fill(&WHITE)?;
    let positive = |k: usize| rows.iter().map(move |r| r[k]).filter(|v| *v > 0.0);
    let lo = (1..6).flat_map(positive).fold(f64::INFINITY, f64::min) / 2.0;
    let hi = (1..6).flat_map(positive).fold(0.0, f64::max) * 2.0;
    let (n_lo, n_hi) = (rows[0][0] / 1.5, rows[rows.len() - 1][0] * 1.5);
    let mut chart = ChartBuilder::on(&root)
        .caption("cluster on B1: time of each stage", ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((n_lo..n_hi).log_scale(), (lo..hi).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("samples N")
        .y_desc("seconds")
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()?;
    let names = [
        "local datasets",
        "K-means",
        "steps 1-5",
        "regions",
        "end to end",
    ];
    for (k, name) in names.iter().enumerate() {
        let colour = Palette99::pick(k).to_rgba();
        chart
            .draw_series(LineSeries::new(
                rows.iter().map(|r| (r[0], r[k + 1])).filter(|p| p.1 > 0.0),
                colour.stroke_width(2),
            ))?
            .label(*name)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        chart.draw_series(
            rows.iter()
                .filter(|r| r[k + 1] > 0.0)
                .map(|r| Circle::new((r[0], r[k + 1]), 3, colour.filled())),
        )?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
