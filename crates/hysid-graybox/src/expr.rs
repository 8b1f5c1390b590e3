//! Expressions of a gray-box model: parsed once by `evalexpr`, compiled into
//! a postfix tape over numbered slots, evaluated without parsing or
//! allocating.
//!
//! The grammar is evalexpr's (`+ - * / % ^`, unary `-`, comparisons
//! `< <= > >= == !=`, `&& || !`, parentheses, function calls); every
//! number is a 64-bit float (`1/2` is `0.5`), and a comparison is `1` when
//! true and `0` when false. The functions are [`Function`]'s.

use evalexpr::{DefaultNumericTypes, Node, Operator, Value};

/// Deepest evaluation stack an expression may need (checked at compile).
pub const MAX_DEPTH: usize = 32;

/// Registers of one tape: values of definitions that an expression uses
/// more than once, kept at their first evaluation and read again at the
/// others ([`Expression::inline`]). Past this many, a definition is
/// evaluated again where it recurs.
pub const REGISTERS: usize = 16;

/// The functions an expression may call, with their arities.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Function {
    /// `abs(x)`.
    Abs,
    /// `sign(x)`: -1, 0 or 1.
    Sign,
    /// `sqrt(x)`.
    Sqrt,
    /// `exp(x)`.
    Exp,
    /// `ln(x)`, natural logarithm.
    Ln,
    /// `sin(x)`.
    Sin,
    /// `cos(x)`.
    Cos,
    /// `tan(x)`.
    Tan,
    /// `tanh(x)`.
    Tanh,
    /// `atan(x)`.
    Atan,
    /// `min(a, b)`.
    Min,
    /// `max(a, b)`.
    Max,
    /// `atan2(y, x)`.
    Atan2,
    /// `clamp(x, low, high)`.
    Clamp,
    /// `if(condition, a, b)`: `a` when the condition is non-zero, else `b`.
    If,
}

impl Function {
    /// Every function, for listings.
    pub const ALL: [Function; 15] = [
        Function::Abs,
        Function::Sign,
        Function::Sqrt,
        Function::Exp,
        Function::Ln,
        Function::Sin,
        Function::Cos,
        Function::Tan,
        Function::Tanh,
        Function::Atan,
        Function::Min,
        Function::Max,
        Function::Atan2,
        Function::Clamp,
        Function::If,
    ];

    /// The name in an expression.
    pub fn name(self) -> &'static str {
        match self {
            Function::Abs => "abs",
            Function::Sign => "sign",
            Function::Sqrt => "sqrt",
            Function::Exp => "exp",
            Function::Ln => "ln",
            Function::Sin => "sin",
            Function::Cos => "cos",
            Function::Tan => "tan",
            Function::Tanh => "tanh",
            Function::Atan => "atan",
            Function::Min => "min",
            Function::Max => "max",
            Function::Atan2 => "atan2",
            Function::Clamp => "clamp",
            Function::If => "if",
        }
    }

    /// Number of arguments.
    pub fn arity(self) -> usize {
        match self {
            Function::Min | Function::Max | Function::Atan2 => 2,
            Function::Clamp | Function::If => 3,
            _ => 1,
        }
    }

    fn by_name(name: &str) -> Option<Function> {
        Function::ALL.into_iter().find(|f| f.name() == name)
    }

    fn apply(self, a: &[f64]) -> f64 {
        match self {
            Function::Abs => a[0].abs(),
            Function::Sign => {
                if a[0] > 0.0 {
                    1.0
                } else if a[0] < 0.0 {
                    -1.0
                } else {
                    0.0
                }
            }
            Function::Sqrt => a[0].sqrt(),
            Function::Exp => a[0].exp(),
            Function::Ln => a[0].ln(),
            Function::Sin => a[0].sin(),
            Function::Cos => a[0].cos(),
            Function::Tan => a[0].tan(),
            Function::Tanh => a[0].tanh(),
            Function::Atan => a[0].atan(),
            Function::Min => a[0].min(a[1]),
            Function::Max => a[0].max(a[1]),
            Function::Atan2 => a[0].atan2(a[1]),
            Function::Clamp => a[0].max(a[1]).min(a[2]),
            Function::If => {
                if a[0] != 0.0 {
                    a[1]
                } else {
                    a[2]
                }
            }
        }
    }
}

/// Binary operators of the tape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Binary {
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

