//! The tiny kernels of `hysid_estimation::dense` beside faer's `Llt` on the
//! same symmetric positive definite `p x p` systems: factor, then solve one
//! right-hand side. Run with `cargo bench -p hysid-estimation --bench dense`.

use faer::linalg::solvers::Solve;
use hysid_estimation::dense;

fn main() {
    divan::main();
}

/// The sizes `cluster` factors once or twice per local dataset: the
/// regressor dimension plus one.
const SIZES: [usize; 4] = [3, 5, 8, 12];

/// A well-conditioned SPD matrix `B^T B + p I` (row-major) and a
/// right-hand side.
fn system(p: usize) -> (Vec<f64>, Vec<f64>) {
    let b: Vec<f64> = (0..p * p)
        .map(|k| ((k * 7919) % 101) as f64 / 101.0 - 0.5)
        .collect();
    let mut a = vec![0.0; p * p];
    for i in 0..p {
        for j in 0..p {
            a[i * p + j] = (0..p).map(|k| b[k * p + i] * b[k * p + j]).sum::<f64>();
        }
        a[i * p + i] += p as f64;
    }
    (a, (0..p).map(|i| i as f64 - 1.0).collect())
}

#[divan::bench(args = SIZES)]
fn hand_written(bencher: divan::Bencher, p: usize) {
    let (a, rhs) = system(p);
    let (mut l, mut x) = (a.clone(), rhs.clone());
    bencher.bench_local(|| {
        l.copy_from_slice(&a);
        x.copy_from_slice(&rhs);
        dense::cholesky(divan::black_box(&mut l), p).unwrap();
        dense::cholesky_solve(&l, p, &mut x);
        divan::black_box(x[0])
    });
}

#[divan::bench(args = SIZES)]
fn faer_llt(bencher: divan::Bencher, p: usize) {
    let (a, rhs) = system(p);
    let m = faer::Mat::from_fn(p, p, |i, j| a[i * p + j]);
    let b = faer::Mat::from_fn(p, 1, |i, _| rhs[i]);
    bencher.bench_local(|| {
        let llt = divan::black_box(&m).llt(faer::Side::Lower).unwrap();
        let x = llt.solve(&b);
        divan::black_box(x[(0, 0)])
    });
}
