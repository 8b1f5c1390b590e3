//! A model in words and equations, as `hysid show` prints it: its signals
//! and provenance (method, seed, samples, the options `--auto` chose), then
//! what it says of the system:
//!
//! - a PWARX model: each mode's ARX equation and its region as
//!   inequalities of the regressors (equalities: a lower-dimensional
//!   guard set, a saturation);
//! - a hybrid automaton: its output map, each mode's affine flow and
//!   invariant, each transition's guard set and reset map;
//! - a physical model: its parameters with their units and, once fitted,
//!   standard errors, 95 % intervals and what the rows determine of them
//!   (`hysid_physical::diagnostics`); its stops, and a gray-box model's
//!   flows and transitions as its file writes them.

use hysid_core::model::{Model, signed_sum};
use hysid_graybox::GrayBoxModel;
use hysid_model::data::{DEFAULT_INPUT, DEFAULT_OUTPUT};
use hysid_model::geometry::Polyhedron;
use hysid_model::model::{
    HybridAutomaton, ModelInfo, PhysicalParameter, PwarxModel, StopBound, TimeDomain,
};
use hysid_physical::diagnostics::PhysicalDiagnostics;
use std::fmt::Write;

/// `model` as text; the first line starts with its kind.
pub fn describe(model: &Model) -> String {
    let mut s = String::new();
    let name = match model {
        Model::Mechanical(m) if !m.name.is_empty() => format!(" \"{}\"", m.name),
        Model::GrayBox(m) if !m.name.is_empty() => format!(" \"{}\"", m.name),
        _ => String::new(),
    };
    let modes = model.mode_names();
    let _ = writeln!(
        s,
        "{} model{name}, {} mode(s): {}",
        model.kind(),
        modes.len(),
        modes.join(", ")
    );
    let names = Names::of(model);
    let ts = (model.info().ts).map_or_else(String::new, |ts| format!(", ts = {} s", number(ts)));
    let _ = writeln!(
        s,
        "  signals: {} -> {}{ts}",
        names.inputs.join(", "),
        names.output
    );
    provenance(&mut s, model.info());
    s.push('\n');
    match model {
        Model::Pwarx(m) => pwarx(&mut s, m, &names),
        Model::HybridAutomaton(m) => automaton(&mut s, m),
        Model::Mechanical(m) => {
            parameters(&mut s, &m.parameters, &m.info);
            stops(&mut s, model, "position");
        }
        Model::GrayBox(m) => {
            gray_box(&mut s, m);
            stops(&mut s, model, "output");
        }
    }
    s
}

/// The names a model's equations read its signals by: those it was
/// identified on, else those its file declares, else `u` (`u1`, `u2`,
/// ... for several) and `y`.
struct Names {
    inputs: Vec<String>,
    output: String,
}

impl Names {
    fn of(model: &Model) -> Self {
        let own = model.signal_names();
        let inputs = own.inputs.unwrap_or_else(|| match model.inputs() {
            1 => vec![DEFAULT_INPUT.to_string()],
            m => (1..=m).map(|i| format!("{DEFAULT_INPUT}{i}")).collect(),
        });
        Names {
            inputs,
            output: own.output.unwrap_or_else(|| DEFAULT_OUTPUT.to_string()),
        }
    }
}

/// How the model came about: the back-end, its seed and samples, and the
/// options an automatic selection chose, with their selection-row FIT.
fn provenance(s: &mut String, info: &ModelInfo) {
    if info.method.is_empty() {
        return;
    }
    let seed = info
        .seed
        .map_or_else(String::new, |k| format!(", seed {k}"));
    let samples = (info.diagnostics.samples).map_or_else(String::new, |n| format!(", {n} samples"));
    let _ = writeln!(s, "  identified by {}{seed}{samples}", info.method);
    if let Some(sel) = &info.selection {
        let values: Vec<String> = (sel.chosen_values().iter())
            .map(|(k, v)| format!("{k} = {v}"))
            .collect();
        let rows: Vec<&str> = sel.splits.iter().map(|r| r.select_rows.as_str()).collect();
        let score = (sel.candidates.get(sel.chosen).and_then(|c| c.fit_sim))
            .map_or_else(String::new, |f| format!(": selection FIT {f:.2} %"));
        let _ = writeln!(
            s,
            "  options chosen on the selection rows {}: {}{score}",
            rows.join(", "),
            values.join(", ")
        );
    }
    for status in &info.diagnostics.status {
        let _ = writeln!(s, "  status: {status}");
    }
}

/// Each mode's equation `y(k) = a1 y(k-1) + ... + c` and its region.
fn pwarx(s: &mut String, m: &PwarxModel, names: &Names) {
    let y = &names.output;
    let mut regressors: Vec<String> = (1..=m.na).map(|j| format!("{y}(k-{j})")).collect();
    for u in &names.inputs {
        regressors.extend((1..=m.nb).map(|j| format!("{u}(k-{j})")));
    }
    for (i, mode) in m.modes.iter().enumerate() {
        let name = hysid_model::model::mode_name(mode.name.as_deref(), i);
        let (terms, c) = mode.theta.split_at(mode.theta.len().saturating_sub(1));
        let equation = linear(terms, &regressors, c.first().copied().unwrap_or(0.0));
        let _ = writeln!(s, "{}: {y}(k) = {equation}", mode_label(&name));
        region(s, &mode.region, &regressors, "  where");
    }
}

