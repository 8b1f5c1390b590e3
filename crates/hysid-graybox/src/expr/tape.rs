//! The postfix tape of a compiled expression: its operations (slots and
//! constants pushed, operators and functions applied, values kept in
//! registers), the limits of its stack, and the three-address form it is
//! evaluated in.
//!
//! The tape pushes slots and constants onto a stack before every operation
//! reads them. Its [`Program`] plays the stack out once, when the
//! expression is made: an operand is read where it lies (a slot, a
//! constant, the result of an earlier operation), and only the operations
//! remain, each writing its result into the stack cell the tape would have
//! left it in (a stack cell is read by the one operation that pops it, so
//! cells can be reused as the tape reuses them). Kept values go to cells of
//! their own. The operations, their operands and their order are the
//! tape's, so a program's value is the tape's bit for bit.

/// Deepest evaluation stack an expression may need (checked at compile).
pub const MAX_DEPTH: usize = 32;

/// Registers of one tape: values of definitions that an expression uses
/// more than once, kept at their first evaluation and read again at the
/// others ([`Expression::inline`](super::Expression::inline)). Past this
/// many, a definition is evaluated again where it recurs.
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

    pub(super) fn by_name(name: &str) -> Option<Function> {
        Function::ALL.into_iter().find(|f| f.name() == name)
    }

    #[inline(always)]
    pub(super) fn apply(self, a: &[f64]) -> f64 {
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
pub(super) enum Binary {
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
    /// Whether it compares its operands (`<`, `<=`, `>`, `>=`, `==`, `!=`).
    pub(super) fn compares(self) -> bool {
        matches!(
            self,
            Binary::Lt | Binary::Le | Binary::Gt | Binary::Ge | Binary::Eq | Binary::Ne
        )
    }

    #[inline(always)]
    pub(super) fn apply(self, a: f64, b: f64) -> f64 {
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
pub(super) enum Op {
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

impl Op {
    /// Operands taken from the stack.
    pub(super) fn operands(self) -> usize {
        match self {
            Op::Const(_) | Op::Load(_) | Op::Recall(_) => 0,
            Op::Neg | Op::Not | Op::Keep(_) => 1,
            Op::Binary(_) => 2,
            Op::Call(f) => f.arity(),
        }
    }
}

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

impl Instruction {
    /// The cell it writes.
    fn target(self) -> u8 {
        match self {
            Instruction::Keep { to, .. }
            | Instruction::Neg { to, .. }
            | Instruction::Not { to, .. }
            | Instruction::Binary { to, .. }
            | Instruction::Call { to, .. } => to,
        }
    }

    /// The same operation writing cell `to`.
    fn writing(self, to: u8) -> Instruction {
        match self {
            Instruction::Keep { a, .. } => Instruction::Keep { to, a },
            Instruction::Neg { a, .. } => Instruction::Neg { to, a },
            Instruction::Not { a, .. } => Instruction::Not { to, a },
            Instruction::Binary { op, a, b, .. } => Instruction::Binary { op, to, a, b },
            Instruction::Call { f, args, .. } => Instruction::Call { f, to, args },
        }
    }

    /// The same operation on the operands `rename` gives for its own (a
    /// call's padding included).
    fn reading(self, mut rename: impl FnMut(Operand) -> Operand) -> Instruction {
        match self {
            Instruction::Keep { to, a } => Instruction::Keep { to, a: rename(a) },
            Instruction::Neg { to, a } => Instruction::Neg { to, a: rename(a) },
            Instruction::Not { to, a } => Instruction::Not { to, a: rename(a) },
            Instruction::Binary { op, to, a, b } => Instruction::Binary {
                op,
                to,
                a: rename(a),
                b: rename(b),
            },
            Instruction::Call { f, to, args } => Instruction::Call {
                f,
                to,
                args: args.map(rename),
            },
        }
    }
}

/// Cells of the workspace: the stack's, then one per register.
const CELLS: usize = MAX_DEPTH + REGISTERS;

/// A tape's operations with their operands resolved, and the same laid
/// out on one memory ([`Joint`]) where they fit it, which runs faster.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Program {
    code: Vec<Instruction>,
    result: Operand,
    alone: Option<Box<Joint>>,
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
        let mut program = Program {
            code,
            result: stack.pop().expect("a well-formed tape"),
            alone: None,
        };
        program.alone = Joint::of(&[(0, &program)]).map(Box::new);
        program
    }

    /// The value at `slots`: on one memory where the program fits it,
    /// else on its cells.
    #[inline(never)]
    pub(super) fn run(&self, slots: &[f64]) -> f64 {
        match &self.alone {
            Some(joint) => {
                let mut out = [0.0];
                joint.run(slots, &mut out);
                out[0]
            }
            None => self.run_on_cells(slots),
        }
    }

    /// The value at `slots`, each operand read where it lies (a slot, a
    /// constant, a cell).
    pub(super) fn run_on_cells(&self, slots: &[f64]) -> f64 {
        let mut cells = [0.0f64; CELLS];
        execute(&self.code, slots, &mut cells);
        read(self.result, slots, &cells)
    }
}

/// The value of operand `o`.
#[inline(always)]
fn read(o: Operand, slots: &[f64], cells: &[f64; CELLS]) -> f64 {
    match o {
        Operand::Slot(s) => slots[s as usize],
        Operand::Const(v) => v,
        Operand::Cell(c) => cells[c as usize],
    }
}

/// Runs `code` at `slots` in the workspace `cells`.
#[inline(always)]
fn execute(code: &[Instruction], slots: &[f64], cells: &mut [f64; CELLS]) {
    for instruction in code {
        match *instruction {
            Instruction::Keep { to, a } => cells[to as usize] = read(a, slots, cells),
            Instruction::Neg { to, a } => cells[to as usize] = -read(a, slots, cells),
            Instruction::Not { to, a } => {
                cells[to as usize] = if read(a, slots, cells) == 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
            Instruction::Binary { op, to, a, b } => {
                cells[to as usize] = op.apply(read(a, slots, cells), read(b, slots, cells));
            }
            Instruction::Call { f, to, args } => {
                let values = args.map(|o| read(o, slots, cells));
                cells[to as usize] = f.apply(&values[..f.arity()]);
            }
        }
    }
}

/// Several tapes run as one program, each operation that two of them (or
/// one twice) apply to the same operands done once, as value numbering
/// does it: the flows of a mode, which read the same definitions. A pure
/// operation on the same operands gives the same bits, and `x - 0` (the
/// number `+0`) is `x` bit for bit, so each result is its own tape's value
/// bit for bit. Every value has a cell of its own, its operation's index,
/// and every operand is an entry of one memory (those cells, then the
/// slots read, then the constants), so an operation reads its operands
/// without asking what kind they are.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Joint {
    steps: Vec<Step>,
    /// The slots read, each with its entry (after the cells).
    gather: Vec<(u8, u32)>,
    /// The constants, in their entries after the slots'.
    constants: Vec<f64>,
    /// Per tape: where its value goes in the output, and its entry.
    results: Vec<(usize, u8)>,
}

/// Entries of a [`Joint`] program's memory, at most (its entries are
/// numbered by bytes).
const MEMORY: usize = 256;

/// Entries of a memory a [`Joint`] program runs in on the stack; a larger
/// one is allocated at each run. Every mode of every model in `models/`
/// needs at most 31; a stack memory is cleared at every run, which costs
/// more the larger it is.
const STACK_MEMORY: usize = 48;

/// One operation of a [`Joint`] program, on entries of its memory: what
/// it does, where it writes, and its operands (padded with the first).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Step {
    code: Code,
    to: u8,
    operands: [u8; 3],
}

/// The operations of a [`Step`], every operator and function its own, so
/// that running one is a single dispatch; each does what its [`Binary`] or
/// [`Function`] does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Code {
    Neg,
    Not,
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
    Abs,
    Sign,
    Sqrt,
    Exp,
    Ln,
    Sin,
    Cos,
    Tan,
    Tanh,
    Atan,
    Min,
    Max,
    Atan2,
    Clamp,
    If,
}

