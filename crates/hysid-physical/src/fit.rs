//! The fit: parameter map (priors), cost, swarm, Nelder-Mead, sensitivity.

use crate::PhysicalOptions;
use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use argmin::solver::particleswarm::ParticleSwarm;
use hysid_core::backend::{IdentifyError, Progress, RunContext};
use hysid_core::data::Dataset;
use hysid_core::model::{MechanicalInitialState, MechanicalModel};
use hysid_core::priors::Priors;
use hysid_core::simulate::mechanical;
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
            model
                .parameter_index(n)
                .ok_or_else(|| format!("prior {entry}: unknown parameter '{n}' (known: {})", names.join(", ")))
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
            let ids: Vec<usize> = t.params.iter().map(|n| idx(n, "[[tie]]")).collect::<Result<_, _>>()?;
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
            let lo = g.iter().map(|&i| bounds[i][0]).fold(f64::NEG_INFINITY, f64::max);
            let hi = g.iter().map(|&i| bounds[i][1]).fold(f64::INFINITY, f64::min);
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                let who: Vec<&str> = g.iter().map(|&i| names[i].as_str()).collect();
                return Err(format!("prior: the bounds of [{}] leave no admissible value", who.join(", ")));
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
        Ok(Self { base, groups: free_groups, bounds: free_bounds, param_bounds: bounds, names })
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
            .map(|(g, [lo, hi])| if hi > lo { ((values[g[0]] - lo) / (hi - lo)).clamp(0.0, 1.0) } else { 0.5 })
            .collect()
    }
}

/// The simulation-error cost of a parameter vector.
struct SimulationCost<'a> {
    model: &'a MechanicalModel,
    data: &'a Dataset,
    map: &'a ParameterMap,
    progress: &'a dyn Progress,
    evals: &'a AtomicU64,
}

/// Cost of a diverged or failed simulation.
const FAILED: f64 = 1e30;

