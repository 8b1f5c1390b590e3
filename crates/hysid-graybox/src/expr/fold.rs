//! Constants folded as a tape is written, the parameters bound into the
//! tapes, and a friction's sliding direction chosen in the comparisons
//! that read it.

use super::Expression;
use super::tape::{Function, Op, Program};

/// The value of a tape that reads no slot (an operation on constants).
pub(super) fn fold_constants(ops: &[Op]) -> f64 {
    Program::of(ops).run(&[])
}

/// Appends `op` to a postfix tape, replacing it and its operands by their
/// value when every operand is a constant. An operand is constant exactly
/// when its own (already folded) tape is one `Const`, so the last
/// `operands()` instructions are all constants exactly then. A `Keep` is
/// never folded: a later `Recall` reads its register.
pub(super) fn push_folded(ops: &mut Vec<Op>, op: Op) {
    let k = op.operands();
    let n = ops.len();
    ops.push(op);
    let keeps = matches!(op, Op::Keep(_));
    if k > 0 && !keeps && ops[n - k..n].iter().all(|o| matches!(o, Op::Const(_))) {
        let v = fold_constants(&ops[n - k..]);
        ops.truncate(n - k);
        ops.push(Op::Const(v));
    }
}

impl Expression {
    /// The expression with the slots `first..first + values.len()` replaced
    /// by `values` and folded: a tape specialised to one parameter vector.
    pub fn bind(&self, first: u32, values: &[f64]) -> Expression {
        let mut ops = Vec::with_capacity(self.ops.len());
        for op in &self.ops {
            let op = match *op {
                Op::Load(s) if s >= first && ((s - first) as usize) < values.len() => {
                    Op::Const(values[(s - first) as usize])
                }
                op => op,
            };
            push_folded(&mut ops, op);
        }
        Expression::from_ops(ops)
    }
}

/// Where the operand of a postfix tape that ends just before `end` starts:
/// walking back, each instruction takes its operands and gives one value.
fn operand_start(ops: &[Op], end: usize) -> Option<usize> {
    let mut need = 1;
    let mut i = end;
    while need > 0 {
        i = i.checked_sub(1)?;
        need = need - 1 + ops[i].operands();
    }
    Some(i)
}

impl Expression {
    /// The expression where the value in slot `slot` is known to be
    /// non-zero, of the sign `positive` says: its comparisons with the
    /// number 0 (`v > 0`, `0 < v`, `v <= 0`, ...) and `sign(v)` are
    /// decided, constants folded, and an `if` whose condition became a
    /// number keeps the branch it selects (both stay where the other
    /// branch sets a register a later instruction may read). `None` when
    /// nothing is decided.
    pub fn with_sign(&self, slot: u32, positive: bool) -> Option<Expression> {
        let value = if positive { 1.0 } else { -1.0 };
        let mut ops: Vec<Op> = Vec::with_capacity(self.ops.len());
        let mut decided = false;
        for &op in &self.ops {
            let n = ops.len();
            let folded = match op {
                Op::Binary(b) if b.compares() && n >= 2 => match (ops[n - 2], ops[n - 1]) {
                    (Op::Load(s), Op::Const(c)) if s == slot && c == 0.0 => {
                        Some((n - 2, b.apply(value, 0.0)))
                    }
                    (Op::Const(c), Op::Load(s)) if s == slot && c == 0.0 => {
                        Some((n - 2, b.apply(0.0, value)))
                    }
                    _ => None,
                },
                Op::Call(Function::Sign) if ops.last() == Some(&Op::Load(slot)) => {
                    Some((n - 1, value))
                }
                _ => None,
            };
            if let Some((from, v)) = folded {
                ops.truncate(from);
                push_folded(&mut ops, Op::Const(v));
                decided = true;
                continue;
            }
            if op == Op::Call(Function::If)
                && let Some(kept) = chosen_branch(&ops)
            {
                let condition = kept.1;
                let branch = ops[kept.0.clone()].to_vec();
                ops.truncate(condition);
                ops.extend(branch);
                decided = true;
                continue;
            }
            push_folded(&mut ops, op);
        }
        decided.then(|| Expression::from_ops(ops))
    }
}

/// For an `if` about to be appended to `ops`: where the branch its
/// condition selects lies in `ops`, and where the condition starts, when
/// the condition is a number and the other branch sets no register.
fn chosen_branch(ops: &[Op]) -> Option<(std::ops::Range<usize>, usize)> {
    let end = ops.len();
    let b = operand_start(ops, end)?;
    let a = operand_start(ops, b)?;
    let condition = operand_start(ops, a)?;
    let Op::Const(c) = ops[condition] else {
        return None;
    };
    if a != condition + 1 {
        return None;
    }
    let (kept, dropped) = if c != 0.0 {
        (a..b, b..end)
    } else {
        (b..end, a..b)
    };
    let sets_register = ops[dropped].iter().any(|o| matches!(o, Op::Keep(_)));
    (!sets_register).then_some((kept, condition))
}
