//! Exact first derivatives of a compiled expression in the slots asked
//! for: reverse-mode differentiation of the postfix tape (Griewank &
//! Walther, *Evaluating Derivatives*, 2nd ed., SIAM 2008, section 3.2),
//! one forward and one reverse sweep whatever the number of slots.
//!
//! Where an expression is not differentiable (a comparison, `sign`, the
//! branch of `if`, `min`, `max`, `clamp`, `abs` at 0, `%` at a jump), the
//! derivative is the one of the branch the value takes: between the events
//! of a simulation, where no branch changes, that is the derivative of the
//! flow. A term whose partial derivative is zero, or whose operand reads
//! no slot asked for, is left out, so a derivative that is not finite in a
//! direction the value does not depend on (`ln` of a negative base in
//! `x^2`, `sqrt` of a negative number in the branch `if` does not take)
//! does not spoil the others.

use super::{Binary, Expression, Form, Function, MAX_DEPTH, Op, REGISTERS};

impl Expression {
    /// The value at `slots`, and in `gradient[i]` its partial derivative in
    /// slot `wrt[i]` (see the module doc for the points where it is not
    /// differentiable). `gradient` is filled up to the shorter of the two.
    pub fn gradient(&self, slots: &[f64], wrt: &[u32], gradient: &mut [f64]) -> f64 {
        self.gradient_with(slots, wrt, gradient, &mut Adjoints::default())
    }

    /// [`Expression::gradient`] with the workspace `scratch` kept between
    /// calls.
    pub fn gradient_with(
        &self,
        slots: &[f64],
        wrt: &[u32],
        gradient: &mut [f64],
        scratch: &mut Adjoints,
    ) -> f64 {
        gradient.fill(0.0);
        let seed = |slot: u32, coefficient: f64, gradient: &mut [f64]| {
            for (g, &w) in gradient.iter_mut().zip(wrt) {
                if w == slot {
                    *g += coefficient;
                }
            }
        };
        match &self.form {
            Form::Constant(v) => *v,
            Form::Slot(s) => {
                seed(*s, 1.0, gradient);
                slots[*s as usize]
            }
            Form::Affine(a) => {
                for &(s, c) in &a.terms {
                    seed(s, c, gradient);
                }
                a.eval(slots)
            }
            Form::Tape(_) => self
                .sweep
                .get_or_init(|| Sweep::of(&self.ops))
                .gradient(slots, wrt, gradient, scratch),
        }
    }
}

/// The workspace of [`Expression::gradient_with`]: the values of the
/// nodes of an expression's graph, their partial derivatives, whether
/// they read a slot asked for, and their adjoints, kept between calls.
#[derive(Debug, Default, Clone)]
pub struct Adjoints {
    values: Vec<f64>,
    partials: Vec<[f64; 3]>,
    reads: Vec<bool>,
    adjoints: Vec<f64>,
    /// The slots asked for at the last call ([`Asked`]).
    asked: Asked,
}

/// Where each slot stands among the slots asked for (its positions in
/// them: none where it is not asked for, several where it is asked for
/// more than once), listed again when they change.
#[derive(Debug, Default, Clone)]
struct Asked {
    wrt: Vec<u32>,
    positions: Vec<Vec<u32>>,
}

impl Asked {
    /// The positions of slot `slot` among the slots of the last
    /// [`Asked::list`].
    fn of(&self, slot: u32) -> &[u32] {
        self.positions.get(slot as usize).map_or(&[], Vec::as_slice)
    }

    /// Lists the positions of the slots of `wrt`, when `wrt` differs from
    /// the last call's.
    fn list(&mut self, wrt: &[u32]) {
        if self.wrt != wrt {
            self.wrt.clear();
            self.wrt.extend_from_slice(wrt);
            let size = wrt.iter().map(|&w| w as usize + 1).max().unwrap_or(0);
            self.positions = vec![Vec::new(); size];
            for (i, &w) in wrt.iter().enumerate() {
                self.positions[w as usize].push(i as u32);
            }
        }
    }
}

/// A postfix tape's graph for reverse-mode differentiation (Griewank and
/// Walther 2008, section 3.2), laid out once: one node per value the tape
/// computes, in tape order, with the operation that makes it and the
/// nodes it reads (a kept value read again is the same node). A gradient
/// then takes a forward sweep of values and partial derivatives over the
/// nodes and a reverse sweep of adjoints.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Sweep {
    nodes: Vec<SweepNode>,
    /// The node of the expression's value.
    result: u32,
}