/// A hybrid automaton's output map, flows, invariants and transitions; its
/// sets live in `[x; u]`.
fn automaton(s: &mut String, m: &HybridAutomaton) {
    let mut z = m.states.clone();
    z.extend(m.inputs.iter().cloned());
    let mut output = m.output.c.clone();
    output.resize(m.states.len(), 0.0);
    output.extend(&m.output.d);
    let _ = writeln!(s, "output: y = {}", linear(&output, &z, m.output.e));
    let next = |x: &str| match m.time {
        TimeDomain::Discrete => format!("next {x}"),
        TimeDomain::Continuous => format!("{x}'"),
    };
    // Rows a file leaves out (no input, no offset, an identity reset)
    // read as the simulator reads them.
    let row = |rows: &[Vec<f64>], i: usize, n: usize| rows.get(i).cloned().unwrap_or(vec![0.0; n]);
    let (n, inputs) = (m.states.len(), m.inputs.len());
    for mode in &m.modes {
        let _ = writeln!(s, "{}:", mode_label(&mode.name));
        for (i, x) in m.states.iter().enumerate() {
            let flow = &mode.flow;
            let mut a = row(&flow.a, i, n);
            a.extend(row(&flow.b, i, inputs));
            let f = flow.f.get(i).copied().unwrap_or(0.0);
            let _ = writeln!(s, "  {} = {}", next(x), linear(&a, &z, f));
        }
        region(s, &mode.invariant, &z, "  invariant");
    }
    for t in &m.transitions {
        let _ = writeln!(s, "transition {} -> {}:", t.from, t.to);
        region(s, &t.guard.0, &z, "  guard");
        for (i, x) in m.states.iter().enumerate() {
            let identity: Vec<f64> = (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect();
            let r = if t.reset.r.is_empty() {
                identity
            } else {
                row(&t.reset.r, i, n)
            };
            let reset = linear(&r, &m.states, t.reset.c.get(i).copied().unwrap_or(0.0));
            if reset != *x {
                let _ = writeln!(s, "  reset {x} := {reset}");
            }
        }
    }
}

/// `mode NAME`, or the name alone where it says so itself (`mode 2`, the
/// name of an unnamed mode).
fn mode_label(name: &str) -> String {
    if name.starts_with("mode ") {
        name.to_string()
    } else {
        format!("mode {name}")
    }
}

/// A physical model's stops ([`Model::stops`]), each a bound on `what`.
fn stops(s: &mut String, model: &Model, what: &str) {
    for stop in model.stops() {
        let side = match stop.bound {
            StopBound::Max => "<=",
            StopBound::Min => ">=",
        };
        let _ = writeln!(s, "stop: {what} {side} {}", number(stop.level));
    }
}

/// A gray-box model's parameters, flows and transitions, as its file
/// writes them.
fn gray_box(s: &mut String, m: &GrayBoxModel) {
    parameters(s, &m.parameters, &m.info);
    for output in &m.outputs {
        let _ = writeln!(s, "output: {} = {}", output.name, output.value);
    }
    for (name, value) in &m.definitions {
        let _ = writeln!(s, "{name} = {value}");
    }
    for mode in &m.modes {
        let flows: Vec<String> = (mode.flow.iter())
            .map(|(x, f)| format!("{x}' = {f}"))
            .collect();
        let _ = writeln!(s, "{}: {}", mode_label(&mode.name), flows.join(", "));
        for (name, value) in &mode.definitions {
            let _ = writeln!(s, "  {name} = {value}");
        }
        for condition in &mode.invariant {
            let _ = writeln!(s, "  invariant {condition}");
        }
    }
    for t in &m.transitions {
        let when = (t.when.as_ref()).map_or_else(String::new, |w| format!(" when {w}"));
        let resets: Vec<String> = (t.reset.iter())
            .map(|(x, e)| format!("{x} := {e}"))
            .collect();
        let reset = if resets.is_empty() {
            String::new()
        } else {
            format!(", {}", resets.join(", "))
        };
        let _ = writeln!(
            s,
            "transition {} -> {}: {}{when}{reset}",
            t.from, t.to, t.guard
        );
    }
}

/// A physical model's parameters: value and unit, and once fitted
/// (`info.diagnostics` of the `physical` back-end) the standard error, the
/// 95 % interval and what the identification rows determine; fixed ones
/// say so. Then the initial states the fit estimated, and its cost.
fn parameters(s: &mut String, parameters: &[PhysicalParameter], info: &ModelInfo) {
    let fitted = PhysicalDiagnostics::of(&info.diagnostics);
    let mut rows = vec![[
        "parameter".to_string(),
        "value".to_string(),
        "unit".to_string(),
        "std error".to_string(),
        "95 % interval".to_string(),
        "identifiability".to_string(),
    ]];
    for p in parameters {
        let diagnosed = fitted.as_ref().and_then(|d| d.parameters.get(&p.name));
        let (error, interval, said) = match diagnosed {
            _ if p.fixed => (String::new(), String::new(), "fixed".to_string()),
            Some(d) => (
                d.std_error.map_or_else(String::new, number),
                (d.ci95).map_or_else(String::new, |[lo, hi]| {
                    format!("[{}, {}]", number(lo), number(hi))
                }),
                (d.identifiability).map_or_else(String::new, |i| {
                    serde_json::to_value(i)
                        .ok()
                        .and_then(|v| v.as_str().map(str::to_string))
                        .unwrap_or_default()
                        .replace('_', " ")
                }),
            ),
            None => (String::new(), String::new(), String::new()),
        };
        rows.push([
            p.name.clone(),
            number(p.value),
            p.unit.clone(),
            error,
            interval,
            said,
        ]);
    }
    table(s, &rows);
    let Some(d) = fitted else {
        return;
    };
    for (state, value) in &d.initial_states {
        let _ = writeln!(s, "initial state (estimated): {state} = {}", number(*value));
    }
    let _ = writeln!(
        s,
        "free-run cost {} (RMSE {}) on the identification rows",
        number(d.cost),
        number(d.rmse_fit)
    );
}

/// `rows` in columns, each as wide as its widest entry (the last column's
/// trailing spaces left out).
fn table(s: &mut String, rows: &[[String; 6]]) {
    let widths: Vec<usize> = (0..6)
        .map(|j| rows.iter().map(|r| r[j].chars().count()).max().unwrap_or(0))
        .collect();
    for row in rows {
        let line: Vec<String> = (row.iter().zip(&widths))
            .map(|(cell, &w)| format!("{cell:<w$}"))
            .collect();
        let _ = writeln!(s, "{}", line.join("  ").trim_end());
    }
}

/// The region `p` as one line per inequality (`a . x <= b`) and equality
/// (`a . x = b`) of the names `x`, the first led by `lead`; `everywhere`
/// for a region without rows.
fn region(s: &mut String, p: &Polyhedron, x: &[String], lead: &str) {
    let rows = (p.a.iter().zip(&p.b).map(|(a, b)| (a, b, "<=")))
        .chain(p.a_eq.iter().zip(&p.b_eq).map(|(a, b)| (a, b, "=")));
    let pad = " ".repeat(lead.len());
    let mut any = false;
    for (k, (a, b, relation)) in rows.enumerate() {
        let lead = if k == 0 { lead } else { &pad };
        let _ = writeln!(s, "{lead} {} {relation} {}", linear(a, x, 0.0), number(*b));
        any = true;
    }
    if !any {
        let _ = writeln!(s, "{lead} everywhere");
    }
}

/// `c1 x1 + c2 x2 ... + c0` with the zero coefficients left out (`0` when
/// every term is), signs folded into the operators ([`signed_sum`]).
fn linear(coefficients: &[f64], x: &[String], constant: f64) -> String {
    let terms: Vec<(bool, String)> = (coefficients.iter().zip(x))
        .filter(|(c, _)| **c != 0.0)
        .map(|(c, x)| match c.abs() {
            1.0 => (*c > 0.0, x.clone()),
            m => (*c > 0.0, format!("{} {x}", number(m))),
        })
        .chain((constant != 0.0).then(|| (constant > 0.0, number(constant.abs()))))
        .collect();
    signed_sum(&terms)
}

/// `v` with six significant digits: plain where `1e-4 <= |v| < 1e6`
/// (trailing zeros dropped), else with an exponent.
fn number(v: f64) -> String {
    let m = v.abs();
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    if !(1e-4..1e6).contains(&m) {
        return format!("{v:.5e}");
    }
    let decimals = (5 - m.log10().floor() as i32).max(0) as usize;
    let text = format!("{v:.decimals$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_keep_six_significant_digits() {
        assert_eq!(number(1.523456789), "1.52346");
        assert_eq!(number(0.0103), "0.0103");
        assert_eq!(number(-154116.44), "-154116");
        assert_eq!(number(146.2), "146.2");
        assert_eq!(number(2.5e-7), "2.50000e-7");
        assert_eq!(number(0.0), "0");
    }

    #[test]
    fn linear_forms_fold_signs_and_leave_zeros_out() {
        let x = ["a".to_string(), "b".to_string(), "c".to_string()];
        assert_eq!(linear(&[1.5, 0.0, -2.0], &x, 0.25), "1.5 a - 2 c + 0.25");
        assert_eq!(linear(&[-1.0, 1.0, 0.0], &x, -3.0), "-a + b - 3");
        assert_eq!(linear(&[0.0, 0.0, 0.0], &x, 0.0), "0");
    }
}
