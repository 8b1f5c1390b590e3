//! Hybrid automata with affine dynamics (Henzinger, "The theory of hybrid
//! automata", LICS 1996; the PWA special case of Heemels, De Schutter,
//! Bemporad, Automatica 2001).
//!
//! Everything geometric lives in the extended space `z = [x; u]` (state,
//! then the current input), so guards such as "the motor pushes down" can
//! be written. A mode has dynamics and an invariant; a transition has a
//! [`GuardSet`], possibly lower-dimensional (the stop `y = 25`), and a
//! [`ResetMap`] applied when it fires (the velocity reset `v := 0`).
//! Saturations are modes of this kind, never full-dimensional regions.

use super::{ModelInfo, PwarxMode, PwarxModel, mode_name};
use crate::geometry::{Polyhedron, PolyhedronError};
use crate::model::{Stop, StopBound};
use crate::regressors::RegressorSpec;
use serde::{Deserialize, Serialize};

/// Discrete or continuous time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeDomain {
    /// `x(k+1) = A x(k) + B u(k) + f`, one step per sample.
    #[default]
    Discrete,
    /// `dx/dt = A x + B u + f`, integrated with a fixed internal step.
    Continuous,
}

/// Affine dynamics `A x + B u + f` (next state or derivative).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AffineDynamics {
    /// State matrix, rows.
    pub a: Vec<Vec<f64>>,
    /// Input matrix, rows (empty for no input).
    #[serde(default)]
    pub b: Vec<Vec<f64>>,
    /// Constant term (empty means zero).
    #[serde(default)]
    pub f: Vec<f64>,
}

impl AffineDynamics {
    /// `A x + B u + f`.
    pub fn eval(&self, x: &[f64], u: &[f64], out: &mut [f64]) {
        for (i, o) in out.iter_mut().enumerate() {
            let mut v = self.f.get(i).copied().unwrap_or(0.0);
            v += self.a[i].iter().zip(x).map(|(p, q)| p * q).sum::<f64>();
            if let Some(row) = self.b.get(i) {
                v += row.iter().zip(u).map(|(p, q)| p * q).sum::<f64>();
            }
            *o = v;
        }
    }
}

/// Output `y = c x + d u + e`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputMap {
    /// State weights.
    pub c: Vec<f64>,
    /// Input weights (empty means zero).
    #[serde(default)]
    pub d: Vec<f64>,
    /// Offset.
    #[serde(default)]
    pub e: f64,
}

impl OutputMap {
    /// `c x + d u + e`.
    pub fn eval(&self, x: &[f64], u: &[f64]) -> f64 {
        self.c.iter().zip(x).map(|(p, q)| p * q).sum::<f64>()
            + self.d.iter().zip(u).map(|(p, q)| p * q).sum::<f64>()
            + self.e
    }
}

/// A guard set in `[x; u]`: a polyhedron that may have equality rows. A
/// transition fires at the first point of a step's trajectory that lies in
/// it, when the step did not start inside it.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct GuardSet(pub Polyhedron);

/// Reset `x+ = r x + c` applied when a transition fires; an empty `r` means
/// identity, an empty `c` zero.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResetMap {
    /// Linear part, rows (empty: identity).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub r: Vec<Vec<f64>>,
    /// Offset (empty: zero).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub c: Vec<f64>,
}

impl ResetMap {
    /// `x_i := value`, other states unchanged, in an `n`-dimensional state.
    pub fn assign(n: usize, assignments: &[(usize, f64)]) -> Self {
        let mut r: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
            .collect();
        let mut c = vec![0.0; n];
        for &(i, v) in assignments {
            r[i][i] = 0.0;
            c[i] = v;
        }
        Self { r, c }
    }

    /// Applies the map in place.
    pub fn apply(&self, x: &mut [f64]) {
        if !self.r.is_empty() {
            let y: Vec<f64> = self
                .r
                .iter()
                .map(|row| row.iter().zip(x.iter()).map(|(p, q)| p * q).sum())
                .collect();
            x.copy_from_slice(&y);
        }
        for (xi, ci) in x.iter_mut().zip(&self.c) {
            *xi += ci;
        }
    }
}

