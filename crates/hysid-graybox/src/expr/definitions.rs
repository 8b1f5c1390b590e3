//! Definitions inlined into the expressions that read them: each
//! definition's expansion summarised once per mode, written plainly or,
//! where it recurs, once into a register.

use super::fold::{fold_constants, push_folded};
use super::tape::{MAX_DEPTH, Op, REGISTERS};
use super::{Expression, Form};
use std::collections::HashMap;
use std::rc::Rc;

impl Expression {
    /// The expression with every definition it reads (slots from
    /// `defs`' first on, which may use other definitions) replaced by that
    /// definition's tape and folded: a flow written with definitions
    /// becomes one expression of the states, inputs and parameters. A
    /// definition that the result would evaluate more than once is
    /// evaluated once into a register ([`REGISTERS`]) and read back where it
    /// recurs, unless the result is affine (whose evaluation reads no
    /// tape). A definition that folds to a constant is written as that
    /// constant.
    ///
    /// The work is proportional to the result: each definition's
    /// expansion is summarised once per mode ([`Definitions::new`]), so the
    /// size of the plain expansion is known before it is written, and the
    /// tape written holds every operation walked. A result of more than
    /// `limit` operations is refused ([`InlineError::TooLarge`]): the plain
    /// expansion is written when it fits, else the one with registers,
    /// when it fits.
    pub fn inline(&self, defs: &mut Definitions, limit: usize) -> Result<Expression, InlineError> {
        let plain = summarise(&self.ops, defs.first, &defs.summary, &mut Vec::new());
        if let Some(v) = plain.constant {
            return Ok(Expression::constant(v));
        }
        let uses = defs.count(&self.ops);
        let recurs = uses.values().any(|&n| n > 1);
        let e = if plain.size <= limit as u64 {
            let mut ops = Vec::with_capacity(plain.size as usize);
            defs.expand(&mut ops, &self.ops, None, limit)?;
            let e = Expression::from_ops(ops);
            if recurs && matches!(e.form, Form::Tape(_)) {
                // Registers add their keeps: within them of the limit, the
                // plain tape stays.
                defs.shared(&self.ops, &uses, limit).unwrap_or(e)
            } else {
                e
            }
        } else if recurs {
            defs.shared(&self.ops, &uses, limit)?
        } else {
            return Err(InlineError::TooLarge);
        };
        if e.depth() > MAX_DEPTH {
            return Err(InlineError::TooDeep);
        }
        Ok(e)
    }
}

/// Why [`Expression::inline`] refuses an expression.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InlineError {
    /// The result needs more than [`MAX_DEPTH`] pending operands.
    TooDeep,
    /// The result holds more operations than the limit given.
    TooLarge,
}

/// Why a mode's definitions cannot be written into its expressions
/// ([`Definitions::new`]); indices are the definitions'.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DefinitionError {
    /// Definitions that read each other in a ring, from the one of least
    /// index: each reads the next, the last reads the first (one entry: a
    /// definition that reads itself).
    Cycle(Vec<usize>),
    /// Written out, the definition needs more than [`MAX_DEPTH`] pending
    /// operands.
    TooDeep(usize),
}

/// What a definition's tape becomes once the definitions it reads are
/// written into it without registers, as [`push_folded`] folds it: its
/// value when it folds to a constant, else its size and its deepest
/// stack. Sizes saturate (a definition used twice by the next, again and
/// again, doubles at each step).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Summary {
    constant: Option<f64>,
    size: u64,
    peak: u64,
}

impl Summary {
    fn constant(v: f64) -> Self {
        Summary {
            constant: Some(v),
            size: 1,
            peak: 1,
        }
    }

    fn slot() -> Self {
        Summary {
            constant: None,
            size: 1,
            peak: 1,
        }
    }
}

/// The definition read from slot `s`, if it is one: its index.
fn definition_of(s: u32, first: u32, count: usize) -> Option<usize> {
    let i = s.checked_sub(first)? as usize;
    (i < count).then_some(i)
}

