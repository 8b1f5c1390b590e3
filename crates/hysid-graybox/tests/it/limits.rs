//! Files a program generated, or a user received: each limit of
//! `docs/gray-box-models.md` ("Limits") refused with a clear error at its
//! boundary, and definitions written out once each, whatever their number.

use hysid_graybox::compile::{
    MAX_DEFINITIONS, MAX_ELEMENTS, MAX_MODE_DEFINITIONS, MAX_MODES, MAX_OPERATIONS, Problem,
};
use hysid_graybox::expr::{ExprError, MAX_LENGTH, MAX_NESTING};
use hysid_graybox::{CompiledModel, GrayBoxModel, InvalidGrayBox};
use hysid_model::data::{Dataset, Signal};
use hysid_model::simulate::SimulationOptions;

use crate::from_toml;

/// A model of the states `v0, v1, ..` (`v0` the output), the input `u`
/// and the parameter `a`, with `definitions` and one mode `only` whose
/// flows are `flows`, written as a TOML file is (without its `kind`).
fn model(flows: &[String], definitions: &[(String, String)], extra: &str) -> GrayBoxModel {
    let states: Vec<String> = (0..flows.len()).map(|i| format!("\"v{i}\"")).collect();
    let mut text = format!(
        "format = 1\ninternal_step = 0.001\nstates = [{}]\ninputs = [\"u\"]\n\
         outputs = [{{ name = \"y\", value = \"v0\" }}]\n\
         initial_state = {{ from = \"given\", values = {{ v0 = 0.5 }} }}\n\
         [[parameters]]\nname = \"a\"\nvalue = 1.0\nbounds = [0.0, 2.0]\n{extra}\n",
        states.join(", ")
    );
    text.push_str("[definitions]\n");
    for (name, value) in definitions {
        text.push_str(&format!("{name} = \"{value}\"\n"));
    }
    text.push_str("\n[[modes]]\nname = \"only\"\nflow = { ");
    let flows: Vec<String> = flows
        .iter()
        .enumerate()
        .map(|(i, f)| format!("v{i} = \"{f}\""))
        .collect();
    text.push_str(&flows.join(", "));
    text.push_str(" }\n");
    from_toml(&text, None)
}

/// `zz0 = "-a*v0 + u"` and `zz{i} = "zz{i-1} + 0"` up to `zz{n-1}`.
fn chain(n: usize) -> Vec<(String, String)> {
    (0..n)
        .map(|i| match i {
            0 => ("zz0".to_string(), "-a*v0 + u".to_string()),
            i => (format!("zz{i}"), format!("zz{} + 0", i - 1)),
        })
        .collect()
}

fn error(m: &GrayBoxModel) -> InvalidGrayBox {
    CompiledModel::new(m).unwrap_err()
}

#[test]
fn a_flow_of_200_000_terms_or_parentheses_is_refused_by_its_length() {
    let terms = format!("-a*v0 + u{}", " + 0".repeat(200_000));
    let parens = format!("{}-a*v0 + u{}", "(".repeat(200_000), ")".repeat(200_000));
    for flow in [terms, parens] {
        let e = error(&model(std::slice::from_ref(&flow), &[], ""));
        assert_eq!(e.place, "mode 'only', flow of 'v0'");
        assert_eq!(e.text.as_deref(), Some(flow.as_str()));
        assert_eq!(
            e.problem,
            Problem::Expression(ExprError::TooLong(flow.len()))
        );
        assert!(
            e.to_string()
                .contains(&format!("the limit is {MAX_LENGTH}"))
        );
    }
}

#[test]
fn parentheses_are_refused_past_the_nesting_limit() {
    let nested = |n: usize| format!("{}u - a*v0{}", "(".repeat(n), ")".repeat(n));
    assert!(CompiledModel::new(&model(&[nested(MAX_NESTING)], &[], "")).is_ok());
    let e = error(&model(&[nested(MAX_NESTING + 1)], &[], ""));
    assert_eq!(e.problem, Problem::Expression(ExprError::TooNested));
    assert!(
        e.to_string()
            .contains(&format!("more than {MAX_NESTING} deep"))
    );
}