/// One discrete mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AutomatonMode {
    /// Name, unique in the automaton.
    pub name: String,
    /// Dynamics in this mode.
    pub flow: AffineDynamics,
    /// Where the mode may be active, in `[x; u]` (no rows: everywhere).
    #[serde(default)]
    pub invariant: Polyhedron,
}

/// A discrete transition with guard and reset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Transition {
    /// Source mode name.
    pub from: String,
    /// Target mode name.
    pub to: String,
    /// Guard set in `[x; u]`.
    pub guard: GuardSet,
    /// Reset applied on the transition.
    #[serde(default)]
    pub reset: ResetMap,
}

/// How the initial state of a simulation is obtained.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "from", rename_all = "snake_case", deny_unknown_fields)]
pub enum InitialState {
    /// The state is the ARX history `[y(k) .. y(k-n+1), u_i(k-1) .. u_i(k-nb+1)]`
    /// with `n = max(na, 1)`, read from measured data.
    ArxHistory {
        /// Output lags.
        na: usize,
        /// Input lags.
        nb: usize,
    },
    /// A fixed state.
    Given {
        /// The state.
        state: Vec<f64>,
    },
}

/// A hybrid automaton with affine dynamics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HybridAutomaton {
    /// Discrete or continuous time.
    #[serde(default)]
    pub time: TimeDomain,
    /// Internal integration step in seconds (continuous time only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub internal_step: Option<f64>,
    /// State names (define the state dimension).
    pub states: Vec<String>,
    /// Input names.
    #[serde(default)]
    pub inputs: Vec<String>,
    /// Output map.
    pub output: OutputMap,
    /// Modes.
    pub modes: Vec<AutomatonMode>,
    /// Transitions.
    #[serde(default)]
    pub transitions: Vec<Transition>,
    /// Mode at the start (default: chosen by invariant).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial_mode: Option<String>,
    /// How to get the initial state.
    pub initial_state: InitialState,
    /// Provenance.
    #[serde(default)]
    pub info: ModelInfo,
}

fn check_rows(
    what: &str,
    rows: &[Vec<f64>],
    n_rows: usize,
    n_cols: usize,
) -> Result<(), InvalidModel> {
    if rows.len() != n_rows {
        return Err(InvalidModel::RowCount {
            matrix: what.to_string(),
            rows: rows.len(),
            expected: n_rows,
        });
    }
    for (i, r) in rows.iter().enumerate() {
        if r.len() != n_cols || r.iter().any(|v| !v.is_finite()) {
            return Err(InvalidModel::Row {
                matrix: what.to_string(),
                row: i + 1,
                cols: n_cols,
            });
        }
    }
    Ok(())
}

/// An error naming `what` when one of `values` is NaN or infinite.
fn check_finite<'v>(
    what: impl Fn() -> String,
    values: impl IntoIterator<Item = &'v f64>,
) -> Result<(), InvalidModel> {
    if values.into_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(InvalidModel::NonFinite { what: what() })
    }
}

