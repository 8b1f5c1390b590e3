//! Gray-box model files built from a structure: states, inputs,
//! parameters, definitions (a chain of them up to 20 000 long, past the
//! limit), modes with their own definitions and labels (the last one
//! copied up to past the mode limit), transitions, elements, written as TOML with
//! expressions from shapes that reach the length and nesting limits. The
//! text goes through the model reader (`Model::from_toml`): a file that
//! reads writes JSON that reads back to the same model, and simulates
//! briefly when its compiled expressions are small. Never a panic, never
//! a stack overflow.
#![no_main]

#[path = "models.rs"]
mod models;
#[path = "shapes.rs"]
mod shapes;

use hysid_core::model::Model;
use hysid_graybox::CompiledModel;
use libfuzzer_sys::arbitrary::{self, Arbitrary};
use libfuzzer_sys::fuzz_target;
use shapes::{Shape, Size};
use toml::{Table, Value};

#[derive(Arbitrary, Debug)]
struct File {
    states: u8,
    inputs: u8,
    parameters: Vec<f64>,
    definitions: Vec<Shape>,
    /// `c0 = first`, `c_i = c_(i-1) + (next)`: [`Size`] links.
    chain: Option<(Size, Shape, Shape)>,
    modes: Vec<Mode>,
    /// Copies of the last mode (named apart).
    copies: Size,
    transitions: Vec<Transition>,
    elements: Vec<Element>,
    output: Shape,
    energy: Option<Shape>,
    step: u8,
}

#[derive(Arbitrary, Debug)]
struct Mode {
    flows: Vec<Shape>,
    invariant: Vec<(Shape, u8, Shape)>,
    /// Its own values of definitions, by index.
    definitions: Vec<(u8, Shape)>,
    /// Its label: another mode's name (`true`) or a label of its own.
    label: Option<(bool, u8)>,
    /// `element_modes`: an element (by index, past the last: one that is
    /// not there) and a label of its own or another mode's name.
    element_modes: Vec<(u8, bool, u8)>,
}

#[derive(Arbitrary, Debug)]
struct Transition {
    from: u8,
    to: u8,
    guard: (Shape, u8, Shape),
    when: Option<Shape>,
    reset: Vec<(u8, Shape)>,
}

#[derive(Arbitrary, Debug)]
enum Element {
    Friction {
        velocity: u8,
        kinetic: Shape,
        static_level: Shape,
    },
    Stop {
        position: u8,
        velocity: u8,
        at: Shape,
        max: bool,
        restitution: Shape,
    },
}

/// `a op b`, a relation.
fn relation((a, op, b): &(Shape, u8, Shape), names: &[String]) -> String {
    let op = [">=", "<=", "==", ">", "<"][usize::from(*op) % 5];
    format!("{} {op} {}", a.text(names), b.text(names))
}

fn strings(items: impl IntoIterator<Item = String>) -> Value {
    Value::Array(items.into_iter().map(Value::String).collect())
}

fn table(entries: impl IntoIterator<Item = (String, Value)>) -> Value {
    Value::Table(entries.into_iter().collect())
}

fn pick(names: &[String], i: u8) -> String {
    names[usize::from(i) % names.len()].clone()
}