/// The [`Summary`] of the tape `ops` with the definitions of `summary`
/// (slots from `first` on) written in. The operands of an operation are
/// the last entries of the stack: their tapes lie one after the other, so
/// the deepest stack of the result is the deepest of `j + peak` over its
/// operands `j = 0, 1, ..`, and an operation whose operands are all
/// constants folds exactly as [`push_folded`] folds it (the same
/// [`fold_constants`] on the same constants). `stack` is scratch space.
fn summarise(ops: &[Op], first: u32, summary: &[Summary], stack: &mut Vec<Summary>) -> Summary {
    stack.clear();
    for op in ops {
        let entry = match *op {
            Op::Const(v) => Summary::constant(v),
            Op::Load(s) => {
                definition_of(s, first, summary.len()).map_or_else(Summary::slot, |i| summary[i])
            }
            Op::Recall(_) => Summary::slot(),
            op => {
                let k = op.operands();
                let args = &stack[stack.len() - k..];
                let folds = !matches!(op, Op::Keep(_)) && args.iter().all(|a| a.constant.is_some());
                let entry = if folds {
                    let mut tape = [Op::Const(0.0); 4];
                    for (t, a) in tape.iter_mut().zip(args) {
                        *t = Op::Const(a.constant.unwrap_or_default());
                    }
                    tape[k] = op;
                    Summary::constant(fold_constants(&tape[..=k]))
                } else {
                    let size = args.iter().fold(1u64, |s, a| s.saturating_add(a.size));
                    let peak = args
                        .iter()
                        .enumerate()
                        .map(|(j, a)| a.peak.saturating_add(j as u64))
                        .max()
                        .unwrap_or(1);
                    Summary {
                        constant: None,
                        size,
                        peak,
                    }
                };
                stack.truncate(stack.len() - k);
                entry
            }
        };
        stack.push(entry);
    }
    stack.pop().unwrap_or_else(Summary::slot)
}

/// The definitions of one mode, ready to be written into its expressions
/// ([`Expression::inline`]): each definition's tape as written, what it
/// becomes written out (its constant value, or its size and deepest
/// stack), and, made when an expression first reads it, its tape with
/// the constant definitions it reads folded in (every operation of that
/// tape stays in any expansion, so writing a definition out costs what it
/// adds to the result).
#[derive(Debug)]
pub struct Definitions {
    first: u32,
    written: Vec<Rc<Expression>>,
    summary: Vec<Summary>,
    folded: Vec<Option<Vec<Op>>>,
}

/// A definition's state in the walk of [`Definitions::new`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Walk {
    New,
    Open,
    Done,
    Cyclic,
}

impl Definitions {
    /// The definitions `written[i]` of the slots `first + i`. Walks them
    /// in dependency order, without recursion, once each: the first ring
    /// of definitions that read each other the walk meets, from the
    /// definitions in index order, is refused ([`DefinitionError::Cycle`]);
    /// then each is summarised
    /// after those it reads, and the first found whose expansion needs
    /// more than [`MAX_DEPTH`] pending operands (its own definitions
    /// within it) is refused ([`DefinitionError::TooDeep`]).
    pub fn new(first: u32, written: Vec<Rc<Expression>>) -> Result<Self, DefinitionError> {
        let n = written.len();
        let mut walk = vec![Walk::New; n];
        let mut order = Vec::with_capacity(n);
        // (definition, next operation to look at, reaches a cycle)
        let mut open: Vec<(usize, usize, bool)> = Vec::new();
        let mut ring: Option<Vec<usize>> = None;
        for root in 0..n {
            if walk[root] != Walk::New {
                continue;
            }
            walk[root] = Walk::Open;
            open.push((root, 0, false));
            while let Some((i, pos, cyclic)) = open.last_mut() {
                let ops = &written[*i].ops;
                let mut next = None;
                // The first open definition this one reads: the open path
                // from it to this one is a ring.
                let mut closes = None;
                while *pos < ops.len() {
                    let op = ops[*pos];
                    *pos += 1;
                    if let Op::Load(s) = op
                        && let Some(j) = definition_of(s, first, n)
                    {
                        match walk[j] {
                            Walk::New => {
                                next = Some(j);
                                break;
                            }
                            Walk::Open => {
                                *cyclic = true;
                                closes = closes.or(Some(j));
                            }
                            Walk::Cyclic => *cyclic = true,
                            Walk::Done => {}
                        }
                    }
                }
                if let Some(j) = closes
                    && ring.is_none()
                    && let Some(from) = open.iter().position(|&(d, _, _)| d == j)
                {
                    let mut members: Vec<usize> = open[from..].iter().map(|&(d, _, _)| d).collect();
                    // Named from its first definition in index order.
                    if let Some(least) = (0..members.len()).min_by_key(|&k| members[k]) {
                        members.rotate_left(least);
                    }
                    ring = Some(members);
                }
                if let Some(j) = next {
                    walk[j] = Walk::Open;
                    open.push((j, 0, false));
                    continue;
                }
                let (i, _, cyclic) = *open.last().expect("an open definition");
                open.pop();
                walk[i] = if cyclic { Walk::Cyclic } else { Walk::Done };
                if let Some(parent) = open.last_mut() {
                    parent.2 |= cyclic;
                }
                order.push(i);
            }
        }
        if let Some(ring) = ring {
            return Err(DefinitionError::Cycle(ring));
        }
        let mut summary = vec![Summary::slot(); n];
        let mut stack = Vec::new();
        for i in order {
            summary[i] = summarise(&written[i].ops, first, &summary, &mut stack);
            if summary[i].peak > MAX_DEPTH as u64 {
                return Err(DefinitionError::TooDeep(i));
            }
        }
        Ok(Definitions {
            first,
            written,
            folded: vec![None; n],
            summary,
        })
    }