/// A structurally inconsistent PWARX model or hybrid automaton
/// ([`PwarxModel::validate`], [`HybridAutomaton::validate`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InvalidModel {
    /// A PWARX model without modes.
    #[error("a PWARX model needs at least one mode")]
    NoPwarxMode,
    /// Input lags without inputs.
    #[error("nb > 0 needs at least one input")]
    NbWithoutInput,
    /// A parameter vector of the wrong length.
    #[error(
        "mode {}: theta has {len} entries, na = {na}, nb = {nb}, {inputs} input(s) need {need}",
        .mode + 1
    )]
    ThetaLength {
        /// Mode index (from 0; shown from 1, as modes are named).
        mode: usize,
        /// Its entries.
        len: usize,
        /// Output order.
        na: usize,
        /// Input order.
        nb: usize,
        /// Inputs.
        inputs: usize,
        /// Entries needed.
        need: usize,
    },
    /// Orders whose parameter count is past any size a model can hold.
    #[error(
        "na = {na}, nb = {nb} and {inputs} input(s) need more parameters than a model can hold"
    )]
    OrdersTooLarge {
        /// Output order.
        na: usize,
        /// Input order.
        nb: usize,
        /// Inputs.
        inputs: usize,
    },
    /// A vector or number of an automaton with NaN or an infinity.
    #[error("{what} has a non-finite entry")]
    NonFinite {
        /// Which vector or number.
        what: String,
    },
    /// A parameter vector with NaN or an infinity.
    #[error("mode {}: theta has a non-finite entry", .mode + 1)]
    NonFiniteTheta {
        /// Mode index.
        mode: usize,
    },
    /// A malformed region.
    #[error("mode {}: region: {problem}", .mode + 1)]
    Region {
        /// Mode index.
        mode: usize,
        /// What is wrong.
        problem: PolyhedronError,
    },
    /// An automaton without state or mode.
    #[error("an automaton needs at least one state and one mode")]
    EmptyAutomaton,
    /// A continuous-time automaton without a positive internal step.
    #[error("a continuous-time automaton needs internal_step > 0")]
    NoInternalStep,
    /// An output map of the wrong shape.
    #[error("output: c needs {states} entries and d none or {inputs}")]
    OutputShape {
        /// States.
        states: usize,
        /// Inputs.
        inputs: usize,
    },
    /// Two modes of one name (as shown: a PWARX mode without a name is
    /// `mode k`, [`super::pwarx::mode_name`]).
    #[error("mode name '{0}' appears twice")]
    DuplicateMode(String),
    /// A mode name that is empty or blank.
    #[error("mode {}: an empty name (give it one; a PWARX mode may leave it out)", .mode + 1)]
    EmptyModeName {
        /// Mode index (from 0; shown from 1).
        mode: usize,
    },
    /// A matrix with the wrong number of rows.
    #[error("{matrix} has {rows} rows, expected {expected}")]
    RowCount {
        /// Which matrix (`mode 'q': flow.a`, ...).
        matrix: String,
        /// Its rows.
        rows: usize,
        /// Rows expected.
        expected: usize,
    },
    /// A matrix row of the wrong length or with a non-finite entry.
    #[error("{matrix} row {row}: expected {cols} finite entries")]
    Row {
        /// Which matrix.
        matrix: String,
        /// Row number, from 1.
        row: usize,
        /// Entries expected.
        cols: usize,
    },
    /// A flow offset of the wrong length.
    #[error("mode '{mode}': flow.f needs none or one entry per state")]
    FlowOffset {
        /// Mode name.
        mode: String,
    },
    /// A malformed invariant.
    #[error("mode '{mode}': invariant {problem}")]
    Invariant {
        /// Mode name.
        mode: String,
        /// What is wrong.
        problem: PolyhedronError,
    },
    /// A transition naming an unknown mode.
    #[error("transition {from} -> {to}: no mode named '{name}'")]
    TransitionMode {
        /// Source mode.
        from: String,
        /// Target mode.
        to: String,
        /// The unknown name.
        name: String,
    },
    /// A malformed guard set.
    #[error("transition {from} -> {to}: guard {problem}")]
    Guard {
        /// Source mode.
        from: String,
        /// Target mode.
        to: String,
        /// What is wrong.
        problem: PolyhedronError,
    },
    /// A reset offset of the wrong length.
    #[error("transition {from} -> {to}: reset.c needs none or one entry per state")]
    ResetOffset {
        /// Source mode.
        from: String,
        /// Target mode.
        to: String,
    },
    /// An unknown initial mode.
    #[error("initial_mode: no mode named '{0}'")]
    InitialMode(String),
    /// A given initial state of the wrong length.
    #[error("initial_state has {len} entries, expected {states}")]
    InitialStateLength {
        /// Its entries.
        len: usize,
        /// States.
        states: usize,
    },
    /// An ARX history that does not give the state.
    #[error("initial_state: ARX history does not match the state dimension")]
    ArxHistory,
}

impl HybridAutomaton {
    /// Index of the mode named `name`.
    pub fn mode_index(&self, name: &str) -> Option<usize> {
        self.modes.iter().position(|m| m.name == name)
    }