fn text(file: &File) -> Option<String> {
    let states: Vec<String> = (0..1 + file.states % 4).map(|i| format!("s{i}")).collect();
    let inputs: Vec<String> = (0..file.inputs % 3).map(|i| format!("u{i}")).collect();
    let parameters: Vec<String> = (0..file.parameters.len().min(6))
        .map(|i| format!("p{i}"))
        .collect();
    // At most 20 000 links, and about 1 MB of chain text (each link is
    // its `next` again).
    let links = file.chain.as_ref().map_or(0, |c| {
        let next = c.2.text(&[]).len();
        c.0.get().min(20_000).min(1_000_000 / (next + 8))
    });
    let definitions: Vec<String> = (0..file.definitions.len().min(8))
        .map(|i| format!("d{i}"))
        .chain((0..links).map(|i| format!("c{i}")))
        .collect();
    let names: Vec<String> = [&states, &inputs, &parameters, &definitions]
        .into_iter()
        .flatten()
        .cloned()
        .chain(["nope".to_string()])
        .collect();

    let mut doc = Table::new();
    doc.insert("kind".into(), "gray_box".into());
    doc.insert("format".into(), 1.into());
    doc.insert(
        "internal_step".into(),
        (0.01 / f64::from(1 + file.step % 10)).into(),
    );
    doc.insert("states".into(), strings(states.clone()));
    doc.insert("inputs".into(), strings(inputs.clone()));
    doc.insert(
        "outputs".into(),
        Value::Array(vec![table([
            ("name".into(), "y".into()),
            ("value".into(), file.output.text(&names).into()),
        ])]),
    );
    doc.insert(
        "initial_state".into(),
        table([
            ("from".into(), "given".into()),
            ("values".into(), table([(states[0].clone(), 0.0.into())])),
        ]),
    );
    doc.insert(
        "parameters".into(),
        Value::Array(
            parameters
                .iter()
                .zip(&file.parameters)
                .map(|(name, &v)| {
                    let v = if v.is_finite() { v } else { 0.0 };
                    table([
                        ("name".into(), name.clone().into()),
                        ("value".into(), v.into()),
                        ("bounds".into(), Value::Array(vec![(v - 1.0).into(), (v + 1.0).into()])),
                    ])
                })
                .collect(),
        ),
    );
    let mut written: Table = file
        .definitions
        .iter()
        .zip(&definitions)
        .map(|(d, name)| (name.clone(), d.text(&names).into()))
        .collect();
    if let Some((_, first, next)) = &file.chain {
        let (first, next) = (first.text(&names), next.text(&names));
        for i in 0..links {
            let text = match i {
                0 => first.clone(),
                i => format!("c{} + ({next})", i - 1),
            };
            written.insert(format!("c{i}"), text.into());
        }
    }
    doc.insert("definitions".into(), Value::Table(written));
    let mode = |(i, q): (usize, &Mode)| {
        let flow: Table = states
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let text = q.flows.get(k).map_or_else(|| "0".to_string(), |f| f.text(&names));
                (s.clone(), text.into())
            })
            .collect();
        let mut entries = vec![
            ("name".to_string(), format!("m{i}").into()),
            ("flow".into(), Value::Table(flow)),
            (
                "invariant".into(),
                strings(q.invariant.iter().map(|r| relation(r, &names))),
            ),
        ];
        let label = |other: bool, k: u8| {
            if other {
                format!("m{}", usize::from(k) % file.modes.len())
            } else {
                format!("l{}", k % 4)
            }
        };
        if let Some((other, k)) = q.label {
            entries.push(("label".into(), label(other, k).into()));
        }
        if !q.element_modes.is_empty() {
            let held: Table = q
                .element_modes
                .iter()
                .map(|&(e, other, k)| {
                    let element = format!("e{}", usize::from(e) % (file.elements.len() + 1));
                    (element, label(other, k).into())
                })
                .collect();
            entries.push(("element_modes".into(), Value::Table(held)));
        }
        if !q.definitions.is_empty() && !definitions.is_empty() {
            let own: Table = q
                .definitions
                .iter()
                .map(|(d, text)| (pick(&definitions, *d), text.text(&names).into()))
                .collect();
            entries.push(("definitions".into(), Value::Table(own)));
        }
        table(entries)
    };
    let mut modes: Vec<Value> = file.modes.iter().enumerate().map(mode).collect();
    // The last mode copied, named apart: at most 1 001 copies, and about
    // 4 MB of them (the time of a run is the fuzzer's, not a property).
    let last = modes.last()?.clone();
    let size = toml::to_string(&last).map_or(1, |t| t.len());
    let copies = file.copies.get().min(1_001).min(4_000_000 / size);
    for _ in 0..copies {
        let mut copy = last.clone();
        if let Value::Table(t) = &mut copy {
            t.insert("name".into(), format!("m{}", modes.len()).into());
        }
        modes.push(copy);
    }
    let count = modes.len();
    doc.insert("modes".into(), Value::Array(modes));
    let mode_name = |i: u8| format!("m{}", usize::from(i) % count);
    let transitions = file.transitions.iter().map(|t| {
        let reset: Table = t
            .reset
            .iter()
            .map(|(s, e)| (pick(&states, *s), e.text(&names).into()))
            .collect();
        let mut entries = vec![
            ("from".to_string(), mode_name(t.from).into()),
            ("to".into(), mode_name(t.to).into()),
            ("guard".into(), relation(&t.guard, &names).into()),
            ("reset".into(), Value::Table(reset)),
        ];
        if let Some(w) = &t.when {
            entries.push(("when".into(), w.text(&names).into()));
        }
        table(entries)
    });
    doc.insert("transitions".into(), Value::Array(transitions.collect()));
    let elements = file.elements.iter().enumerate().map(|(i, e)| match e {
        Element::Friction {
            velocity,
            kinetic,
            static_level,
        } => table([
            ("type".into(), "dry_friction".into()),
            ("name".into(), format!("e{i}").into()),
            ("velocity".into(), pick(&states, *velocity).into()),
            ("kinetic".into(), kinetic.text(&names).into()),
            ("static".into(), static_level.text(&names).into()),
            ("mode".into(), format!("stuck{i}").into()),
        ]),
        Element::Stop {
            position,
            velocity,
            at,
            max,
            restitution,
        } => table([
            ("type".into(), "stop".into()),
            ("name".into(), format!("e{i}").into()),
            ("position".into(), pick(&states, *position).into()),
            ("velocity".into(), pick(&states, *velocity).into()),
            ("at".into(), at.text(&names).into()),
            ("side".into(), if *max { "max" } else { "min" }.into()),
            ("restitution".into(), restitution.text(&names).into()),
            ("mode".into(), format!("rest{i}").into()),
        ]),
    });
    doc.insert("elements".into(), Value::Array(elements.collect()));
    if let Some(e) = &file.energy {
        doc.insert("energy".into(), e.text(&names).into());
    }
    toml::to_string(&doc).ok()
}

fuzz_target!(|file: File| {
    let Some(text) = text(&file) else {
        return;
    };
    let Ok(m) = Model::from_toml(&text, "fuzz.toml") else {
        return;
    };
    let again = Model::from_json(&m.to_json(), "again.json").expect("a model's own JSON reads back");
    assert_eq!(m, again);
    // A run of 20 samples evaluates every flow about 100 times per sample.
    let Model::GrayBox(g) = &m else {
        return;
    };
    let size: usize = CompiledModel::new(g)
        .expect("a model that reads compiles")
        .modes
        .iter()
        .flat_map(|q| &q.flow)
        .map(|e| e.operations())
        .sum();
    if size <= 10_000 {
        models::run_briefly(&m);
    }
});
