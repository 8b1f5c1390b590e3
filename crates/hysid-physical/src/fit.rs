//! The fit: parameter map (priors), cost, swarm, Nelder-Mead, sensitivity.

use crate::PhysicalOptions;
use argmin::core::{CostFunction, Error as ArgminError, Executor, State, TerminationReason};
use argmin::solver::neldermead::NelderMead;
use argmin::solver::particleswarm::ParticleSwarm;
use hysid_core::backend::{IdentifyError, Progress, RunContext};
use hysid_core::priors::Priors;
use hysid_mechanical::simulate as mechanical;
use hysid_mechanical::{MechanicalInitialState, MechanicalModel};
use hysid_model::data::Dataset;
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde_json::json;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// How the free coordinates `z in [0, 1]^d` map onto the model's parameters:
/// fixed parameters keep their value, tied ones share a coordinate, each
/// coordinate spans its (intersected) bounds.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterMap {
    /// Value of every parameter when `z` is not involved (fixed ones).
    pub base: Vec<f64>,
    /// Per free coordinate: the parameters it sets.
    pub groups: Vec<Vec<usize>>,
    /// Per free coordinate: `[low, high]`.
    pub bounds: Vec<[f64; 2]>,
    /// Per parameter: its bounds after priors.
    pub param_bounds: Vec<[f64; 2]>,
    /// Parameter names.
    pub names: Vec<String>,
}

impl ParameterMap {
    /// Builds the map from the model (its `fixed` flags and bounds) and the
    /// priors (`[fixed]`, `[bounds]`, `[[tie]]`), checking every name.
    pub fn new(model: &MechanicalModel, priors: &Priors) -> Result<Self, String> {
        let names = model.parameter_names();
        let idx = |n: &str, entry: &str| {
            model.parameter_index(n).ok_or_else(|| {
                format!(
                    "prior {entry}: unknown parameter '{n}' (known: {})",
                    names.join(", ")
                )
            })
        };
        let mut base = model.values();
        let mut bounds: Vec<[f64; 2]> = model.parameters.iter().map(|p| p.bounds).collect();
        let mut fixed: Vec<bool> = model.parameters.iter().map(|p| p.fixed).collect();
        for (n, [lo, hi]) in &priors.bounds {
            let i = idx(n, "[bounds]")?;
            bounds[i] = [*lo, *hi];
        }
        for (n, v) in &priors.fixed {
            let i = idx(n, "[fixed]")?;
            base[i] = *v;
            fixed[i] = true;
        }
        // Union-find over ties.
        let mut parent: Vec<usize> = (0..names.len()).collect();
        fn find(p: &mut [usize], i: usize) -> usize {
            let mut r = i;
            while p[r] != r {
                r = p[r];
            }
            p[i] = r;
            r
        }
        for t in &priors.tie {
            let ids: Vec<usize> = t
                .params
                .iter()
                .map(|n| idx(n, "[[tie]]"))
                .collect::<Result<_, _>>()?;
            for w in ids.windows(2) {
                let (a, b) = (find(&mut parent, w[0]), find(&mut parent, w[1]));
                if a != b {
                    parent[b.max(a)] = a.min(b);
                }
            }
        }
        let mut groups: Vec<Vec<usize>> = Vec::new();
        let mut roots: Vec<usize> = Vec::new();
        for i in 0..names.len() {
            let r = find(&mut parent, i);
            match roots.iter().position(|&x| x == r) {
                Some(g) => groups[g].push(i),
                None => {
                    roots.push(r);
                    groups.push(vec![i]);
                }
            }
        }
        let mut free_groups = Vec::new();
        let mut free_bounds = Vec::new();
        for g in groups {
            let fixed_members: Vec<usize> = g.iter().copied().filter(|&i| fixed[i]).collect();
            if let Some(&f) = fixed_members.first() {
                // A tie with a fixed member fixes the whole group.
                for &i in &fixed_members {
                    if base[i] != base[f] {
                        return Err(format!(
                            "prior [[tie]]: '{}' and '{}' are tied but fixed to different values",
                            names[f], names[i]
                        ));
                    }
                }
                for &i in &g {
                    base[i] = base[f];
                }
                continue;
            }
            let lo = g
                .iter()
                .map(|&i| bounds[i][0])
                .fold(f64::NEG_INFINITY, f64::max);
            let hi = g
                .iter()
                .map(|&i| bounds[i][1])
                .fold(f64::INFINITY, f64::min);
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                let who: Vec<&str> = g.iter().map(|&i| names[i].as_str()).collect();
                return Err(format!(
                    "prior: the bounds of [{}] leave no admissible value",
                    who.join(", ")
                ));
            }
            // A tied group starts from the mean of its nominal values, clamped.
            let start = (g.iter().map(|&i| base[i]).sum::<f64>() / g.len() as f64).clamp(lo, hi);
            for &i in &g {
                base[i] = start;
            }
            free_groups.push(g);
            free_bounds.push([lo, hi]);
        }
        for (g, b) in free_groups.iter().zip(&free_bounds) {
            for &i in g {
                bounds[i] = *b;
            }
        }
        Ok(Self {
            base,
            groups: free_groups,
            bounds: free_bounds,
            param_bounds: bounds,
            names,
        })
    }

    /// Number of free coordinates.
    pub fn dim(&self) -> usize {
        self.groups.len()
    }

    /// Parameter values for `z` (clamped into `[0, 1]`).
    pub fn values(&self, z: &[f64]) -> Vec<f64> {
        let mut v = self.base.clone();
        for ((g, [lo, hi]), zi) in self.groups.iter().zip(&self.bounds).zip(z) {
            let x = lo + (hi - lo) * zi.clamp(0.0, 1.0);
            for &i in g {
                v[i] = x;
            }
        }
        v
    }

    /// Normalised coordinates of the parameter values `values`.
    pub fn coords(&self, values: &[f64]) -> Vec<f64> {
        self.groups
            .iter()
            .zip(&self.bounds)
            .map(|(g, [lo, hi])| {
                if hi > lo {
                    ((values[g[0]] - lo) / (hi - lo)).clamp(0.0, 1.0)
                } else {
                    0.5
                }
            })
            .collect()
    }
}