impl Code {
    fn binary(op: Binary) -> Code {
        match op {
            Binary::Add => Code::Add,
            Binary::Sub => Code::Sub,
            Binary::Mul => Code::Mul,
            Binary::Div => Code::Div,
            Binary::Rem => Code::Rem,
            Binary::Pow => Code::Pow,
            Binary::Lt => Code::Lt,
            Binary::Le => Code::Le,
            Binary::Gt => Code::Gt,
            Binary::Ge => Code::Ge,
            Binary::Eq => Code::Eq,
            Binary::Ne => Code::Ne,
            Binary::And => Code::And,
            Binary::Or => Code::Or,
        }
    }

    fn function(f: Function) -> Code {
        match f {
            Function::Abs => Code::Abs,
            Function::Sign => Code::Sign,
            Function::Sqrt => Code::Sqrt,
            Function::Exp => Code::Exp,
            Function::Ln => Code::Ln,
            Function::Sin => Code::Sin,
            Function::Cos => Code::Cos,
            Function::Tan => Code::Tan,
            Function::Tanh => Code::Tanh,
            Function::Atan => Code::Atan,
            Function::Min => Code::Min,
            Function::Max => Code::Max,
            Function::Atan2 => Code::Atan2,
            Function::Clamp => Code::Clamp,
            Function::If => Code::If,
        }
    }

