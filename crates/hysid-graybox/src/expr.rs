//! Expressions of a gray-box model: parsed once by `evalexpr`, compiled into
//! a postfix tape over numbered slots, evaluated without parsing or
//! allocating.
//!
//! The grammar is evalexpr's (`+ - * / % ^`, unary `-`, comparisons
//! `< <= > >= == !=`, `&& || !`, parentheses, function calls); every
//! number is a 64-bit float (`1/2` is `0.5`), and a comparison is `1` when
//! true and `0` when false. The functions are [`Function`]'s.
//!
//! This module holds [`Expression`] and its evaluation; `parse` turns the
//! text into a tape, `fold` folds constants and binds parameters,
//! `definitions` inlines a mode's definitions, `relation` reads guards and
//! invariants, `tape` runs the tapes and `derivative` differentiates them.

pub use definitions::{DefinitionError, Definitions, InlineError};
pub use derivative::Adjoints;
use derivative::Sweep;
use parse::{Builder, parse};
pub use relation::{Crossing, Relation};
use std::sync::OnceLock;
use tape::{Binary, Joint, Op, Program};
pub use tape::{Function, MAX_DEPTH, REGISTERS};

mod definitions;
mod derivative;
mod fold;
mod parse;
mod relation;
mod tape;

/// Longest expression text, in bytes (checked before parsing). evalexpr's
/// tree of a sum is as deep as the sum has terms, and its parser drops a
/// tree it gives up on recursively, one level at a time; at this length
/// that stays within a small thread stack.
pub const MAX_LENGTH: usize = 10_000;

/// Deepest nesting of an expression's text (checked before parsing): each
/// open parenthesis is a level, and so is each unary sign (`-`, `!`) and
/// function name written since the last binary operator within the same
/// parentheses (`-(-x)` nests 3 deep, `sin(cos(x))` 4).
pub const MAX_NESTING: usize = 64;

/// Why an expression does not compile.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExprError {
    /// evalexpr could not parse it.
    #[error("cannot parse '{text}': {message}")]
    Syntax {
        /// The expression.
        text: String,
        /// evalexpr's message.
        message: String,
    },
    /// A name that is no state, input, parameter or definition.
    #[error("unknown symbol '{0}'")]
    UnknownSymbol(String),
    /// A function that is not one of [`Function`]'s, or with the wrong
    /// number of arguments.
    #[error("unknown function '{name}' with {args} argument(s)")]
    UnknownFunction {
        /// Its name.
        name: String,
        /// Arguments given.
        args: usize,
    },
    /// Assignments, `;` chains, strings and empty expressions.
    #[error("'{0}' is not a numeric expression")]
    NotNumeric(String),
    /// Longer than [`MAX_LENGTH`] bytes: the length.
    #[error("the expression is {0} bytes long; the limit is {MAX_LENGTH}")]
    TooLong(usize),
    /// Nested deeper than [`MAX_NESTING`].
    #[error(
        "the expression nests parentheses, function calls and signs more than {MAX_NESTING} deep"
    )]
    TooNested,
    /// With its definitions written out, more operations than a model may
    /// hold.
    #[error(
        "with its definitions written out, the expression has more than {0} operations (the limit)"
    )]
    TooLarge(usize),
    /// Deeper than [`MAX_DEPTH`].
    #[error("'{0}' is nested too deeply (at most {MAX_DEPTH} pending operands)")]
    TooDeep(String),
    /// A relation was expected (`a >= b`, `a <= b`, `a == b`, ...).
    #[error("'{0}' is not a relation such as 'a >= b', 'a <= b' or 'a == b'")]
    NotRelation(String),
    /// A function called with another number of arguments than it takes.
    #[error("'{name}' takes {takes} argument(s), not {given}")]
    Arity {
        /// Its name.
        name: String,
        /// Arguments it takes.
        takes: usize,
        /// Arguments given.
        given: usize,
    },
    /// An operator of another language (`and`, `or`, `not`, `**`), which
    /// the parser read as something else: what is written and what is
    /// meant.
    #[error("'{text}': write '{written}' as '{meant}'")]
    OtherLanguage {
        /// The expression.
        text: String,
        /// The operator as written.
        written: &'static str,
        /// hysid's operator.
        meant: &'static str,
    },
    /// Comparisons chained (`a <= x <= b`), which would compare the truth
    /// of the first.
    #[error(
        "'{0}' chains comparisons, which compares the truth of the first: write each comparison on its own (an invariant lists them; a value joins them with '&&')"
    )]
    ChainedComparison(String),
}

/// The error `e` of compiling `text`, named by the operator of another
/// language that `text` writes ([`other_language`]) where the parser read
/// it as something else.
fn in_other_words(text: &str, e: ExprError) -> ExprError {
    match e {
        ExprError::UnknownFunction { .. }
        | ExprError::UnknownSymbol(_)
        | ExprError::NotNumeric(_)
        | ExprError::NotRelation(_)
        | ExprError::Syntax { .. }
        | ExprError::ChainedComparison(_) => {
            other_language(text).map_or(e, |(written, meant)| ExprError::OtherLanguage {
                text: text.to_string(),
                written,
                meant,
            })
        }
        e => e,
    }
}

/// The first operator of another language that `text` writes outside
/// its names, with hysid's own: `and`, `or` and `not` as words, `**`.
fn other_language(text: &str) -> Option<(&'static str, &'static str)> {
    if text.contains("**") {
        return Some(("**", "^"));
    }
    let words = text.split(|c: char| !(c.is_alphanumeric() || c == '_'));
    words.into_iter().find_map(|w| match w {
        "and" => Some(("and", "&&")),
        "or" => Some(("or", "||")),
        "not" => Some(("not", "!")),
        _ => None,
    })
}

/// A compiled expression: a postfix tape over the slots of a
/// [`crate::compile::CompiledModel`] (states, inputs, parameters,
/// definitions).
#[derive(Debug, Clone)]
pub struct Expression {
    ops: Vec<Op>,
    /// How it is evaluated.
    form: Form,
    /// A tape's graph for its derivatives, laid out at the first
    /// [`Expression::gradient`].
    sweep: OnceLock<Sweep>,
}