/// The simulation-error cost of a parameter vector.
struct SimulationCost<'a> {
    /// 0: free-run cost; else the segmented (multiple-shooting) cost.
    segment: usize,
    velocity_tol: f64,
    model: &'a MechanicalModel,
    data: &'a Dataset,
    map: &'a ParameterMap,
    progress: &'a dyn Progress,
    evals: &'a AtomicU64,
}

/// Cost of a diverged or failed simulation.
const FAILED: f64 = 1e30;

/// Free-run simulation residuals `y(k) - yhat(k)` after the initial state
/// (`None` when the simulation fails).
pub fn simulation_residuals(
    model: &MechanicalModel,
    values: &[f64],
    data: &Dataset,
) -> Option<Vec<f64>> {
    let r = mechanical::run(model, values, data).ok()?;
    let y = data.y();
    let e: Vec<f64> = y[r.start + 1..]
        .iter()
        .zip(&r.y[r.start + 1..])
        .map(|(a, b)| a - b)
        .collect();
    (!e.is_empty() && e.iter().all(|x| x.is_finite())).then_some(e)
}

fn mse(e: Option<Vec<f64>>) -> f64 {
    match e {
        Some(e) => e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64,
        None => FAILED,
    }
}

/// Mean squared free-run simulation error over the samples after the initial state.
pub fn simulation_mse(model: &MechanicalModel, values: &[f64], data: &Dataset) -> f64 {
    mse(simulation_residuals(model, values, data))
}

/// Velocity thresholds below which an estimated velocity counts as zero
/// (the mass is taken to be at rest), from the measurement noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityTolerances {
    /// Output noise standard deviation, estimated.
    pub noise: f64,
    /// For [`segment_velocity`] (a 3-point slope).
    pub centred: f64,
    /// For the initial-state estimator of the simulator (backward quadratic).
    pub backward: f64,
}

/// Estimates the output noise robustly from second differences
/// (`1.4826 median |d2 y| / sqrt(6)`; quantised records whose samples
/// repeat while stuck give 0) and sets the thresholds at three standard
/// deviations of each velocity estimator, plus a floor of `1e-6` of the
/// output range per second against rounding.
pub fn velocity_tolerances(y: &[f64], ts: f64) -> VelocityTolerances {
    let mut d2: Vec<f64> = y
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .collect();
    let noise = if d2.is_empty() {
        0.0
    } else {
        let mid = d2.len() / 2;
        let (_, m, _) = d2.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
        1.4826 * *m / 6f64.sqrt()
    };
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let floor = 1e-6 * (hi - lo).max(0.0) / ts;
    // Noise gain of an estimator: the norm of its weights (unit impulses).
    let gain = |f: &dyn Fn(&[f64]) -> f64| -> f64 {
        (0..5)
            .map(|j| {
                let mut e = [0.0; 5];
                e[j] = 1.0;
                f(&e).powi(2)
            })
            .sum::<f64>()
            .sqrt()
    };
    let g_c = 0.5f64.sqrt() / ts;
    let g_b = gain(&|e| mechanical::estimate_velocity(e, 4, ts));
    VelocityTolerances {
        noise,
        centred: 3.0 * noise * g_c + floor,
        backward: 3.0 * noise * g_b + floor,
    }
}