    fn index(&self, s: u32) -> Option<usize> {
        definition_of(s, self.first, self.written.len())
    }

    /// The index of a definition read from slot `s` that does not fold to
    /// a constant.
    fn variable(&self, s: u32) -> Option<usize> {
        self.index(s)
            .filter(|&i| self.summary[i].constant.is_none())
    }

    /// Makes the tape of definition `i` with the constant definitions it
    /// reads folded in, once.
    fn fold(&mut self, i: usize) {
        if self.folded[i].is_some() {
            return;
        }
        let mut ops = Vec::with_capacity(self.written[i].ops.len());
        for op in &self.written[i].ops {
            match *op {
                Op::Load(s) => match self.index(s).and_then(|j| self.summary[j].constant) {
                    Some(v) => push_folded(&mut ops, Op::Const(v)),
                    None => push_folded(&mut ops, *op),
                },
                op => push_folded(&mut ops, op),
            }
        }
        self.folded[i] = Some(ops);
    }

    /// The uses of every definition that does not fold to a constant in
    /// the expansion of `ops`, a definition's own uses counted once (a kept
    /// definition is expanded once), with their folded tapes made.
    fn count(&mut self, ops: &[Op]) -> HashMap<usize, usize> {
        let mut uses = HashMap::new();
        let mut pending = Vec::new();
        let note = |uses: &mut HashMap<usize, usize>, pending: &mut Vec<usize>, i: usize| {
            let n = uses.entry(i).or_insert(0);
            *n += 1;
            if *n == 1 {
                pending.push(i);
            }
        };
        for op in ops {
            if let Op::Load(s) = *op
                && let Some(i) = self.variable(s)
            {
                note(&mut uses, &mut pending, i);
            }
        }
        while let Some(i) = pending.pop() {
            self.fold(i);
            let folded = self.folded[i].as_deref().unwrap_or_default();
            for op in folded {
                if let Op::Load(s) = *op
                    && let Some(j) = self.variable(s)
                {
                    note(&mut uses, &mut pending, j);
                }
            }
        }
        uses
    }

    /// Appends `ops` to `out` with every definition written out, folding
    /// constants; with `sharing` (the uses of [`Definitions::count`]) a
    /// definition used more than once is kept in a register after its
    /// first expansion and read back at the others, while registers last.
    /// `Err` once `out` holds more than `limit` operations.
    fn expand(
        &self,
        out: &mut Vec<Op>,
        ops: &[Op],
        sharing: Option<&HashMap<usize, usize>>,
        limit: usize,
    ) -> Result<(), InlineError> {
        let mut register: HashMap<usize, u8> = HashMap::new();
        // (tape, next operation, the definition it is)
        let mut tapes: Vec<(&[Op], usize, Option<usize>)> = vec![(ops, 0, None)];
        while let Some((tape, pos, def)) = tapes.last_mut() {
            let Some(&op) = tape.get(*pos) else {
                let def = *def;
                tapes.pop();
                if let (Some(i), Some(uses)) = (def, sharing)
                    && uses.get(&i).is_some_and(|&n| n > 1)
                    && register.len() < REGISTERS
                {
                    let r = register.len() as u8;
                    out.push(Op::Keep(r));
                    register.insert(i, r);
                }
                continue;
            };
            *pos += 1;
            if let Op::Load(s) = op
                && let Some(i) = self.index(s)
            {
                if let Some(v) = self.summary[i].constant {
                    push_folded(out, Op::Const(v));
                } else if let Some(&r) = register.get(&i) {
                    out.push(Op::Recall(r));
                } else {
                    let folded = self.folded[i].as_deref().unwrap_or_default();
                    tapes.push((folded, 0, Some(i)));
                }
            } else {
                push_folded(out, op);
            }
            if out.len() > limit {
                return Err(InlineError::TooLarge);
            }
        }
        Ok(())
    }

    /// The expansion of `ops` with recurring definitions in registers.
    fn shared(
        &self,
        ops: &[Op],
        uses: &HashMap<usize, usize>,
        limit: usize,
    ) -> Result<Expression, InlineError> {
        let mut out = Vec::with_capacity(ops.len());
        self.expand(&mut out, ops, Some(uses), limit)?;
        Ok(Expression::from_ops(out))
    }
}