/// Two expressions are equal when their tapes are (the rest is made from
/// the tape).
impl PartialEq for Expression {
    fn eq(&self, other: &Self) -> bool {
        self.ops == other.ops
    }
}

/// The cheapest evaluation of an expression's tape.
#[derive(Debug, Clone, PartialEq)]
enum Form {
    /// A number.
    Constant(f64),
    /// One slot.
    Slot(u32),
    /// `constant + sum(coefficient * slot)`: most flows of physical models
    /// are affine in the states and inputs once the parameters are bound.
    Affine(Affine),
    /// Anything else: the postfix tape, run as three-address code.
    Tape(Program),
}

/// An affine form `constant + sum(coefficient * slot)`.
#[derive(Debug, Clone, PartialEq)]
struct Affine {
    constant: f64,
    terms: Vec<(u32, f64)>,
}

impl Affine {
    /// Scales every coefficient; returns the terms touched.
    fn scale(&mut self, c: f64) -> usize {
        self.constant *= c;
        for t in &mut self.terms {
            t.1 *= c;
        }
        self.terms.len()
    }

    /// Adds `sign` times `other`; returns the terms compared.
    fn add(&mut self, other: Affine, sign: f64) -> usize {
        self.constant += sign * other.constant;
        let mut work = 0;
        for (s, c) in other.terms {
            match self.terms.iter_mut().position(|t| t.0 == s) {
                Some(i) => {
                    work += i + 1;
                    self.terms[i].1 += sign * c;
                }
                None => {
                    work += self.terms.len() + 1;
                    self.terms.push((s, sign * c));
                }
            }
        }
        work
    }

    /// The affine form of a postfix tape, if it has one: sums, differences,
    /// negations, products with a constant and divisions by a non-zero one.
    /// Collecting the terms costs up to the product of the terms and the
    /// operations (each scaling touches every term so far); past
    /// `4096 + 64` per operation, the tape is left to be run as it is.
    fn of(ops: &[Op]) -> Option<Affine> {
        let budget = 4096 + 64 * ops.len();
        let mut work = 0usize;
        let mut stack: Vec<Affine> = Vec::new();
        for op in ops {
            match *op {
                Op::Const(v) => stack.push(Affine {
                    constant: v,
                    terms: Vec::new(),
                }),
                Op::Load(s) => stack.push(Affine {
                    constant: 0.0,
                    terms: vec![(s, 1.0)],
                }),
                Op::Neg => work += stack.last_mut()?.scale(-1.0),
                Op::Binary(b @ (Binary::Add | Binary::Sub | Binary::Mul | Binary::Div)) => {
                    let rhs = stack.pop()?;
                    let mut lhs = stack.pop()?;
                    work += match b {
                        Binary::Add => lhs.add(rhs, 1.0),
                        Binary::Sub => lhs.add(rhs, -1.0),
                        Binary::Mul if rhs.terms.is_empty() => lhs.scale(rhs.constant),
                        Binary::Mul if lhs.terms.is_empty() => {
                            let c = lhs.constant;
                            lhs = rhs;
                            lhs.scale(c)
                        }
                        Binary::Div if rhs.terms.is_empty() && rhs.constant != 0.0 => {
                            lhs.scale(1.0 / rhs.constant)
                        }
                        _ => return None,
                    };
                    stack.push(lhs);
                }
                _ => return None,
            }
            if work > budget {
                return None;
            }
        }
        match stack.len() {
            1 => stack.pop(),
            _ => None,
        }
    }

    #[inline]
    fn eval(&self, slots: &[f64]) -> f64 {
        let mut acc = self.constant;
        for &(s, c) in &self.terms {
            acc += c * slots[s as usize];
        }
        acc
    }
}

impl Expression {
    fn from_ops(ops: Vec<Op>) -> Self {
        let form = match ops.as_slice() {
            [Op::Const(v)] => Form::Constant(*v),
            [Op::Load(s)] => Form::Slot(*s),
            _ => Affine::of(&ops).map_or_else(|| Form::Tape(Program::of(&ops)), Form::Affine),
        };
        Expression {
            ops,
            form,
            sweep: OnceLock::new(),
        }
    }

    /// Parses `text` and compiles it; `resolve` maps a name to its slot.
    pub fn compile(text: &str, resolve: &dyn Fn(&str) -> Option<u32>) -> Result<Self, ExprError> {
        let compiled = parse(text).and_then(|root| {
            let mut b = Builder::new(text, resolve);
            b.node(&root.0)?;
            b.finish()
        });
        compiled.map_err(|e| in_other_words(text, e))
    }

    /// A constant.
    pub fn constant(v: f64) -> Self {
        Expression::from_ops(vec![Op::Const(v)])
    }