/// Velocity at sample `k` for re-initialising a segment (offline, so it
/// may look ahead): the slopes `b` over `k-2..=k` and `f` over `k..=k+2`
/// (clipped to the record) are compared. Both within `tol`, or of opposite
/// signs: at rest (0). Within a factor 2 of each other: smooth motion,
/// their mean (the centred slope). Otherwise an event lies in the window
/// (break-away, impact on a stop) and the smaller one is the velocity at
/// `k` (0 at a break-away, the stop's 0 after an impact).
pub fn segment_velocity(y: &[f64], k: usize, ts: f64, tol: f64) -> f64 {
    let n = y.len();
    let slope = |a: usize, b: usize| {
        if b > a {
            (y[b] - y[a]) / ((b - a) as f64 * ts)
        } else {
            0.0
        }
    };
    let b = slope(k.saturating_sub(2), k);
    let f = slope(k, (k + 2).min(n - 1));
    let (ab, af) = (b.abs(), f.abs());
    if (ab <= tol && af <= tol) || b * f < 0.0 {
        return 0.0;
    }
    if k < 2 {
        return f;
    }
    if k + 2 >= n {
        return b;
    }
    let (lo, hi) = if ab < af { (ab, af) } else { (af, ab) };
    if hi <= 2.0 * lo {
        0.5 * (b + f)
    } else if ab < af {
        b
    } else {
        f
    }
}

/// The segmented (multiple-shooting) simulation error: the record is cut
/// into segments of `segment` samples, each simulated from the state
/// measured at its start (position, [`segment_velocity`]). Errors do not
/// accumulate across segments, so the cost is much smoother in the
/// parameters than the free-run error; it serves the global stage.
pub fn segmented_mse(
    model: &MechanicalModel,
    values: &[f64],
    data: &Dataset,
    segment: usize,
    velocity_tol: f64,
) -> f64 {
    mse(segmented_residuals(
        model,
        values,
        data,
        segment,
        velocity_tol,
    ))
}

/// The residuals of [`segmented_mse`].
pub fn segmented_residuals(
    model: &MechanicalModel,
    values: &[f64],
    data: &Dataset,
    segment: usize,
    velocity_tol: f64,
) -> Option<Vec<f64>> {
    let ts = data.ts?;
    let r = model.resolve_with(values);
    let n_sub = mechanical::substeps(ts, model.internal_step).ok()?;
    let y = data.y();
    let n = y.len();
    let mut u = vec![0.0; data.inputs.len()];
    let mut e = Vec::with_capacity(n);
    let mut s = 0;
    while s + 1 < n {
        for (i, x) in u.iter_mut().enumerate() {
            *x = data.inputs[i].values[s];
        }
        let v = segment_velocity(y, s, ts, velocity_tol);
        let mut st = r.state_at(y[s], v, &u);
        for k in s..(s + segment.max(1)).min(n - 1) {
            for (i, x) in u.iter_mut().enumerate() {
                *x = data.inputs[i].values[k];
            }
            r.advance(&mut st, &u, ts, n_sub);
            e.push(y[k + 1] - st.y);
        }
        s += segment.max(1);
    }
    (!e.is_empty() && e.iter().all(|x| x.is_finite())).then_some(e)
}

/// Levenberg-Marquardt (Marquardt 1963) on residuals `res(z)` in the
/// normalised box `[0, 1]^d` (steps projected onto it), with a central
/// finite-difference Jacobian of step `fd`; at most `iters` iterations.
/// Why an iterative stage of the fit stopped (recorded per stage in the
/// model's `info.diagnostics["termination"]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Termination {
    /// The stage's own convergence test held (Nelder-Mead: the simplex's
    /// cost spread below its tolerance; Levenberg-Marquardt: a relative
    /// decrease below 1e-9).
    Converged,
    /// Levenberg-Marquardt: no step decreased the cost, even with a
    /// damping of 1e8 (a local minimum, or a flat or failing simulation).
    NoDecrease,
    /// The iteration limit of the stage (`swarm_iters`, `lm_iters`,
    /// `local_iters`) was reached first.
    MaxIterations,
    /// `--time-budget` ran out.
    TimeBudget,
    /// Anything else (argmin's other reasons; a start whose simulation failed).
    Other,
}

impl Termination {
    /// The name written in the diagnostics.
    pub fn as_str(self) -> &'static str {
        match self {
            Termination::Converged => "converged",
            Termination::NoDecrease => "no_decrease",
            Termination::MaxIterations => "max_iterations",
            Termination::TimeBudget => "time_budget",
            Termination::Other => "other",
        }
    }

    fn of_argmin(r: Option<&TerminationReason>) -> Self {
        match r {
            Some(TerminationReason::SolverConverged | TerminationReason::TargetCostReached) => {
                Termination::Converged
            }
            Some(TerminationReason::MaxItersReached) => Termination::MaxIterations,
            Some(TerminationReason::Timeout) => Termination::TimeBudget,
            _ => Termination::Other,
        }
    }
}