    /// Structural checks.
    pub fn validate(&self) -> Result<(), InvalidModel> {
        use InvalidModel as E;
        let n = self.states.len();
        let m = self.inputs.len();
        if n == 0 || self.modes.is_empty() {
            return Err(E::EmptyAutomaton);
        }
        if self.time == TimeDomain::Continuous {
            match self.internal_step {
                Some(h) if h.is_finite() && h > 0.0 => {}
                _ => return Err(E::NoInternalStep),
            }
        }
        if self.output.c.len() != n || !(self.output.d.is_empty() || self.output.d.len() == m) {
            return Err(E::OutputShape {
                states: n,
                inputs: m,
            });
        }
        check_finite(
            || "output".into(),
            (self.output.c.iter()).chain(&self.output.d),
        )?;
        check_finite(|| "output.e".into(), [&self.output.e])?;
        let mut names = std::collections::HashSet::with_capacity(self.modes.len());
        for (k, q) in self.modes.iter().enumerate() {
            let mode = || q.name.clone();
            if q.name.trim().is_empty() {
                return Err(E::EmptyModeName { mode: k });
            }
            if !names.insert(q.name.as_str()) {
                return Err(E::DuplicateMode(mode()));
            }
            let w = |s: &str| format!("mode '{}': {s}", q.name);
            check_rows(&w("flow.a"), &q.flow.a, n, n)?;
            if !q.flow.b.is_empty() {
                check_rows(&w("flow.b"), &q.flow.b, n, m)?;
            }
            if !(q.flow.f.is_empty() || q.flow.f.len() == n) {
                return Err(E::FlowOffset { mode: mode() });
            }
            check_finite(|| w("flow.f"), &q.flow.f)?;
            q.invariant
                .validate(n + m)
                .map_err(|problem| E::Invariant {
                    mode: mode(),
                    problem,
                })?;
        }
        for t in &self.transitions {
            let (from, to) = (|| t.from.clone(), || t.to.clone());
            for name in [&t.from, &t.to] {
                if !names.contains(name.as_str()) {
                    return Err(E::TransitionMode {
                        from: from(),
                        to: to(),
                        name: name.clone(),
                    });
                }
            }
            t.guard.0.validate(n + m).map_err(|problem| E::Guard {
                from: from(),
                to: to(),
                problem,
            })?;
            if !t.reset.r.is_empty() {
                check_rows(
                    &format!("transition {} -> {}: reset.r", t.from, t.to),
                    &t.reset.r,
                    n,
                    n,
                )?;
            }
            if !(t.reset.c.is_empty() || t.reset.c.len() == n) {
                return Err(E::ResetOffset {
                    from: from(),
                    to: to(),
                });
            }
            check_finite(
                || format!("transition {} -> {}: reset.c", t.from, t.to),
                &t.reset.c,
            )?;
        }
        if let Some(q) = &self.initial_mode
            && !names.contains(q.as_str())
        {
            return Err(E::InitialMode(q.clone()));
        }
        match &self.initial_state {
            InitialState::Given { state } if state.len() != n => Err(E::InitialStateLength {
                len: state.len(),
                states: n,
            }),
            InitialState::Given { state } => check_finite(|| "initial_state.state".into(), state),
            InitialState::ArxHistory { na, nb } if na.max(&1) + nb.saturating_sub(1) * m != n => {
                Err(E::ArxHistory)
            }
            _ => Ok(()),
        }
    }