    /// The slots the expression reads, in tape order, with repeats.
    pub fn slots(&self) -> impl Iterator<Item = u32> + '_ {
        self.ops.iter().filter_map(|op| match op {
            Op::Load(s) => Some(*s),
            _ => None,
        })
    }

    /// `(constant, [(slot, coefficient)])` when the expression is affine in
    /// the slots it reads (a constant or one slot included).
    pub fn affine(&self) -> Option<(f64, Vec<(u32, f64)>)> {
        match &self.form {
            Form::Constant(v) => Some((*v, Vec::new())),
            Form::Slot(s) => Some((0.0, vec![(*s, 1.0)])),
            Form::Affine(a) => Some((a.constant, a.terms.clone())),
            Form::Tape(_) => None,
        }
    }

    /// Whether the expression is affine in slot `slot` whatever the other
    /// slots hold: `a + b * slot` with `a` and `b` free of it (`c*x + off`,
    /// `(x - x0)/k`, `if(u > 0, x, 2*x)`). Decided on the tape: sums,
    /// differences and negations keep the form, a product or a quotient
    /// keeps it when the other factor (the divisor) is free of the slot, an
    /// `if` whose condition is free of it keeps it, and anything else of
    /// the slot (a power, a function, a comparison) is not affine.
    pub fn affine_in(&self, slot: u32) -> bool {
        #[derive(Clone, Copy, PartialEq, PartialOrd)]
        enum Class {
            Free,
            Affine,
            Other,
        }
        let mut stack: Vec<Class> = Vec::with_capacity(self.depth());
        let mut registers = [Class::Free; REGISTERS];
        let free_or_other = |args: &[Class]| {
            if args.iter().all(|c| *c == Class::Free) {
                Class::Free
            } else {
                Class::Other
            }
        };
        for op in &self.ops {
            let class = match *op {
                Op::Const(_) => Class::Free,
                Op::Load(s) if s == slot => Class::Affine,
                Op::Load(_) => Class::Free,
                Op::Recall(r) => registers[r as usize],
                Op::Keep(r) => {
                    registers[r as usize] = stack.last().copied().unwrap_or(Class::Other);
                    continue;
                }
                Op::Neg => stack.pop().unwrap_or(Class::Other),
                Op::Not => free_or_other(&[stack.pop().unwrap_or(Class::Other)]),
                Op::Binary(b) => {
                    let y = stack.pop().unwrap_or(Class::Other);
                    let x = stack.pop().unwrap_or(Class::Other);
                    let higher = if x > y { x } else { y };
                    match b {
                        Binary::Add | Binary::Sub => higher,
                        Binary::Mul if x == Class::Free || y == Class::Free => higher,
                        Binary::Div if y == Class::Free => x,
                        _ => free_or_other(&[x, y]),
                    }
                }
                Op::Call(f) => {
                    let args = stack.split_off(stack.len().saturating_sub(f.arity()));
                    match (f, args.as_slice()) {
                        (Function::If, [Class::Free, a, b]) => {
                            if a > b {
                                *a
                            } else {
                                *b
                            }
                        }
                        _ => free_or_other(&args),
                    }
                }
            };
            stack.push(class);
        }
        stack.pop().is_some_and(|c| c != Class::Other)
    }

    /// The constant value, when the expression reads no slot.
    pub fn as_constant(&self) -> Option<f64> {
        match self.form {
            Form::Constant(v) => Some(v),
            _ => None,
        }
    }

    /// Evaluates the expression with the slot values `slots`.
    #[inline]
    pub fn eval(&self, slots: &[f64]) -> f64 {
        match &self.form {
            Form::Constant(v) => *v,
            Form::Slot(s) => slots[*s as usize],
            Form::Affine(a) => a.eval(slots),
            Form::Tape(program) => program.run(slots),
        }
    }

    /// The number of operations of its tape.
    pub fn operations(&self) -> usize {
        self.ops.len()
    }

    /// Whether its value is a truth value, 1 where it holds and 0
    /// elsewhere: a comparison, `&&`, `||` or `!` at its top.
    pub fn is_relation(&self) -> bool {
        match self.ops.last() {
            Some(Op::Not) => true,
            Some(Op::Binary(b)) => b.compares() || matches!(b, Binary::And | Binary::Or),
            _ => false,
        }
    }

    /// The tape's deepest stack.
    fn depth(&self) -> usize {
        let (mut depth, mut deepest) = (0usize, 0usize);
        for op in &self.ops {
            depth = depth + 1 - op.operands();
            deepest = deepest.max(depth);
        }
        deepest
    }
}

/// Expressions evaluated together, as a mode's flows are: those on a tape
/// run as one program in which an operation two of them share (a
/// definition both read) is done once, each value the same bits as its
/// own [`Expression::eval`].
#[derive(Debug, Clone, PartialEq)]
pub struct Shared {
    joint: Option<Joint>,
}

impl Shared {
    /// The joint program of `expressions` (none where fewer than two are
    /// tapes, or their operations do not fit one workspace).
    pub fn of(expressions: &[Expression]) -> Shared {
        let tapes: Vec<(usize, &Program)> = expressions
            .iter()
            .enumerate()
            .filter_map(|(i, e)| match &e.form {
                Form::Tape(program) => Some((i, program)),
                _ => None,
            })
            .collect();
        Shared {
            joint: (tapes.len() > 1).then(|| Joint::of(&tapes)).flatten(),
        }
    }

