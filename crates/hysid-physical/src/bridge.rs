//! Bridge to the data-driven world: the per-mode discrete-time affine form
//! of a [`MechanicalModel`], as a PWARX model with `na = nb = 2`, so that a
//! physical fit can be compared mode by mode with what PWARX back-ends
//! identify (the head of Juloski, Heemels, Ferrari-Trecate 2003, section 2
//! and figure 3; section 4 fits PWARX models with `na = 2`, `nb = 1` or 2).
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
//!
//! A gray-box model ([`graybox_to_pwarx`]) has `n` states: each mode whose
//! flows and output are affine in the states and inputs gives ARX(n, n)
//! modes by the same discretisation and the general Cayley-Hamilton
//! identity (below); its regions are not derived.

use hysid_graybox::compile::{CompiledElement, CompiledModel};
use hysid_graybox::{GrayBoxModel, InvalidGrayBox};
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
    PwarxModel {
        na: 2,
        nb: 2,
        inputs: m,
        modes,
        info: bridge_info(
            &model.info,
            ts,
            "per-mode ZOH discretisation of a mechanical model; regions indicative",
        ),
    }
}

/// The provenance of a bridged model: the physical model's method, the
/// sampling time, and what the bridge did.
fn bridge_info(physical: &ModelInfo, ts: f64, note: &str) -> ModelInfo {
    let mut info = ModelInfo {
        ts: Some(ts),
        method: physical.method.clone(),
        ..ModelInfo::default()
    };
    info.diagnostics
        .method
        .insert("bridge".into(), serde_json::json!(note));
    info
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

/// Why a gray-box model has no per-mode ARX form.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BridgeError {
    /// The model does not pass its checks.
    #[error(transparent)]
    Invalid(#[from] InvalidGrayBox),
    /// A flow, the output or a friction level that is not affine in the
    /// states and inputs (with the parameters bound).
    #[error("mode '{mode}': {what} is not affine in the states and inputs")]
    NotAffine {
        /// The mode.
        mode: String,
        /// Which expression.
        what: String,
    },
}

/// The coefficients `p_1 .. p_n` of the characteristic polynomial
/// `det(lambda I - A) = lambda^n + p_1 lambda^(n-1) + .. + p_n`
/// (Faddeev-LeVerrier).
fn characteristic(a: &DMatrix<f64>) -> Vec<f64> {
    let n = a.nrows();
    let mut m = DMatrix::<f64>::zeros(n, n);
    let mut p = Vec::with_capacity(n);
    let mut c = 1.0;
    for k in 1..=n {
        m = a * &m + DMatrix::identity(n, n) * c;
        c = -(a * &m).trace() / k as f64;
        p.push(c);
    }
    p
}

/// `theta = [a_1..a_n, b_11..b_1n, .., b_m1..b_mn, c]` of
/// `x' = A x + B u + f`, `y = C x + d`, held input, at `ts`. With
/// `x(k+1) = Ad x(k) + Bd u(k) + fd` and `p_i` the characteristic
/// coefficients of `Ad` (`p_0 = 1`), Cayley-Hamilton gives
/// `y(k) = -sum p_i y(k-i) + sum_r C M_r (Bd u(k-r) + fd) + d sum p_i`,
/// `M_r = sum_{i<r} p_i Ad^(r-1-i)`.
fn arx_theta(a: &DMatrix<f64>, bw: &DMatrix<f64>, c: &DMatrix<f64>, d: f64, ts: f64) -> Vec<f64> {
    let (n, m) = (a.nrows(), bw.ncols() - 1);
    let (ad, bd) = zoh(a, bw, ts);
    let mut p = vec![1.0];
    p.extend(characteristic(&ad));
    let mut theta: Vec<f64> = p[1..].iter().map(|pi| -pi).collect();
    // C M_r [Bd fd], r = 1..n.
    let mut cm_bd = Vec::with_capacity(n);
    let mut power = DMatrix::<f64>::identity(n, n);
    let mut powers = vec![power.clone()];
    for _ in 1..n {
        power = &ad * &power;
        powers.push(power.clone());
    }
    for r in 1..=n {
        let mut mr = DMatrix::<f64>::zeros(n, n);
        for (i, pi) in p.iter().enumerate().take(r) {
            mr += &powers[r - 1 - i] * *pi;
        }
        cm_bd.push(c * mr * &bd);
    }
    for i in 0..m {
        theta.extend(cm_bd.iter().map(|row| row[(0, i)]));
    }
    let constant: f64 =
        cm_bd.iter().map(|row| row[(0, m)]).sum::<f64>() + d * p.iter().sum::<f64>();
    theta.push(constant);
    theta
}

/// The per-mode ARX(n, n) form of a gray-box model at its parameter values
/// and sampling time `ts` (`n` its number of states). Each declared mode
/// gives one mode per sliding direction of its friction (`mode+`, `mode-`)
/// or one mode without friction; a friction's stick is `y(k) = y(k-1)` and
/// a stop on the output's state `y(k) = level`. Regions are not derived
/// (every region is the whole regressor space).
pub fn graybox_to_pwarx(model: &GrayBoxModel, ts: f64) -> Result<PwarxModel, BridgeError> {
    let compiled = CompiledModel::new(model)?.bind(&model.values());
    let (n, m) = (compiled.states, compiled.inputs);
    let affine_rows = |mode: &str, what: &str, e: &hysid_graybox::expr::Expression| {
        let (constant, terms) = e.affine().ok_or_else(|| BridgeError::NotAffine {
            mode: mode.to_string(),
            what: what.to_string(),
        })?;
        let mut row = vec![0.0; n + m];
        for (s, c) in terms {
            // Parameters are bound: only states and inputs remain.
            *row.get_mut(s as usize)
                .ok_or_else(|| BridgeError::NotAffine {
                    mode: mode.to_string(),
                    what: what.to_string(),
                })? += c;
        }
        Ok::<_, BridgeError>((row, constant))
    };
    let friction = compiled
        .elements
        .iter()
        .enumerate()
        .find_map(|(i, e)| match e {
            CompiledElement::DryFriction { velocity, .. } => Some((i, *velocity)),
            CompiledElement::Stop { .. } => None,
        });
    let mut modes = Vec::new();
    for (q, mode) in model.modes.iter().zip(&compiled.modes) {
        let mut a = DMatrix::zeros(n, n);
        let mut bw = DMatrix::zeros(n, m + 1);
        for (j, (s, f)) in model.states.iter().zip(&mode.flow).enumerate() {
            let (row, constant) = affine_rows(&q.name, &format!("the flow of '{s}'"), f)?;
            for k in 0..n {
                a[(j, k)] = row[k];
            }
            for i in 0..m {
                bw[(j, i)] = row[n + i];
            }
            bw[(j, m)] = constant;
        }
        let (row, d) = affine_rows(&q.name, "the output", &mode.output)?;
        if row[n..].iter().any(|b| *b != 0.0) {
            return Err(BridgeError::NotAffine {
                mode: q.name.clone(),
                what: "the output (it reads an input)".into(),
            });
        }
        let c = DMatrix::from_row_slice(1, n, &row[..n]);
        match friction {
            Some((i, v)) => {
                let kinetic =
                    mode.friction[i]
                        .0
                        .as_constant()
                        .ok_or_else(|| BridgeError::NotAffine {
                            mode: q.name.clone(),
                            what: "the kinetic friction level (it depends on the state)".into(),
                        })?;
                for (s, tag) in [(1.0, "+"), (-1.0, "-")] {
                    let mut bs = bw.clone();
                    bs[(v, m)] -= s * kinetic.max(0.0);
                    modes.push(PwarxMode {
                        theta: arx_theta(&a, &bs, &c, d, ts),
                        region: Polyhedron::default(),
                        name: Some(format!("{}{tag}", q.name)),
                    });
                }
            }
            None => modes.push(PwarxMode {
                theta: arx_theta(&a, &bw, &c, d, ts),
                region: Polyhedron::default(),
                name: Some(q.name.clone()),
            }),
        }
    }
    let labels = model.mode_names();
    let rest = |name: &str, theta: Vec<f64>| PwarxMode {
        theta,
        region: Polyhedron::default(),
        name: Some(name.to_string()),
    };
    // The output's state, when the output is one state.
    let output_state =
        compiled.modes[0]
            .output
            .affine()
            .and_then(|(d, terms)| match terms.as_slice() {
                [(s, c)] if d == 0.0 && *c == 1.0 => Some(*s as usize),
                _ => None,
            });
    let width = n + n * m + 1;
    for e in &compiled.elements {
        match e {
            CompiledElement::DryFriction { label, .. } => {
                let mut theta = vec![0.0; width];
                theta[0] = 1.0;
                modes.push(rest(&labels[*label], theta));
            }
            CompiledElement::Stop {
                position,
                at,
                label,
                ..
            } if Some(*position) == output_state => {
                let mut theta = vec![0.0; width];
                theta[width - 1] = at.as_constant().unwrap_or(f64::NAN);
                modes.push(rest(&labels[*label], theta));
            }
            CompiledElement::Stop { .. } => {}
        }
    }
    Ok(PwarxModel {
        na: n,
        nb: n,
        inputs: m,
        modes,
        info: bridge_info(
            &model.info,
            ts,
            "per-mode ZOH discretisation of a gray-box model; regions not derived",
        ),
    })
}