/// Mean squared simulation error over the samples after the initial state.
pub fn simulation_mse(model: &MechanicalModel, values: &[f64], data: &Dataset) -> f64 {
    match mechanical::run(model, values, data) {
        Ok(r) => {
            let y = data.y();
            let n = y.len() - (r.start + 1);
            if n == 0 {
                return FAILED;
            }
            let s: f64 = y[r.start + 1..].iter().zip(&r.y[r.start + 1..]).map(|(a, b)| (a - b) * (a - b)).sum();
            let m = s / n as f64;
            if m.is_finite() { m } else { FAILED }
        }
        Err(_) => FAILED,
    }
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
        let c = simulation_mse(self.model, &self.map.values(z), self.data);
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
    IdentifyError::Failed { method: "physical".into(), message: message.into() }
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
    model.validate().map_err(|e| IdentifyError::BadData(format!("model: {e}")))?;
    if data.inputs.len() != model.inputs.len() {
        return Err(IdentifyError::BadData(format!(
            "the model has {} input(s), the data {}",
            model.inputs.len(),
            data.inputs.len()
        )));
    }
    if data.ts.is_none() {
        return Err(IdentifyError::BadData(
            "the physical method needs the sampling time: give a 't' signal or --ts".into(),
        ));
    }
    if !(options.simplex > 0.0 && options.simplex <= 1.0) {
        return Err(IdentifyError::BadData(format!("--set simplex={}: must be in (0, 1]", options.simplex)));
    }
    if !(options.fd_step > 0.0 && options.fd_step < 0.5) {
        return Err(IdentifyError::BadData(format!("--set fd_step={}: must be in (0, 0.5)", options.fd_step)));
    }
    let mut model = model.clone();
    if options.init_samples > 0 {
        model.initial_state = MechanicalInitialState::Measured {
            samples: options.init_samples,
            velocity_tol: match model.initial_state {
                MechanicalInitialState::Measured { velocity_tol, .. } => velocity_tol,
                _ => 0.0,
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
    let problem = || SimulationCost { model: &model, data, map: &map, progress: ctx.progress, evals: &evals };
    let nominal_z = map.coords(&map.base);
    let nominal_cost = simulation_mse(&model, &map.values(&nominal_z), data);
    let timeout = |ex_deadline: Option<Instant>| ex_deadline.map(|t| t.saturating_duration_since(Instant::now()));

    let mut best_z = nominal_z.clone();
    let mut best_cost = nominal_cost;
    let mut swarm_cost = None;
    if d > 0 && options.particles > 0 && options.swarm_iters > 0 {
        ctx.progress.start((options.particles * (options.swarm_iters + 1)) as u64, "physical: particle swarm");
        let pso: ParticleSwarm<Vec<f64>, f64, ChaCha8Rng> = ParticleSwarm::new((vec![0.0; d], vec![1.0; d]), options.particles)
            .with_rng_generator(ChaCha8Rng::seed_from_u64(ctx.seed));
        let mut ex = Executor::new(problem(), pso).configure(|s| s.max_iters(options.swarm_iters as u64));
        if let Some(t) = timeout(ctx.deadline) {
            ex = ex.timeout(t);
        }
        let res = ex.run().map_err(|e| failed(format!("particle swarm: {e}")))?;
        ctx.progress.finish();
        if let Some(p) = res.state().get_best_param() {
            let c = p.cost;
            swarm_cost = Some(c);
            if c < best_cost {
                best_cost = c;
                best_z = p.position.clone();
            }
        }
    }
    if d > 0 && options.local_iters > 0 && options.restarts > 0 {
        ctx.progress.start((options.local_iters * options.restarts) as u64, "physical: Nelder-Mead");
        for _ in 0..options.restarts {
            if ctx.deadline.is_some_and(|t| Instant::now() >= t) {
                break;
            }
            let mut simplex = vec![best_z.clone()];
            for j in 0..d {
                let mut p = best_z.clone();
                // Step inwards so the simplex stays in the box.
                p[j] += if p[j] + options.simplex <= 1.0 { options.simplex } else { -options.simplex };
                simplex.push(p);
            }
            let nm: NelderMead<Vec<f64>, f64> = NelderMead::new(simplex)
                .with_sd_tolerance(1e-12)
                .map_err(|e| failed(format!("Nelder-Mead: {e}")))?;
            let mut ex = Executor::new(problem(), nm).configure(|s| s.max_iters(options.local_iters as u64));
            if let Some(t) = timeout(ctx.deadline) {
                ex = ex.timeout(t);
            }
            let res = ex.run().map_err(|e| failed(format!("Nelder-Mead: {e}")))?;
            let st = res.state();
            if let Some(p) = st.get_best_param()
                && st.get_best_cost() < best_cost
            {
                best_cost = st.get_best_cost();
                best_z = p.iter().map(|x| x.clamp(0.0, 1.0)).collect();
            }
        }
        ctx.progress.finish();
    }
    let values = map.values(&best_z);
    let cost = simulation_mse(&model, &values, data);
    if cost >= FAILED {
        return Err(failed("every candidate simulation failed or diverged"));
    }
    let sens = sensitivity(&model, &map, &values, data, options.fd_step);

    let mut fitted = model.clone();
    for (p, (v, b)) in fitted.parameters.iter_mut().zip(values.iter().zip(&map.param_bounds)) {
        p.value = *v;
        p.bounds = *b;
    }
    for g in &map.groups {
        let _ = g;
    }
    let fixed: Vec<bool> = (0..values.len()).map(|i| !map.groups.iter().any(|g| g.contains(&i))).collect();
    for (p, f) in fitted.parameters.iter_mut().zip(&fixed) {
        p.fixed = *f;
    }
    let seconds = t0.elapsed().as_secs_f64();
    let n_eval = evals.load(Ordering::Relaxed);
    let diag = &mut fitted.info.diagnostics;
    diag.insert("cost".into(), json!(cost));
    diag.insert("cost_definition".into(), json!("mean squared free-run simulation error after the initial state"));
    diag.insert("rmse_fit".into(), json!(cost.sqrt()));
    diag.insert("nominal_cost".into(), json!(nominal_cost));
    if let Some(c) = swarm_cost {
        diag.insert("swarm_cost".into(), json!(c));
    }
    diag.insert("evaluations".into(), json!(n_eval));
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
    if !at_bound.is_empty() {
        diag.insert("at_bound".into(), json!(at_bound));
    }
    diag.insert("seconds".into(), json!(seconds));
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
fn sensitivity(model: &MechanicalModel, map: &ParameterMap, values: &[f64], data: &Dataset, step: f64) -> Sensitivity {
    let d = map.dim();
    let residuals = |v: &[f64]| -> Option<Vec<f64>> {
        let r = mechanical::run(model, v, data).ok()?;
        Some(data.y()[r.start + 1..].iter().zip(&r.y[r.start + 1..]).map(|(a, b)| a - b).collect())
    };
    let nan = || Sensitivity { std_errors: vec![f64::NAN; d], sensitivity: vec![f64::NAN; d], condition: f64::NAN };
    let Some(r0) = residuals(values) else { return nan() };
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
        let (Some(rp), Some(rm)) = (residuals(&set(xp)), residuals(&set(xm))) else { return nan() };
        for k in 0..n {
            // d yhat / d theta = - d r / d theta
            jac[(k, j)] = -(rp[k] - rm[k]) / (xp - xm);
        }
    }
    let sse: f64 = r0.iter().map(|e| e * e).sum();
    let s2 = sse / (n.saturating_sub(d).max(1)) as f64;
    let jtj = jac.transpose() * &jac;
    let sv = jtj.clone().svd(false, false).singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    let condition = if smin > 0.0 { (smax / smin).sqrt() } else { f64::INFINITY };
    let std_errors = match hysid_core::linalg::pinv(&jtj) {
        Ok(inv) if smin > 1e-14 * smax => (0..d).map(|j| (s2 * inv[(j, j)]).max(0.0).sqrt()).collect(),
        _ => vec![f64::NAN; d],
    };
    // Scaled sensitivity: RMS change of the output per relative change of the parameter.
    let sensitivity = (0..d)
        .map(|j| {
            let x = values[map.groups[j][0]];
            jac.column(j).norm() / (n as f64).sqrt() * x.abs()
        })
        .collect();
    Sensitivity { std_errors, sensitivity, condition }
}
