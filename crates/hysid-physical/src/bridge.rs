//! Bridge to the data-driven world: the per-mode discrete-time affine form
//! of a [`MechanicalModel`], as a PWARX model with `na = nb = 2`, so that a
//! physical fit can be compared mode by mode with what PWARX back-ends
//! identify (`shared/docs/mounting-head.md`, section 2.2, "Discrete-time
//! view").
//!
//! In each sliding regime (direction of motion `s`, engaged contacts) the
//! dynamics are `d/dt [y; v] = A [y; v] + B u + f` with the friction
//! entering as the constant `-s f_k`. The zero-order-hold discretisation at
//! the sampling time (exact: the exponential of the augmented matrix
//! `[[A, B, f], [0, 0, 0]] Ts`) gives `x(k+1) = Ad x(k) + Bd u(k) + fd`, and
//! by Cayley-Hamilton (`Ad^2 - tr(Ad) Ad + det(Ad) I = 0`) with `y = [1 0] x`
//!
//! `y(k) = a1 y(k-1) + a2 y(k-2) + b1 u(k-1) + b2 u(k-2) + c`,
//! `a1 = tr Ad`, `a2 = -det Ad`, `[b1 | c1] = C [Bd fd]`,
//! `[b2 | c2] = C Ad [Bd fd] - tr(Ad) C [Bd fd]`, `c = c1 + c2`.
//!
//! Stick modes are `y(k) = y(k-1)` and stop modes `y(k) = level`.
//! Regions (regressor `[y1, y2, u1, u2]`) are the natural indicators of the
//! regimes: direction `s (y1 - y2) >= 0`, contact `s_c (y1 - y_c) >= 0`,
//! stick `y1 = y2`, stop `y1 = level` (the last two lower-dimensional).
//! They are indicative only: the true switching depends on the velocity
//! and the friction state, which these regressors do not resolve exactly.

use hysid_mechanical::{MechanicalModel, ResolvedForce, ResolvedMechanics};
use hysid_model::geometry::Polyhedron;
use hysid_model::model::{ModelInfo, PwarxMode, PwarxModel};
use nalgebra::DMatrix;

/// The ZOH discretisation of `d/dt x = A x + B w` (`w` held) at `ts`:
/// `(Ad, Bd)`.
pub fn zoh(a: &DMatrix<f64>, b: &DMatrix<f64>, ts: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, m) = (a.nrows(), b.ncols());
    let mut big = DMatrix::zeros(n + m, n + m);
    big.view_mut((0, 0), (n, n)).copy_from(&(a * ts));
    big.view_mut((0, n), (n, m)).copy_from(&(b * ts));
    let e = big.exp();
    (
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, m)).into_owned(),
    )
}

/// `theta = [a1, a2, b_11, b_12, .., b_m1, b_m2, c]` of a sliding regime.
fn slip_theta(a: &DMatrix<f64>, bw: &DMatrix<f64>, ts: f64, inputs: usize) -> Vec<f64> {
    let (ad, bd) = zoh(a, bw, ts);
    let tr = ad[(0, 0)] + ad[(1, 1)];
    let det = ad[(0, 0)] * ad[(1, 1)] - ad[(0, 1)] * ad[(1, 0)];
    let cb = bd.row(0).into_owned();
    let cab = (ad.row(0) * &bd).into_owned();
    let mut theta = vec![tr, -det];
    for i in 0..inputs {
        theta.push(cb[i]);
        theta.push(cab[i] - tr * cb[i]);
    }
    theta.push(cb[inputs] + cab[inputs] - tr * cb[inputs]);
    theta
}

/// The per-mode ARX(2,2) form of `model` at sampling time `ts`: modes named
/// `slip+[contacts]`, `slip-[contacts]`, `stick`, `stop[name]`.
pub fn to_pwarx(model: &MechanicalModel, ts: f64) -> PwarxModel {
    let r = model.resolve();
    let m = model.inputs.len();
    let mut modes = slip_modes(model, &r, ts);
    modes.extend(rest_modes(model, &r));
    let mut info = ModelInfo {
        ts: Some(ts),
        ..ModelInfo::default()
    };
    info.method = model.info.method.clone();
    info.diagnostics.method.insert(
        "bridge".into(),
        serde_json::json!("per-mode ZOH discretisation of a mechanical model; regions indicative"),
    );
    PwarxModel {
        na: 2,
        nb: 2,
        inputs: m,
        modes,
        info,
    }
}

