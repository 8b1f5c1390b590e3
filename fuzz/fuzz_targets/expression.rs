//! Gray-box expressions (`hysid_graybox::expr`): texts built from shapes
//! that reach the limits, or any text, with definitions that use one
//! another and a chain of definitions up to thousands long. Every text
//! compiles to a tape or gives an `ExprError` (a text beyond the length
//! limit `TooLong`, at once); definitions are ordered and summarised or
//! refused; an expression is written out with them or refused; a tape
//! evaluates. Never a panic, never a stack overflow.
#![no_main]

#[path = "shapes.rs"]
mod shapes;

use hysid_graybox::expr::{Definitions, ExprError, Expression, MAX_LENGTH, Relation};
use libfuzzer_sys::arbitrary::{self, Arbitrary};
use libfuzzer_sys::fuzz_target;
use shapes::{Operator, Shape, Size};
use std::collections::HashMap;
use std::rc::Rc;

/// The slots: `x, y, z, p`, then the definitions `d0..d3`, then the chain
/// `c0, c1, ..`.
const SLOTS: [&str; 4] = ["x", "y", "z", "p"];

#[derive(Arbitrary, Debug)]
struct Input {
    /// The expression: a shape, or a text as given.
    expression: Result<Shape, String>,
    /// Up to four definitions `d0..d3`, each may read the others.
    definitions: Vec<Shape>,
    /// `c0 = first`, `c_i = c_(i-1) op next`: a chain of [`Size`] links.
    chain: Option<(Size, Operator, Shape, Shape)>,
    relation: bool,
    slots: [f64; 4],
}

fuzz_target!(|input: Input| {
    // At most 20 000 links, and about 1 MB of chain text (each link is its
    // `next` again): the time of a run is the fuzzer's, not a property.
    let links = input.chain.as_ref().map_or(0, |c| {
        let next = c.3.text(&[]).len();
        c.0.get().min(20_000).min(1_000_000 / (next + 8))
    });
    let mut names: Vec<String> = SLOTS.iter().map(|s| s.to_string()).collect();
    names.extend((0..input.definitions.len().min(4)).map(|i| format!("d{i}")));
    names.extend((0..links).map(|i| format!("c{i}")));
    let slots: HashMap<&str, u32> = names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i as u32))
        .collect();
    let resolve = |n: &str| slots.get(n).copied();

    let text = match &input.expression {
        Ok(shape) => shape.text(&names),
        Err(text) => text.clone(),
    };
    if input.relation {
        let _ = Relation::compile(&text, &resolve);
    }
    let compiled = Expression::compile(&text, &resolve);
    if text.len() > MAX_LENGTH {
        assert_eq!(compiled, Err(ExprError::TooLong(text.len())));
    }
    let Ok(e) = compiled else {
        return;
    };
    if e.slots().all(|s| (s as usize) < SLOTS.len()) {
        let _ = e.eval(&input.slots);
    }

    // The definitions, written as texts of the same names.
    let mut written = Vec::new();
    for d in input.definitions.iter().take(4) {
        match Expression::compile(&d.text(&names), &resolve) {
            Ok(d) => written.push(Rc::new(d)),
            Err(_) => return,
        }
    }
    if let Some((_, op, first, next)) = &input.chain {
        let (first, next) = (first.text(&names), next.text(&names));
        for i in 0..links {
            let text = match i {
                0 => first.clone(),
                i => format!("c{}{}({next})", i - 1, op_text(*op)),
            };
            match Expression::compile(&text, &resolve) {
                Ok(d) => written.push(Rc::new(d)),
                Err(_) => return,
            }
        }
    }
    let Ok(mut defs) = Definitions::new(SLOTS.len() as u32, written) else {
        return;
    };
    let limit = 100_000;
    if let Ok(inlined) = e.inline(&mut defs, limit) {
        assert!(inlined.operations() <= limit);
        let _ = inlined.eval(&input.slots);
        let _ = inlined.bind(3, &input.slots[3..]).eval(&input.slots);
    }
});

fn op_text(op: Operator) -> &'static str {
    match op {
        Operator::Add => " + ",
        Operator::Sub => " - ",
        Operator::Mul => "*",
        _ => "/",
    }
}