/// Counts of [`Termination`]s of the runs of one stage, as a JSON object.
fn termination_counts(runs: &[Termination]) -> serde_json::Value {
    let mut m = serde_json::Map::new();
    for t in runs {
        let e = m.entry(t.as_str()).or_insert(json!(0));
        *e = json!(e.as_u64().unwrap_or(0) + 1);
    }
    serde_json::Value::Object(m)
}

/// Returns the best point, its sum of squares and why it stopped.
pub fn levenberg_marquardt(
    res: &dyn Fn(&[f64]) -> Option<Vec<f64>>,
    z0: &[f64],
    fd: f64,
    iters: usize,
    deadline: Option<Instant>,
    evals: &AtomicU64,
) -> (Vec<f64>, f64, Termination) {
    let d = z0.len();
    let sse = |e: &[f64]| e.iter().map(|x| x * x).sum::<f64>();
    let mut z = z0.to_vec();
    let Some(mut r) = res(&z) else {
        return (z, f64::INFINITY, Termination::Other);
    };
    evals.fetch_add(1, Ordering::Relaxed);
    let mut cost = sse(&r);
    let mut mu = 1e-3;
    let mut jac: Option<DMatrix<f64>> = None;
    let mut stop = Termination::MaxIterations;
    for _ in 0..iters {
        if deadline.is_some_and(|t| Instant::now() >= t) {
            stop = Termination::TimeBudget;
            break;
        }
        if jac.is_none() {
            let mut j = DMatrix::zeros(r.len(), d);
            for c in 0..d {
                let (mut zp, mut zm) = (z.clone(), z.clone());
                zp[c] = (z[c] + fd).min(1.0);
                zm[c] = (z[c] - fd).max(0.0);
                evals.fetch_add(2, Ordering::Relaxed);
                let (Some(rp), Some(rm)) = (res(&zp), res(&zm)) else {
                    continue;
                };
                let h = zp[c] - zm[c];
                for k in 0..r.len().min(rp.len()).min(rm.len()) {
                    j[(k, c)] = (rp[k] - rm[k]) / h;
                }
            }
            jac = Some(j);
        }
        let j = jac.as_ref().expect("set above");
        let jtj = j.transpose() * j;
        let g = j.transpose() * nalgebra::DVector::from_column_slice(&r);
        let mut a = jtj.clone();
        for c in 0..d {
            a[(c, c)] += mu * (jtj[(c, c)] + 1e-12);
        }
        let Some(ch) = a.cholesky() else {
            mu *= 10.0;
            continue;
        };
        let step = ch.solve(&(-g));
        let zn: Vec<f64> = z
            .iter()
            .zip(step.iter())
            .map(|(a, b)| (a + b).clamp(0.0, 1.0))
            .collect();
        evals.fetch_add(1, Ordering::Relaxed);
        match res(&zn) {
            Some(rn) if sse(&rn) < cost => {
                let improvement = (cost - sse(&rn)) / cost.max(f64::MIN_POSITIVE);
                z = zn;
                r = rn;
                cost = sse(&r);
                mu = (mu / 3.0).max(1e-12);
                jac = None;
                if improvement < 1e-9 {
                    stop = Termination::Converged;
                    break;
                }
            }
            _ => {
                mu *= 4.0;
                if mu > 1e8 {
                    stop = Termination::NoDecrease;
                    break;
                }
            }
        }
    }
    (z, cost, stop)
}

impl CostFunction for SimulationCost<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, z: &Vec<f64>) -> Result<f64, ArgminError> {
        self.evals.fetch_add(1, Ordering::Relaxed);
        self.progress.advance(1);
        // Outside the box: the clamped point's cost plus a penalty that
        // points back inside (Nelder-Mead is unconstrained).
        let out: f64 = z.iter().map(|x| (x - x.clamp(0.0, 1.0)).powi(2)).sum();
        let v = self.map.values(z);
        let c = if self.segment == 0 {
            simulation_mse(self.model, &v, self.data)
        } else {
            segmented_mse(self.model, &v, self.data, self.segment, self.velocity_tol)
        };
        Ok(c * (1.0 + 10.0 * out) + out)
    }
}