    /// The value on operands `x`.
    #[inline(always)]
    fn apply(self, x: [f64; 3]) -> f64 {
        let binary = |op: Binary| op.apply(x[0], x[1]);
        let call = |f: Function| f.apply(&x[..f.arity()]);
        match self {
            Code::Neg => -x[0],
            Code::Not => {
                if x[0] == 0.0 {
                    1.0
                } else {
                    0.0
                }
            }
            Code::Add => binary(Binary::Add),
            Code::Sub => binary(Binary::Sub),
            Code::Mul => binary(Binary::Mul),
            Code::Div => binary(Binary::Div),
            Code::Rem => binary(Binary::Rem),
            Code::Pow => binary(Binary::Pow),
            Code::Lt => binary(Binary::Lt),
            Code::Le => binary(Binary::Le),
            Code::Gt => binary(Binary::Gt),
            Code::Ge => binary(Binary::Ge),
            Code::Eq => binary(Binary::Eq),
            Code::Ne => binary(Binary::Ne),
            Code::And => binary(Binary::And),
            Code::Or => binary(Binary::Or),
            Code::Abs => call(Function::Abs),
            Code::Sign => call(Function::Sign),
            Code::Sqrt => call(Function::Sqrt),
            Code::Exp => call(Function::Exp),
            Code::Ln => call(Function::Ln),
            Code::Sin => call(Function::Sin),
            Code::Cos => call(Function::Cos),
            Code::Tan => call(Function::Tan),
            Code::Tanh => call(Function::Tanh),
            Code::Atan => call(Function::Atan),
            Code::Min => call(Function::Min),
            Code::Max => call(Function::Max),
            Code::Atan2 => call(Function::Atan2),
            Code::Clamp => call(Function::Clamp),
            Code::If => call(Function::If),
        }
    }
}

impl Joint {
    /// The joint program of `programs`, each with the output position of
    /// its value: each program's cells renamed to the values they hold
    /// when read; `None` when their distinct operations need more than the
    /// workspace's cells, or their cells, slots and constants more than
    /// [`MEMORY`] entries.
    pub(super) fn of(programs: &[(usize, &Program)]) -> Option<Joint> {
        let mut code = Vec::new();
        let mut results = Vec::with_capacity(programs.len());
        for &(at, program) in programs {
            // The value each of the program's cells holds.
            let mut held = [Operand::Const(0.0); CELLS];
            let value = |o: Operand, held: &[Operand; CELLS]| match o {
                Operand::Cell(c) => held[c as usize],
                o => o,
            };
            for instruction in &program.code {
                let renamed = instruction.reading(|o| value(o, &held));
                held[renamed.target() as usize] = match renamed {
                    Instruction::Keep { a, .. } => a,
                    Instruction::Binary {
                        op: Binary::Sub,
                        a,
                        b,
                        ..
                    } if is_positive_zero(b) => a,
                    _ => value_of(&mut code, renamed)?,
                };
            }
            results.push((at, value(program.result, &held)));
        }
        Layout::program(&code, &results)
    }

    /// Number of operations run.
    #[cfg(test)]
    pub(super) fn operations(&self) -> usize {
        self.steps.len()
    }

    /// Entries of its memory.
    #[cfg(test)]
    pub(super) fn entries(&self) -> usize {
        self.steps.len() + self.gather.len() + self.constants.len()
    }

    /// Writes each tape's value at `slots` into its position of `out`.
    #[inline(never)]
    pub(super) fn run(&self, slots: &[f64], out: &mut [f64]) {
        let constants = self.steps.len() + self.gather.len();
        let entries = constants + self.constants.len();
        if entries <= STACK_MEMORY {
            self.run_in(&mut [0.0; STACK_MEMORY], slots, out);
        } else {
            self.run_in(&mut vec![0.0; entries], slots, out);
        }
    }

    /// [`Joint::run`] in the memory `m`, of at least the program's entries.
    #[inline(never)]
    fn run_in(&self, m: &mut [f64], slots: &[f64], out: &mut [f64]) {
        for &(entry, slot) in &self.gather {
            m[entry as usize] = slots[slot as usize];
        }
        let constants = self.steps.len() + self.gather.len();
        m[constants..constants + self.constants.len()].copy_from_slice(&self.constants);
        for step in &self.steps {
            let x = step.operands.map(|e| m[e as usize]);
            m[step.to as usize] = step.code.apply(x);
        }
        for &(at, entry) in &self.results {
            out[at] = m[entry as usize];
        }
    }
}

/// The entries of a [`Joint`] program's memory while it is laid out: its
/// cells, and the slots and constants it reads in the order first met.
struct Layout {
    cells: usize,
    slots: Vec<u32>,
    constants: Vec<f64>,
}