impl Binary {
    #[inline]
    fn apply(self, a: f64, b: f64) -> f64 {
        let truth = |c: bool| if c { 1.0 } else { 0.0 };
        match self {
            Binary::Add => a + b,
            Binary::Sub => a - b,
            Binary::Mul => a * b,
            Binary::Div => a / b,
            Binary::Rem => a % b,
            Binary::Pow => a.powf(b),
            Binary::Lt => truth(a < b),
            Binary::Le => truth(a <= b),
            Binary::Gt => truth(a > b),
            Binary::Ge => truth(a >= b),
            Binary::Eq => truth(a == b),
            Binary::Ne => truth(a != b),
            Binary::And => truth(a != 0.0 && b != 0.0),
            Binary::Or => truth(a != 0.0 || b != 0.0),
        }
    }
}

/// One instruction of the postfix tape.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    Const(f64),
    Load(u32),
    Neg,
    Not,
    Binary(Binary),
    Call(Function),
    /// Copies the top of the stack into a register (the value stays).
    Keep(u8),
    /// Pushes a register's value.
    Recall(u8),
}

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
    /// Deeper than [`MAX_DEPTH`].
    #[error("'{0}' is nested too deeply (at most {MAX_DEPTH} pending operands)")]
    TooDeep(String),
    /// A relation was expected (`a >= b`, `a <= b`, `a == b`, ...).
    #[error("'{0}' is not a relation such as 'a >= b', 'a <= b' or 'a == b'")]
    NotRelation(String),
}

/// A compiled expression: a postfix tape over the slots of a
/// [`crate::compile::CompiledModel`] (states, inputs, parameters,
/// definitions).
#[derive(Debug, Clone, PartialEq)]
pub struct Expression {
    ops: Vec<Op>,
    /// How it is evaluated.
    form: Form,
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
    /// Anything else: the postfix tape.
    Tape,
}

/// An affine form `constant + sum(coefficient * slot)`.
#[derive(Debug, Clone, PartialEq)]
struct Affine {
    constant: f64,
    terms: Vec<(u32, f64)>,
}

impl Affine {
    fn scale(&mut self, c: f64) {
        self.constant *= c;
        for t in &mut self.terms {
            t.1 *= c;
        }
    }

    fn add(&mut self, other: Affine, sign: f64) {
        self.constant += sign * other.constant;
        for (s, c) in other.terms {
            match self.terms.iter_mut().find(|t| t.0 == s) {
                Some(t) => t.1 += sign * c,
                None => self.terms.push((s, sign * c)),
            }
        }
    }

    /// The affine form of a postfix tape, if it has one: sums, differences,
    /// negations, products with a constant and divisions by a non-zero one.
    fn of(ops: &[Op]) -> Option<Affine> {
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
                Op::Neg => stack.last_mut()?.scale(-1.0),
                Op::Binary(b @ (Binary::Add | Binary::Sub | Binary::Mul | Binary::Div)) => {
                    let rhs = stack.pop()?;
                    let mut lhs = stack.pop()?;
                    match b {
                        Binary::Add => lhs.add(rhs, 1.0),
                        Binary::Sub => lhs.add(rhs, -1.0),
                        Binary::Mul if rhs.terms.is_empty() => lhs.scale(rhs.constant),
                        Binary::Mul if lhs.terms.is_empty() => {
                            let c = lhs.constant;
                            lhs = rhs;
                            lhs.scale(c);
                        }
                        Binary::Div if rhs.terms.is_empty() && rhs.constant != 0.0 => {
                            lhs.scale(1.0 / rhs.constant)
                        }
                        _ => return None,
                    }
                    stack.push(lhs);
                }
                _ => return None,
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
            _ => Affine::of(&ops).map_or(Form::Tape, Form::Affine),
        };
        Expression { ops, form }
    }

    /// Parses `text` and compiles it; `resolve` maps a name to its slot.
    pub fn compile(text: &str, resolve: &dyn Fn(&str) -> Option<u32>) -> Result<Self, ExprError> {
        let root = parse(text)?;
        let mut b = Builder::new(text, resolve);
        b.node(&root)?;
        b.finish()
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
            Form::Tape => None,
        }
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
            Form::Tape => run_tape(&self.ops, slots),
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

    /// The expression with every slot from `first` on that `definitions`
    /// gives (`definitions[slot - first]`, which may use other definitions)
    /// replaced by that expression's tape and folded: a flow written with
    /// definitions becomes one expression of the states, inputs and
    /// parameters. A definition that the result would evaluate more than
    /// once is evaluated once into a register ([`REGISTERS`]) and read back
    /// where it recurs, unless the result is affine (whose evaluation reads
    /// no tape). `None` when the result would need more than [`MAX_DEPTH`]
    /// pending operands.
    pub fn inline(&self, first: u32, definitions: &[Option<Expression>]) -> Option<Expression> {
        let mut plain = Sharing::off(definitions.len());
        plain.count(&self.ops, first, definitions);
        let recurs = plain.uses.iter().any(|&n| n > 1);
        let mut ops = Vec::with_capacity(self.ops.len());
        plain.expand(&mut ops, &self.ops, first, definitions);
        let mut e = Expression::from_ops(ops);
        if recurs && matches!(e.form, Form::Tape) {
            let mut shared = Sharing { on: true, ..plain };
            let mut ops = Vec::with_capacity(e.ops.len());
            shared.expand(&mut ops, &self.ops, first, definitions);
            e = Expression::from_ops(ops);
        }
        (e.depth() <= MAX_DEPTH).then_some(e)
    }
}

