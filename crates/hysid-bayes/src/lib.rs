//! # hysid-bayes
//!
//! The `bayes` back-end: the Bayesian procedure of A. Lj. Juloski,
//! S. Weiland and W. P. M. H. Heemels, "A Bayesian approach to
//! identification of hybrid systems", IEEE TAC 50(10), 2005, then the
//! regions.
//!
//! The parameters `theta_i` of every mode are random variables with a
//! prior pdf `p_i(theta)`. The steps:
//!
//! 1. the noise level `sigma` of the equation noise
//!    ([`noise_level`]) and the prior of every mode ([`mode_priors`]);
//! 2. each mode's pdf as a particle cloud drawn from its prior
//!    ([`initial_pdfs`]);
//! 3. the samples one by one ([`process_sequentially`], in the order of
//!    [`processing_order`]): the sample goes to the mode of largest
//!    predictive density `l_i(k) = int N(y_k; phi_k' theta, sigma^2)
//!    p_i(theta) dtheta`, and only that mode's pdf is updated by Bayes'
//!    rule;
//! 4. the parameters are the posterior means ([`point_estimates`]);
//! 5. every sample is classified again with the final pdfs
//!    ([`reclassify`]), with its confidence (the posterior probability of
//!    its mode under equal mode probabilities);
//! 6. the regions from those labels (`hysid_estimation::regions`, as for the other
//!    PWARX back-ends).
//!
//! `docs/bayes.md` has the equations and every deviation from the paper.

mod gaussian;
mod particles;
mod prior;

pub use gaussian::GaussianPosterior;
pub use particles::{MAX_REDRAWS, ParticleCloud, log_sum_exp, systematic};
pub use prior::{ModePrior, black_box_priors, sqrt_psd};

use hysid_core::backend::{Deadline, IdentifyError, RunContext};
use hysid_core::options::{CheckOptions, OptionError, check_count, check_float};
use hysid_core::priors::{PriorKind, Priors};
use hysid_estimation::constrained::Parametrisation;
use hysid_estimation::noise::{local_noise_sigma, noise_floor};
use hysid_estimation::pwarx::{PwarxData, PwarxFit, PwarxMethod};
use hysid_estimation::regions::RegionMethod;
use hysid_model::model::{PwarxMode, RunStatus};
use hysid_model::regressors::Regressors;
use nalgebra::DVector;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

/// The largest mode count `--auto` tries when none is given.
pub const DEFAULT_MAX_MODES: usize = 5;

/// The deadline is looked at once every this many samples of step 3 and
/// of the nearest-neighbour chain.
const DEADLINE_STRIDE: usize = 256;

hysid_core::option_enum! {
    /// How a mode's pdf is represented.
    pub enum Posterior { /// gaussian, unless [bounds] truncate the prior: then particles
        Auto => "auto", /// a weighted particle cloud (the paper), any prior, bounds included
        Particles => "particles", /// the exact Gaussian posterior of the untruncated Gaussian prior (refuses [bounds])
        Gaussian => "gaussian" }
}

hysid_core::option_enum! {
    /// The order the samples are processed in.
    pub enum Order { /// the record's order
        Time => "time", /// a permutation drawn from the seed
        Random => "random", /// a nearest-neighbour chain through the standardised regressors
        Nearest => "nearest" }
}

hysid_core::backend_options! {
    /// Options of the `bayes` back-end.
    pub struct BayesOptions {
        /// Particles per mode.
        particles: usize = 1000,
        /// Representation of the pdfs: particles (the paper), gaussian (exact for the
        /// untruncated Gaussian prior; refuses [bounds]) or auto (gaussian unless [bounds]
        /// truncate the prior).
        posterior: Posterior = Posterior::Auto,
        /// Standard deviation of the Gaussian equation noise, data units; 0: the median noise
        /// level of local affine fits.
        noise_std: f64 = 0.0,
        /// Spread of the black-box prior around the affine fit, in standardised units.
        prior_std: f64 = 1.0,
        /// Order the samples are processed in: time, random or nearest.
        order: Order = Order::Nearest,
        /// Resample a cloud when its effective sample size falls below this fraction of its
        /// particles.
        resample_below: f64 = 0.5,
        /// Kernel bandwidth h of the Liu-West move after resampling, in (0, 1); 0:
        /// (4 / ((p + 2) n))^(1 / (p + 4)) for p parameters and n particles.
        bandwidth: f64 = 0.0,
        /// Region estimation from the final classification (docs/regions.md): mrlp, msvm, psvc
        /// or softmax.
        regions: RegionMethod = RegionMethod::Mrlp,
    }
}

