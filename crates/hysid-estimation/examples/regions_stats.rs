//! Prints working-set statistics and one-shot times for the benchmark data.
//! `cargo run --release -p hysid-estimation --example regions_stats`
#[path = "../benches/regions_data/mod.rs"]
mod regions_data;

use hysid_estimation::regions::{RegionMethod, RegionOptions, estimate};
use regions_data::data;

fn main() {
    let sizes: Vec<usize> = match std::env::args().nth(1) {
        Some(a) => a
            .split(',')
            .map(|v| v.parse().expect("sizes like 1000,8000"))
            .collect(),
        None => vec![1_000, 8_000, 100_000],
    };
    for n in sizes {
        let (x, labels) = data(n);
        for method in [
            RegionMethod::Mrlp,
            RegionMethod::Msvm,
            RegionMethod::Softmax,
            RegionMethod::Psvc,
        ] {
            let opts = RegionOptions {
                method,
                ..RegionOptions::default()
            };
            let repeats = if n > 10_000 { 1 } else { 5 };
            let mut best = f64::INFINITY;
            let mut part = None;
            for _ in 0..repeats {
                let t = std::time::Instant::now();
                part = Some(estimate(&x, &labels, 3, &opts).unwrap());
                best = best.min(t.elapsed().as_secs_f64() * 1e3);
            }
            let p = part.unwrap();
            // points with a hinge loss at the solution (margin < 1): the
            // smallest working set that certifies the optimum
            let active = (0..n)
                .filter(|&r| {
                    if p.scores.is_empty() {
                        return false;
                    }
                    let f: Vec<f64> = p
                        .scores
                        .iter()
                        .map(|c| c[0] * x[(r, 0)] + c[1] * x[(r, 1)] + c[2] * x[(r, 2)] + c[3])
                        .collect();
                    let other = (0..3)
                        .filter(|&j| j != labels[r])
                        .map(|j| f[j])
                        .fold(f64::NEG_INFINITY, f64::max);
                    f[labels[r]] - other < 1.0 - 1e-6
                })
                .count();
            println!(
                "N={n:>6} {method:>7}: {best:9.1} ms (best of {repeats})  accuracy {:.4}  solves {}  working set {}  margin<1 {}  ipm iters {}  newton {}",
                p.training_accuracy,
                p.stats.solves,
                p.stats.working_points,
                active,
                p.stats.solver_iterations,
                p.stats.newton_steps
            );
        }
    }
}