/// How [`Expression::inline`] expands definitions: how often each is used,
/// and the register each kept one is in.
struct Sharing {
    /// Keep recurring definitions in registers.
    on: bool,
    /// Uses of each definition in the expansion that keeps them.
    uses: Vec<usize>,
    /// The register of each definition evaluated so far and kept.
    register: Vec<Option<u8>>,
    /// Registers taken.
    taken: usize,
}

impl Sharing {
    fn off(definitions: usize) -> Self {
        Sharing {
            on: false,
            uses: vec![0; definitions],
            register: vec![None; definitions],
            taken: 0,
        }
    }

    /// The definition `ops` reads from slot `s`, with its index.
    fn definition(
        s: u32,
        first: u32,
        definitions: &[Option<Expression>],
    ) -> Option<(usize, &Expression)> {
        let i = s.checked_sub(first)? as usize;
        definitions.get(i)?.as_ref().map(|d| (i, d))
    }

    /// Counts the uses of every definition in `ops`, a definition's own
    /// uses once (a kept definition is expanded once). Definitions do not
    /// use themselves (the caller has checked for cycles), so this ends.
    fn count(&mut self, ops: &[Op], first: u32, definitions: &[Option<Expression>]) {
        for op in ops {
            if let Op::Load(s) = *op
                && let Some((i, d)) = Self::definition(s, first, definitions)
            {
                self.uses[i] += 1;
                if self.uses[i] == 1 {
                    self.count(&d.ops, first, definitions);
                }
            }
        }
    }

    /// Appends `ops` to `out` with every definition expanded (or read from
    /// its register), folding constants.
    fn expand(
        &mut self,
        out: &mut Vec<Op>,
        ops: &[Op],
        first: u32,
        definitions: &[Option<Expression>],
    ) {
        for op in ops {
            let Op::Load(s) = *op else {
                push_folded(out, *op);
                continue;
            };
            let Some((i, d)) = Self::definition(s, first, definitions) else {
                push_folded(out, *op);
                continue;
            };
            if let Some(r) = self.register[i] {
                out.push(Op::Recall(r));
                continue;
            }
            self.expand(out, &d.ops, first, definitions);
            if self.on && self.uses[i] > 1 && self.taken < REGISTERS {
                let r = self.taken as u8;
                out.push(Op::Keep(r));
                self.register[i] = Some(r);
                self.taken += 1;
            }
        }
    }
}

/// The postfix interpreter.
#[inline(never)]
fn run_tape(ops: &[Op], slots: &[f64]) -> f64 {
    let mut stack = [0.0f64; MAX_DEPTH];
    let mut registers = [0.0f64; REGISTERS];
    let mut sp = 0usize;
    for op in ops {
        match *op {
            Op::Const(v) => {
                stack[sp] = v;
                sp += 1;
            }
            Op::Load(s) => {
                stack[sp] = slots[s as usize];
                sp += 1;
            }
            Op::Neg => stack[sp - 1] = -stack[sp - 1],
            Op::Not => stack[sp - 1] = if stack[sp - 1] == 0.0 { 1.0 } else { 0.0 },
            Op::Binary(b) => {
                sp -= 1;
                stack[sp - 1] = b.apply(stack[sp - 1], stack[sp]);
            }
            Op::Call(f) => {
                let k = f.arity();
                sp -= k;
                stack[sp] = f.apply(&stack[sp..sp + k]);
                sp += 1;
            }
            Op::Keep(r) => registers[r as usize] = stack[sp - 1],
            Op::Recall(r) => {
                stack[sp] = registers[r as usize];
                sp += 1;
            }
        }
    }
    stack[0]
}