    /// The discrete-time automaton equivalent to a PWARX model.
    ///
    /// State `x(k) = [y(k) .. y(k-n+1), u_i(k-1) .. u_i(k-nb+1)]` with
    /// `n = max(na, 1)`; input `u(k)`. Then `[x(k); u(k)]` holds the PWARX
    /// regressor of `y(k+1)`, so each region becomes an invariant and each
    /// mode's `theta` the first row of its dynamics; `y = x_1`.
    // Index arithmetic over state blocks reads clearer than iterators here.
    #[allow(clippy::needless_range_loop)]
    pub fn from_pwarx(p: &PwarxModel) -> Self {
        let (na, nb, m) = (p.na, p.nb, p.inputs);
        let ny = na.max(1);
        let nu = nb.saturating_sub(1);
        let n = ny + nu * m;
        let mut states: Vec<String> = (0..ny).map(|i| format!("y(k-{i})")).collect();
        for i in 0..m {
            for j in 1..=nu {
                states.push(format!("u{}(k-{j})", i + 1));
            }
        }
        let pos = arx_state_positions(&p.spec());
        let d = p.spec().dim();
        let modes = p
            .modes
            .iter()
            .enumerate()
            .map(|(qi, mode)| {
                let mut a = vec![vec![0.0; n]; n];
                let mut b = vec![vec![0.0; m]; n];
                let mut f = vec![0.0; n];
                for (r, &zi) in pos.iter().enumerate() {
                    if zi < n {
                        a[0][zi] += mode.theta[r];
                    } else {
                        b[0][zi - n] += mode.theta[r];
                    }
                }
                f[0] = mode.theta[d];
                for j in 1..ny {
                    a[j][j - 1] = 1.0;
                }
                for i in 0..m {
                    for j in 0..nu {
                        let row = ny + i * nu + j;
                        if j == 0 {
                            b[row][i] = 1.0;
                        } else {
                            a[row][row - 1] = 1.0;
                        }
                    }
                }
                let remap = |rows: &[Vec<f64>]| -> Vec<Vec<f64>> {
                    rows.iter()
                        .map(|r| {
                            let mut z = vec![0.0; n + m];
                            for (c, &zi) in pos.iter().enumerate() {
                                z[zi] += r[c];
                            }
                            z
                        })
                        .collect()
                };
                AutomatonMode {
                    name: super::mode_name(mode.name.as_deref(), qi),
                    flow: AffineDynamics { a, b, f },
                    invariant: Polyhedron {
                        a: remap(&mode.region.a),
                        b: mode.region.b.clone(),
                        a_eq: remap(&mode.region.a_eq),
                        b_eq: mode.region.b_eq.clone(),
                    },
                }
            })
            .collect();
        let mut c = vec![0.0; n];
        c[0] = 1.0;
        HybridAutomaton {
            time: TimeDomain::Discrete,
            internal_step: None,
            states,
            inputs: if p.info.input_names.len() == m {
                p.info.input_names.clone()
            } else {
                (1..=m).map(|i| format!("u{i}")).collect()
            },
            output: OutputMap {
                c,
                d: vec![],
                e: 0.0,
            },
            modes,
            transitions: vec![],
            initial_mode: None,
            initial_state: InitialState::ArxHistory { na, nb },
            info: p.info.clone(),
        }
    }
}

/// Where each PWARX regressor entry of `y(k+1)` sits in `z = [x(k); u(k)]`
/// of the automaton of [`HybridAutomaton::from_pwarx`]: `y(k-j)` is the
/// state `x_j`, `u_i(k)` the input `i`, `u_i(k-j)` (j >= 1) a state of
/// the input history.
pub fn arx_state_positions(spec: &RegressorSpec) -> Vec<usize> {
    let (na, nb, m) = (spec.na, spec.nb, spec.inputs);
    let ny = na.max(1);
    let nu = nb.saturating_sub(1);
    let n = ny + nu * m;
    let mut pos = Vec::with_capacity(spec.dim());
    for j in 0..na {
        pos.push(j); // y(k+1-(j+1)) = y(k-j) = x_j
    }
    for i in 0..m {
        for j in 1..=nb {
            // u_i(k+1-j): j = 1 is the current input, else state u_i(k-(j-1))
            pos.push(if j == 1 { n + i } else { ny + i * nu + (j - 2) });
        }
    }
    pos
}

