//! The small Levenberg-Marquardt solver of initial states that a rule
//! leaves unknown: the states estimated from a record's warm-up outputs
//! and the rest state of the `steady` rule
//! ([`crate::simulate::estimate`], the `steady` rule of
//! [`crate::simulate::run`]).

use nalgebra::{DMatrix, DVector};

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
