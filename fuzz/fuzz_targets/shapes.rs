//! Structure-aware gray-box expressions for the `expression` and
//! `model_graybox` targets: shapes drawn by `arbitrary` and written as
//! text, so that a few input bytes reach the sizes the readers limit
//! (sums of thousands of terms, parentheses, signs and function names
//! nested past `MAX_NESTING`, texts past `MAX_LENGTH`) as well as small
//! well-formed expressions and odd tokens.

use hysid_graybox::expr::{MAX_LENGTH, MAX_NESTING};
use libfuzzer_sys::arbitrary::{self, Arbitrary};

/// Longest text written from one shape: past the length limit, short of
/// making every run slow.
pub const TEXT_BUDGET: usize = 2 * MAX_LENGTH;

/// A count drawn in one of four ranges: small, around the nesting limit,
/// up to the length limit, and just past it (past the limits on
/// definitions and modes too).
#[derive(Arbitrary, Debug, Clone, Copy)]
pub struct Size {
    range: u8,
    value: u8,
}

impl Size {
    pub fn get(self) -> usize {
        let v = usize::from(self.value);
        match self.range % 4 {
            0 => v % 16,
            1 => MAX_NESTING - 2 + v % 5,
            2 => v * 40,
            _ => MAX_LENGTH + v * 10,
        }
    }
}

#[derive(Arbitrary, Debug, Clone, Copy)]
pub enum Operator {
    Add,
    Sub,
    Mul,
    Div,
    Rem,
    Pow,
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
    And,
    Or,
}

impl Operator {
    fn text(self) -> &'static str {
        match self {
            Operator::Add => " + ",
            Operator::Sub => " - ",
            Operator::Mul => "*",
            Operator::Div => "/",
            Operator::Rem => " % ",
            Operator::Pow => "^",
            Operator::Lt => " < ",
            Operator::Le => " <= ",
            Operator::Gt => " > ",
            Operator::Ge => " >= ",
            Operator::Eq => " == ",
            Operator::Ne => " != ",
            Operator::And => " && ",
            Operator::Or => " || ",
        }
    }
}

/// The functions of the grammar, and a name that is none.
const FUNCTIONS: [&str; 16] = [
    "abs", "sign", "sqrt", "exp", "ln", "sin", "cos", "tan", "tanh", "atan", "min", "max", "atan2",
    "clamp", "if", "nope",
];

/// Tokens that are odd in an expression: comments, strings, assignments,
/// sequences, a dangling exponent.
const ODD: [&str; 12] = [
    "/*", "*/", "//", "\n", "\"", "\"(\"", "=", ";", ",", "1e-", "&", "true",
];

/// How [`Shape::Nest`] wraps its shape once.
#[derive(Arbitrary, Debug, Clone, Copy)]
pub enum Wrap {
    Parentheses,
    Minus,
    Not,
    /// `f(...)`.
    Call(u8),
    /// `f ...` (evalexpr calls a name followed by a value).
    Bare(u8),
}

#[derive(Arbitrary, Debug)]
pub enum Shape {
    /// A name of the file, by index.
    Name(u8),
    Integer(u16),
    Float(f64),
    /// `m e -k`.
    Scientific(u8, u8),
    Odd(u8),
    Minus(Box<Shape>),
    Not(Box<Shape>),
    Binary(Box<Shape>, Operator, Box<Shape>),
    Call(u8, Vec<Shape>),
    Parentheses(Box<Shape>),
    /// `shape op shape op ...`, [`Size`] times.
    Repeat(Size, Operator, Box<Shape>),
    /// `shape` inside [`Size`] wrappings.
    Nest(Size, Wrap, Box<Shape>),
}

impl Shape {
    /// The text, its names taken from `names` (by index, modulo), cut
    /// once it passes [`TEXT_BUDGET`].
    pub fn text(&self, names: &[String]) -> String {
        let mut out = String::new();
        self.write(names, &mut out);
        out
    }

    fn write(&self, names: &[String], out: &mut String) {
        if out.len() > TEXT_BUDGET {
            return;
        }
        let function = |i: u8| FUNCTIONS[usize::from(i) % FUNCTIONS.len()];
        match self {
            Shape::Name(i) => match names.len() {
                0 => out.push('x'),
                n => out.push_str(&names[usize::from(*i) % n]),
            },
            Shape::Integer(v) => out.push_str(&v.to_string()),
            Shape::Float(v) => out.push_str(&format!("{v:?}")),
            Shape::Scientific(m, k) => out.push_str(&format!("{m}e-{k}")),
            Shape::Odd(i) => out.push_str(ODD[usize::from(*i) % ODD.len()]),
            Shape::Minus(a) => {
                out.push('-');
                a.write(names, out);
            }
            Shape::Not(a) => {
                out.push('!');
                a.write(names, out);
            }
            Shape::Binary(a, op, b) => {
                a.write(names, out);
                out.push_str(op.text());
                b.write(names, out);
            }
            Shape::Call(f, args) => {
                out.push_str(function(*f));
                out.push('(');
                for (i, a) in args.iter().enumerate() {
                    if i > 0 {
                        out.push_str(", ");
                    }
                    a.write(names, out);
                }
                out.push(')');
            }
            Shape::Parentheses(a) => {
                out.push('(');
                a.write(names, out);
                out.push(')');
            }
            Shape::Repeat(size, op, a) => {
                let piece = a.text(names);
                for i in 0..size.get().max(1) {
                    if out.len() > TEXT_BUDGET {
                        break;
                    }
                    if i > 0 {
                        out.push_str(op.text());
                    }
                    out.push_str(&piece);
                }
            }
            Shape::Nest(size, wrap, a) => {
                let levels = size.get().min(TEXT_BUDGET / 4);
                let (open, close) = match *wrap {
                    Wrap::Parentheses => ("(".to_string(), ")"),
                    Wrap::Minus => ("-".to_string(), ""),
                    Wrap::Not => ("!".to_string(), ""),
                    Wrap::Call(f) => (format!("{}(", function(f)), ")"),
                    Wrap::Bare(f) => (format!("{} ", function(f)), ""),
                };
                out.push_str(&open.repeat(levels));
                a.write(names, out);
                out.push_str(&close.repeat(levels));
            }
        }
    }
}
