//! Cost of the `cluster` back-end on B1 (three-mode PWARX, na = nb = 1)
//! from N = 10^3 to 10^6, with the time of each stage, for
//! `docs/performance-cluster.md`. One run per N, single-threaded.
//!
//! ```text
//! cargo run --release -p hysid-cluster --example cluster_scaling [-- N N ... [c=K]]
//! ```

use hysid_cluster::kmeans::{KmeansInit, weighted_kmeans};
use hysid_cluster::local::feature_vectors;
use hysid_cluster::systems::b1;
use hysid_cluster::{Cluster, Clustering, Features, Weights, procedure};
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::data::Standardization;
use hysid_core::metrics::mode_accuracy;
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use rand::SeedableRng;
use std::time::Instant;

fn main() {
    let ns: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    // `c=K` fixes the local dataset size instead of the default rule.
    let fixed_c: Option<usize> = std::env::args()
        .skip(1)
        .find_map(|a| a.strip_prefix("c=").and_then(|v| v.parse().ok()));
    let ns = if ns.is_empty() {
        vec![1_000, 3_000, 10_000, 30_000, 100_000, 300_000, 1_000_000]
    } else {
        ns
    };
    println!(
        "| N | c | local datasets + features (s) | K-means, 15 restarts (s) | steps 1-5 total (s) | regions + refit (s) | end to end (s) | end to end / (N log2 N) (ns) | cluster label accuracy | region mode accuracy |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for n in ns {
        let ex = b1(n, 1);
        let sc = Standardization::of(&ex.data);
        let reg = ex.orders.build(&sc.apply(&ex.data)).unwrap();
        let d = ex.orders.dim();
        let x: Vec<f64> = (0..reg.len())
            .flat_map(|r| (0..d).map(move |k| (r, k)))
            .map(|(r, k)| reg.x[(r, k)])
            .collect();
        let y: Vec<f64> = reg.y.iter().copied().collect();
        let c = fixed_c.unwrap_or_else(|| hysid_cluster::default_c(d, reg.len(), 3));
        let t = Instant::now();
        let f = feature_vectors(&x, d, &y, c, Features::Fv, 1e-6);
        let t_local = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let _k = weighted_kmeans(
            &f,
            3,
            15,
            100,
            KmeansInit::Blocks,
            &mut rand_chacha::ChaCha8Rng::seed_from_u64(1),
        );
        let t_kmeans = t.elapsed().as_secs_f64();
        let settings = procedure::Settings {
            c,
            modes: 3,
            features: Features::Fv,
            clustering: Clustering::Kmeans,
            sl_distance: None,
            restarts: 15,
            max_iter: 100,
            init: KmeansInit::Blocks,
            discard: 2.0,
            reattribute: true,
            regularization: 1e-6,
            min_weight: 1e-8,
            weights: Weights::Confidence,
            deadline: None,
        };
        let t = Instant::now();
        let fit = procedure::run(
            &x,
            d,
            &y,
            &settings,
            &mut rand_chacha::ChaCha8Rng::seed_from_u64(1),
        )
        .unwrap();
        let t_proc = t.elapsed().as_secs_f64();
        let acc_labels = mode_accuracy(&ex.modes, &fit.labels).accuracy;
        let priors = Priors {
            modes: Some(3),
            ..Default::default()
        };
        let problem = Problem {
            data: &ex.data,
            orders: ex.orders,
            priors: &priors,
            priors_origin: None,
        };
        let t = Instant::now();
        let m = Cluster
            .run(&problem, &Settings::default(), &RunContext::quiet(1))
            .unwrap();
        let t_all = t.elapsed().as_secs_f64();
        let Model::Pwarx(p) = &m else { unreachable!() };
        let raw = ex.orders.build(&ex.data).unwrap();
        let ident: Vec<usize> = (0..raw.len())
            .map(|r| {
                p.mode_of(&raw.x.row(r).iter().copied().collect::<Vec<_>>())
                    .mode
            })
            .collect();
        let acc = mode_accuracy(&ex.modes, &ident).accuracy;
        println!(
            "| {n} | {c} | {t_local:.4} | {t_kmeans:.4} | {t_proc:.4} | {:.4} | {t_all:.4} | {:.1} | {acc_labels:.4} | {acc:.4} |",
            t_all - t_proc,
            t_all * 1e9 / (n as f64 * (n as f64).log2())
        );
    }
}
