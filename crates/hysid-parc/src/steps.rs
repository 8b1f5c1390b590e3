//! The steps of PARC: the initial assignment, the local models, the
//! separator, the assignment, and the clean-up at the end.

use crate::{Init, ParcError, ParcOptions};
use hysid_core::backend::IdentifyError;
use hysid_estimation::constrained::{Parametrisation, fit_modes_on, normal_equations};
use hysid_estimation::pwarx::PwarxData;
use hysid_estimation::regions::{RegionMethod, RegionOptions, SoftmaxSettings};
use hysid_model::geometry::Polyhedron;
use hysid_model::regressors::Regressors;
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Runs of k-means of the initial assignment.
const KMEANS_RUNS: usize = 10;

/// Lloyd iterations per k-means run at most.
const KMEANS_ITERATIONS: usize = 100;

/// The cluster of every ordinary sample (`None`: an outlier, dropped at
/// the end), numbered `0..live` without gaps.
#[derive(Debug, Clone, PartialEq)]
pub struct Clusters {
    /// Cluster per sample.
    pub labels: Vec<Option<usize>>,
}

impl Clusters {
    /// Clusters from labels.
    pub fn new(labels: Vec<usize>) -> Self {
        let mut c = Self {
            labels: labels.into_iter().map(Some).collect(),
        };
        c.drop_empty();
        c
    }

    /// Renumbers the clusters that have samples as `0..live` (in order).
    pub fn drop_empty(&mut self) {
        let most = self.labels.iter().flatten().max().map_or(0, |m| m + 1);
        let mut new = vec![None; most];
        let mut next = 0;
        for q in self.labels.iter().flatten() {
            if new[*q].is_none() {
                new[*q] = Some(0);
            }
        }
        for slot in new.iter_mut().flatten() {
            *slot = next;
            next += 1;
        }
        for l in self.labels.iter_mut() {
            *l = l.and_then(|q| new[q]);
        }
    }

    /// Clusters with samples.
    pub fn live(&self) -> usize {
        self.labels.iter().flatten().max().map_or(0, |m| m + 1)
    }

    /// Samples of each cluster.
    pub fn members(&self) -> Vec<Vec<usize>> {
        let mut rows = vec![Vec::new(); self.live()];
        for (k, q) in self.labels.iter().enumerate() {
            if let Some(q) = q {
                rows[*q].push(k);
            }
        }
        rows
    }

    /// Samples that are not outliers, and their clusters.
    fn assigned(&self) -> (Vec<usize>, Vec<usize>) {
        self.labels
            .iter()
            .enumerate()
            .filter_map(|(k, q)| q.map(|q| (k, q)))
            .unzip()
    }
}

/// The initial assignment of `k` clusters: k-means on the standardised
/// regressors (k-means++ seeding, the least within-cluster sum of squares
/// of 10 runs, PARC's `("kmeans", 10)`), or uniformly random labels.
pub fn initial_labels(options: &ParcOptions, reg: &Regressors, k: usize, seed: u64) -> Vec<usize> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = reg.x.nrows();
    match options.init {
        Init::Random => (0..n).map(|_| rng.random_range(0..k)).collect(),
        Init::Kmeans => {
            let z = standardised(&reg.x);
            (0..KMEANS_RUNS)
                .map(|_| kmeans(&z, k, &mut rng))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(labels, _)| labels)
                .unwrap_or_else(|| vec![0; n])
        }
    }
}

