//! Cost of the `cluster` back-end on B1 (three-mode PWARX, na = nb = 1)
//! from N = 10^3 to 10^6, with the time of each stage, for
//! `docs/performance-cluster.md`. The local datasets run in parallel (rayon;
//! `RAYON_NUM_THREADS=1` for one thread), the rest on one thread; every
//! stage is run with the back-end's default options (k-means++ seeding, 15 restarts, MRLP
//! regions), so the stage times add up to about the end-to-end time.
//!
//! ```text
//! cargo run --release -p hysid-cluster --example cluster_scaling [-- N N ... [c=K] [reps=R]]
//! ```
//!
//! Each N is run `reps` times (default 1) and the fastest time of every
//! column is printed (the least disturbed by other load on the machine).

use hysid_cluster::kmeans::{KmeansInit, weighted_kmeans};
use hysid_cluster::local::feature_vectors;
use hysid_cluster::{Cluster, ClusterOptions, Clustering, Features, procedure};
use hysid_core::backend::{Backend, Problem, RunContext};
use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
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
    let ns = if ns.is_empty() {
        vec![1_000, 10_000, 100_000, 1_000_000]
    } else {
        ns
    };
    let defaults = ClusterOptions::default();
    println!(
        "| N | c | local datasets + features (s) | K-means, {} restarts (s) | steps 1-5 total (s) | regions (s) | end to end (s) | end to end / (N log2 N) (ns) | cluster label accuracy | region mode accuracy |",
        defaults.restarts
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for n in ns {
        // `n` regressor rows of B1 (`u ~ U[-4, 4]`, noise `U[-0.1, 0.1]`).
        let ex = hysid_testkit::b1(n + 1, 4.0, Noise::Uniform(0.1), 1);
        let orders = ex.truth.spec();
        let truth_modes = ex.row_modes();
        let sc = Standardization::of(&ex.data);
        let reg = orders.build(&sc.apply(&ex.data)).unwrap();
        let d = orders.dim();
        let x: Vec<f64> = (0..reg.len())
            .flat_map(|r| (0..d).map(move |k| (r, k)))
            .map(|(r, k)| reg.x[(r, k)])
            .collect();
        let y: Vec<f64> = reg.y.iter().copied().collect();
        let c = fixed_c.unwrap_or_else(|| hysid_cluster::default_c(d, reg.len(), 3));
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
        let settings_all = match fixed_c {
            Some(c) => Settings::from_pairs(vec![("c".into(), c.to_string())]),
            None => Settings::default(),
        };
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
            acc_labels = mode_accuracy(&truth_modes, &fit.labels).unwrap().accuracy;
            let t = Instant::now();
            let ropts = hysid_regions::RegionOptions {
                standardize: false,
                ..Default::default()
            };
            hysid_regions::estimate(&reg.x, &fit.labels, fit.theta.len(), &ropts).unwrap();
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
            let m = Cluster
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
        println!(
            "| {n} | {c} | {:.4} | {:.4} | {:.4} | {:.4} | {t_all:.4} | {:.1} | {acc_labels:.4} | {acc:.4} |",
            fastest(tl),
            fastest(tk),
            fastest(tp),
            fastest(tr),
            t_all * 1e9 / (n as f64 * (n as f64).log2())
        );
    }
}