/// What a fit did.
#[derive(Debug, Clone, PartialEq)]
pub struct FitReport {
    /// Cost of the nominal values.
    pub nominal_cost: f64,
    /// Best cost after the swarm.
    pub swarm_cost: Option<f64>,
    /// Final cost (mean squared simulation error).
    pub cost: f64,
    /// Cost evaluations (simulations).
    pub evaluations: u64,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Per free coordinate: the standard error (NaN when not estimable).
    pub std_errors: Vec<f64>,
}

fn failed(message: impl Into<String>) -> IdentifyError {
    IdentifyError::Failed {
        method: "physical".into(),
        message: message.into(),
    }
}

/// Fits `model`'s parameters to `data`. Returns the fitted model (values
/// replaced, diagnostics filled) and a report.
pub fn fit_mechanical(
    model: &MechanicalModel,
    data: &Dataset,
    priors: &Priors,
    options: &PhysicalOptions,
    ctx: &RunContext<'_>,
) -> Result<(MechanicalModel, FitReport), IdentifyError> {
    let t0 = Instant::now();
    model
        .validate()
        .map_err(|e| IdentifyError::BadData(format!("model: {e}")))?;
    if data.inputs.len() != model.inputs.len() {
        return Err(IdentifyError::BadData(format!(
            "the model has {} input(s), the data {}",
            model.inputs.len(),
            data.inputs.len()
        )));
    }
    let Some(ts) = data.ts else {
        return Err(IdentifyError::BadData(
            "the physical method needs the sampling time: give a 't' signal or --ts".into(),
        ));
    };
    mechanical::substeps(ts, model.internal_step)
        .map_err(|e| IdentifyError::BadData(format!("model: {e}")))?;
    if !(options.simplex > 0.0 && options.simplex <= 1.0) {
        return Err(IdentifyError::BadData(format!(
            "--set simplex={}: must be in (0, 1]",
            options.simplex
        )));
    }
    if !(options.fd_step > 0.0 && options.fd_step < 0.5) {
        return Err(IdentifyError::BadData(format!(
            "--set fd_step={}: must be in (0, 0.5)",
            options.fd_step
        )));
    }
    let mut model = model.clone();
    let tols = velocity_tolerances(data.y(), data.ts.unwrap_or(1.0));
    if options.init_samples > 0 {
        model.initial_state = MechanicalInitialState::Measured {
            samples: options.init_samples,
            velocity_tol: match model.initial_state {
                MechanicalInitialState::Measured { velocity_tol, .. } => {
                    velocity_tol.max(tols.backward)
                }
                _ => tols.backward,
            },
        };
    }
    let map = ParameterMap::new(&model, priors).map_err(IdentifyError::BadData)?;
    let d = map.dim();
    let needed = match model.initial_state {
        MechanicalInitialState::Measured { samples, .. } => samples + d + 1,
        MechanicalInitialState::Given { .. } => d + 1,
    };
    if data.len() < needed {
        return Err(IdentifyError::BadData(format!(
            "{} samples for {d} free parameters and the initial state: need at least {needed}",
            data.len()
        )));
    }
    let evals = AtomicU64::new(0);
    let problem = |segment: usize| SimulationCost {
        segment,
        velocity_tol: tols.centred,
        model: &model,
        data,
        map: &map,
        progress: ctx.progress,
        evals: &evals,
    };
    let nominal_z = map.coords(&map.base);
    let nominal_cost = simulation_mse(&model, &map.values(&nominal_z), data);
    let timeout = |ex_deadline: Option<Instant>| {
        ex_deadline.map(|t| t.saturating_duration_since(Instant::now()))
    };

    // The stage during which the time budget ran out, if it did.
    let past_deadline = || ctx.deadline.is_some_and(|t| Instant::now() >= t);
    let mut cut_short: Option<&str> = None;
    let mut best_z = nominal_z.clone();
    let mut swarm_cost = None;
    let mut segmented_cost = None;
    let mut extra_starts: Vec<Vec<f64>> = Vec::new();
    // Why each run of each stage stopped, in order.
    let mut swarm_stop: Option<Termination> = None;
    let mut lm_stops: Vec<Termination> = Vec::new();
    let mut nm_stops: Vec<Termination> = Vec::new();
    if d > 0 && options.particles > 0 && options.swarm_iters > 0 {
        ctx.progress.start(
            (options.particles * (options.swarm_iters + 1)) as u64,
            "physical: particle swarm",
        );
        let pso: ParticleSwarm<Vec<f64>, f64, ChaCha8Rng> =
            ParticleSwarm::new((vec![0.0; d], vec![1.0; d]), options.particles)
                .with_rng_generator(ChaCha8Rng::seed_from_u64(ctx.seed));
        let mut ex = Executor::new(problem(options.segment), pso)
            .configure(|s| s.max_iters(options.swarm_iters as u64));
        if let Some(t) = timeout(ctx.deadline) {
            ex = ex.timeout(t);
        }
        let res = ex
            .run()
            .map_err(|e| failed(format!("particle swarm: {e}")))?;
        ctx.progress.finish();
        swarm_stop = Some(Termination::of_argmin(res.state().get_termination_reason()));
        if past_deadline() {
            cut_short.get_or_insert("particle swarm");
        }
        if let Some(p) = res.state().get_best_param() {
            let c = p.cost;
            swarm_cost = Some(c);
            // The swarm's best (on its own cost) replaces the nominal start
            // when its free-run cost is lower.
            let z: Vec<f64> = p.position.iter().map(|x| x.clamp(0.0, 1.0)).collect();
            if options.segment > 0 || c < nominal_cost {
                best_z = z;
            }
        }
        // Further starts for the first local stage: the nominal values and
        // the best other particles (distinct positions), by cost.
        let mut pop: Vec<(f64, Vec<f64>)> = res
            .state()
            .get_population()
            .map(|ps| {
                ps.iter()
                    .map(|p| {
                        (
                            p.cost,
                            p.position.iter().map(|x| x.clamp(0.0, 1.0)).collect(),
                        )
                    })
                    .collect()
            })
            .unwrap_or_default();
        pop.sort_by(|a, b| a.0.total_cmp(&b.0));
        extra_starts.push(nominal_z.clone());
        for (_, z) in pop {
            if extra_starts.len() + 1 >= options.starts {
                break;
            }
            if z != best_z && !extra_starts.contains(&z) {
                extra_starts.push(z);
            }
        }
        extra_starts.truncate(options.starts.saturating_sub(1));
    }
    if d > 0 && options.local_iters > 0 && options.restarts > 0 {
        // Stage 2 (segmented cost, when enabled), then stage 3 (free run).
        let stages: Vec<usize> = if options.segment > 0 {
            vec![options.segment, 0]
        } else {
            vec![0]
        };
        ctx.progress.start(
            (options.local_iters * options.restarts * stages.len()) as u64,
            "physical: Nelder-Mead",
        );
        for &segment in &stages {
            let cost_of = |z: &[f64]| {
                let v = map.values(z);
                if segment == 0 {
                    simulation_mse(&model, &v, data)
                } else {
                    segmented_mse(&model, &v, data, segment, tols.centred)
                }
            };
            let mut stage_z = best_z.clone();
            let mut stage_cost = cost_of(&stage_z);
            // The first stage starts from every start, the later ones from the best.
            let starts: Vec<Vec<f64>> = if segment == stages[0] {
                std::iter::once(best_z.clone())
                    .chain(extra_starts.iter().cloned())
                    .collect()
            } else {
                vec![best_z.clone()]
            };
            for start in starts {
                let c0 = cost_of(&start);
                if c0 < stage_cost {
                    stage_cost = c0;
                    stage_z = start.clone();
                }
                if options.lm_iters == 0 {
                    continue;
                }
                let res = |z: &[f64]| {
                    let v = map.values(z);
                    if segment == 0 {
                        simulation_residuals(&model, &v, data)
                    } else {
                        segmented_residuals(&model, &v, data, segment, tols.centred)
                    }
                };
                let (z, _, stop) = levenberg_marquardt(
                    &res,
                    &start,
                    options.fd_step,
                    options.lm_iters,
                    ctx.deadline,
                    &evals,
                );
                lm_stops.push(stop);
                let c = cost_of(&z);
                if c < stage_cost {
                    stage_cost = c;
                    stage_z = z;
                }
                if past_deadline() {
                    cut_short.get_or_insert("Levenberg-Marquardt");
                }
            }
            for _ in 0..options.restarts {
                if past_deadline() {
                    cut_short.get_or_insert("Nelder-Mead");
                    break;
                }
                let mut simplex = vec![stage_z.clone()];
                for j in 0..d {
                    let mut p = stage_z.clone();
                    // Step inwards so the simplex stays in the box.
                    p[j] += if p[j] + options.simplex <= 1.0 {
                        options.simplex
                    } else {
                        -options.simplex
                    };
                    simplex.push(p);
                }
                let nm: NelderMead<Vec<f64>, f64> = NelderMead::new(simplex)
                    .with_sd_tolerance(1e-12)
                    .map_err(|e| failed(format!("Nelder-Mead: {e}")))?;
                let mut ex = Executor::new(problem(segment), nm)
                    .configure(|s| s.max_iters(options.local_iters as u64));
                if let Some(t) = timeout(ctx.deadline) {
                    ex = ex.timeout(t);
                }
                let res = ex.run().map_err(|e| failed(format!("Nelder-Mead: {e}")))?;
                if past_deadline() {
                    cut_short.get_or_insert("Nelder-Mead");
                }
                let st = res.state();
                nm_stops.push(Termination::of_argmin(st.get_termination_reason()));
                if let Some(p) = st.get_best_param() {
                    let z: Vec<f64> = p.iter().map(|x| x.clamp(0.0, 1.0)).collect();
                    let c = cost_of(&z);
                    if c < stage_cost {
                        stage_cost = c;
                        stage_z = z;
                    }
                }
            }
            best_z = stage_z;
            if segment > 0 {
                segmented_cost = Some(stage_cost);
            }
        }
        ctx.progress.finish();
    }
    let values = map.values(&best_z);
    let cost = simulation_mse(&model, &values, data);
    if cost >= FAILED {
        return Err(failed(format!(
            "every candidate simulation failed or diverged ({} simulations): the model cannot follow this record",
            evals.load(Ordering::Relaxed)
        )));
    }
    let sens = sensitivity(&model, &map, &values, data, options.fd_step);

    let mut fitted = model.clone();
    for (p, (v, b)) in fitted
        .parameters
        .iter_mut()
        .zip(values.iter().zip(&map.param_bounds))
    {
        p.value = *v;
        p.bounds = *b;
    }
    let fixed: Vec<bool> = (0..values.len())
        .map(|i| !map.groups.iter().any(|g| g.contains(&i)))
        .collect();
    for (p, f) in fitted.parameters.iter_mut().zip(&fixed) {
        p.fixed = *f;
    }
    let seconds = t0.elapsed().as_secs_f64();
    let n_eval = evals.load(Ordering::Relaxed);
    let diag = &mut fitted.info.diagnostics;
    diag.insert("cost".into(), json!(cost));
    diag.insert(
        "cost_definition".into(),
        json!("mean squared free-run simulation error after the initial state"),
    );
    diag.insert("rmse_fit".into(), json!(cost.sqrt()));
    diag.insert("nominal_cost".into(), json!(nominal_cost));
    if let Some(c) = swarm_cost {
        diag.insert("swarm_cost".into(), json!(c));
    }
    if let Some(c) = segmented_cost {
        diag.insert("segmented_cost".into(), json!(c));
        diag.insert("segment".into(), json!(options.segment));
    }
    diag.insert("evaluations".into(), json!(n_eval));
    // The last local run (the final Nelder-Mead run, on the free-run cost)
    // decides whether the result counts as converged.
    let last = nm_stops.last().copied();
    let mut termination = serde_json::Map::new();
    if let Some(t) = swarm_stop {
        termination.insert("particle_swarm".into(), json!(t.as_str()));
    }
    if !lm_stops.is_empty() {
        termination.insert("levenberg_marquardt".into(), termination_counts(&lm_stops));
    }
    if !nm_stops.is_empty() {
        termination.insert("nelder_mead".into(), termination_counts(&nm_stops));
    }
    if let Some(t) = last {
        termination.insert("last_local_run".into(), json!(t.as_str()));
    }
    diag.insert("termination".into(), serde_json::Value::Object(termination));
    if let Some(stage) = cut_short {
        diag.insert(
            "status".into(),
            json!(format!(
                "time budget reached during the {stage} stage after {n_eval} simulations: best parameters found by then"
            )),
        );
    } else if last == Some(Termination::MaxIterations) {
        diag.insert(
            "status".into(),
            json!(format!(
                "iteration limit reached: the last Nelder-Mead run stopped at local_iters = {} before its convergence test held; the parameters may not be converged (raise local_iters)",
                options.local_iters
            )),
        );
    }
    diag.insert("noise_estimate".into(), json!(tols.noise));
    diag.insert("samples".into(), json!(data.len()));
    diag.insert("free_parameters".into(), json!(d));
    let mut at_bound = Vec::new();
    let mut sens_json = serde_json::Map::new();
    for (gi, g) in map.groups.iter().enumerate() {
        let [lo, hi] = map.bounds[gi];
        let v = values[g[0]];
        if (v - lo).abs() <= 1e-6 * (hi - lo) || (hi - v).abs() <= 1e-6 * (hi - lo) {
            at_bound.extend(g.iter().map(|&i| map.names[i].clone()));
        }
        let se = sens.std_errors[gi];
        let entry = json!({
            "value": v,
            "std_error": if se.is_finite() { json!(se) } else { json!(null) },
            "relative_std_error": if se.is_finite() && v != 0.0 { json!((se / v).abs()) } else { json!(null) },
            "ci95": if se.is_finite() { json!([v - 1.96 * se, v + 1.96 * se]) } else { json!(null) },
            "sensitivity": sens.sensitivity[gi],
        });
        for &i in g {
            sens_json.insert(map.names[i].clone(), entry.clone());
        }
    }
    diag.insert("parameters".into(), serde_json::Value::Object(sens_json));
    diag.insert(
        "confidence_method".into(),
        json!("Gauss-Newton s^2 (J^T J)^-1 from a central finite-difference Jacobian of the simulation residuals; local, and optimistic since the residuals are correlated"),
    );
    diag.insert("jacobian_condition".into(), json!(sens.condition));
    let silent: Vec<String> = map
        .groups
        .iter()
        .zip(&sens.sensitivity)
        .filter(|(_, s)| **s == 0.0)
        .flat_map(|(g, _)| g.iter().map(|&i| map.names[i].clone()))
        .collect();
    if !silent.is_empty() {
        // No effect on the simulated output under a small change: not
        // identifiable from this record (a stop never reached), or a
        // threshold (static friction) that no small change flips.
        diag.insert("zero_sensitivity".into(), json!(silent));
    }
    if !at_bound.is_empty() {
        diag.insert("at_bound".into(), json!(at_bound));
    }
    let report = FitReport {
        nominal_cost,
        swarm_cost,
        cost,
        evaluations: n_eval,
        seconds,
        std_errors: sens.std_errors,
    };
    Ok((fitted, report))
}