fn standardised(x: &DMatrix<f64>) -> DMatrix<f64> {
    let n = x.nrows().max(1) as f64;
    let mut z = x.clone();
    for mut col in z.column_iter_mut() {
        let mean = col.sum() / n;
        let sd = (col.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
        let sd = if sd > 0.0 { sd } else { 1.0 };
        col.iter_mut().for_each(|v| *v = (*v - mean) / sd);
    }
    z
}

fn squared_distance(z: &DMatrix<f64>, k: usize, c: &[f64]) -> f64 {
    c.iter()
        .enumerate()
        .map(|(j, cj)| (z[(k, j)] - cj).powi(2))
        .sum()
}

/// One k-means run: k-means++ seeding, then Lloyd iterations until the
/// labels repeat. Returns the labels and the within-cluster sum of squares.
fn kmeans(z: &DMatrix<f64>, k: usize, rng: &mut ChaCha8Rng) -> (Vec<usize>, f64) {
    let (n, d) = (z.nrows(), z.ncols());
    let row = |i: usize| -> Vec<f64> { (0..d).map(|j| z[(i, j)]).collect() };
    let mut centres = vec![row(rng.random_range(0..n))];
    while centres.len() < k {
        let dist: Vec<f64> = (0..n)
            .map(|i| {
                centres
                    .iter()
                    .map(|c| squared_distance(z, i, c))
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        let total: f64 = dist.iter().sum();
        let pick = if total > 0.0 {
            let mut t = rng.random_range(0.0..total);
            dist.iter()
                .position(|&v| {
                    t -= v;
                    t <= 0.0
                })
                .unwrap_or(n - 1)
        } else {
            rng.random_range(0..n)
        };
        centres.push(row(pick));
    }
    let nearest = |centres: &[Vec<f64>], i: usize| -> (usize, f64) {
        centres
            .iter()
            .enumerate()
            .map(|(q, c)| (q, squared_distance(z, i, c)))
            .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a })
    };
    let mut labels: Vec<usize> = (0..n).map(|i| nearest(&centres, i).0).collect();
    for _ in 0..KMEANS_ITERATIONS {
        for (q, c) in centres.iter_mut().enumerate() {
            let members: Vec<usize> = (0..n).filter(|&i| labels[i] == q).collect();
            if members.is_empty() {
                continue;
            }
            for (j, cj) in c.iter_mut().enumerate() {
                *cj = members.iter().map(|&i| z[(i, j)]).sum::<f64>() / members.len() as f64;
            }
        }
        let next: Vec<usize> = (0..n).map(|i| nearest(&centres, i).0).collect();
        if next == labels {
            break;
        }
        labels = next;
    }
    let inertia = (0..n).map(|i| nearest(&centres, i).1).sum();
    (labels, inertia)
}

/// Step 1: least squares per cluster on its samples, under the priors
/// (`hysid_estimation::constrained`); without parameter priors, inside the
/// descent (`exact` false), from the normal equations of each cluster.
pub fn fit_local_models(
    data: &PwarxData<'_>,
    reg: &Regressors,
    clusters: &Clusters,
    exact: bool,
) -> Result<Vec<Vec<f64>>, IdentifyError> {
    let par = Parametrisation::from_priors(data.priors(), &data.spec, clusters.live())
        .map_err(|e| data.prior_error(e))?;
    if !exact
        && par.is_free()
        && let Some(thetas) = normal_equations(
            reg,
            clusters
                .labels
                .iter()
                .enumerate()
                .filter_map(|(k, q)| q.map(|q| (k, q))),
            clusters.live(),
        )
    {
        return Ok(thetas);
    }
    fit_modes_on(&par, reg, &clusters.members()).map_err(|e| ParcError::LocalModels(e).into())
}

/// Step 2: the separator, a multinomial logistic regression of the
/// clusters on the regressors (`hysid_estimation::regions` softmax, every sample
/// weighing 1, ridge `beta` on the sum of the losses; normals restricted to
/// the `switching` regressors), started from `start` (the previous
/// round's scores) when it has one per cluster. Returns per cluster the
/// score `f_j` as `[omega_j; gamma_j]` in the record's units.
pub fn fit_separator(
    options: &ParcOptions,
    data: &PwarxData<'_>,
    reg: &Regressors,
    clusters: &Clusters,
    start: Option<&[Vec<f64>]>,
) -> Result<Vec<Vec<f64>>, IdentifyError> {
    let d = reg.x.ncols();
    let live = clusters.live();
    if live <= 1 {
        return Ok(vec![vec![0.0; d + 1]; live.max(1)]);
    }
    let (rows, labels) = clusters.assigned();
    let x = reg.x.select_rows(&rows);
    let region_options = RegionOptions {
        method: RegionMethod::Softmax,
        switching: data.switching.clone(),
        softmax: SoftmaxSettings {
            balanced: false,
            ridge: options.beta / rows.len().max(1) as f64,
            start: start.map(<[Vec<f64>]>::to_vec),
        },
        ..Default::default()
    };
    hysid_estimation::regions::estimate(&x, &labels, live, &region_options)
        .map(|p| p.scores)
        .map_err(|e| ParcError::Separator(e).into())
}

fn score(f: &[f64], x: &[f64]) -> f64 {
    let d = x.len();
    f[d] + x.iter().zip(f).map(|(a, b)| a * b).sum::<f64>()
}

/// Step 3: every sample to the cluster of least cost
/// `(y - theta_j . [x; 1])^2 + (sigma / N) (logsumexp_h f_h(x) - f_j(x))`
/// (the lowest index on a tie); clusters left empty die. Returns the total
/// cost.
pub fn reassign(
    options: &ParcOptions,
    reg: &Regressors,
    thetas: &[Vec<f64>],
    scores: &[Vec<f64>],
    clusters: &mut Clusters,
) -> f64 {
    let (n, d) = (reg.x.nrows(), reg.x.ncols());
    let sigma = options.sigma / n.max(1) as f64;
    let mut total = 0.0;
    let mut x = vec![0.0; d];
    let mut f = vec![0.0; scores.len()];
    for k in 0..n {
        if clusters.labels[k].is_none() {
            continue;
        }
        for (j, xj) in x.iter_mut().enumerate() {
            *xj = reg.x[(k, j)];
        }
        for (fj, s) in f.iter_mut().zip(scores) {
            *fj = score(s, &x);
        }
        let top = f.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let lse = top + f.iter().map(|v| (v - top).exp()).sum::<f64>().ln();
        let mut best = (0, f64::INFINITY);
        for (j, theta) in thetas.iter().enumerate() {
            let e = reg.y[k] - score(theta, &x);
            let c = e * e + sigma * (lse - f[j]);
            if c < best.1 {
                best = (j, c);
            }
        }
        clusters.labels[k] = Some(best.0);
        total += best.1;
    }
    clusters.drop_empty();
    total
}

/// What the run ends with.
#[derive(Debug, Clone)]
pub struct Finished {
    /// Parameters per mode.
    pub thetas: Vec<Vec<f64>>,
    /// The cells of the partition, one per mode.
    pub regions: Vec<Polyhedron>,
    /// Samples left out (in dropped clusters or cells).
    pub outliers: usize,
}

/// The clean-up: clusters under `min_number` samples become outliers, the
/// separator is refitted on the rest, and with `fit_on_partition` every
/// other sample goes to the cell of its largest score, cells under
/// `min_number` become outliers, and the local models are refitted per
/// cell. The regions are the cells of the kept scores.
pub fn finish(
    options: &ParcOptions,
    data: &PwarxData<'_>,
    reg: &Regressors,
    mut clusters: Clusters,
) -> Result<Finished, IdentifyError> {
    let d = reg.x.ncols();
    let min_number = options.smallest_cluster(reg);
    drop_small(&mut clusters, min_number);
    if clusters.live() == 0 {
        return Err(ParcError::EveryClusterTooSmall { min_number }.into());
    }
    let mut scores = fit_separator(options, data, reg, &clusters, None)?;
    if options.fit_on_partition {
        let mut x = vec![0.0; d];
        for k in 0..reg.x.nrows() {
            if clusters.labels[k].is_some() {
                for (j, xj) in x.iter_mut().enumerate() {
                    *xj = reg.x[(k, j)];
                }
                let cell = scores
                    .iter()
                    .enumerate()
                    .map(|(j, s)| (j, score(s, &x)))
                    .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
                clusters.labels[k] = Some(cell.0);
            }
        }
        let sizes: Vec<usize> = (0..scores.len())
            .map(|j| clusters.labels.iter().filter(|&&q| q == Some(j)).count())
            .collect();
        let kept: Vec<usize> = (0..scores.len())
            .filter(|&j| sizes[j] >= min_number)
            .collect();
        if kept.is_empty() {
            return Err(ParcError::EveryCellTooSmall { min_number }.into());
        }
        for l in clusters.labels.iter_mut() {
            *l = l.and_then(|q| kept.iter().position(|&j| j == q));
        }
        scores = kept.iter().map(|&j| scores[j].clone()).collect();
    }
    let thetas = fit_local_models(data, reg, &clusters, true)?;
    let outliers = clusters.labels.iter().filter(|q| q.is_none()).count();
    Ok(Finished {
        regions: regions(&scores),
        thetas,
        outliers,
    })
}

/// Clusters under `min_number` samples become outliers.
fn drop_small(clusters: &mut Clusters, min_number: usize) {
    let sizes: Vec<usize> = clusters.members().iter().map(Vec::len).collect();
    for l in clusters.labels.iter_mut() {
        if l.is_some_and(|q| sizes[q] < min_number) {
            *l = None;
        }
    }
    clusters.drop_empty();
}

/// The cells `{x : f_j(x) >= f_h(x) for all h}`; one mode owns the space.
fn regions(scores: &[Vec<f64>]) -> Vec<Polyhedron> {
    if scores.len() <= 1 {
        return vec![Polyhedron::everything(); scores.len().max(1)];
    }
    hysid_estimation::regions::argmax_regions(scores)
}