/// A regressor-space row `[y1, y2, 0, ..]` of `inputs` inputs.
fn row(inputs: usize, y1: f64, y2: f64) -> Vec<f64> {
    let mut z = vec![0.0; 2 + 2 * inputs];
    z[0] = y1;
    z[1] = y2;
    z
}

/// The free-flight forces `(stiffness, damping, constant, input gains)`:
/// the sums over the model's springs, dampers, constants and inputs.
fn free_forces(r: &ResolvedMechanics, inputs: usize) -> (f64, f64, f64, Vec<f64>) {
    let (mut k, mut d, mut f) = (0.0, 0.0, 0.0);
    let mut b = vec![0.0; inputs];
    for fe in &r.forces {
        match *fe {
            ResolvedForce::Input(i, g) => b[i] += g,
            ResolvedForce::Constant(c) => f += c,
            ResolvedForce::Spring(s, rest) => {
                k += s;
                f += s * rest;
            }
            ResolvedForce::Damper(c) => d += c,
        }
    }
    (k, d, f, b)
}

/// The sliding modes: per set of engaged contacts, one per direction of
/// motion.
fn slip_modes(model: &MechanicalModel, r: &ResolvedMechanics, ts: f64) -> Vec<PwarxMode> {
    let m = model.inputs.len();
    let (k, d, f, b) = free_forces(r, m);
    let mut modes = Vec::new();
    let nc = r.contacts.len();
    for mask in 0..(1u32 << nc) {
        let (mut kk, mut dd, mut ff) = (k, d, f);
        let (kin, _) = r.friction(mask);
        let mut ra = Vec::new();
        let mut rb = Vec::new();
        let mut names = Vec::new();
        for (i, c) in r.contacts.iter().enumerate() {
            if mask & (1 << i) != 0 {
                kk += c.stiffness;
                dd += c.damping;
                ff += c.stiffness * c.position;
                names.push(model.contacts[i].name.clone());
                ra.push(row(m, -c.sign, 0.0));
                rb.push(-c.sign * c.position);
            } else {
                ra.push(row(m, c.sign, 0.0));
                rb.push(c.sign * c.position);
            }
        }
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -kk, -dd]);
        for (s, tag) in [(1.0, "+"), (-1.0, "-")] {
            let mut bw = DMatrix::zeros(2, m + 1);
            for i in 0..m {
                bw[(1, i)] = b[i];
            }
            bw[(1, m)] = ff - s * kin;
            let mut a_rows = ra.clone();
            let mut b_rows = rb.clone();
            a_rows.push(row(m, -s, s)); // s (y1 - y2) >= 0
            b_rows.push(0.0);
            modes.push(PwarxMode {
                theta: slip_theta(&a, &bw, ts, m),
                region: Polyhedron::from_inequalities(a_rows, b_rows),
                name: Some(format!("slip{tag}[{}]", names.join("+"))),
            });
        }
    }
    modes
}

/// The modes at rest: `stick` (`y(k) = y(k-1)`) and one per stop
/// (`y(k) = level`).
fn rest_modes(model: &MechanicalModel, r: &ResolvedMechanics) -> Vec<PwarxMode> {
    let m = model.inputs.len();
    let mut stick = vec![0.0; 3 + 2 * m];
    stick[0] = 1.0;
    let mut modes = vec![PwarxMode {
        theta: stick,
        region: Polyhedron {
            a: vec![],
            b: vec![],
            a_eq: vec![row(m, 1.0, -1.0)],
            b_eq: vec![0.0],
        },
        name: Some("stick".into()),
    }];
    for (i, s) in r.stops.iter().enumerate() {
        let mut theta = vec![0.0; 3 + 2 * m];
        theta[2 + 2 * m] = s.position;
        modes.push(PwarxMode {
            theta,
            region: Polyhedron {
                a: vec![],
                b: vec![],
                a_eq: vec![row(m, 1.0, 0.0)],
                b_eq: vec![s.position],
            },
            name: Some(format!("stop[{}]", model.stops[i].name)),
        });
    }
    modes
}