impl CheckOptions for BayesOptions {
    fn check(&self) -> Result<(), OptionError> {
        if self.particles < 2 {
            return Err(OptionError::invalid(
                "particles",
                self.particles,
                "must be at least 2",
            ));
        }
        check_count("particles", self.particles, 2)?;
        check_float(
            "noise_std",
            self.noise_std,
            |s| s >= 0.0,
            "must be a finite number >= 0 (0: estimated)",
        )?;
        check_float(
            "prior_std",
            self.prior_std,
            |s| s > 0.0,
            "must be a finite number > 0",
        )?;
        check_float(
            "resample_below",
            self.resample_below,
            |f| (0.0..=1.0).contains(&f),
            "must lie in [0, 1]",
        )?;
        check_float(
            "bandwidth",
            self.bandwidth,
            |h| (0.0..1.0).contains(&h),
            "must lie in [0, 1) (0: the default bandwidth)",
        )?;
        Ok(())
    }
}

/// The `bayes` back-end.
#[derive(Debug, Clone, Copy, Default)]
pub struct Bayes;

impl PwarxMethod for Bayes {
    type Options = BayesOptions;
    type Diagnostics = BayesDiagnostics;
    const NAME: &'static str = "bayes";
    const SUMMARY: &'static str = "Bayesian procedure (Juloski, Weiland, Heemels 2005): mode parameter pdfs (exact Gaussian or particle clouds), samples assigned and pdfs updated one by one; then regions";
    const HONOURS: &'static [PriorKind] = &[
        PriorKind::Modes,
        PriorKind::MaxModes,
        PriorKind::Saturation,
        PriorKind::Fixed,
        PriorKind::Bounds,
        PriorKind::Switching,
    ];
    const OUTPUT_UNITS: &'static [&'static str] = &["noise_std"];
    const SEARCH: &'static str = "the mode count from 1 to 5 (at most --max-modes; saturation modes added), unless --modes is given; every candidate with trim = 3";
    const MAX_MODES: Option<usize> = Some(DEFAULT_MAX_MODES);
    const SEED_USE: &'static str = "with posterior = particles (or auto with [bounds]) or order = random, not with the defaults";

    /// The seed draws the particle clouds and the random order only: the
    /// exact Gaussian posterior (`posterior = auto` without `[bounds]`, which
    /// would truncate the prior) in time or nearest-neighbour order draws
    /// nothing.
    fn seeded_with(&self, priors: &Priors, options: &BayesOptions) -> bool {
        let particles = match options.posterior {
            Posterior::Particles => true,
            Posterior::Gaussian => false,
            Posterior::Auto => !priors.bounds.is_empty(),
        };
        particles || matches!(options.order, Order::Random)
    }

    fn fit(
        &self,
        data: &PwarxData<'_>,
        options: &BayesOptions,
        ctx: &RunContext<'_>,
    ) -> Result<PwarxFit<BayesDiagnostics>, IdentifyError> {
        fit(options, data, ctx)
    }
}

/// What the `bayes` back-end reports besides the common diagnostics.
#[derive(Debug, Clone, Serialize)]
pub struct BayesDiagnostics {
    /// The representation of the pdfs used (`posterior = auto` resolved).
    pub posterior: Posterior,
    /// Standard deviation of the equation noise used, data units.
    pub noise_std: f64,
    /// Whether `noise_std` was estimated (option 0).
    pub noise_estimated: bool,
    /// Samples processed in step 3 (fewer than the ordinary samples when
    /// the time budget ended it).
    pub processed: usize,
    /// Samples each mode received in step 3.
    pub assigned: Vec<usize>,
    /// Resamplings of all clouds in step 3.
    pub resamplings: usize,
    /// The smallest effective sample size a cloud fell to, as a fraction
    /// of its particles (1 for Gaussian posteriors).
    pub min_effective_fraction: f64,
    /// Fraction of the processed samples whose mode changed in step 5.
    pub relabelled_fraction: f64,
    /// Mean confidence of the step-5 classification.
    pub mean_confidence: f64,
    /// Fraction of the samples inside their own mode's region.
    pub region_training_accuracy: f64,
}