/// One value of a [`Sweep`]: its operation and the nodes of its operands
/// (the first [`SweepNode::count`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct SweepNode {
    op: NodeOp,
    operands: [u32; 3],
}

/// The operation that makes a node's value.
#[derive(Debug, Clone, Copy, PartialEq)]
enum NodeOp {
    Const(f64),
    Load(u32),
    Neg,
    /// Logical not: a value without derivative edges.
    Not,
    Binary(Binary),
    Call(Function),
}

impl SweepNode {
    /// Operands with a partial derivative (a logical not's is none).
    fn count(&self) -> usize {
        match self.op {
            NodeOp::Const(_) | NodeOp::Load(_) | NodeOp::Not => 0,
            NodeOp::Neg => 1,
            NodeOp::Binary(_) => 2,
            NodeOp::Call(f) => f.arity(),
        }
    }
}

impl Sweep {
    /// The graph of a well-formed tape.
    pub(super) fn of(ops: &[Op]) -> Sweep {
        let mut nodes: Vec<SweepNode> = Vec::with_capacity(ops.len());
        let mut stack: Vec<u32> = Vec::with_capacity(MAX_DEPTH);
        let mut registers = [0u32; REGISTERS];
        for op in ops {
            let node = match *op {
                Op::Keep(r) => {
                    registers[r as usize] = stack[stack.len() - 1];
                    continue;
                }
                Op::Recall(r) => {
                    stack.push(registers[r as usize]);
                    continue;
                }
                Op::Const(v) => NodeOp::Const(v),
                Op::Load(s) => NodeOp::Load(s),
                Op::Neg => NodeOp::Neg,
                Op::Not => NodeOp::Not,
                Op::Binary(b) => NodeOp::Binary(b),
                Op::Call(f) => NodeOp::Call(f),
            };
            let popped = op.operands();
            let from = stack.len() - popped;
            let mut operands = [0u32; 3];
            operands[..popped].copy_from_slice(&stack[from..]);
            stack.truncate(from);
            stack.push(nodes.len() as u32);
            nodes.push(SweepNode { op: node, operands });
        }
        Sweep {
            nodes,
            result: stack[0],
        }
    }

    /// [`Expression::gradient`] by a forward sweep (each node's value and
    /// its partial derivatives in its operands, and whether it reads a
    /// slot of `wrt`) and a reverse sweep (the adjoints, seeded with 1 at
    /// the value); a term whose partial derivative is zero, or whose
    /// operand reads no slot asked for, is left out.
    fn gradient(
        &self,
        slots: &[f64],
        wrt: &[u32],
        gradient: &mut [f64],
        work: &mut Adjoints,
    ) -> f64 {
        let n = self.nodes.len();
        let Adjoints {
            values,
            partials,
            reads,
            adjoints,
            asked,
        } = work;
        asked.list(wrt);
        values.resize(n, 0.0);
        partials.resize(n, [0.0; 3]);
        reads.resize(n, false);
        for (i, node) in self.nodes.iter().enumerate() {
            let [a, b, c] = node.operands.map(|o| o as usize);
            let (value, read) = match node.op {
                NodeOp::Const(v) => (v, false),
                NodeOp::Load(s) => (slots[s as usize], !asked.of(s).is_empty()),
                NodeOp::Neg => {
                    partials[i][0] = -1.0;
                    (-values[a], reads[a])
                }
                NodeOp::Not => (if values[a] == 0.0 { 1.0 } else { 0.0 }, false),
                NodeOp::Binary(op) => {
                    let (x, y) = (values[a], values[b]);
                    let value = op.apply(x, y);
                    let [px, py] = op.partials(x, y, value);
                    partials[i][..2].copy_from_slice(&[px, py]);
                    (value, reads[a] || reads[b])
                }
                NodeOp::Call(f) => {
                    let k = f.arity();
                    let args = [values[a], values[b], values[c]];
                    let value = f.apply(&args[..k]);
                    partials[i] = f.partials(&args[..k], value);
                    let read = [a, b, c][..k].iter().any(|&o| reads[o]);
                    (value, read)
                }
            };
            values[i] = value;
            reads[i] = read;
        }
        adjoints.clear();
        adjoints.resize(n, 0.0);
        adjoints[self.result as usize] = 1.0;
        for (i, node) in self.nodes.iter().enumerate().rev() {
            let a = adjoints[i];
            if a == 0.0 || !reads[i] {
                continue;
            }
            if let NodeOp::Load(slot) = node.op {
                for &p in asked.of(slot) {
                    if let Some(g) = gradient.get_mut(p as usize) {
                        *g += a;
                    }
                }
            }
            for (&o, &p) in node.operands[..node.count()].iter().zip(&partials[i]) {
                if p != 0.0 && reads[o as usize] {
                    adjoints[o as usize] += p * a;
                }
            }
        }
        values[self.result as usize]
    }
}

