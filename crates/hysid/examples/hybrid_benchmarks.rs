//! Every PWARX back-end that takes a mode count on the literature's
//! benchmark systems (B1, H1-H4 of `hysid-testkit`), five draws each, the
//! same draws for every back-end: the median mode accuracy of its regions
//! on a fresh draw and the median parameter error (largest relative error
//! after the best matching). Figures in docs/klinreg.md, docs/parc.md and
//! docs/bayes.md.
//!
//! Run: cargo run --release -p hysid --example hybrid_benchmarks
//! [-- METHOD[:KEY=VALUE,...] ...] (default: cluster, klinreg, parc and
//! bayes at their defaults; `cluster` always gets the reference options).

use hysid_core::model::Model;
use hysid_core::options::Settings;
use hysid_core::priors::Priors;
use hysid_testkit::{Benchmark, Noise, median};

type Generator = fn(usize, u64) -> Benchmark;

/// A benchmark system: name, samples, modes, generator, and `cluster`'s
/// options as its reference tests set them.
struct System {
    name: &'static str,
    samples: usize,
    modes: usize,
    generate: Generator,
    cluster_options: &'static [(&'static str, &'static str)],
}

fn b1(n: usize, seed: u64) -> Benchmark {
    hysid_testkit::b1(n, 4.0, Noise::Uniform(0.1), seed)
}

fn main() {
    let system = |name, samples, modes, generate: Generator, cluster_options| System {
        name,
        samples,
        modes,
        generate,
        cluster_options,
    };
    let systems = [
        system("B1", 301, 3, b1, &[]),
        system("H1", 71, 3, hysid_testkit::h1, &[("c", "6")]),
        system("H2", 101, 5, hysid_testkit::h2, &[("c", "8")]),
        system("H3", 61, 3, hysid_testkit::h3, &[("c", "6")]),
        system("H4", 61, 3, hysid_testkit::h4, &[("c", "6")]),
    ];
    let registry = hysid::registry();
    let mut runs: Vec<(String, Vec<(String, String)>)> = std::env::args()
        .skip(1)
        .map(|arg| {
            let (method, set) = arg.split_once(':').unwrap_or((&arg, ""));
            let pairs = set
                .split(',')
                .filter_map(|kv| kv.split_once('='))
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect();
            (method.to_string(), pairs)
        })
        .collect();
    if runs.is_empty() {
        runs = ["cluster", "klinreg", "parc", "bayes"]
            .map(|m| (m.to_string(), Vec::new()))
            .into();
    }
    println!(
        "| system | method | median mode accuracy | median parameter error | runs that failed |"
    );
    println!("|---|---|---|---|---|");
    for System {
        name,
        samples: n,
        modes,
        generate,
        cluster_options,
    } in systems
    {
        for (method, pairs) in &runs {
            let backend = registry.require(method).expect("a registered method");
            let mut pairs = pairs.clone();
            if method == "cluster" {
                pairs.extend(
                    cluster_options
                        .iter()
                        .map(|(k, v)| (k.to_string(), v.to_string())),
                );
            }
            let shown: Vec<String> = pairs.iter().map(|(k, v)| format!("{k}={v}")).collect();
            let settings = Settings::from_pairs(pairs);
            let (mut acc, mut err, mut failed) = (Vec::new(), Vec::new(), 0);
            for seed in 1..=5u64 {
                let b = generate(n, seed);
                let fresh = generate(n, seed + 100);
                let priors = Priors {
                    modes: Some(modes),
                    ..Priors::default()
                };
                match b.run(backend, &priors, &settings, seed) {
                    Ok(Model::Pwarx(p)) => {
                        acc.push(fresh.recovery(&p).0);
                        err.push(b.recovery(&p).1);
                    }
                    _ => failed += 1,
                }
            }
            let show = |v: Vec<f64>| {
                if v.is_empty() {
                    "-".to_string()
                } else {
                    format!("{:.3}", median(v))
                }
            };
            let label = match runs.iter().filter(|(m, _)| m == method).count() {
                1 => method.clone(),
                _ => format!("{method} {}", shown.join(","))
                    .trim_end()
                    .to_string(),
            };
            println!(
                "| {name} | {label} | {} | {} | {failed} |",
                show(acc),
                show(err)
            );
        }
    }
}