/// The method's steps (module doc).
pub fn fit(
    options: &BayesOptions,
    data: &PwarxData<'_>,
    ctx: &RunContext<'_>,
) -> Result<PwarxFit<BayesDiagnostics>, IdentifyError> {
    let modes = data.exact_modes(Bayes::NAME)?;
    let reg = data.ordinary_regressors();
    let par = Parametrisation::from_priors(data.priors(), &data.spec, modes)
        .map_err(|e| data.prior_error(e))?;
    let sigma = noise_level(options, &reg);
    let priors = mode_priors(options, &reg, &par).map_err(|e| match e {
        BayesError::BoundsNeedParticles => data.prior_error(e),
        e => e.into(),
    })?;
    let mut rng = ChaCha8Rng::seed_from_u64(ctx.seed);
    let representation = representation(options.posterior, &priors);
    let mut pdfs = initial_pdfs(representation, options.particles, &priors, &mut rng);
    let order = processing_order(options.order, &reg, &mut rng, &ctx.deadline);
    let pass = process_sequentially(
        &mut pdfs, &reg, &order, sigma, &priors, options, &mut rng, ctx,
    );
    let thetas = point_estimates(&pdfs, &priors);
    let classes = reclassify(&pdfs, &reg, sigma);
    let cut_short = pass.processed < reg.len();
    check_every_mode_has_samples(&classes.labels, modes, cut_short.then_some(pass.processed))?;
    let partition =
        hysid_estimation::regions::for_pwarx(options.regions, data, &reg, &classes.labels, modes)?;
    let relabelled = order[..pass.processed]
        .iter()
        .filter(|&&k| pass.labels[k] != Some(classes.labels[k]))
        .count();
    let diagnostics = BayesDiagnostics {
        posterior: representation,
        noise_std: sigma,
        noise_estimated: options.noise_std == 0.0,
        processed: pass.processed,
        assigned: pass.assigned,
        resamplings: pass.resamplings,
        min_effective_fraction: pass.min_effective_fraction,
        relabelled_fraction: relabelled as f64 / pass.processed.max(1) as f64,
        mean_confidence: classes.confidence.iter().sum::<f64>()
            / classes.confidence.len().max(1) as f64,
        region_training_accuracy: partition.training_accuracy,
    };
    Ok(PwarxFit {
        modes: PwarxMode::unnamed(thetas, partition.regions),
        regions_complete: partition.complete,
        uncovered_fraction: None,
        run_status: if cut_short {
            RunStatus::TimeBudget
        } else {
            RunStatus::Completed
        },
        status: if cut_short {
            vec![format!(
                "time budget reached after {} of {} samples: the pdfs of those",
                pass.processed,
                reg.len()
            )]
        } else {
            Vec::new()
        },
        scaling: None,
        refinement: None,
        trimming: None,
        diagnostics,
    })
}

/// Step 1: `sigma`, the option or the median local noise level
/// (`hysid_estimation::noise`), floored at `1e-6 std(y)` so that
/// noise-free records keep finite densities.
pub fn noise_level(options: &BayesOptions, reg: &Regressors) -> f64 {
    if options.noise_std > 0.0 {
        return options.noise_std;
    }
    local_noise_sigma(reg).max(noise_floor(reg))
}

/// Step 1: the prior of every mode (`prior` module: the black-box
/// Gaussian, conditioned on `[fixed]`, truncated to `[bounds]`).
pub fn mode_priors(
    options: &BayesOptions,
    reg: &Regressors,
    par: &Parametrisation,
) -> Result<Vec<ModePrior>, BayesError> {
    let priors =
        black_box_priors(reg, par, options.prior_std).ok_or(BayesError::AffineFitFailed)?;
    if options.posterior == Posterior::Gaussian && priors.iter().any(ModePrior::is_truncated) {
        return Err(BayesError::BoundsNeedParticles);
    }
    Ok(priors)
}

/// A mode's pdf in one of the two representations.
#[derive(Debug, Clone, PartialEq)]
pub enum ModePdf {
    /// Weighted particles, with the Gaussian approximation of the same
    /// posterior whose covariance is the kernel's when the cloud has
    /// collapsed ([`ParticleCloud::resample`]).
    Particles(ParticleCloud, GaussianPosterior),
    /// Exact Gaussian.
    Gaussian(GaussianPosterior),
}