impl Layout {
    /// The program of `code` (each instruction writing the cell of its
    /// index, none keeping a value) and `results` on one memory; `None`
    /// past [`MEMORY`] entries.
    fn program(code: &[Instruction], results: &[(usize, Operand)]) -> Option<Joint> {
        let mut memory = Layout {
            cells: code.len(),
            slots: Vec::new(),
            constants: Vec::new(),
        };
        // Slots and constants first met, so that their entries can be
        // numbered once the cells' count is known.
        for instruction in code {
            instruction.reading(|o| {
                memory.note(o);
                o
            });
        }
        for &(_, o) in results {
            memory.note(o);
        }
        if memory.cells + memory.slots.len() + memory.constants.len() > MEMORY {
            return None;
        }
        let steps = code
            .iter()
            .map(|instruction| {
                let (code, to, operands): (Code, u8, &[Operand]) = match instruction {
                    Instruction::Keep { .. } => return None,
                    Instruction::Neg { to, a } => (Code::Neg, *to, std::slice::from_ref(a)),
                    Instruction::Not { to, a } => (Code::Not, *to, std::slice::from_ref(a)),
                    Instruction::Binary { op, to, a, b } => (Code::binary(*op), *to, &[*a, *b][..]),
                    Instruction::Call { f, to, args } => {
                        (Code::function(*f), *to, &args[..f.arity()])
                    }
                };
                let mut entries = [memory.entry(operands[0]); 3];
                for (e, &o) in entries.iter_mut().zip(operands) {
                    *e = memory.entry(o);
                }
                Some(Step {
                    code,
                    to,
                    operands: entries,
                })
            })
            .collect::<Option<Vec<Step>>>()?;
        Some(Joint {
            steps,
            gather: memory
                .slots
                .iter()
                .enumerate()
                .map(|(k, &s)| ((memory.cells + k) as u8, s))
                .collect(),
            results: results
                .iter()
                .map(|&(at, o)| (at, memory.entry(o)))
                .collect(),
            constants: memory.constants,
        })
    }

    /// Notes the slot or constant `o` reads.
    fn note(&mut self, o: Operand) {
        match o {
            Operand::Slot(s) if !self.slots.contains(&s) => self.slots.push(s),
            Operand::Const(v) if !self.constants.iter().any(|c| c.to_bits() == v.to_bits()) => {
                self.constants.push(v)
            }
            _ => {}
        }
    }

    /// The entry of operand `o` (a cell, or a slot or constant noted).
    fn entry(&self, o: Operand) -> u8 {
        let at = match o {
            Operand::Cell(c) => c as usize,
            Operand::Slot(s) => self.cells + self.slots.iter().position(|&t| t == s).unwrap_or(0),
            Operand::Const(v) => {
                self.cells
                    + self.slots.len()
                    + self
                        .constants
                        .iter()
                        .position(|c| c.to_bits() == v.to_bits())
                        .unwrap_or(0)
            }
        };
        at as u8
    }
}

fn is_positive_zero(o: Operand) -> bool {
    matches!(o, Operand::Const(v) if v.to_bits() == 0.0f64.to_bits())
}

/// The cell holding the value of `instruction` (its `to` not read): the
/// cell of the same operation on the same operands in `code`, else a new
/// cell, written by `instruction` appended; `None` past the workspace.
fn value_of(code: &mut Vec<Instruction>, instruction: Instruction) -> Option<Operand> {
    if let Some(done) = code.iter().position(|c| same_operation(c, &instruction)) {
        return Some(Operand::Cell(done as u8));
    }
    let to = code.len();
    if to >= CELLS {
        return None;
    }
    code.push(instruction.writing(to as u8));
    Some(Operand::Cell(to as u8))
}

/// Whether `x` and `y` apply the same operation to the same operands
/// (numbers compared by their bits), wherever they write.
fn same_operation(x: &Instruction, y: &Instruction) -> bool {
    let same = |a: &Operand, b: &Operand| match (a, b) {
        (Operand::Const(u), Operand::Const(v)) => u.to_bits() == v.to_bits(),
        (a, b) => a == b,
    };
    match (x, y) {
        (Instruction::Keep { a, .. }, Instruction::Keep { a: b, .. })
        | (Instruction::Neg { a, .. }, Instruction::Neg { a: b, .. })
        | (Instruction::Not { a, .. }, Instruction::Not { a: b, .. }) => same(a, b),
        (
            Instruction::Binary { op, a, b, .. },
            Instruction::Binary {
                op: op2,
                a: a2,
                b: b2,
                ..
            },
        ) => op == op2 && same(a, a2) && same(b, b2),
        (
            Instruction::Call { f, args, .. },
            Instruction::Call {
                f: f2, args: args2, ..
            },
        ) => f == f2 && args.iter().zip(args2).all(|(a, b)| same(a, b)),
        _ => false,
    }
}