impl Op {
    /// Operands taken from the stack.
    fn operands(self) -> usize {
        match self {
            Op::Const(_) | Op::Load(_) | Op::Recall(_) => 0,
            Op::Neg | Op::Not | Op::Keep(_) => 1,
            Op::Binary(_) => 2,
            Op::Call(f) => f.arity(),
        }
    }
}

/// Appends `op` to a postfix tape, replacing it and its operands by their
/// value when every operand is a constant. An operand is constant exactly
/// when its own (already folded) tape is one `Const`, so the last
/// `operands()` instructions are all constants exactly then. A `Keep` is
/// never folded: a later `Recall` reads its register.
fn push_folded(ops: &mut Vec<Op>, op: Op) {
    let k = op.operands();
    let n = ops.len();
    ops.push(op);
    let keeps = matches!(op, Op::Keep(_));
    if k > 0 && !keeps && ops[n - k..n].iter().all(|o| matches!(o, Op::Const(_))) {
        let v = run_tape(&ops[n - k..], &[]);
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
        let root = parse(text)?;
        let node = strip_root(&root);
        let crossing = match node.operator() {
            Operator::Gt | Operator::Geq => Crossing::Rising,
            Operator::Lt | Operator::Leq => Crossing::Falling,
            Operator::Eq => Crossing::Either,
            _ => return Err(ExprError::NotRelation(text.to_string())),
        };
        let [lhs, rhs] = node.children() else {
            return Err(ExprError::NotNumeric(text.to_string()));
        };
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

fn parse(text: &str) -> Result<Node<DefaultNumericTypes>, ExprError> {
    evalexpr::build_operator_tree::<DefaultNumericTypes>(text).map_err(|e| ExprError::Syntax {
        text: text.to_string(),
        message: e.to_string(),
    })
}

/// The node under evalexpr's `RootNode` wrappers.
fn strip_root(mut n: &Node<DefaultNumericTypes>) -> &Node<DefaultNumericTypes> {
    while matches!(n.operator(), Operator::RootNode) && n.children().len() == 1 {
        n = &n.children()[0];
    }
    n
}

/// Emits the tape of a tree, folding constant operands.
struct Builder<'a> {
    text: &'a str,
    resolve: &'a dyn Fn(&str) -> Option<u32>,
    ops: Vec<Op>,
    depth: usize,
    max_depth: usize,
}

impl<'a> Builder<'a> {
    fn new(text: &'a str, resolve: &'a dyn Fn(&str) -> Option<u32>) -> Self {
        Builder {
            text,
            resolve,
            ops: Vec::new(),
            depth: 0,
            max_depth: 0,
        }
    }

    fn not_numeric(&self) -> ExprError {
        ExprError::NotNumeric(self.text.to_string())
    }

    fn push(&mut self, op: Op) -> Result<(), ExprError> {
        self.ops.push(op);
        self.depth += 1;
        self.max_depth = self.max_depth.max(self.depth);
        if self.max_depth > MAX_DEPTH {
            return Err(ExprError::TooDeep(self.text.to_string()));
        }
        Ok(())
    }

    /// Emits an operator, folded when its operands are constants.
    fn op(&mut self, op: Op) {
        push_folded(&mut self.ops, op);
        self.depth = self.depth + 1 - op.operands();
    }

    fn node(&mut self, node: &Node<DefaultNumericTypes>) -> Result<(), ExprError> {
        let node = strip_root(node);
        let children = node.children();
        let binary = |b| Some(Op::Binary(b));
        let op = match node.operator() {
            Operator::Const { value } => {
                let v = match value {
                    Value::Float(f) => *f,
                    Value::Int(i) => *i as f64,
                    Value::Boolean(b) => f64::from(u8::from(*b)),
                    _ => return Err(self.not_numeric()),
                };
                return self.push(Op::Const(v));
            }
            Operator::VariableIdentifierRead { identifier } => {
                let slot = (self.resolve)(identifier)
                    .ok_or_else(|| ExprError::UnknownSymbol(identifier.clone()))?;
                return self.push(Op::Load(slot));
            }
            Operator::FunctionIdentifier { identifier } => {
                let args: Vec<&Node<DefaultNumericTypes>> = match children {
                    [] => Vec::new(),
                    [one] => {
                        let inner = strip_root(one);
                        if matches!(inner.operator(), Operator::Tuple) {
                            inner.children().iter().collect()
                        } else {
                            vec![inner]
                        }
                    }
                    _ => return Err(self.not_numeric()),
                };
                let f = Function::by_name(identifier)
                    .filter(|f| f.arity() == args.len())
                    .ok_or_else(|| ExprError::UnknownFunction {
                        name: identifier.clone(),
                        args: args.len(),
                    })?;
                for a in &args {
                    self.node(a)?;
                }
                self.op(Op::Call(f));
                return Ok(());
            }
            Operator::Neg => Some(Op::Neg),
            Operator::Not => Some(Op::Not),
            Operator::Add => binary(Binary::Add),
            Operator::Sub => binary(Binary::Sub),
            Operator::Mul => binary(Binary::Mul),
            Operator::Div => binary(Binary::Div),
            Operator::Mod => binary(Binary::Rem),
            Operator::Exp => binary(Binary::Pow),
            Operator::Lt => binary(Binary::Lt),
            Operator::Leq => binary(Binary::Le),
            Operator::Gt => binary(Binary::Gt),
            Operator::Geq => binary(Binary::Ge),
            Operator::Eq => binary(Binary::Eq),
            Operator::Neq => binary(Binary::Ne),
            Operator::And => binary(Binary::And),
            Operator::Or => binary(Binary::Or),
            _ => None,
        }
        .ok_or_else(|| self.not_numeric())?;
        if children.len() != op.operands() {
            return Err(self.not_numeric());
        }
        for c in children {
            self.node(c)?;
        }
        self.op(op);
        Ok(())
    }

    fn finish(self) -> Result<Expression, ExprError> {
        if self.ops.is_empty() || self.depth != 1 {
            return Err(ExprError::NotNumeric(self.text.to_string()));
        }
        Ok(Expression::from_ops(self.ops))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn names(n: &str) -> Option<u32> {
        ["x", "y", "z"]
            .iter()
            .position(|s| *s == n)
            .map(|i| i as u32)
    }

    fn eval(text: &str, slots: &[f64]) -> f64 {
        Expression::compile(text, &names).unwrap().eval(slots)
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
        assert!(matches!(err("min(x)"), ExprError::UnknownFunction { .. }));
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
    enum Tree {
        Num(f64),
        Var(usize),
        Neg(Box<Tree>),
        Bin(u8, Box<Tree>, Box<Tree>),
        Min(Box<Tree>, Box<Tree>),
    }

    impl Tree {
        fn text(&self) -> String {
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
        fn value(&self, s: &[f64]) -> f64 {
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

    fn tree() -> impl Strategy<Value = Tree> {
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
    fn with_definitions(n: &str) -> Option<u32> {
        ["x", "y", "z", "a", "b"]
            .iter()
            .position(|s| *s == n)
            .map(|i| i as u32)
    }

    /// `text` with the definitions `a` and `b` (texts) expanded, without
    /// registers: every use evaluated where it stands.
    fn expanded_plainly(text: &str, a: &str, b: &str) -> Expression {
        let e = Expression::compile(text, &with_definitions).unwrap();
        let defs = [a, b].map(|d| Some(Expression::compile(d, &with_definitions).unwrap()));
        let mut ops = Vec::new();
        Sharing::off(2).expand(&mut ops, &e.ops, 3, &defs);
        Expression::from_ops(ops)
    }

    #[test]
    fn a_definition_used_twice_is_evaluated_once() {
        let (a, b) = ("sin(x) * y + z", "a * a - 1");
        let defs = [a, b].map(|d| Some(Expression::compile(d, &with_definitions).unwrap()));
        let e = Expression::compile("b / (1 + a) + sign(a)", &with_definitions)
            .unwrap()
            .inline(3, &defs)
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
        let plain = expanded_plainly("b / (1 + a) + sign(a)", a, b);
        assert!(e.ops.len() < plain.ops.len());
        let s = [0.7, -1.3, 2.1];
        assert_eq!(e.eval(&s).to_bits(), plain.eval(&s).to_bits());
        // An affine result keeps its affine form (no tape is run).
        let affine = Expression::compile("a + a", &with_definitions)
            .unwrap()
            .inline(
                3,
                &[
                    Some(Expression::compile("2 * x + y", &with_definitions).unwrap()),
                    None,
                ],
            )
            .unwrap();
        assert!(affine.affine().is_some());
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
            let (a, b) = (ta.text(), format!("({}) * a", tb.text()));
            let text = format!("({}) + a * b - min(a, b)", te.text());
            let defs = [&a, &b].map(|d| Some(Expression::compile(d, &with_definitions).unwrap()));
            let e = Expression::compile(&text, &with_definitions).unwrap().inline(3, &defs);
            let plain = expanded_plainly(&text, &a, &b);
            prop_assume!(e.is_some());
            let (kept, plain) = (e.unwrap().eval(&s), plain.eval(&s));
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
}