impl HybridAutomaton {
    /// A PWARX model with known stops, as a discrete-time automaton in
    /// which every stop is a mode on a **lower-dimensional guard set**
    /// (`y = level`), not a full-dimensional region.
    ///
    /// For a stop at level `L` with bound `max` (the output never exceeds
    /// `L`; `min` mirrors every inequality):
    /// - mode `sat_max_L`: invariant `{ y(k) = L }`, flow holds the output at
    ///   `L` and shifts the lags;
    /// - from every ordinary mode, a crossing transition on the guard
    ///   `y = L` with the reset `y(k) := L, y(k-1) := L`: the position is held
    ///   at the stop and the velocity `y(k) - y(k-1)` is reset to zero (the
    ///   inelastic stop of Juloski et al., IFAC ADHS 2003, section 2);
    /// - back to ordinary mode `q`, a condition transition on
    ///   `region_q ∩ { theta_q . [x; 1] <= L }`: the dynamics of `q` pull away
    ///   from the stop;
    /// - the invariant of every ordinary mode gains the allowed side
    ///   `y <= L`, so a simulation that starts on or beyond the stop (a
    ///   measured initial output at rest there, or just past it by noise)
    ///   starts in the stop's mode.
    ///
    /// So a simulation never passes a known stop, and saturated segments
    /// are reproduced exactly.
    pub fn from_pwarx_with_stops(p: &PwarxModel, stops: &[Stop]) -> Self {
        let mut a = Self::from_pwarx(p);
        let n = a.states.len();
        let m = a.inputs.len();
        let ny = p.na.max(1);
        let ordinary: Vec<AutomatonMode> = a.modes.clone();
        for stop in stops {
            let (tag, sigma) = match stop.bound {
                StopBound::Max => ("max", 1.0),
                StopBound::Min => ("min", -1.0),
            };
            let name = format!("sat_{tag}_{}", stop.level);
            // Hold: the shift structure of any ordinary mode with row 0 = L.
            let mut flow = ordinary[0].flow.clone();
            flow.a[0] = vec![0.0; n];
            flow.b[0] = vec![0.0; m];
            flow.f = vec![0.0; n];
            flow.f[0] = stop.level;
            let mut on_stop = vec![0.0; n + m];
            on_stop[0] = 1.0;
            a.modes.push(AutomatonMode {
                name: name.clone(),
                flow,
                invariant: Polyhedron {
                    a: vec![],
                    b: vec![],
                    a_eq: vec![on_stop.clone()],
                    b_eq: vec![stop.level],
                },
            });
            let mut hold: Vec<(usize, f64)> = vec![(0, stop.level)];
            if ny >= 2 {
                hold.push((1, stop.level));
            }
            for q in &ordinary {
                a.transitions.push(Transition {
                    from: q.name.clone(),
                    to: name.clone(),
                    guard: GuardSet(Polyhedron {
                        a: vec![],
                        b: vec![],
                        a_eq: vec![on_stop.clone()],
                        b_eq: vec![stop.level],
                    }),
                    reset: ResetMap::assign(n, &hold),
                });
                let mut release: Vec<f64> = q.flow.a[0].iter().map(|v| sigma * v).collect();
                release.extend(q.flow.b[0].iter().map(|v| sigma * v));
                let mut guard = q.invariant.clone();
                guard.a.push(release);
                guard.b.push(sigma * (stop.level - q.flow.f[0]));
                a.transitions.push(Transition {
                    from: name.clone(),
                    to: q.name.clone(),
                    guard: GuardSet(guard),
                    reset: ResetMap::default(),
                });
            }
            // The ordinary modes live on the stop's allowed side, so a state
            // beyond it (a noisy measured initial output) lies in no
            // ordinary invariant and is held at the stop.
            let allowed: Vec<f64> = on_stop.iter().map(|v| sigma * v).collect();
            for q in a.modes.iter_mut().take(ordinary.len()) {
                q.invariant.a.push(allowed.clone());
                q.invariant.b.push(sigma * stop.level);
            }
        }
        a
    }

