//! Initial states that a rule leaves unknown: the states estimated from a
//! record's warm-up outputs ([`estimate`]) and the rest state of the
//! `steady` rule ([`steady`]), both by one small Levenberg-Marquardt
//! solver ([`levenberg_marquardt`]).

use crate::compile::CompiledModel;
use crate::simulate::{Machine, run_from};
use hysid_model::data::{Dataset, RowRange};
use hysid_model::simulate::SimError;
use nalgebra::{DMatrix, DVector};

/// Iterations of the warm-up estimate's solver.
pub const ESTIMATE_ITERATIONS: usize = 100;

/// Iterations of the rest state's Newton (Levenberg-Marquardt) solve.
pub const STEADY_ITERATIONS: usize = 100;

/// Largest flow (relative to the flows at the guess, at least 1) that
/// counts as at rest.
pub const STEADY_TOLERANCE: f64 = 1e-9;

/// The states [`CompiledModel::estimates`] lists, estimated from the
/// outputs of `data`'s warm-up alone (its first
/// [`crate::compile::CompiledInitial::warmup`] samples; the rows after it
/// are not read): the values within their bounds that minimise the sum of
/// squared differences between the measured and the simulated outputs
/// over the warm-up, from the rule's starting guesses, by
/// [`levenberg_marquardt`] in box-normalised coordinates (steps projected
/// onto the bounds). Empty when the rule estimates nothing.
pub fn estimate(m: &CompiledModel, values: &[f64], data: &Dataset) -> Result<Vec<f64>, SimError> {
    if m.estimates.is_empty() {
        return Ok(Vec::new());
    }
    let w = m.initial.warmup().unwrap_or(1);
    if data.len() < w {
        return Err(SimError::TooShort {
            samples: data.len(),
            needed: w,
        });
    }
    let window = data
        .slice(RowRange {
            start: Some(0),
            end: Some(w),
        })
        .map_err(|e| SimError::InitialState(e.to_string()))?;
    let to_values = |z: &[f64]| -> Vec<f64> {
        m.estimates
            .iter()
            .zip(z)
            .map(|(e, z)| e.bounds[0] + (e.bounds[1] - e.bounds[0]) * z.clamp(0.0, 1.0))
            .collect()
    };
    let residuals = |z: &[f64]| -> Option<Vec<f64>> {
        let r = run_from(m, values, &to_values(z), &window).ok()?;
        let e: Vec<f64> = window.y().iter().zip(&r.y).map(|(a, b)| a - b).collect();
        e.iter().all(|v| v.is_finite()).then_some(e)
    };
    let z0: Vec<f64> = m
        .estimates
        .iter()
        .map(|e| {
            let [lo, hi] = e.bounds;
            if hi > lo {
                (e.start - lo) / (hi - lo)
            } else {
                0.5
            }
        })
        .collect();
    let unit = vec![[0.0, 1.0]; z0.len()];
    let (z, _) = levenberg_marquardt(&residuals, &z0, Some(&unit), 1e-7, ESTIMATE_ITERATIONS);
    Ok(to_values(&z))
}

/// The rest state under the input `u`: the states where every flow of the
/// mode is zero (the elements aside: at rest a friction holds a velocity
/// at zero whatever its level), solved by [`levenberg_marquardt`] from
/// the guess `guess` ([`STEADY_ITERATIONS`] iterations at most), in
/// `mode`, or else in the first mode whose rest state satisfies its
/// invariant. Returns the state and its mode; an error when no mode has
/// one (the solve does not reach [`STEADY_TOLERANCE`], or its rest state
/// leaves the invariant).
pub(crate) fn steady(
    machine: &mut Machine,
    guess: &[f64],
    u: &[f64],
    mode: Option<usize>,
) -> Result<(Vec<f64>, usize), SimError> {
    let modes: Vec<usize> = match mode {
        Some(q) => vec![q],
        None => (0..machine.modes()).collect(),
    };
    let n = guess.len();
    let cell = std::cell::RefCell::new(machine);
    for &q in &modes {
        let flows = |x: &[f64]| -> Option<Vec<f64>> {
            let mut out = vec![0.0; n];
            cell.borrow_mut().bare_flows(x, u, q, &mut out);
            out.iter().all(|v| v.is_finite()).then_some(out)
        };
        let Some(f0) = flows(guess) else { continue };
        let scale = f0.iter().fold(1.0f64, |a, v| a.max(v.abs()));
        let (x, _) = levenberg_marquardt(&flows, guess, None, 1e-7, STEADY_ITERATIONS);
        let at_rest =
            flows(&x).is_some_and(|f| f.iter().all(|v| v.abs() <= STEADY_TOLERANCE * scale));
        if at_rest && cell.borrow_mut().in_invariant(&x, u, q) {
            return Ok((x, q));
        }
    }
    Err(SimError::InitialState(format!(
        "no rest state under the first input: in {} the flows do not vanish at a state within \
         the invariant (Newton's method from the guess, at most {STEADY_ITERATIONS} iterations)",
        match mode {
            Some(_) => "the rule's mode".to_string(),
            None => format!("none of the {} modes", modes.len()),
        }
    )))
}

