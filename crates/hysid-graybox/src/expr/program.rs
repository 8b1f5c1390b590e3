//! A postfix tape as three-address code, the form a tape is evaluated in.
//!
//! The tape pushes slots and constants onto a stack before every operation
//! reads them. Here the stack is played out once, when the expression is
//! made: an operand is read where it lies (a slot, a constant, the result
//! of an earlier operation), and only the operations remain, each writing
//! its result into the stack cell the tape would have left it in (a stack
//! cell is read by the one operation that pops it, so cells can be reused
//! as the tape reuses them). Kept values go to cells of their own. The
//! operations, their operands and their order are the tape's, so a
//! program's value is the tape's bit for bit.

use super::{Binary, Function, MAX_DEPTH, Op, REGISTERS};

/// Where an operation reads an operand.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Operand {
    Slot(u32),
    Const(f64),
    /// A cell of the workspace: a stack cell, or a kept value's.
    Cell(u8),
}

/// One operation, writing cell `to`.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Instruction {
    /// A kept value, copied into its register's cell.
    Keep {
        to: u8,
        a: Operand,
    },
    Neg {
        to: u8,
        a: Operand,
    },
    Not {
        to: u8,
        a: Operand,
    },
    Binary {
        op: Binary,
        to: u8,
        a: Operand,
        b: Operand,
    },
    /// Its arguments, padded to three with zeros.
    Call {
        f: Function,
        to: u8,
        args: [Operand; 3],
    },
}

/// Cells of the workspace: the stack's, then one per register.
const CELLS: usize = MAX_DEPTH + REGISTERS;

/// A tape's operations with their operands resolved.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Program {
    code: Vec<Instruction>,
    result: Operand,
}

impl Program {
    /// The program of a well-formed tape (every operation finds its
    /// operands, one value remains, at most [`MAX_DEPTH`] pending).
    pub(super) fn of(ops: &[Op]) -> Program {
        let mut stack: Vec<Operand> = Vec::with_capacity(MAX_DEPTH);
        let mut code = Vec::with_capacity(ops.len());
        for op in ops {
            let operand = match *op {
                Op::Const(v) => Operand::Const(v),
                Op::Load(s) => Operand::Slot(s),
                Op::Recall(r) => Operand::Cell((MAX_DEPTH + r as usize) as u8),
                Op::Keep(r) => {
                    let a = stack[stack.len() - 1];
                    let to = (MAX_DEPTH + r as usize) as u8;
                    code.push(Instruction::Keep { to, a });
                    continue;
                }
                Op::Neg | Op::Not => {
                    let a = stack.pop().expect("a well-formed tape");
                    let to = stack.len() as u8;
                    code.push(if matches!(op, Op::Neg) {
                        Instruction::Neg { to, a }
                    } else {
                        Instruction::Not { to, a }
                    });
                    Operand::Cell(to)
                }
                Op::Binary(b) => {
                    let y = stack.pop().expect("a well-formed tape");
                    let x = stack.pop().expect("a well-formed tape");
                    let to = stack.len() as u8;
                    code.push(Instruction::Binary {
                        op: b,
                        to,
                        a: x,
                        b: y,
                    });
                    Operand::Cell(to)
                }
                Op::Call(f) => {
                    let k = f.arity();
                    let mut args = [Operand::Const(0.0); 3];
                    let from = stack.len() - k;
                    args[..k].copy_from_slice(&stack[from..]);
                    stack.truncate(from);
                    let to = stack.len() as u8;
                    code.push(Instruction::Call { f, to, args });
                    Operand::Cell(to)
                }
            };
            stack.push(operand);
        }
        Program {
            code,
            result: stack.pop().expect("a well-formed tape"),
        }
    }

    /// The value at `slots`.
    #[inline(never)]
    pub(super) fn run(&self, slots: &[f64]) -> f64 {
        let mut cells = [0.0f64; CELLS];
        let read = |o: Operand, cells: &[f64; CELLS]| match o {
            Operand::Slot(s) => slots[s as usize],
            Operand::Const(v) => v,
            Operand::Cell(c) => cells[c as usize],
        };
        for instruction in &self.code {
            match *instruction {
                Instruction::Keep { to, a } => cells[to as usize] = read(a, &cells),
                Instruction::Neg { to, a } => cells[to as usize] = -read(a, &cells),
                Instruction::Not { to, a } => {
                    cells[to as usize] = if read(a, &cells) == 0.0 { 1.0 } else { 0.0 }
                }
                Instruction::Binary { op, to, a, b } => {
                    cells[to as usize] = op.apply(read(a, &cells), read(b, &cells));
                }
                Instruction::Call { f, to, args } => {
                    let values = args.map(|o| read(o, &cells));
                    cells[to as usize] = f.apply(&values[..f.arity()]);
                }
            }
        }
        read(self.result, &cells)
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{tree, with_recurring_definitions};
    use super::*;
    use proptest::prelude::*;

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
        /// them), and the same with every use written out: the program
        /// gives the stack's bits.
        #[test]
        fn the_program_gives_the_stacks_bits(
            ta in tree(), tb in tree(), te in tree(),
            s in proptest::collection::vec(-5.0f64..5.0, 3),
        ) {
            let (text, kept, plain) = with_recurring_definitions(&ta, &tb, &te);
            for e in kept.iter().chain([&plain]) {
                let (program, stack) = (Program::of(&e.ops).run(&s), on_a_stack(&e.ops, &s));
                prop_assert!(program.to_bits() == stack.to_bits() || (program.is_nan() && stack.is_nan()),
                    "{}: program {} stack {}", text, program, stack);
            }
        }
    }

    #[test]
    fn every_operation_reads_its_operands_in_order() {
        let slots = [3.0, -2.0, 0.5];
        let names = |n: &str| {
            ["x", "y", "z"]
                .iter()
                .position(|s| *s == n)
                .map(|i| i as u32)
        };
        for text in [
            "x - y/z",
            "-(x - y) + !(z > 1)",
            "atan2(y, x) - clamp(x, y, z)",
            "if(x > y, sqrt(x), y^2) % z",
            "min(x, y) * max(y, z) + (x >= y && y != z || x == z)",
        ] {
            let e = super::super::Expression::compile(text, &names).unwrap();
            let (program, stack) = (Program::of(&e.ops).run(&slots), on_a_stack(&e.ops, &slots));
            assert_eq!(program.to_bits(), stack.to_bits(), "{text}");
        }
    }
}