    /// The known stops of an automaton built by
    /// [`HybridAutomaton::from_pwarx_with_stops`], read back from its
    /// structure: a stop is a mode whose invariant is the single equality
    /// `x_1 = L` on the output state (a lower-dimensional set) and whose
    /// flow holds `x_1` at `L`; its side is the one the other modes'
    /// invariants allow (`x_1 <= L`: a `max` stop). Empty for an automaton
    /// without such modes.
    pub fn stops(&self) -> Vec<Stop> {
        let width = self.states.len() + self.inputs.len();
        let is_output_row = |row: &[f64], sign: f64| {
            row.len() == width
                && row
                    .iter()
                    .enumerate()
                    .all(|(j, &v)| v == if j == 0 { sign } else { 0.0 })
        };
        let holds_output = |m: &AutomatonMode, level: f64| {
            m.flow
                .a
                .first()
                .is_some_and(|r| r.iter().all(|&v| v == 0.0))
                && m.flow.b.first().is_none_or(|r| r.iter().all(|&v| v == 0.0))
                && m.flow.f.first() == Some(&level)
        };
        let output_is_first_state = self.output.c.first() == Some(&1.0)
            && self.output.c.iter().skip(1).all(|&v| v == 0.0)
            && self.output.d.iter().all(|&v| v == 0.0)
            && self.output.e == 0.0;
        if !output_is_first_state {
            return Vec::new();
        }
        let mut stops = Vec::new();
        for m in &self.modes {
            let inv = &m.invariant;
            let [row] = inv.a_eq.as_slice() else {
                continue;
            };
            let level = inv.b_eq[0];
            if !inv.a.is_empty() || !is_output_row(row, 1.0) || !holds_output(m, level) {
                continue;
            }
            let allows = |sign: f64| {
                self.modes.iter().any(|o| {
                    o.invariant
                        .a
                        .iter()
                        .zip(&o.invariant.b)
                        .any(|(r, &b)| is_output_row(r, sign) && b == sign * level)
                })
            };
            let bound = if allows(1.0) {
                StopBound::Max
            } else if allows(-1.0) {
                StopBound::Min
            } else {
                continue;
            };
            stops.push(Stop {
                level,
                bound,
                tol: None,
            });
        }
        stops
    }