impl ModePdf {
    /// `ln l_i(k)`, the log predictive density of `y` at `phi = [x; 1]`.
    pub fn log_predictive(&self, phi: &DVector<f64>, y: f64, sigma: f64) -> f64 {
        match self {
            ModePdf::Particles(c, _) => c.log_predictive(phi, y, sigma),
            ModePdf::Gaussian(g) => g.log_predictive(phi, y, sigma),
        }
    }

    /// The posterior mean.
    pub fn mean(&self) -> DVector<f64> {
        match self {
            ModePdf::Particles(c, _) => c.mean(),
            ModePdf::Gaussian(g) => g.mean.clone(),
        }
    }
}

/// The representation `posterior` stands for: `auto` is `gaussian`
/// unless some prior is truncated by bounds.
pub fn representation(posterior: Posterior, priors: &[ModePrior]) -> Posterior {
    match posterior {
        Posterior::Auto if priors.iter().any(ModePrior::is_truncated) => Posterior::Particles,
        Posterior::Auto => Posterior::Gaussian,
        p => p,
    }
}

/// Step 2: every mode's pdf from its prior: `particles` draws per mode
/// for [`Posterior::Particles`], the prior itself for
/// [`Posterior::Gaussian`].
pub fn initial_pdfs(
    representation: Posterior,
    particles: usize,
    priors: &[ModePrior],
    rng: &mut ChaCha8Rng,
) -> Vec<ModePdf> {
    priors
        .iter()
        .map(|p| match representation {
            Posterior::Particles => ModePdf::Particles(
                ParticleCloud::draw(p, particles, rng),
                GaussianPosterior::from_prior(p),
            ),
            _ => ModePdf::Gaussian(GaussianPosterior::from_prior(p)),
        })
        .collect()
}

/// Step 3's order: `0..n`, a permutation drawn from `rng`, or the
/// nearest-neighbour chain of [`nearest_neighbour_chain`].
pub fn processing_order(
    order: Order,
    reg: &Regressors,
    rng: &mut ChaCha8Rng,
    deadline: &Deadline,
) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..reg.len()).collect();
    match order {
        Order::Time => {}
        Order::Random => idx.shuffle(rng),
        Order::Nearest => idx = nearest_neighbour_chain(reg, deadline),
    }
    idx
}

/// A greedy chain through the samples in standardised regressor space:
/// from the sample of least first regressor, always on to the nearest
/// sample not yet visited (the lowest index on a tie). Samples close in
/// regressor space mostly share a region, so a mode's pdf sees a run of
/// its own samples before the chain crosses into another region. `O(N^2)`
/// distance evaluations; once `deadline` passes, the samples not yet
/// visited follow in the record's order.
pub fn nearest_neighbour_chain(reg: &Regressors, deadline: &Deadline) -> Vec<usize> {
    let (n, d) = reg.x.shape();
    if n == 0 {
        return Vec::new();
    }
    let z = standardised_rows(reg);
    let row = |k: usize| &z[k * d..(k + 1) * d];
    let start = (0..n)
        .min_by(|&a, &b| {
            row(a)
                .first()
                .partial_cmp(&row(b).first())
                .unwrap_or(std::cmp::Ordering::Equal)
        })
        .unwrap_or(0);
    let mut visited = vec![false; n];
    let mut chain = Vec::with_capacity(n);
    let mut current = start;
    for step in 0..n {
        visited[current] = true;
        chain.push(current);
        if step % DEADLINE_STRIDE == 0 && deadline.passed() {
            chain.extend((0..n).filter(|&k| !visited[k]));
            break;
        }
        let here = row(current);
        let mut best: Option<(f64, usize)> = None;
        for k in (0..n).filter(|&k| !visited[k]) {
            let dist: f64 = row(k)
                .iter()
                .zip(here)
                .map(|(a, b)| (a - b) * (a - b))
                .sum();
            if best.is_none_or(|(b, _)| dist < b) {
                best = Some((dist, k));
            }
        }
        match best {
            Some((_, k)) => current = k,
            None => break,
        }
    }
    chain
}

