//! Expression text parsed by evalexpr and built into a postfix tape: the
//! size and nesting checked before parsing, the tree walked without
//! recursion.

use super::fold::push_folded;
use super::tape::{Binary, Function, MAX_DEPTH, Op};
use super::{ExprError, Expression, MAX_LENGTH, MAX_NESTING};
use evalexpr::{DefaultNumericTypes, Node, Operator, Value};

/// Parses `text` with evalexpr, after [`check_size`].
pub(super) fn parse(text: &str) -> Result<Tree, ExprError> {
    check_size(text)?;
    evalexpr::build_operator_tree::<DefaultNumericTypes>(text)
        .map(Tree)
        .map_err(|e| ExprError::Syntax {
            text: text.to_string(),
            message: e.to_string(),
        })
}

/// evalexpr's tree of an expression. A sum of many terms is a tree as deep
/// as it has terms; it is taken apart here without recursion (the tree's
/// own drop recurses once per level).
pub(super) struct Tree(pub(super) Node<DefaultNumericTypes>);

impl Drop for Tree {
    fn drop(&mut self) {
        let mut pending = std::mem::take(self.0.children_mut());
        while let Some(mut node) = pending.pop() {
            pending.append(node.children_mut());
        }
    }
}

/// Refuses a text longer than [`MAX_LENGTH`] or nested deeper than
/// [`MAX_NESTING`] ([`nesting`]) before evalexpr parses it.
fn check_size(text: &str) -> Result<(), ExprError> {
    if text.len() > MAX_LENGTH {
        return Err(ExprError::TooLong(text.len()));
    }
    if nesting(text) > MAX_NESTING {
        return Err(ExprError::TooNested);
    }
    Ok(())
}

/// The operator characters of evalexpr's tokenizer; any other character
/// that is not whitespace belongs to a name or a number.
fn is_operator(c: char) -> bool {
    "+-*/%^(),;=!<>&|\"".contains(c)
}

/// How deeply `text` nests, counted as evalexpr's parser descends: an open
/// parenthesis is one level, and so is each prefix item since the last
/// binary operator within the same parentheses (a unary `-` or `!`, a
/// function name followed by its argument). evalexpr inserts each token
/// by recursing down the right edge of the tree built so far, and that
/// edge holds these levels plus one node per operator precedence (a
/// binary operator cuts it back to its own place), so a text within
/// [`MAX_NESTING`] is parsed with a recursion of at most about
/// `MAX_NESTING` plus the number of precedences. Strings and comments are
/// skipped as evalexpr skips them; a number's exponent sign
/// (`1e-3`) is not an operator. Counting stops past [`MAX_NESTING`].
fn nesting(text: &str) -> usize {
    // Each open parenthesis: the depth before it and the base of its level.
    let mut levels: Vec<(usize, usize)> = Vec::new();
    let (mut depth, mut base, mut deepest) = (0usize, 0usize, 0usize);
    // The last token ends an operand (a name, a number, a string or `)`).
    let mut operand = false;
    let mut chars = text.chars().peekable();
    while let Some(c) = chars.next() {
        match c {
            c if c.is_whitespace() => continue,
            '"' => {
                while let Some(c) = chars.next() {
                    match c {
                        '"' => break,
                        '\\' => {
                            chars.next();
                        }
                        _ => {}
                    }
                }
                operand = true;
            }
            '/' if chars.peek() == Some(&'/') => {
                for c in chars.by_ref() {
                    if c == '\n' {
                        break;
                    }
                }
                continue;
            }
            '/' if chars.peek() == Some(&'*') => {
                chars.next();
                let mut star = false;
                for c in chars.by_ref() {
                    if star && c == '/' {
                        break;
                    }
                    star = c == '*';
                }
                continue;
            }
            '(' => {
                levels.push((depth, base));
                depth += 1;
                base = depth;
                operand = false;
            }
            ')' => {
                (depth, base) = levels.pop().unwrap_or((base, base));
                operand = true;
            }
            '-' if !operand => depth += 1,
            '!' if chars.peek() != Some(&'=') => depth += 1,
            c if is_operator(c) => {
                depth = base;
                operand = false;
            }
            c => {
                // A name or a number, and an exponent's sign with its digits.
                let mut last = c;
                while let Some(&next) = chars.peek() {
                    let literal = !next.is_whitespace() && !is_operator(next);
                    let exponent = matches!(next, '+' | '-')
                        && matches!(last, 'e' | 'E')
                        && (c.is_ascii_digit() || c == '.');
                    if !(literal || exponent) {
                        break;
                    }
                    last = next;
                    chars.next();
                }
                // Followed by a value, it is a function name (evalexpr calls
                // a name followed by a value); counted as one whatever it is.
                let mut ahead = chars.clone();
                let next = loop {
                    match ahead.next() {
                        Some(w) if w.is_whitespace() => continue,
                        other => break other,
                    }
                };
                // A comment may hide what follows: counted as a value.
                let comment = next == Some('/') && matches!(ahead.next(), Some('/' | '*'));
                let value_follows =
                    comment || next.is_some_and(|n| n == '(' || n == '"' || !is_operator(n));
                if value_follows {
                    depth += 1;
                    operand = false;
                } else {
                    operand = true;
                }
            }
        }
        deepest = deepest.max(depth);
        if deepest > MAX_NESTING {
            break;
        }
    }
    deepest
}