struct Sensitivity {
    std_errors: Vec<f64>,
    sensitivity: Vec<f64>,
    condition: f64,
}

/// Central finite-difference Jacobian of the residuals with respect to each
/// free coordinate (in physical units), Gauss-Newton covariance.
fn sensitivity(
    model: &MechanicalModel,
    map: &ParameterMap,
    values: &[f64],
    data: &Dataset,
    step: f64,
) -> Sensitivity {
    let d = map.dim();
    let residuals = |v: &[f64]| -> Option<Vec<f64>> {
        let r = mechanical::run(model, v, data).ok()?;
        Some(
            data.y()[r.start + 1..]
                .iter()
                .zip(&r.y[r.start + 1..])
                .map(|(a, b)| a - b)
                .collect(),
        )
    };
    let nan = || Sensitivity {
        std_errors: vec![f64::NAN; d],
        sensitivity: vec![f64::NAN; d],
        condition: f64::NAN,
    };
    let Some(r0) = residuals(values) else {
        return nan();
    };
    let n = r0.len();
    let mut jac = DMatrix::zeros(n, d);
    for (j, (g, [lo, hi])) in map.groups.iter().zip(&map.bounds).enumerate() {
        let h = step * (hi - lo).max(1e-12);
        let x = values[g[0]];
        let (xp, xm) = ((x + h).min(*hi), (x - h).max(*lo));
        if xp <= xm {
            continue;
        }
        let set = |val: f64| {
            let mut v = values.to_vec();
            for &i in g {
                v[i] = val;
            }
            v
        };
        let (Some(rp), Some(rm)) = (residuals(&set(xp)), residuals(&set(xm))) else {
            return nan();
        };
        for k in 0..n {
            // d yhat / d theta = - d r / d theta
            jac[(k, j)] = -(rp[k] - rm[k]) / (xp - xm);
        }
    }
    let sse: f64 = r0.iter().map(|e| e * e).sum();
    let s2 = sse / (n.saturating_sub(d).max(1)) as f64;
    // Columns with no effect on the output (e.g. a stop never reached) are
    // not identifiable from this record: left out, their error undefined.
    let norms: Vec<f64> = (0..d).map(|j| jac.column(j).norm()).collect();
    let top = norms.iter().copied().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..d)
        .filter(|&j| norms[j] > 1e-9 * top && top > 0.0)
        .collect();
    let mut std_errors = vec![f64::NAN; d];
    let mut condition = f64::NAN;
    if !keep.is_empty() {
        let jk = DMatrix::from_fn(n, keep.len(), |k, c| jac[(k, keep[c])]);
        let jtj = jk.transpose() * &jk;
        let sv = jtj.clone().svd(false, false).singular_values;
        let (smax, smin) = (sv.max(), sv.min());
        condition = if smin > 0.0 {
            (smax / smin).sqrt()
        } else {
            f64::INFINITY
        };
        if let Ok(inv) = hysid_estimation::linalg::pinv(&jtj)
            && smin > 1e-14 * smax
        {
            for (c, &j) in keep.iter().enumerate() {
                std_errors[j] = (s2 * inv[(c, c)]).max(0.0).sqrt();
            }
        }
    }
    // Scaled sensitivity: RMS change of the output per relative change of the parameter.
    let sensitivity = (0..d)
        .map(|j| {
            let x = values[map.groups[j][0]];
            jac.column(j).norm() / (n as f64).sqrt() * x.abs()
        })
        .collect();
    Sensitivity {
        std_errors,
        sensitivity,
        condition,
    }
}