#[test]
fn a_chain_of_definitions_is_written_out_once() {
    let e = error(&model(&["zz19999".into()], &chain(20_000), ""));
    assert_eq!(e.place, "definitions");
    assert_eq!(
        e.problem,
        Problem::TooMany {
            what: "definitions",
            count: 20_000,
            limit: MAX_DEFINITIONS
        }
    );
    // At the limit: the flow is the first definition and one addition of
    // zero per link (6 + 2 (n - 1) operations).
    let n = MAX_DEFINITIONS;
    let m = model(&[format!("zz{}", n - 1)], &chain(n), "");
    let c = CompiledModel::new(&m).unwrap();
    assert_eq!(c.modes[0].flow[0].operations(), 6 + 2 * (n - 1));
    // It simulates as the first definition does on its own (adding zero
    // changes no value here).
    let direct = model(&["-a*v0 + u".into()], &[], "");
    let data = Dataset::new(
        vec![Signal {
            name: "u".into(),
            values: (0..20).map(|k| (k % 7) as f64 - 3.0).collect(),
        }],
        Signal {
            name: "y".into(),
            values: vec![0.0; 20],
        },
        Some(0.01),
    )
    .unwrap();
    let run = |m: &GrayBoxModel| {
        hysid_graybox::simulate(m, &data, SimulationOptions::default())
            .unwrap()
            .y
    };
    let (y, y_direct) = (run(&m), run(&direct));
    assert!(y.iter().any(|v| *v != 0.5));
    assert_eq!(
        y.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        y_direct.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    );
}

#[test]
fn a_model_whose_expressions_hold_too_many_operations_is_refused() {
    // Each flow is the chain at the limit written out: 20 004 operations,
    // fifty of them more than the limit.
    let n = MAX_DEFINITIONS;
    let per_flow = 6 + 2 * (n - 1);
    let flows = MAX_OPERATIONS / per_flow + 1;
    let e = error(&model(&vec![format!("zz{}", n - 1); flows], &chain(n), ""));
    assert_eq!(e.problem, Problem::TooLarge);
    assert_eq!(e.place, format!("mode 'only', flow of 'v{}'", flows - 1));
    // One flow fewer fits.
    let m = model(&vec![format!("zz{}", n - 1); flows - 1], &chain(n), "");
    assert!(CompiledModel::new(&m).is_ok());
}

#[test]
fn modes_and_elements_are_counted() {
    let mut m = model(&["-a*v0 + u".into()], &[], "");
    let only = m.modes[0].clone();
    m.modes = (0..=MAX_MODES)
        .map(|i| {
            let mut q = only.clone();
            q.name = format!("m{i}");
            q
        })
        .collect();
    assert_eq!(
        error(&m).problem,
        Problem::TooMany {
            what: "modes",
            count: MAX_MODES + 1,
            limit: MAX_MODES
        }
    );
    m.modes.truncate(MAX_MODES);
    assert!(CompiledModel::new(&m).is_ok());
    let stops: String = (0..=MAX_ELEMENTS)
        .map(|i| {
            format!(
                "[[elements]]\ntype = \"stop\"\nname = \"s{i}\"\nposition = \"v0\"\n\
                 velocity = \"v0\"\nat = \"a\"\nside = \"max\"\nmode = \"rest{i}\"\n"
            )
        })
        .collect();
    let m = model(&["-a*v0 + u".into()], &[], &stops);
    assert_eq!(
        error(&m).problem,
        Problem::TooMany {
            what: "elements",
            count: MAX_ELEMENTS + 1,
            limit: MAX_ELEMENTS
        }
    );
}

#[test]
fn modes_with_definitions_of_their_own_are_counted_with_the_definitions() {
    // Each mode gives its own first link of a chain at the limit: the
    // modes times the definitions, at the limit and one mode past it.
    let n = MAX_DEFINITIONS;
    let mut m = model(&["u - a*v0".into()], &chain(n), "");
    let only = m.modes[0].clone();
    let modes = |count: usize| {
        (0..count)
            .map(|i| {
                let mut q = only.clone();
                q.name = format!("m{i}");
                q.definitions
                    .insert("zz0".into(), format!("-a*v0 + u + {i}"));
                q
            })
            .collect()
    };
    let fit = MAX_MODE_DEFINITIONS / n;
    m.modes = modes(fit + 1);
    assert_eq!(
        error(&m).problem,
        Problem::ModeDefinitions {
            modes: fit + 1,
            definitions: n
        }
    );
    m.modes = modes(fit);
    assert!(CompiledModel::new(&m).is_ok());
}
