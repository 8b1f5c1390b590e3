//! Relations (`a >= b`, `a < b`, ...): guards and invariants, read as the
//! signed margin of their surface.

use super::parse::{Builder, is_ordering, parse, strip_root};
use super::tape::{Binary, Op};
use super::{ExprError, Expression};
use evalexpr::Operator;

/// The direction in which a relation's surface is crossed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Crossing {
    /// `a >= b` or `a > b`: the surface `a - b` crosses zero upwards.
    Rising,
    /// `a <= b` or `a < b`: downwards.
    Falling,
    /// `a == b`: either way.
    Either,
}

/// A relation `a >= b`, `a <= b` or `a == b`, compiled as the surface
/// `a - b` and the direction that enters the set.
#[derive(Debug, Clone, PartialEq)]
pub struct Relation {
    /// `a - b`.
    pub surface: Expression,
    /// Which crossing of the surface enters the set.
    pub crossing: Crossing,
}

impl Relation {
    /// Parses `a >= b` (also `>`, `<=`, `<`, `==`) and compiles `a - b`.
    pub fn compile(text: &str, resolve: &dyn Fn(&str) -> Option<u32>) -> Result<Self, ExprError> {
        Self::compiled(text, resolve).map_err(|e| super::in_other_words(text, e))
    }

    /// [`Relation::compile`] before an error is put in other words.
    fn compiled(text: &str, resolve: &dyn Fn(&str) -> Option<u32>) -> Result<Self, ExprError> {
        let root = parse(text)?;
        let node = strip_root(&root.0);
        let crossing = match node.operator() {
            Operator::Gt | Operator::Geq => Crossing::Rising,
            Operator::Lt | Operator::Leq => Crossing::Falling,
            Operator::Eq => Crossing::Either,
            _ => return Err(ExprError::NotRelation(text.to_string())),
        };
        let [lhs, rhs] = node.children() else {
            return Err(ExprError::NotNumeric(text.to_string()));
        };
        if [lhs, rhs].iter().any(|side| is_ordering(strip_root(side))) {
            return Err(ExprError::ChainedComparison(text.to_string()));
        }
        let mut b = Builder::new(text, resolve);
        b.node(lhs)?;
        b.node(rhs)?;
        b.op(Op::Binary(Binary::Sub));
        Ok(Relation {
            surface: b.finish()?,
            crossing,
        })
    }

    /// The signed margin: non-negative inside the set (`a - b` for `>=`,
    /// `b - a` for `<=`, `-|a - b|` for `==`).
    #[inline]
    pub fn margin(&self, slots: &[f64]) -> f64 {
        let g = self.surface.eval(slots);
        match self.crossing {
            Crossing::Rising => g,
            Crossing::Falling => -g,
            Crossing::Either => -g.abs(),
        }
    }
}