/// Levenberg-Marquardt (Levenberg 1944, Marquardt 1963) on the residuals
/// `res(x)` from `x0`, at most `iters` iterations: the damped Gauss-Newton
/// step `(J^T J + mu diag(J^T J)) dx = -J^T r` with a central
/// finite-difference Jacobian (step `fd` times `max(1, |x_i|)`, or `fd`
/// in `[0, 1]` coordinates), projected onto `bounds` when given. The
/// damping starts at `1e-3`, is divided by 3 after a step that lowers the
/// sum of squares and multiplied by 4 after one that does not; the solve
/// stops when the sum of squares is zero, its relative decrease falls
/// below `1e-15`, or the damping exceeds `1e10`. Returns the best point
/// and its sum of squares (infinite when `res(x0)` fails).
pub fn levenberg_marquardt(
    res: &dyn Fn(&[f64]) -> Option<Vec<f64>>,
    x0: &[f64],
    bounds: Option<&[[f64; 2]]>,
    fd: f64,
    iters: usize,
) -> (Vec<f64>, f64) {
    let sse = |e: &[f64]| e.iter().map(|v| v * v).sum::<f64>();
    let project = |x: &mut [f64]| {
        if let Some(b) = bounds {
            for (v, [lo, hi]) in x.iter_mut().zip(b) {
                *v = v.clamp(*lo, *hi);
            }
        }
    };
    let mut x = x0.to_vec();
    let Some(mut r) = res(&x) else {
        return (x, f64::INFINITY);
    };
    let mut cost = sse(&r);
    let mut mu = 1e-3;
    let mut jac: Option<DMatrix<f64>> = None;
    for _ in 0..iters {
        if cost == 0.0 {
            break;
        }
        let j = jac.get_or_insert_with(|| jacobian(res, &x, r.len(), fd, &project));
        let jtj = j.transpose() * &*j;
        let g = j.transpose() * DVector::from_column_slice(&r);
        let mut a = jtj.clone();
        for c in 0..a.ncols() {
            a[(c, c)] += mu * (jtj[(c, c)] + 1e-12);
        }
        let Some(step) = a.cholesky().map(|ch| ch.solve(&(-g))) else {
            mu *= 10.0;
            continue;
        };
        let mut xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
        project(&mut xn);
        match res(&xn) {
            Some(rn) if sse(&rn) < cost => {
                let decrease = (cost - sse(&rn)) / cost;
                (x, r) = (xn, rn);
                cost = sse(&r);
                mu = (mu / 3.0).max(1e-15);
                jac = None;
                if decrease < 1e-15 {
                    break;
                }
            }
            _ => {
                mu *= 4.0;
                if mu > 1e10 {
                    break;
                }
            }
        }
    }
    (x, cost)
}

/// Central finite-difference Jacobian (`rows` residuals) of `res` at `x`,
/// the perturbed points projected by `project`; a column whose residuals
/// fail stays zero.
fn jacobian(
    res: &dyn Fn(&[f64]) -> Option<Vec<f64>>,
    x: &[f64],
    rows: usize,
    fd: f64,
    project: &dyn Fn(&mut [f64]),
) -> DMatrix<f64> {
    let mut j = DMatrix::zeros(rows, x.len());
    for c in 0..x.len() {
        let h = fd * x[c].abs().max(1.0);
        let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
        xp[c] += h;
        xm[c] -= h;
        project(&mut xp);
        project(&mut xm);
        let width = xp[c] - xm[c];
        if width <= 0.0 {
            continue;
        }
        let (Some(rp), Some(rm)) = (res(&xp), res(&xm)) else {
            continue;
        };
        for k in 0..rows.min(rp.len()).min(rm.len()) {
            j[(k, c)] = (rp[k] - rm[k]) / width;
        }
    }
    j
}

#[cfg(test)]
mod tests {
    use super::levenberg_marquardt;

    #[test]
    fn levenberg_marquardt_solves_a_nonlinear_system_and_keeps_to_its_bounds() {
        // x^2 = 2, x y = 3: x = sqrt 2, y = 3 / sqrt 2.
        let res = |x: &[f64]| Some(vec![x[0] * x[0] - 2.0, x[0] * x[1] - 3.0]);
        let (x, cost) = levenberg_marquardt(&res, &[1.0, 1.0], None, 1e-7, 100);
        assert!(cost < 1e-24, "{cost}");
        assert!((x[0] - 2f64.sqrt()).abs() < 1e-12);
        assert!((x[1] - 3.0 / 2f64.sqrt()).abs() < 1e-12);
        let (x, _) = levenberg_marquardt(
            &res,
            &[1.0, 1.0],
            Some(&[[0.0, 1.2], [0.0, 5.0]]),
            1e-7,
            100,
        );
        assert!(x[0] <= 1.2 && x[0] > 1.19, "{x:?}");
    }
}