/// The node under evalexpr's `RootNode` wrappers.
pub(super) fn strip_root(mut n: &Node<DefaultNumericTypes>) -> &Node<DefaultNumericTypes> {
    while matches!(n.operator(), Operator::RootNode) && n.children().len() == 1 {
        n = &n.children()[0];
    }
    n
}

/// Whether `n` is an ordering comparison (`<`, `<=`, `>`, `>=`).
pub(super) fn is_ordering(n: &Node<DefaultNumericTypes>) -> bool {
    matches!(
        n.operator(),
        Operator::Lt | Operator::Leq | Operator::Gt | Operator::Geq
    )
}

/// Emits the tape of a tree, folding constant operands.
pub(super) struct Builder<'a> {
    text: &'a str,
    resolve: &'a dyn Fn(&str) -> Option<u32>,
    ops: Vec<Op>,
    depth: usize,
    max_depth: usize,
}

impl<'a> Builder<'a> {
    pub(super) fn new(text: &'a str, resolve: &'a dyn Fn(&str) -> Option<u32>) -> Self {
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
    pub(super) fn op(&mut self, op: Op) {
        push_folded(&mut self.ops, op);
        self.depth = self.depth + 1 - op.operands();
    }

    /// Emits the tape of the tree `root`: its nodes in postfix order,
    /// walked with a stack of its own (a sum of many terms is a deep tree).
    pub(super) fn node(&mut self, root: &Node<DefaultNumericTypes>) -> Result<(), ExprError> {
        // A node to visit, or an operation to emit once its operands are.
        enum Step<'n> {
            Visit(&'n Node<DefaultNumericTypes>),
            Emit(Op),
        }
        let mut steps = vec![Step::Visit(root)];
        while let Some(step) = steps.pop() {
            let node = match step {
                Step::Emit(op) => {
                    self.op(op);
                    continue;
                }
                Step::Visit(node) => strip_root(node),
            };
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
                    self.push(Op::Const(v))?;
                    continue;
                }
                Operator::VariableIdentifierRead { identifier } => {
                    let slot = (self.resolve)(identifier)
                        .ok_or_else(|| ExprError::UnknownSymbol(identifier.clone()))?;
                    self.push(Op::Load(slot))?;
                    continue;
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
                    let f = match Function::by_name(identifier) {
                        Some(f) if f.arity() == args.len() => f,
                        Some(f) => {
                            return Err(ExprError::Arity {
                                name: identifier.clone(),
                                takes: f.arity(),
                                given: args.len(),
                            });
                        }
                        None => {
                            return Err(ExprError::UnknownFunction {
                                name: identifier.clone(),
                                args: args.len(),
                            });
                        }
                    };
                    steps.push(Step::Emit(Op::Call(f)));
                    steps.extend(args.into_iter().rev().map(Step::Visit));
                    continue;
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
            // `a <= x <= b` reads as `(a <= x) <= b`, the truth of one
            // comparison compared again: never what is meant.
            if is_ordering(node) && children.iter().any(|c| is_ordering(strip_root(c))) {
                return Err(ExprError::ChainedComparison(self.text.to_string()));
            }
            steps.push(Step::Emit(op));
            steps.extend(children.iter().rev().map(Step::Visit));
        }
        Ok(())
    }

    pub(super) fn finish(self) -> Result<Expression, ExprError> {
        if self.ops.is_empty() || self.depth != 1 {
            return Err(ExprError::NotNumeric(self.text.to_string()));
        }
        Ok(Expression::from_ops(self.ops))
    }
}

#[cfg(test)]
mod tests {
    use super::nesting;

    #[test]
    fn nesting_is_counted_as_the_parser_descends() {
        for (text, levels) in [
            ("a + b * c - d / e", 0),
            ("(x)", 1),
            ("-x", 1),
            ("- - !x", 3),
            ("-(-(x))", 4),
            ("sin(cos(x))", 4),
            ("sin x", 1),
            ("((x) + (y)) * ((z))", 2),
            ("x != -y", 1),
            ("2e-3 * -x", 1),
            ("-(1) - -(2)", 2),
            ("\"((((\" + /* (((( */ x + // ((((\n 1", 0),
            // What a comment hides may be a function's argument.
            ("x // (\n", 1),
        ] {
            assert_eq!(nesting(text), levels, "{text}");
        }
    }
}