    /// `out[i] = expressions[i].eval(slots)` for the `expressions` this
    /// was made of.
    pub fn eval(&self, expressions: &[Expression], slots: &[f64], out: &mut [f64]) {
        match &self.joint {
            None => {
                for (o, e) in out.iter_mut().zip(expressions) {
                    *o = e.eval(slots);
                }
            }
            Some(joint) => {
                for (o, e) in out.iter_mut().zip(expressions) {
                    if !matches!(e.form, Form::Tape(_)) {
                        *o = e.eval(slots);
                    }
                }
                joint.run(slots, out);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::fold::push_folded;
    use super::*;
    use proptest::prelude::*;
    use std::rc::Rc;

    pub(super) fn names(n: &str) -> Option<u32> {
        ["x", "y", "z"]
            .iter()
            .position(|s| *s == n)
            .map(|i| i as u32)
    }

    fn eval(text: &str, slots: &[f64]) -> f64 {
        Expression::compile(text, &names).unwrap().eval(slots)
    }

    #[test]
    fn affinity_in_one_slot_is_read_on_the_tape() {
        let affine = |t: &str| Expression::compile(t, &names).unwrap().affine_in(0);
        for t in [
            "x",
            "y*x + z",
            "(x - y)/z",
            "-(2*x) + sin(y)*z",
            "if(y > 0, x, 2*x - z)",
            "y - x/3",
            "z^2 + y",
        ] {
            assert!(affine(t), "{t}");
        }
        for t in [
            "x*x",
            "x^2",
            "y/x",
            "sin(x)",
            "if(x > 0, x, 0)",
            "abs(x) + y",
            "x*(y + x)",
            "(x > 1) + x",
        ] {
            assert!(!affine(t), "{t}");
        }
    }

    #[test]
    fn precedence_and_functions_follow_the_usual_rules() {
        let s = [2.0, 3.0, -1.0];
        assert_eq!(eval("-x^2*y + 1/2", &s), -11.5);
        assert_eq!(eval("x - -y", &s), 5.0);
        assert_eq!(eval("min(x, y + 1) * max(z, 0)", &s), 0.0);
        assert_eq!(eval("if(x > y, 1, 2) + clamp(z, 0, 5)", &s), 2.0);
        assert_eq!(eval("sign(z) + sign(0) + abs(z)", &s), 0.0);
        assert_eq!(eval("x >= 2 && !(y < 1) || 0", &s), 1.0);
        assert_eq!(eval("2e-3 * 1000", &s), 2.0);
        assert!((eval("atan2(1, 1) * 4", &s) - std::f64::consts::PI).abs() < 1e-15);
    }

    #[test]
    fn constants_are_folded_and_symbols_resolved_once() {
        let e = Expression::compile("2 * 3 + x * (4 - 1)", &names).unwrap();
        assert_eq!(e.ops.len(), 5, "{:?}", e.ops);
        assert_eq!(e.slots().collect::<Vec<_>>(), [0]);
        assert_eq!(
            Expression::compile("sqrt(16)", &names)
                .unwrap()
                .as_constant(),
            Some(4.0)
        );
    }

    #[test]
    fn binding_slots_folds_what_they_fix() {
        let e = Expression::compile("x * (y + 1) - sqrt(y) * z", &names).unwrap();
        let b = e.bind(1, &[4.0]);
        assert_eq!(b.ops.len(), 7, "{:?}", b.ops);
        assert_eq!(b.eval(&[2.0, f64::NAN, 3.0]), 4.0);
        assert_eq!(e.bind(0, &[2.0, 4.0, 3.0]).as_constant(), Some(4.0));
    }

    #[test]
    fn bad_expressions_are_named() {
        let err = |t: &str| Expression::compile(t, &names).unwrap_err();
        assert_eq!(err("x + w"), ExprError::UnknownSymbol("w".into()));
        assert!(matches!(err("foo(x)"), ExprError::UnknownFunction { .. }));
        assert_eq!(
            err("min(x)"),
            ExprError::Arity {
                name: "min".into(),
                takes: 2,
                given: 1
            }
        );
        assert_eq!(
            err("if(x > y, x)"),
            ExprError::Arity {
                name: "if".into(),
                takes: 3,
                given: 2
            }
        );
        // Operators of other languages are named with hysid's.
        for (text, written, meant) in [
            ("x >= y and y >= -1", "and", "&&"),
            ("x > 1 or y > 1", "or", "||"),
            ("x and y", "and", "&&"),
            ("not x", "not", "!"),
            ("x * (y - z)**2", "**", "^"),
        ] {
            assert_eq!(
                err(text),
                ExprError::OtherLanguage {
                    text: text.into(),
                    written,
                    meant
                }
            );
        }
        assert!(matches!(err("x = 1"), ExprError::NotNumeric(_)));
        assert!(matches!(err("x; y"), ExprError::NotNumeric(_)));
        assert!(matches!(err("\"s\""), ExprError::NotNumeric(_)));
        assert!(matches!(err(""), ExprError::NotNumeric(_)));
        assert!(matches!(err("x +"), ExprError::NotNumeric(_)));
        assert!(matches!(err("(x"), ExprError::Syntax { .. }));
        let deep = format!("{}x{}", "(x + ".repeat(40), ")".repeat(40));
        assert!(matches!(err(&deep), ExprError::TooDeep(_)));
        assert!(matches!(
            Relation::compile("x + 1", &names).unwrap_err(),
            ExprError::NotRelation(_)
        ));
        for half in ["x >=", ">= x", "=="] {
            assert!(Relation::compile(half, &names).is_err(), "{half}");
        }
    }

    #[test]
    fn long_and_deep_texts_are_refused_before_parsing() {
        let err = |t: &str| Expression::compile(t, &names).unwrap_err();
        // A sum of 200 000 terms and 200 000 parentheses: the length
        // refuses both at once.
        let terms = format!("x{}", " + 0".repeat(200_000));
        assert_eq!(err(&terms), ExprError::TooLong(terms.len()));
        let parens = format!("{}x{}", "(".repeat(200_000), ")".repeat(200_000));
        assert_eq!(err(&parens), ExprError::TooLong(parens.len()));
        // Within the length, each way evalexpr's parser recurses, past the
        // nesting limit.
        for deep in [
            format!("{}x{}", "(".repeat(4_000), ")".repeat(4_000)),
            format!("{}x", "-".repeat(9_000)),
            format!("{}x", "!".repeat(9_000)),
            format!("{}x", "sin ".repeat(2_000)),
            format!("{}x{}", "abs(".repeat(1_999), ")".repeat(1_999)),
        ] {
            assert!(deep.len() <= MAX_LENGTH);
            assert_eq!(err(&deep), ExprError::TooNested, "{:.20}", deep);
        }
        // At the limit the text is parsed; one level more is refused.
        let at = |n: usize| format!("{}x{}", "(".repeat(n), ")".repeat(n));
        assert_eq!(
            Expression::compile(&at(MAX_NESTING), &names)
                .unwrap()
                .eval(&[2.0]),
            2.0
        );
        assert_eq!(err(&at(MAX_NESTING + 1)), ExprError::TooNested);
        // The longest sum is a tree as deep as it has terms: compiled and
        // dropped without recursion; with a stray parenthesis at its end,
        // evalexpr gives up on that tree and drops it itself.
        let sum = format!("x{}", "+x".repeat((MAX_LENGTH - 1) / 2));
        assert!(sum.len() <= MAX_LENGTH && sum.len() + 2 > MAX_LENGTH);
        let e = Expression::compile(&sum, &names).unwrap();
        assert_eq!(e.eval(&[1.0]), (1 + (MAX_LENGTH - 1) / 2) as f64);
        let stray = format!("{})", &sum[..sum.len() - 1]);
        assert!(matches!(err(&stray), ExprError::Syntax { .. }));
    }

    #[test]
    fn a_known_sign_decides_comparisons_with_zero_and_the_branches_they_select() {
        let e = |t: &str| Expression::compile(t, &names).unwrap();
        let plus = e("if(x > 0, y, z)*x + sign(x)").with_sign(0, true).unwrap();
        assert_eq!(plus, e("y*x + 1"));
        let minus = e("if(0 < x, y, z)*x").with_sign(0, false).unwrap();
        assert_eq!(minus, e("z*x"));
        // Affine once decided.
        assert!(
            e("if(x >= 0, 2, 3)*x + y")
                .with_sign(0, true)
                .unwrap()
                .affine()
                .is_some()
        );
        // Nothing to decide: other slots, other thresholds.
        assert_eq!(e("if(y > 0, x, z)").with_sign(0, true), None);
        assert_eq!(e("if(x > 1, y, z)").with_sign(0, true), None);
    }

    proptest! {
        /// Wherever the slot has the sign given, the decided expression has
        /// the value of the original (to rounding: a decided expression
        /// that is affine is summed in its affine form).
        #[test]
        fn a_decided_expression_agrees_where_the_sign_holds(
            a in tree(),
            b in tree(),
            relation in prop::sample::select(vec![">", ">=", "<", "<=", "==", "!="]),
            flipped in any::<bool>(),
            positive in any::<bool>(),
            x in 1e-3f64..5.0,
            y in -5.0f64..5.0,
            z in -5.0f64..5.0,
        ) {
            let condition = if flipped {
                format!("0 {relation} x")
            } else {
                format!("x {relation} 0")
            };
            let text = format!("if({condition}, {}, {}) + sign(x)*{}", a.text(), b.text(), a.text());
            let e = Expression::compile(&text, &names).unwrap();
            let d = e.with_sign(0, positive).unwrap();
            let x = if positive { x } else { -x };
            let (v, w) = (e.eval(&[x, y, z]), d.eval(&[x, y, z]));
            let close = (v - w).abs() <= 1e-12 * v.abs().max(1.0);
            prop_assert!(v == w || close || (v.is_nan() && w.is_nan()), "{text}: {v} against {w}");
        }
    }

    #[test]
    fn a_truth_value_at_the_top_is_a_relation() {
        for text in ["x > 0", "(x <= y)", "x == 1 && y != 2", "x || y", "!x"] {
            assert!(
                Expression::compile(text, &names).unwrap().is_relation(),
                "{text}"
            );
        }
        for text in [
            "x",
            "1",
            "x*(x > 0)",
            "if(x > 0, 1, 2)",
            "-(x > 0)",
            "min(x, y)",
        ] {
            assert!(
                !Expression::compile(text, &names).unwrap().is_relation(),
                "{text}"
            );
        }
    }

    /// `a <= x <= b` is refused as a chain, with or without parentheses;
    /// a comparison of a value that merely holds a relation is not.
    #[test]
    fn chained_comparisons_are_refused() {
        for text in [
            "-1 <= x <= y",
            "(x < y) > z",
            "x >= (y >= z)",
            "1 < x < 2 < y",
        ] {
            assert_eq!(
                Expression::compile(text, &names).unwrap_err(),
                ExprError::ChainedComparison(text.into()),
                "{text}"
            );
        }
        for text in [
            "-1 <= x && x <= y",
            "if(x <= y, 1, 0) <= z",
            "(x == y) <= z",
        ] {
            assert!(Expression::compile(text, &names).is_ok(), "{text}");
        }
        // So in a guard or an invariant, where they are most often written,
        // and `and` there is named too.
        for text in ["0 <= x <= 0.1", "x >= (y >= z)"] {
            assert_eq!(
                Relation::compile(text, &names).unwrap_err(),
                ExprError::ChainedComparison(text.into()),
                "{text}"
            );
        }
        assert_eq!(
            Relation::compile("x >= 2 and y > 0", &names).unwrap_err(),
            ExprError::OtherLanguage {
                text: "x >= 2 and y > 0".into(),
                written: "and",
                meant: "&&"
            }
        );
        assert!(Relation::compile("if(x <= y, 1, 0) <= z", &names).is_ok());
    }

    #[test]
    fn relations_give_their_surface_and_direction() {
        let r = Relation::compile("x >= y + 1", &names).unwrap();
        assert_eq!(r.crossing, Crossing::Rising);
        assert_eq!(r.surface.eval(&[5.0, 1.0, 0.0]), 3.0);
        let r = Relation::compile("x <= 1", &names).unwrap();
        assert_eq!(
            (r.crossing, r.margin(&[3.0, 0.0, 0.0])),
            (Crossing::Falling, -2.0)
        );
        let r = Relation::compile("x == y", &names).unwrap();
        assert_eq!(
            (r.crossing, r.margin(&[3.0, 5.0, 0.0])),
            (Crossing::Either, -2.0)
        );
    }

    /// A random arithmetic tree, printed fully parenthesised, evaluates on
    /// the tape as the tree does directly.
    #[derive(Debug, Clone)]
    pub(super) enum Tree {
        Num(f64),
        Var(usize),
        Neg(Box<Tree>),
        Bin(u8, Box<Tree>, Box<Tree>),
        Min(Box<Tree>, Box<Tree>),
    }

    impl Tree {
        /// Whether the tree reads variable `i`.
        pub(super) fn reads(&self, i: usize) -> bool {
            match self {
                Tree::Num(_) => false,
                Tree::Var(j) => *j == i,
                Tree::Neg(a) => a.reads(i),
                Tree::Bin(_, a, b) | Tree::Min(a, b) => a.reads(i) || b.reads(i),
            }
        }

        pub(super) fn text(&self) -> String {
            match self {
                Tree::Num(v) => format!("{v:?}"),
                Tree::Var(i) => ["x", "y", "z"][*i].to_string(),
                Tree::Neg(a) => format!("(-{})", a.text()),
                Tree::Bin(o, a, b) => format!(
                    "({} {} {})",
                    a.text(),
                    ["+", "-", "*", "/"][*o as usize],
                    b.text()
                ),
                Tree::Min(a, b) => format!("min({}, {})", a.text(), b.text()),
            }
        }
        pub(super) fn value(&self, s: &[f64]) -> f64 {
            match self {
                Tree::Num(v) => *v,
                Tree::Var(i) => s[*i],
                Tree::Neg(a) => -a.value(s),
                Tree::Bin(o, a, b) => {
                    let (a, b) = (a.value(s), b.value(s));
                    [a + b, a - b, a * b, a / b][*o as usize]
                }
                Tree::Min(a, b) => a.value(s).min(b.value(s)),
            }
        }
    }

    pub(super) fn tree() -> impl Strategy<Value = Tree> {
        let leaf = prop_oneof![
            (0.5f64..9.5).prop_map(Tree::Num),
            (0usize..3).prop_map(Tree::Var)
        ];
        leaf.prop_recursive(5, 24, 2, |inner| {
            prop_oneof![
                inner.clone().prop_map(|a| Tree::Neg(Box::new(a))),
                (0u8..4, inner.clone(), inner.clone()).prop_map(|(o, a, b)| Tree::Bin(
                    o,
                    Box::new(a),
                    Box::new(b)
                )),
                (inner.clone(), inner).prop_map(|(a, b)| Tree::Min(Box::new(a), Box::new(b))),
            ]
        })
    }

    /// Slots `x, y, z`, then the definitions `a` and `b`.
    pub(super) fn with_definitions(n: &str) -> Option<u32> {
        ["x", "y", "z", "a", "b"]
            .iter()
            .position(|s| *s == n)
            .map(|i| i as u32)
    }

    /// The definitions `texts` of the slots from 3 on (after `x, y, z`).
    pub(super) fn definitions(texts: &[&str]) -> Definitions {
        let written = texts
            .iter()
            .map(|d| Rc::new(Expression::compile(d, &with_definitions).unwrap()))
            .collect();
        Definitions::new(3, written).unwrap()
    }

    /// The random expression `te` using the random definitions `a = ta`
    /// (of the slots) and `b = (tb) * a` several times, as
    /// `(te) + a * b - min(a, b)`: its text, the expression with each
    /// recurring definition kept in a register (`None` when inlining
    /// refuses it), and its plain expansion ([`expanded_plainly`]).
    pub(super) fn with_recurring_definitions(
        ta: &Tree,
        tb: &Tree,
        te: &Tree,
    ) -> (String, Option<Expression>, Expression) {
        let (a, b) = (ta.text(), format!("({}) * a", tb.text()));
        let text = format!("({}) + a * b - min(a, b)", te.text());
        let kept = Expression::compile(&text, &with_definitions)
            .unwrap()
            .inline(&mut definitions(&[&a, &b]), usize::MAX)
            .ok();
        let plain = expanded_plainly(&text, &[&a, &b]);
        (text, kept, plain)
    }

    /// `text` with the definitions `texts` (of the slots from 3 on) written
    /// out without registers, every use where it stands, by recursion: what
    /// the plain expansion of [`Expression::inline`] must give.
    pub(super) fn expanded_plainly(text: &str, texts: &[&str]) -> Expression {
        fn expand(out: &mut Vec<Op>, ops: &[Op], defs: &[Expression]) {
            for op in ops {
                match *op {
                    Op::Load(s) if s >= 3 && ((s - 3) as usize) < defs.len() => {
                        expand(out, &defs[(s - 3) as usize].ops, defs)
                    }
                    op => push_folded(out, op),
                }
            }
        }
        let defs: Vec<Expression> = texts
            .iter()
            .map(|d| Expression::compile(d, &with_definitions).unwrap())
            .collect();
        let mut ops = Vec::new();
        expand(
            &mut ops,
            &Expression::compile(text, &with_definitions).unwrap().ops,
            &defs,
        );
        Expression::from_ops(ops)
    }

    #[test]
    fn a_definition_used_twice_is_evaluated_once() {
        let (a, b) = ("sin(x) * y + z", "a * a - 1");
        let e = Expression::compile("b / (1 + a) + sign(a)", &with_definitions)
            .unwrap()
            .inline(&mut definitions(&[a, b]), usize::MAX)
            .unwrap();
        let count = |f: fn(&Op) -> bool| e.ops.iter().filter(|o| f(o)).count();
        // `a` is evaluated once (inside `b`), kept, and read three times.
        assert_eq!(count(|o| matches!(o, Op::Keep(_))), 1, "{:?}", e.ops);
        assert_eq!(count(|o| matches!(o, Op::Recall(_))), 3, "{:?}", e.ops);
        assert_eq!(
            count(|o| matches!(o, Op::Call(Function::Sin))),
            1,
            "{:?}",
            e.ops
        );
        let plain = expanded_plainly("b / (1 + a) + sign(a)", &[a, b]);
        assert!(e.ops.len() < plain.ops.len());
        let s = [0.7, -1.3, 2.1];
        assert_eq!(e.eval(&s).to_bits(), plain.eval(&s).to_bits());
        // An affine result keeps its affine form (no tape is run).
        let affine = Expression::compile("a + a", &with_definitions)
            .unwrap()
            .inline(&mut definitions(&["2 * x + y", "0"]), usize::MAX)
            .unwrap();
        assert!(affine.affine().is_some());
    }

    #[test]
    fn definitions_on_a_cycle_or_too_deep_are_named() {
        let written = |texts: &[&str]| -> Vec<Rc<Expression>> {
            texts
                .iter()
                .map(|d| Rc::new(Expression::compile(d, &with_definitions).unwrap()))
                .collect()
        };
        // `a` reads `b`, which reads itself: the ring is `b` alone, not
        // `a`, which only reaches it.
        assert_eq!(
            Definitions::new(3, written(&["b + 1", "b * x"])).unwrap_err(),
            DefinitionError::Cycle(vec![1])
        );
        // `a` reads `b`, which reads `a`: the ring in the order read.
        assert_eq!(
            Definitions::new(3, written(&["b + 1", "a * x"])).unwrap_err(),
            DefinitionError::Cycle(vec![0, 1])
        );
        assert_eq!(
            Definitions::new(3, written(&["x + 1", "b * x"])).unwrap_err(),
            DefinitionError::Cycle(vec![1])
        );
        // Each definition nests 20 pending operands inside the other's:
        // `a` fits, `b` with `a` written in does not.
        let nest = |inner: &str| format!("{}{inner}{}", "x * (".repeat(20), ")".repeat(20));
        let (a, b) = (nest("x"), nest("a"));
        assert_eq!(
            Definitions::new(3, written(&[&a, &b])).unwrap_err(),
            DefinitionError::TooDeep(1)
        );
    }

    #[test]
    fn a_doubling_chain_of_definitions_is_refused_by_its_size() {
        // d_i = d_(i-1) * d_(i-1), d_0 = sin(x): written out, d_30 holds
        // 2^30 sines; with registers, sixteen levels cost three operations
        // each and the fourteen above them double.
        let names: Vec<String> = (0..31).map(|i| format!("d{i}")).collect();
        let resolve = |n: &str| {
            (n == "x")
                .then_some(0)
                .or_else(|| names.iter().position(|d| d == n).map(|i| i as u32 + 1))
        };
        let written = (0..31)
            .map(|i| {
                let text = match i {
                    0 => "sin(x)".to_string(),
                    i => format!("d{} * d{}", i - 1, i - 1),
                };
                Rc::new(Expression::compile(&text, &resolve).unwrap())
            })
            .collect();
        let mut defs = Definitions::new(1, written).unwrap();
        let d30 = Expression::compile("d30", &resolve).unwrap();
        assert_eq!(d30.inline(&mut defs, 10_000), Err(InlineError::TooLarge));
        assert!(d30.inline(&mut defs, 100_000).unwrap().ops.len() > 10_000);
        // Sixteen levels fit in the registers: one product each.
        let e = Expression::compile("d16", &resolve)
            .unwrap()
            .inline(&mut defs, 10_000)
            .unwrap();
        assert_eq!(e.ops.len(), 2 + 16 * 3, "{:?}", e.ops);
        let mut v = 1.5f64.sin();
        for _ in 0..16 {
            v *= v;
        }
        assert_eq!(e.eval(&[1.5]).to_bits(), v.to_bits());
    }

    proptest! {
        /// Random definitions `a` (of the slots) and `b` (of the slots and
        /// `a`), used several times by a random expression: the expression
        /// with each recurring definition kept in a register gives the same
        /// bits as with every use evaluated where it stands, and the value
        /// the trees give.
        #[test]
        fn kept_definitions_give_the_same_bits(
            ta in tree(), tb in tree(), te in tree(),
            s in proptest::collection::vec(-5.0f64..5.0, 3),
        ) {
            let (text, kept, plain) = with_recurring_definitions(&ta, &tb, &te);
            prop_assume!(kept.is_some());
            let (kept, plain) = (kept.unwrap().eval(&s), plain.eval(&s));
            prop_assert!(kept.to_bits() == plain.to_bits() || (kept.is_nan() && plain.is_nan()),
                "{}: kept {} plain {}", text, kept, plain);
            let (va, vt) = (ta.value(&s), tb.value(&s));
            let vb = vt * va;
            let tree = te.value(&s) + va * vb - va.min(vb);
            prop_assert!(kept == tree || (kept.is_nan() && tree.is_nan()) || (kept - tree).abs() <= 1e-9 * tree.abs().max(1.0),
                "{}: tape {} trees {}", text, kept, tree);
        }

        #[test]
        fn tape_matches_the_tree(t in tree(), s in proptest::collection::vec(-5.0f64..5.0, 3)) {
            let e = Expression::compile(&t.text(), &names).unwrap();
            let (a, b) = (e.eval(&s), t.value(&s));
            prop_assert!(a == b || (a.is_nan() && b.is_nan()) || (a - b).abs() <= 1e-12 * b.abs().max(1.0),
                "{}: tape {} tree {}", t.text(), a, b);
        }
    }

    /// The tape run on a stack, operation by operation: the reference the
    /// program must agree with bit for bit.
    fn on_a_stack(ops: &[Op], slots: &[f64]) -> f64 {
        let (mut stack, mut registers) = (Vec::new(), [0.0; REGISTERS]);
        for op in ops {
            match *op {
                Op::Const(v) => stack.push(v),
                Op::Load(s) => stack.push(slots[s as usize]),
                Op::Recall(r) => stack.push(registers[r as usize]),
                Op::Keep(r) => registers[r as usize] = stack[stack.len() - 1],
                Op::Neg | Op::Not | Op::Binary(_) | Op::Call(_) => {
                    let args = stack.split_off(stack.len() - op.operands());
                    stack.push(match *op {
                        Op::Neg => -args[0],
                        Op::Not => f64::from(args[0] == 0.0),
                        Op::Binary(b) => b.apply(args[0], args[1]),
                        Op::Call(f) => f.apply(&args),
                        _ => unreachable!("operations only"),
                    });
                }
            }
        }
        stack[0]
    }

    proptest! {
        /// Random expressions over three slots, with two definitions used
        /// several times and kept in registers (as the compiler keeps
        /// them), and the same with every use written out: the program,
        /// on one memory and on its cells, gives the stack's bits.
        #[test]
        fn the_program_gives_the_stacks_bits(
            ta in tree(), tb in tree(), te in tree(),
            s in proptest::collection::vec(-5.0f64..5.0, 3),
        ) {
            let (text, kept, plain) = with_recurring_definitions(&ta, &tb, &te);
            for e in kept.iter().chain([&plain]) {
                let program = Program::of(&e.ops);
                let stack = on_a_stack(&e.ops, &s);
                for value in [program.run(&s), program.run_on_cells(&s)] {
                    prop_assert!(value.to_bits() == stack.to_bits() || (value.is_nan() && stack.is_nan()),
                        "{}: program {} stack {}", text, value, stack);
                }
            }
        }
    }

    proptest! {
        /// Expressions reading the same random definitions (kept in
        /// registers, and written out), evaluated together: each value the
        /// bits of its own evaluation.
        #[test]
        fn shared_evaluation_gives_each_expressions_bits(
            ta in tree(), tb in tree(), te in tree(), tf in tree(),
            s in proptest::collection::vec(-5.0f64..5.0, 3),
        ) {
            let (_, kept, plain) = with_recurring_definitions(&ta, &tb, &te);
            let (_, other, _) = with_recurring_definitions(&ta, &tb, &tf);
            let expressions: Vec<Expression> = kept.into_iter().chain(other).chain([plain]).collect();
            let mut out = vec![0.0; expressions.len()];
            Shared::of(&expressions).eval(&expressions, &s, &mut out);
            for (e, value) in expressions.iter().zip(&out) {
                prop_assert_eq!(e.eval(&s).to_bits(), value.to_bits());
            }
        }
    }

    #[test]
    fn an_operation_two_expressions_share_is_run_once() {
        let (a, b) = ("sin(x) * y + z", "0");
        let defs = |texts: &[&str]| -> Vec<Expression> {
            let mut d = definitions(&[a, b]);
            texts
                .iter()
                .map(|t| {
                    Expression::compile(t, &with_definitions)
                        .unwrap()
                        .inline(&mut d, usize::MAX)
                        .unwrap()
                })
                .collect()
        };
        // sin(x), * y, + z once; + x and * y of `a`; `- b` with b = 0 is no
        // operation.
        let flows = defs(&["a + x - b", "a * y - b"]);
        let shared = Shared::of(&flows);
        assert_eq!(shared.joint.as_ref().map(|j| j.operations()), Some(5));
        let mut out = [0.0; 2];
        shared.eval(&flows, &[0.3, -1.2, 2.5], &mut out);
        let own: Vec<u64> = flows
            .iter()
            .map(|f| f.eval(&[0.3, -1.2, 2.5]).to_bits())
            .collect();
        assert_eq!(out.map(f64::to_bits).to_vec(), own);
        // `x - (-0)` is `x + 0`, not `x`: at x = -0 it is +0.
        let signed = defs(&["sin(x) - (-0)", "sin(x) * y"]);
        let mut out = [0.0; 2];
        Shared::of(&signed).eval(&signed, &[-0.0, 1.0, 0.0], &mut out);
        assert_eq!(out[0].to_bits(), 0.0f64.to_bits());
        // `+ 0` and `+ (-0)` are two operations: at x = -0 they give +0
        // and -0.
        let zeros = defs(&["sin(x) + 0", "sin(x) + (-0)"]);
        let shared = Shared::of(&zeros);
        assert_eq!(shared.joint.as_ref().map(|j| j.operations()), Some(3));
        shared.eval(&zeros, &[-0.0, 1.0, 0.0], &mut out);
        assert_eq!(
            out.map(f64::to_bits),
            [0.0f64.to_bits(), (-0.0f64).to_bits()]
        );
        // One tape alone is run as it is.
        assert!(Shared::of(&defs(&["a + x", "x + y"])).joint.is_none());
    }

    #[test]
    fn every_operator_and_function_run_jointly_gives_its_own_bits() {
        let binary = [
            "+", "-", "*", "/", "%", "^", "<", "<=", ">", ">=", "==", "!=", "&&", "||",
        ];
        let texts = binary
            .iter()
            .map(|op| format!("sin(x) {op} y"))
            .chain(["-sin(x)".into(), "!sin(x)".into()])
            .chain(Function::ALL.iter().map(|f| {
                let args = ["sin(x)", "y", "z"][..f.arity()].join(", ");
                format!("{}({args})", f.name())
            }));
        for text in texts {
            let flows = [
                Expression::compile(&text, &names).unwrap(),
                Expression::compile("cos(x) * y", &names).unwrap(),
            ];
            let shared = Shared::of(&flows);
            assert!(shared.joint.is_some(), "{text}");
            for slots in [
                [0.3, -1.2, 2.5],
                [-0.0, 0.0, 1.0],
                [2.0, 3.0, -1.0],
                [1.5, 0.0, 0.0],
            ] {
                let mut out = [0.0; 2];
                shared.eval(&flows, &slots, &mut out);
                for (f, value) in flows.iter().zip(out) {
                    let own = f.eval(&slots);
                    assert!(
                        own.to_bits() == value.to_bits() || (own.is_nan() && value.is_nan()),
                        "{text} at {slots:?}: {value} jointly, {own} alone"
                    );
                }
            }
        }
    }

    #[test]
    fn flows_beyond_the_stack_memory_run_jointly_in_an_allocated_one() {
        // 43 operations (at most 48 fit a joint program), 13 constants and
        // 2 slots.
        let terms: Vec<String> = (1..=13).map(|k| format!("sin(x + {k}.5)")).collect();
        let flows = [
            Expression::compile(&terms.join(" + "), &names).unwrap(),
            Expression::compile(&format!("y * ({})", terms[..5].join(" - ")), &names).unwrap(),
        ];
        let shared = Shared::of(&flows);
        let entries = shared.joint.as_ref().map(|j| j.entries());
        assert!(entries.is_some_and(|e| e > 48), "{entries:?}");
        let slots = [0.3, -1.2, 2.5];
        let mut out = [0.0; 2];
        shared.eval(&flows, &slots, &mut out);
        for (f, value) in flows.iter().zip(out) {
            assert_eq!(f.eval(&slots).to_bits(), value.to_bits());
        }
    }

    #[test]
    fn every_operation_reads_its_operands_in_order() {
        let slots = [3.0, -2.0, 0.5];
        for text in [
            "x - y/z",
            "-(x - y) + !(z > 1)",
            "atan2(y, x) - clamp(x, y, z)",
            "if(x > y, sqrt(x), y^2) % z",
            "min(x, y) * max(y, z) + (x >= y && y != z || x == z)",
        ] {
            let e = Expression::compile(text, &names).unwrap();
            let (program, stack) = (Program::of(&e.ops).run(&slots), on_a_stack(&e.ops, &slots));
            assert_eq!(program.to_bits(), stack.to_bits(), "{text}");
        }
    }
}