/// The regressors with zero mean and unit standard deviation per column
/// (constant columns at 0), row-major.
fn standardised_rows(reg: &Regressors) -> Vec<f64> {
    let (n, d) = reg.x.shape();
    let mut z = vec![0.0; n * d];
    for j in 0..d {
        let col = reg.x.column(j);
        let mean = col.iter().sum::<f64>() / n as f64;
        let sd = (col.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        let inv = if sd > 0.0 { 1.0 / sd } else { 0.0 };
        for k in 0..n {
            z[k * d + j] = (col[k] - mean) * inv;
        }
    }
    z
}

/// What step 3 did.
#[derive(Debug, Clone, PartialEq)]
pub struct SequentialPass {
    /// Samples processed.
    pub processed: usize,
    /// The mode each processed sample went to (`None`: not processed).
    pub labels: Vec<Option<usize>>,
    /// Samples per mode.
    pub assigned: Vec<usize>,
    /// Resamplings.
    pub resamplings: usize,
    /// Smallest effective sample size over the particles, before
    /// resampling.
    pub min_effective_fraction: f64,
}

/// Step 3: each sample, in `order`, to the mode of largest predictive
/// density (the lowest index on a tie), whose pdf alone is updated. Clouds
/// whose effective sample size falls below `resample_below` are resampled
/// and moved. Stops early, with the samples processed so far, when the
/// run's deadline passes.
#[allow(clippy::too_many_arguments)]
pub fn process_sequentially(
    pdfs: &mut [ModePdf],
    reg: &Regressors,
    order: &[usize],
    sigma: f64,
    priors: &[ModePrior],
    options: &BayesOptions,
    rng: &mut ChaCha8Rng,
    ctx: &RunContext<'_>,
) -> SequentialPass {
    let mut pass = SequentialPass {
        processed: 0,
        labels: vec![None; reg.len()],
        assigned: vec![0; pdfs.len()],
        resamplings: 0,
        min_effective_fraction: 1.0,
    };
    for (t, &k) in order.iter().enumerate() {
        if t % DEADLINE_STRIDE == 0 && ctx.deadline.passed() {
            break;
        }
        let phi = regressor(reg, k);
        let y = reg.y[k];
        let scores: Vec<f64> = pdfs
            .iter()
            .map(|p| p.log_predictive(&phi, y, sigma))
            .collect();
        let i = argmax(&scores);
        match &mut pdfs[i] {
            ModePdf::Gaussian(g) => g.update(&phi, y, sigma),
            ModePdf::Particles(c, shadow) => {
                c.update(&phi, y, sigma);
                shadow.update(&phi, y, sigma);
                let fraction = c.effective_sample_size() / c.len() as f64;
                pass.min_effective_fraction = pass.min_effective_fraction.min(fraction);
                if fraction < options.resample_below {
                    let h = bandwidth(options, c.dim, c.len());
                    c.resample(h, &priors[i], &shadow.cov, rng);
                    pass.resamplings += 1;
                }
            }
        }
        pass.labels[k] = Some(i);
        pass.assigned[i] += 1;
        pass.processed += 1;
    }
    pass
}

/// The Liu-West bandwidth: the option, or the normal-reference rule
/// `(4 / ((p + 2) n))^(1 / (p + 4))`.
pub fn bandwidth(options: &BayesOptions, dim: usize, n: usize) -> f64 {
    if options.bandwidth > 0.0 {
        return options.bandwidth;
    }
    let p = dim as f64;
    (4.0 / ((p + 2.0) * n as f64)).powf(1.0 / (p + 4.0))
}

/// Step 4: the posterior means, clamped into the priors' bounds (a mean
/// of particles inside a box lies in it up to rounding; fixed values come
/// back exactly).
pub fn point_estimates(pdfs: &[ModePdf], priors: &[ModePrior]) -> Vec<Vec<f64>> {
    pdfs.iter()
        .zip(priors)
        .map(|(pdf, prior)| {
            let mut theta: Vec<f64> = pdf.mean().iter().copied().collect();
            prior.clamp(&mut theta);
            theta
        })
        .collect()
}

/// Step 5's classification.
#[derive(Debug, Clone, PartialEq)]
pub struct Reclassification {
    /// The mode of largest predictive density of every sample.
    pub labels: Vec<usize>,
    /// Its posterior probability `l_i / sum_j l_j`.
    pub confidence: Vec<f64>,
}

/// Step 5: every sample to the mode of largest predictive density under
/// the final pdfs.
pub fn reclassify(pdfs: &[ModePdf], reg: &Regressors, sigma: f64) -> Reclassification {
    let mut labels = Vec::with_capacity(reg.len());
    let mut confidence = Vec::with_capacity(reg.len());
    for k in 0..reg.len() {
        let phi = regressor(reg, k);
        let scores: Vec<f64> = pdfs
            .iter()
            .map(|p| p.log_predictive(&phi, reg.y[k], sigma))
            .collect();
        let i = argmax(&scores);
        let total = log_sum_exp(scores.iter().copied());
        labels.push(i);
        confidence.push(if total.is_finite() {
            (scores[i] - total).exp()
        } else {
            1.0 / pdfs.len() as f64
        });
    }
    Reclassification { labels, confidence }
}

/// Every mode needs a sample for its region.
fn check_every_mode_has_samples(
    labels: &[usize],
    modes: usize,
    cut_short_after: Option<usize>,
) -> Result<(), IdentifyError> {
    let mut counts = vec![0usize; modes];
    for &q in labels {
        counts[q] += 1;
    }
    let Some(mode) = counts.iter().position(|&c| c == 0) else {
        return Ok(());
    };
    Err(match cut_short_after {
        Some(processed) => BayesError::EmptyModeCutShort {
            mode,
            modes,
            processed,
            samples: labels.len(),
        },
        None => BayesError::EmptyMode { mode, modes },
    }
    .into())
}

/// `phi = [x(k); 1]`.
fn regressor(reg: &Regressors, k: usize) -> DVector<f64> {
    let d = reg.x.ncols();
    DVector::from_fn(d + 1, |j, _| if j < d { reg.x[(k, j)] } else { 1.0 })
}

/// Index of the largest score, the lowest on a tie; NaN never wins.
fn argmax(scores: &[f64]) -> usize {
    let mut best = 0;
    for (i, &s) in scores.iter().enumerate() {
        if s > scores[best] || scores[best].is_nan() {
            best = i;
        }
    }
    best
}

/// Why a Bayesian run cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum BayesError {
    /// The final classification left a mode without samples.
    #[error(
        "mode {} of {modes} explains no sample after the final classification: fewer modes, or a wider prior_std",
        .mode + 1
    )]
    EmptyMode {
        /// The empty mode (from 0; shown from 1).
        mode: usize,
        /// Modes asked for.
        modes: usize,
    },
    /// The time budget ended the sequential pass before every mode had a
    /// sample of the final classification.
    #[error(
        "mode {} of {modes} explains no sample after the final classification: the time budget ended the sequential pass after {processed} of {samples} samples; give it more time",
        .mode + 1
    )]
    EmptyModeCutShort {
        /// The empty mode (from 0; shown from 1).
        mode: usize,
        /// Modes asked for.
        modes: usize,
        /// Samples the pass processed.
        processed: usize,
        /// Samples of the record.
        samples: usize,
    },
    /// `posterior = gaussian` cannot represent a truncated prior.
    #[error(
        "option posterior=gaussian cannot honour [bounds] (a truncated Gaussian is not Gaussian): use posterior=particles"
    )]
    BoundsNeedParticles,
    /// The affine least-squares fit the black-box prior is centred on
    /// failed.
    #[error("the affine least-squares fit the prior is centred on failed")]
    AffineFitFailed,
}

impl From<BayesError> for IdentifyError {
    fn from(e: BayesError) -> Self {
        match e {
            BayesError::BoundsNeedParticles => IdentifyError::input(e),
            e => IdentifyError::failed(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mode left empty is named with the budget when the budget ended
    /// the sequential pass, and with the options otherwise.
    #[test]
    fn an_empty_mode_names_the_time_budget_that_cut_the_pass_short() {
        let labels = [0, 0, 2, 0];
        let plain = check_every_mode_has_samples(&labels, 3, None).unwrap_err();
        assert!(plain.to_string().contains("mode 2 of 3"), "{plain}");
        assert!(
            plain
                .to_string()
                .ends_with("fewer modes, or a wider prior_std"),
            "{plain}"
        );
        let cut = check_every_mode_has_samples(&labels, 3, Some(2)).unwrap_err();
        assert!(
            cut.to_string().ends_with(
                "the time budget ended the sequential pass after 2 of 4 samples; give it more time"
            ),
            "{cut}"
        );
        assert!(check_every_mode_has_samples(&[0, 1, 2], 3, Some(2)).is_ok());
    }
}