    /// The PWARX model an automaton of
    /// [`HybridAutomaton::from_pwarx_with_stops`] was built from, read back:
    /// the modes not on a stop, with the first row of each flow as `theta`
    /// and the invariant without the rows the stops added as the region.
    /// `None` when the automaton is not of that structure, checked by
    /// building it again from the answer.
    pub fn ordinary_pwarx(&self) -> Option<PwarxModel> {
        let InitialState::ArxHistory { na, nb } = self.initial_state else {
            return None;
        };
        let stops = self.stops();
        let spec = RegressorSpec::new(na, nb, self.inputs.len());
        let pos = arx_state_positions(&spec);
        let n = self.states.len();
        let ordinary = self.modes.len().checked_sub(stops.len())?;
        let regressor_rows = |rows: &[Vec<f64>]| -> Option<Vec<Vec<f64>>> {
            rows.iter()
                .map(|z| pos.iter().map(|&zi| z.get(zi).copied()).collect())
                .collect()
        };
        let mut modes = Vec::with_capacity(ordinary);
        for (qi, q) in self.modes[..ordinary].iter().enumerate() {
            let (a0, b0) = (q.flow.a.first()?, q.flow.b.first()?);
            let mut theta: Vec<f64> = pos
                .iter()
                .map(|&zi| if zi < n { a0.get(zi) } else { b0.get(zi - n) }.copied())
                .collect::<Option<_>>()?;
            theta.push(*q.flow.f.first()?);
            let own = q.invariant.a.len().checked_sub(stops.len())?;
            let name = (q.name != mode_name(None, qi)).then(|| q.name.clone());
            modes.push(PwarxMode {
                theta,
                region: Polyhedron {
                    a: regressor_rows(&q.invariant.a[..own])?,
                    b: q.invariant.b.get(..own)?.to_vec(),
                    a_eq: regressor_rows(&q.invariant.a_eq)?,
                    b_eq: q.invariant.b_eq.clone(),
                },
                name,
            });
        }
        let p = PwarxModel {
            na,
            nb,
            inputs: self.inputs.len(),
            modes,
            info: self.info.clone(),
        };
        (Self::from_pwarx_with_stops(&p, &stops) == *self).then_some(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_lists_of_modes_are_checked_by_name() {
        let p = PwarxModel {
            na: 1,
            nb: 1,
            inputs: 1,
            modes: vec![crate::model::PwarxMode {
                theta: vec![0.5, 0.1, 0.0],
                region: Polyhedron::default(),
                name: None,
            }],
            info: ModelInfo::default(),
        };
        let mut a = HybridAutomaton::from_pwarx(&p);
        let q = a.modes[0].clone();
        a.modes.extend((0..50_000).map(|i| AutomatonMode {
            name: format!("m{i}"),
            ..q.clone()
        }));
        assert_eq!(a.validate(), Ok(()));
        // A transition to the last mode, then to none; a name repeated last.
        let t = Transition {
            from: q.name.clone(),
            to: "m49999".into(),
            guard: GuardSet(Polyhedron::default()),
            reset: ResetMap::default(),
        };
        a.transitions.push(t.clone());
        assert_eq!(a.validate(), Ok(()));
        a.transitions.push(Transition {
            to: "m50000".into(),
            ..t
        });
        assert!(
            matches!(a.validate(), Err(InvalidModel::TransitionMode { name, .. }) if name == "m50000")
        );
        a.transitions.pop();
        a.modes.push(AutomatonMode {
            name: "m7".into(),
            ..q
        });
        assert_eq!(a.validate(), Err(InvalidModel::DuplicateMode("m7".into())));
        let last = a.modes.len() - 1;
        a.modes[last].name = " ".into();
        assert_eq!(
            a.validate(),
            Err(InvalidModel::EmptyModeName { mode: last })
        );
    }

    #[test]
    fn stops_are_read_back_from_the_automaton() {
        let theta = vec![0.5, 0.1, 0.2, 0.3, 0.0];
        let p = PwarxModel {
            na: 2,
            nb: 2,
            inputs: 1,
            modes: vec![crate::model::PwarxMode {
                theta,
                region: Polyhedron::default(),
                name: None,
            }],
            info: ModelInfo::default(),
        };
        let stops = vec![
            Stop {
                level: 1.5,
                bound: StopBound::Max,
                tol: None,
            },
            Stop {
                level: -0.25,
                bound: StopBound::Min,
                tol: None,
            },
        ];
        let a = HybridAutomaton::from_pwarx_with_stops(&p, &stops);
        assert_eq!(a.stops(), stops);
        assert!(HybridAutomaton::from_pwarx(&p).stops().is_empty());
    }

    #[test]
    fn the_pwarx_model_is_read_back_from_its_automaton() {
        let half = |sign: f64| Polyhedron {
            a: vec![vec![sign, 0.5, -1.0, 0.0]],
            b: vec![0.25],
            a_eq: vec![],
            b_eq: vec![],
        };
        let p = PwarxModel {
            na: 2,
            nb: 2,
            inputs: 1,
            modes: vec![
                PwarxMode {
                    theta: vec![0.5, 0.1, 0.2, 0.3, -0.4],
                    region: half(1.0),
                    name: Some("free".into()),
                },
                PwarxMode {
                    theta: vec![1.2, -0.3, 0.7, 0.0, 0.05],
                    region: half(-1.0),
                    name: None,
                },
            ],
            info: ModelInfo::default(),
        };
        let stops = vec![Stop {
            level: 2.0,
            bound: StopBound::Max,
            tol: None,
        }];
        let with_stops = HybridAutomaton::from_pwarx_with_stops(&p, &stops);
        assert_eq!(with_stops.ordinary_pwarx().as_ref(), Some(&p));
        assert_eq!(HybridAutomaton::from_pwarx(&p).ordinary_pwarx(), Some(p));
        // A flow that is not the shift of an ARX history has no PWARX model.
        let mut other = with_stops;
        other.modes[0].flow.a[1][1] = 0.5;
        assert_eq!(other.ordinary_pwarx(), None);
    }

    #[test]
    fn reset_assigns_and_keeps() {
        let r = ResetMap::assign(2, &[(1, 0.0)]);
        let mut x = [3.0, -7.0];
        r.apply(&mut x);
        assert_eq!(x, [3.0, 0.0]);
        let mut y = [1.0, 2.0];
        ResetMap::default().apply(&mut y);
        assert_eq!(y, [1.0, 2.0]);
    }
}