impl Binary {
    /// `(d/dx, d/dy)` of `x op y`, whose value is `value`.
    fn partials(self, x: f64, y: f64, value: f64) -> [f64; 2] {
        match self {
            Binary::Add => [1.0, 1.0],
            Binary::Sub => [1.0, -1.0],
            Binary::Mul => [y, x],
            Binary::Div => [1.0 / y, -(x / y) / y],
            // x % y = x - y trunc(x / y), the quotient constant between jumps.
            Binary::Rem => [1.0, -(x / y).trunc()],
            Binary::Pow => [
                if y == 0.0 { 0.0 } else { y * x.powf(y - 1.0) },
                if value == 0.0 { 0.0 } else { value * x.ln() },
            ],
            Binary::Lt
            | Binary::Le
            | Binary::Gt
            | Binary::Ge
            | Binary::Eq
            | Binary::Ne
            | Binary::And
            | Binary::Or => [0.0, 0.0],
        }
    }
}

impl Function {
    /// The partial derivatives of the function in its arguments `a` (the
    /// first [`Function::arity`] entries), at the value `value`; the branch
    /// taken for `min`, `max`, `clamp` and `if`, as [`Function::apply`]
    /// takes it.
    fn partials(self, a: &[f64], value: f64) -> [f64; 3] {
        // `first.min(second)` is `first` unless `first` is NaN or larger.
        let first_of_min = |x: f64, y: f64| !x.is_nan() && (y.is_nan() || x <= y);
        let first_of_max = |x: f64, y: f64| !x.is_nan() && (y.is_nan() || x >= y);
        let pick = |first: bool| {
            if first {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            }
        };
        match self {
            // The slope of `abs` is the sign.
            Function::Abs => [Function::Sign.apply(a), 0.0, 0.0],
            Function::Sign => [0.0; 3],
            Function::Sqrt => [0.5 / value, 0.0, 0.0],
            Function::Exp => [value, 0.0, 0.0],
            Function::Ln => [1.0 / a[0], 0.0, 0.0],
            Function::Sin => [a[0].cos(), 0.0, 0.0],
            Function::Cos => [-a[0].sin(), 0.0, 0.0],
            Function::Tan => [1.0 + value * value, 0.0, 0.0],
            Function::Tanh => [1.0 - value * value, 0.0, 0.0],
            Function::Atan => [1.0 / (1.0 + a[0] * a[0]), 0.0, 0.0],
            Function::Min => pick(first_of_min(a[0], a[1])),
            Function::Max => pick(first_of_max(a[0], a[1])),
            Function::Atan2 => {
                let r = a[0] * a[0] + a[1] * a[1];
                [a[1] / r, -a[0] / r, 0.0]
            }
            // clamp(x, lo, hi) = min(max(x, lo), hi).
            Function::Clamp => {
                let low = a[0].max(a[1]);
                if first_of_min(low, a[2]) {
                    if first_of_max(a[0], a[1]) {
                        [1.0, 0.0, 0.0]
                    } else {
                        [0.0, 1.0, 0.0]
                    }
                } else {
                    [0.0, 0.0, 1.0]
                }
            }
            Function::If => {
                if a[0] != 0.0 {
                    [0.0, 1.0, 0.0]
                } else {
                    [0.0, 0.0, 1.0]
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{Tree, names, tree, with_recurring_definitions};
    use super::*;
    use proptest::prelude::*;

    /// `gradient` in the slots `x, y, z`.
    fn gradient_of(e: &Expression, s: &[f64]) -> (f64, [f64; 3]) {
        let mut g = [0.0; 3];
        let v = e.gradient(s, &[0, 1, 2], &mut g);
        (v, g)
    }

    /// The derivative of a tree in variable `i`, by recursion over the tree
    /// (the tape's rule for the terms left out included): the oracle of the
    /// tape's reverse mode.
    fn tree_derivative(t: &Tree, s: &[f64], i: usize) -> f64 {
        let term = |p: f64, d: f64, a: &Tree| {
            if p == 0.0 || !a.reads(i) { 0.0 } else { p * d }
        };
        match t {
            Tree::Num(_) => 0.0,
            Tree::Var(j) => f64::from(u8::from(*j == i)),
            Tree::Neg(a) => -tree_derivative(a, s, i),
            Tree::Bin(o, a, b) => {
                let (x, y) = (a.value(s), b.value(s));
                let (dx, dy) = (tree_derivative(a, s, i), tree_derivative(b, s, i));
                match o {
                    0 => term(1.0, dx, a) + term(1.0, dy, b),
                    1 => term(1.0, dx, a) + term(-1.0, dy, b),
                    2 => term(y, dx, a) + term(x, dy, b),
                    _ => term(1.0 / y, dx, a) + term(-(x / y) / y, dy, b),
                }
            }
            Tree::Min(a, b) => {
                let (x, y) = (a.value(s), b.value(s));
                if !x.is_nan() && (y.is_nan() || x <= y) {
                    tree_derivative(a, s, i)
                } else {
                    tree_derivative(b, s, i)
                }
            }
        }
    }

    /// Equal to `1e-9` of their size, or both NaN.
    fn close(a: f64, b: f64) -> bool {
        a == b
            || (a.is_nan() && b.is_nan())
            || (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0)
    }

    /// One workspace across calls that ask for other slots (some twice,
    /// some unread, beyond the slots read) gives each call the bits a
    /// fresh workspace gives it: the positions of the slots asked for are
    /// listed again when they change.
    #[test]
    fn a_workspace_serves_calls_that_ask_for_other_slots() {
        let e = Expression::compile("x * y + sin(x) / (1 + z*z)", &names).unwrap();
        let slots = [0.5, 2.0, -1.5];
        let asks: [&[u32]; 5] = [&[0, 1, 2], &[2, 0], &[1, 1, 0], &[7, 0, 3], &[0, 1, 2]];
        let mut shared = Adjoints::default();
        for wrt in asks.iter().cycle().take(10) {
            let (mut g, mut fresh) = ([0.0; 3], [0.0; 3]);
            let v = e.gradient_with(&slots, wrt, &mut g, &mut shared);
            let w = e.gradient(&slots, wrt, &mut fresh);
            assert_eq!(v.to_bits(), w.to_bits(), "{wrt:?}");
            assert_eq!(g.map(f64::to_bits), fresh.map(f64::to_bits), "{wrt:?}");
            // Every entry of the gradient is the derivative in its slot.
            for (gi, &slot) in g.iter().zip(wrt.iter()) {
                let want = match slot {
                    0 => 2.0 + 0.5f64.cos() / (1.0 + 2.25),
                    1 => 0.5,
                    2 => -(0.5f64.sin()) * 2.0 * -1.5 / (1.0 + 2.25f64).powi(2),
                    _ => 0.0,
                };
                assert!((gi - want).abs() <= 1e-12, "{wrt:?}: {gi} against {want}");
            }
        }
    }

    #[test]
    fn the_slots_asked_for_may_repeat_or_be_unread() {
        let e = Expression::compile("x * y + sin(x)", &names).unwrap();
        let mut g = [9.0; 4];
        let v = e.gradient(&[0.5, 2.0, 7.0], &[2, 0, 1, 0], &mut g);
        assert_eq!(v, 1.0 + 0.5f64.sin());
        assert_eq!(g, [0.0, 2.0 + 0.5f64.cos(), 0.5, 2.0 + 0.5f64.cos()]);
        // The affine, one-slot and constant forms.
        for (text, expected) in [
            ("2*x - y/4 + 3", [2.0, -0.25, 0.0]),
            ("z", [0.0, 0.0, 1.0]),
            ("sqrt(16)", [0.0; 3]),
        ] {
            let (_, g) = gradient_of(
                &Expression::compile(text, &names).unwrap(),
                &[1.0, 2.0, 3.0],
            );
            assert_eq!(g, expected, "{text}");
        }
        // The branch a kink takes: `abs` at 0, `min` on a tie, `if`.
        let at = |text: &str, s: [f64; 3]| {
            gradient_of(&Expression::compile(text, &names).unwrap(), &s).1
        };
        assert_eq!(at("abs(x)", [0.0, 0.0, 0.0]), [0.0; 3]);
        assert_eq!(at("min(x, y)", [1.0, 1.0, 0.0]), [1.0, 0.0, 0.0]);
        assert_eq!(at("if(x > y, y, z)", [1.0, 2.0, 0.0]), [0.0, 0.0, 1.0]);
        // `ln` of a negative base does not reach a constant exponent, nor
        // does the branch `if` does not take.
        assert_eq!(at("x^2", [-3.0, 0.0, 0.0]), [-6.0, 0.0, 0.0]);
        assert_eq!(
            at("if(x > 0, sqrt(x), y)", [-1.0, 2.0, 0.0]),
            [0.0, 1.0, 0.0]
        );
    }

    proptest! {
        /// Every operator and function against central finite differences
        /// (relative `1e-6`), at points away from their kinks and poles.
        #[test]
        fn every_operator_and_function_matches_central_differences(
            x in 0.5f64..2.0, y in 0.5f64..2.0, z in -2.0f64..-0.5,
        ) {
            let s = [x, y, z];
            for text in [
                "x + y - z", "x * y / z", "x % (y + 3)", "x ^ y", "z ^ 2", "-(x * z)",
                "abs(z) * sign(z) + abs(x)", "sqrt(x * y)", "exp(x - y)", "ln(x + y)",
                "sin(x * z)", "cos(y + z)", "tan(x / 4)", "tanh(x * z)", "atan(x * y)",
                "min(x, y + 3) + max(z, -3)", "atan2(z, x)",
                "clamp(x, 0, 5) + clamp(z, 0, 1) + clamp(y, 0, 0.25)",
                "if(x > 0, y * z, x) + (x > 3) * y + !(z > 0) * x",
                "(x < 3 && y > 0 || z > 0) * z + (x == 9) + (x != 9) * y",
            ] {
                let e = Expression::compile(text, &names).unwrap();
                let (value, g) = gradient_of(&e, &s);
                prop_assert_eq!(value.to_bits(), e.eval(&s).to_bits(), "{}", text);
                for i in 0..3 {
                    let h = 1e-6 * s[i].abs().max(1.0);
                    let (mut up, mut down) = (s, s);
                    up[i] += h;
                    down[i] -= h;
                    let fd = (e.eval(&up) - e.eval(&down)) / (2.0 * h);
                    prop_assert!((g[i] - fd).abs() <= 1e-6 * g[i].abs().max(1.0),
                        "{}: d/ds{} exact {} differences {}", text, i, g[i], fd);
                }
            }
        }

        /// A random arithmetic tree: the tape's reverse mode gives the
        /// derivative the tree gives by recursion, and the value `eval`
        /// gives.
        #[test]
        fn the_tape_differentiates_as_the_tree(
            t in tree(), s in proptest::collection::vec(-5.0f64..5.0, 3),
        ) {
            let e = Expression::compile(&t.text(), &names).unwrap();
            let (value, g) = gradient_of(&e, &s);
            prop_assert!(value.to_bits() == e.eval(&s).to_bits() || value.is_nan());
            for (i, gi) in g.iter().enumerate() {
                let oracle = tree_derivative(&t, &s, i);
                prop_assert!(close(*gi, oracle), "{}: d/ds{} tape {} tree {}", t.text(), i, gi, oracle);
            }
        }

        /// Definitions kept in registers give the derivatives of their
        /// plain expansion, to rounding (the reverse sweep sums a kept
        /// definition's adjoints before it passes them on, the expansion
        /// passes each copy's on).
        #[test]
        fn kept_definitions_give_the_same_derivatives(
            ta in tree(), tb in tree(), te in tree(),
            s in proptest::collection::vec(-5.0f64..5.0, 3),
        ) {
            let (text, kept, plain) = with_recurring_definitions(&ta, &tb, &te);
            prop_assume!(kept.is_some());
            let (_, gk) = gradient_of(&kept.unwrap(), &s);
            let (_, gp) = gradient_of(&plain, &s);
            for (k, p) in gk.iter().zip(&gp) {
                prop_assert!(close(*k, *p), "{}: kept {:?} plain {:?}", text, gk, gp);
            }
        }
    }
}
