//! Values of a line compiled once and evaluated on every pass: the lines of loops and
//! subroutines are read again each time they run, and reading an expression from its
//! text costs most of such a line's time (issue 16, "Numbers": the loop benchmark).
//! LinuxCNC keeps its O-word blocks for the same reason (`interp_o_word.cc`).
//!
//! [`compile`] reads a value as [`Reader`](crate::expr::Reader) reads it
//! (`read_real_value`, `read_real_expression`, `read_integer_value`), but emits the
//! steps of its evaluation in the order the reader takes them instead of taking them.
//! Only a value that reads without any syntax error compiles (else `None`, and the
//! caller reads the text as before), so the compiled form can fail only where the
//! reader's evaluation fails (division by zero, an undefined parameter, …), at the
//! same step with the same offset and message: results are bit-identical, errors
//! too. [`eval`] runs the steps on a fixed stack (no allocation).

use crate::error::ErrorKind;
use crate::expr::{to_integer, BinOp, Env, ExprError, Func};
use crate::params::NUM_PARAMS;

type R<T> = Result<T, ExprError>;

/// Nesting deeper than this is not compiled (the text reader reads it, and refuses
/// it past its own limit): it bounds the evaluation stack.
const MAX_COMPILED_DEPTH: u32 = 24;

/// Entries of the evaluation stack; a value that needs more is not compiled (the
/// text reader reads it).
const STACK: usize = 16;

/// A name with no slot yet (see [`Code`]).
const NO_SLOT: u32 = u32::MAX;

/// Which reader a value is read with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// `read_real_value`.
    Real,
    /// `read_real_expression` (at a `[`; no not-a-number check of its own).
    Expression,
    /// `read_integer_value`: a real value within 0.0001 of an integer.
    Integer,
}

/// One evaluation step. Offsets are in the normalized line, as the reader's.
#[derive(Debug, Clone)]
enum Op {
    /// Push a number.
    Num(f64),
    /// Push numbered parameter `index` (an index written as a plain number in range).
    Param(usize),
    /// Pop an index, push that numbered parameter (`#` at `at`, index at `iat`).
    ParamAt { at: usize, iat: usize },
    /// Pop an index, push whether it names a numbered parameter (`EXISTS`).
    ExistsAt { iat: usize },
    /// Push named parameter `names[name]` (`#` at `at`), or whether it exists.
    Named {
        at: usize,
        name: usize,
        exists: bool,
    },
    /// Negate the top.
    Neg,
    /// Refuse a top that is not a number or infinite (`read_real_value`'s end).
    Check(usize),
    /// Pop two, push `left op right` (error at `at`).
    Bin(BinOp, usize),
    /// `Num(right)` then `Bin(op, at)` in one step: the top becomes `top op right`.
    BinNum(BinOp, f64, usize),
    /// Apply a function to the top (error at `at`).
    Func(Func, usize),
    /// Pop two, push `atan2` in degrees.
    Atan,
    /// Refuse a top that is no integer (`read_integer_value`, value at `at`).
    Integer(usize),
    /// `Param(index)` then `Check(start)`.
    ParamC(usize, usize),
    /// `Named` (not `exists`) then `Check(start)`.
    NamedC {
        at: usize,
        name: usize,
        start: usize,
    },
    /// `Bin(op, at)` then `Check(start)`.
    BinC(BinOp, usize, usize),
    /// `BinNum(op, right, at)` then `Check(start)`.
    BinNumC(BinOp, f64, usize, usize),
    /// `Func(f, at)` then `Check(start)`.
    FuncC(Func, usize, usize),
}

/// A compiled value.
#[derive(Debug, Clone)]
pub struct Code {
    ops: Vec<Op>,
    names: Vec<Box<str>>,
    /// `slots[k]`: the slot of `names[k]` in the environment's table once it has
    /// one ([`Env::named_slot`]; [`NO_SLOT`] before). A name keeps its slot for
    /// the whole reading, so it is looked up by name until it has been assigned
    /// once, then read by slot: a code is evaluated with one environment only.
    slots: Vec<std::cell::Cell<u32>>,
    /// Offset just after the value in the normalized line.
    pub end: usize,
}

/// A kept line compiled whole ([`crate::norm::Norm::plan`]): LinuxCNC's
/// `read_items` takes a line's items in order (`read_one_item`); the items of a
/// line of words, parameter settings and comments are fixed by its text, so they
/// are found once and only their values are evaluated on later passes.
#[derive(Debug, Clone, Default)]
pub enum Plan {
    /// Not read whole yet.
    #[default]
    Unread,
    /// Read from its text on every pass (a value that does not compile, an item
    /// other than a word, a setting or a comment).
    Text,
    /// The items, in the order of the line.
    Items(Vec<Item>),
    /// An O-line with a label of fixed text and nothing after its values.
    O(OPlan),
}

/// A kept O-line compiled whole ([`Plan::O`]).
#[derive(Debug, Clone)]
pub struct OPlan {
    /// What it does (its keyword).
    pub(crate) kind: crate::oword::OKind,
    /// Its label as read (a local label is qualified on each pass, by the
    /// subroutine it runs in).
    pub(crate) label: std::rc::Rc<str>,
    /// The normalized offset of the label.
    pub(crate) label_at: usize,
    /// The raw offset of the `o`.
    pub(crate) at: u32,
    /// Its condition, repeat count or return value, where it has one.
    pub(crate) value: Option<Code>,
    /// A call's arguments, in order.
    pub(crate) args: Vec<Code>,
    /// A local label: its qualified name in the subroutine it ran in last (the
    /// key of that subroutine's name, 0 for the main program).
    pub(crate) qualified: std::cell::RefCell<Option<(u64, std::rc::Rc<str>)>>,
}

/// One item of a line compiled whole ([`Plan`]).
#[derive(Debug, Clone)]
pub enum Item {
    /// A word.
    Word {
        /// Its letter, upper case.
        letter: u8,
        /// Its value.
        code: Code,
        /// The raw offset of its letter.
        offset: u32,
    },
    /// `#<name>=value`.
    Named {
        /// The name.
        name: std::rc::Rc<str>,
        /// The value.
        code: Code,
        /// The normalized offset of the `#`.
        at: usize,
        /// The name's parameter slot once it has one (a name keeps its slot for
        /// the whole reading: later passes assign by it without a lookup).
        slot: std::cell::Cell<Option<u32>>,
    },
    /// `#index=value`.
    Numbered {
        /// The index (read as an integer).
        index: Code,
        /// The value.
        code: Code,
        /// The normalized offset of the `#`.
        at: usize,
    },
    /// A comment.
    Comment {
        /// The raw offsets of its text, start and end.
        text: (u32, u32),
        /// The raw offset of its `(`.
        offset: u32,
    },
}

/// Compile the value of kind `kind` at `b[i]`; `None` where the text does not read
/// without a syntax error (or nests deeper than this compiler takes).
pub fn compile(b: &[u8], i: usize, kind: Kind) -> Option<Code> {
    let mut c = Compiler {
        b,
        i,
        ops: Vec::new(),
        names: Vec::new(),
    };
    match kind {
        Kind::Real => c.real_value(0)?,
        Kind::Expression => c.expression(1)?,
        Kind::Integer => {
            let at = c.i;
            c.real_value(0)?;
            c.ops.push(Op::Integer(at));
        }
    }
    let ops = fold(c.ops);
    // the stack the steps need
    let (mut height, mut most) = (0usize, 0usize);
    for op in &ops {
        match op {
            Op::Num(_) | Op::Param(_) | Op::Named { .. } | Op::ParamC(..) | Op::NamedC { .. } => {
                height += 1
            }
            Op::Bin(..) | Op::BinC(..) | Op::Atan => height -= 1,
            Op::BinNum(..) | Op::BinNumC(..) | Op::FuncC(..) => {}
            _ => {}
        }
        most = most.max(height);
    }
    if most > STACK {
        return None;
    }
    Some(Code {
        ops,
        slots: vec![std::cell::Cell::new(NO_SLOT); c.names.len()],
        names: c.names,
        end: c.i,
    })
}

/// The steps `ops` with the work that needs no parameter done once, here: a check
/// of a finite constant (it cannot fail) or of a value just checked is dropped, an
/// operation or function of constants that succeeds becomes its result (the same
/// function on the same values: the same bits), and a constant right operand is
/// taken by its operation ([`Op::BinNum`]); a check is done by the step before it
/// (`Op::ParamC`, …: one step fewer to dispatch). Steps that can fail stay where
/// they are, so errors come at the same step with the same offset.
fn fold(ops: Vec<Op>) -> Vec<Op> {
    let mut out: Vec<Op> = Vec::with_capacity(ops.len());
    for op in ops {
        match (op, out.as_slice()) {
            (Op::Check(_), [.., Op::Num(v)]) if v.is_finite() => {}
            // checked already (a check leaves the top as it is); whether a
            // parameter exists is 0 or 1
            (
                Op::Check(_),
                [.., Op::Check(_)
                | Op::ParamC(..)
                | Op::NamedC { .. }
                | Op::BinC(..)
                | Op::BinNumC(..)
                | Op::FuncC(..)
                | Op::Named { exists: true, .. }],
            ) => {}
            (Op::Check(start), [.., last]) if checked(last, start).is_some() => {
                let fused = checked(last, start).unwrap_or(Op::Check(start));
                out.pop();
                out.push(fused);
            }
            (Op::Neg, [.., Op::Num(v)]) => {
                let v = -*v;
                out.pop();
                out.push(Op::Num(v));
            }
            (Op::Func(f, at), [.., Op::Num(v)]) => match f.apply(*v) {
                Ok(r) => {
                    out.pop();
                    out.push(Op::Num(r));
                }
                Err(_) => out.push(Op::Func(f, at)),
            },
            (Op::Bin(op, _), [.., Op::Num(a), Op::Num(b)]) if op.apply(*a, *b).is_ok() => {
                let r = op.apply(*a, *b).unwrap_or_default();
                out.truncate(out.len() - 2);
                out.push(Op::Num(r));
            }
            (Op::Bin(op, at), [.., Op::Num(b)]) => {
                let b = *b;
                out.pop();
                out.push(Op::BinNum(op, b, at));
            }
            (op, _) => out.push(op),
        }
    }
    out
}

/// Step `last` followed by `Check(start)` as one step, where there is one.
fn checked(last: &Op, start: usize) -> Option<Op> {
    Some(match *last {
        Op::Param(k) => Op::ParamC(k, start),
        Op::Named {
            at,
            name,
            exists: false,
        } => Op::NamedC { at, name, start },
        Op::Bin(op, at) => Op::BinC(op, at, start),
        Op::BinNum(op, right, at) => Op::BinNumC(op, right, at, start),
        Op::Func(f, at) => Op::FuncC(f, at, start),
        _ => return None,
    })
}

struct Compiler<'a> {
    b: &'a [u8],
    i: usize,
    ops: Vec<Op>,
    names: Vec<Box<str>>,
}

impl Compiler<'_> {
    fn at(&self, i: usize) -> u8 {
        self.b.get(i).copied().unwrap_or(0)
    }

    fn cur(&self) -> u8 {
        self.at(self.i)
    }

    /// `Reader::real_value_d`.
    fn real_value(&mut self, depth: u32) -> Option<()> {
        let start = self.i;
        if depth > MAX_COMPILED_DEPTH {
            return None;
        }
        let c = self.cur();
        if c == 0 {
            return None;
        }
        let c1 = self.at(self.i + 1);
        if c == b'[' {
            self.expression(depth + 1)?;
        } else if c == b'#' {
            self.parameter(false, depth + 1)?;
        } else if c == b'+' && c1 != 0 && !c1.is_ascii_digit() && c1 != b'.' {
            self.i += 1;
            self.real_value(depth + 1)?;
        } else if c == b'-' && c1 != 0 && !c1.is_ascii_digit() && c1 != b'.' {
            self.i += 1;
            self.real_value(depth + 1)?;
            self.ops.push(Op::Neg);
        } else if c.is_ascii_lowercase() {
            self.unary(depth + 1)?;
        } else {
            let v = self.real_number()?;
            self.ops.push(Op::Num(v));
        }
        self.ops.push(Op::Check(start));
        Some(())
    }

    /// `Reader::real_number`, through the reader itself (it needs no parameters).
    fn real_number(&mut self) -> Option<f64> {
        let mut r = crate::expr::Reader::new(self.b, self.i, &NoEnv);
        let v = r.real_number().ok()?;
        self.i = r.i;
        Some(v)
    }

    /// `Reader::expression_d`: the reductions happen where the reader makes them
    /// (they depend on the operators only), so the steps keep its order.
    fn expression(&mut self, depth: u32) -> Option<()> {
        if self.cur() != b'[' {
            return None;
        }
        self.i += 1;
        let mut ops = [(BinOp::RightBracket, 0usize); 8];
        self.real_value(depth)?;
        ops[0] = (self.operation()?, 0);
        let mut n = 1;
        while ops[0].0 != BinOp::RightBracket {
            if n >= 8 {
                return None;
            }
            self.real_value(depth)?;
            let op_at = self.i;
            ops[n] = (self.operation()?, op_at);
            n += 1;
            while n >= 2 && ops[n - 1].0.precedence() <= ops[n - 2].0.precedence() {
                self.ops.push(Op::Bin(ops[n - 2].0, ops[n - 1].1));
                ops[n - 2] = ops[n - 1];
                n -= 1;
            }
        }
        Some(())
    }

    /// `Reader::operation`.
    fn operation(&mut self) -> Option<BinOp> {
        let c = self.cur();
        self.i += 1;
        let n1 = self.cur();
        let n2 = self.at(self.i + 1);
        let mut two = |op: BinOp, a: u8, b: u8| -> Option<BinOp> {
            (n1 == a && n2 == b).then(|| {
                self.i += 2;
                op
            })
        };
        use BinOp::*;
        match c {
            b'+' => Some(Plus),
            b'-' => Some(Minus),
            b'/' => Some(Div),
            b'*' => {
                if n1 == b'*' {
                    self.i += 1;
                    Some(Power)
                } else {
                    Some(Times)
                }
            }
            b']' => Some(RightBracket),
            b'a' => two(And, b'n', b'd'),
            b'm' => two(Mod, b'o', b'd'),
            b'x' => two(Xor, b'o', b'r'),
            b'o' | b'e' | b'n' | b'g' | b'l' => {
                let op = match (c, n1) {
                    (b'o', b'r') => Or,
                    (b'e', b'q') => Eq,
                    (b'n', b'e') => Ne,
                    (b'g', b'e') => Ge,
                    (b'g', b't') => Gt,
                    (b'l', b'e') => Le,
                    (b'l', b't') => Lt,
                    _ => return None,
                };
                self.i += 1;
                Some(op)
            }
            _ => None,
        }
    }

    /// `Reader::unary`.
    fn unary(&mut self, depth: u32) -> Option<()> {
        let at = self.i;
        let rest = &self.b[self.i.min(self.b.len())..];
        let (func, len) = match rest.first().copied().unwrap_or(0) {
            b'a' if rest.starts_with(b"abs") => (Func::Abs, 3),
            b'a' if rest.starts_with(b"acos") => (Func::Acos, 4),
            b'a' if rest.starts_with(b"asin") => (Func::Asin, 4),
            b'a' if rest.starts_with(b"atan") => (Func::Atan, 4),
            b'c' if rest.starts_with(b"cos") => (Func::Cos, 3),
            b'e' if rest.starts_with(b"exp") => (Func::Exp, 3),
            b'e' if rest.starts_with(b"exists") => (Func::Exists, 6),
            b'f' if rest.starts_with(b"fix") => (Func::Fix, 3),
            b'f' if rest.starts_with(b"fup") => (Func::Fup, 3),
            b'l' if rest.starts_with(b"ln") => (Func::Ln, 2),
            b'r' if rest.starts_with(b"round") => (Func::Round, 5),
            b's' if rest.starts_with(b"sin") => (Func::Sin, 3),
            b's' if rest.starts_with(b"sqrt") => (Func::Sqrt, 4),
            b't' if rest.starts_with(b"tan") => (Func::Tan, 3),
            _ => return None,
        };
        self.i += len;
        if self.cur() != b'[' {
            return None;
        }
        if func == Func::Exists {
            self.i += 1;
            if self.cur() != b'#' {
                return None;
            }
            self.parameter(true, depth)?;
            if self.cur() != b']' {
                return None;
            }
            self.i += 1;
            return Some(());
        }
        self.expression(depth)?;
        if func == Func::Atan {
            if self.cur() != b'/' {
                return None;
            }
            self.i += 1;
            if self.cur() != b'[' {
                return None;
            }
            self.expression(depth)?;
            self.ops.push(Op::Atan);
            return Some(());
        }
        self.ops.push(Op::Func(func, at));
        Some(())
    }

    /// `Reader::parameter`.
    fn parameter(&mut self, exists: bool, depth: u32) -> Option<()> {
        let at = self.i;
        self.i += 1; // '#'
        if self.cur() == b'<' {
            self.i += 1;
            let rest = &self.b[self.i.min(self.b.len())..];
            let k = rest.iter().position(|&c| c == b'>')?;
            let name: Box<str> = String::from_utf8_lossy(&rest[..k]).into();
            self.i += k + 1;
            let index = match self.names.iter().position(|n| *n == name) {
                Some(p) => p,
                None => {
                    self.names.push(name);
                    self.names.len() - 1
                }
            };
            self.ops.push(Op::Named {
                at,
                name: index,
                exists,
            });
            return Some(());
        }
        let iat = self.i;
        let first = self.ops.len();
        self.real_value(depth)?;
        if exists {
            self.ops.push(Op::ExistsAt { iat });
            return Some(());
        }
        // `#5`: a constant index in range reads the parameter directly
        if let [Op::Num(v), Op::Check(_)] = self.ops[first..] {
            if let Some(k) = to_integer(v).filter(|k| (1..NUM_PARAMS as i32).contains(k)) {
                self.ops.truncate(first);
                self.ops.push(Op::Param(k as usize));
                return Some(());
            }
        }
        self.ops.push(Op::ParamAt { at, iat });
        Some(())
    }
}

/// No parameters: for reading plain numbers.
struct NoEnv;

impl Env for NoEnv {
    fn numbered(&self, _: usize) -> f64 {
        0.0
    }
    fn named(&self, _: &str) -> Result<Option<f64>, ErrorKind> {
        Ok(None)
    }
}

fn bad<T>(at: usize, msg: impl Into<String>) -> R<T> {
    Err((at, ErrorKind::Invalid(msg.into())))
}

/// Evaluate `code` with the parameters of `env`: the value, or the error the text
/// reader gives for the same line and parameters.
#[inline]
pub fn eval<E: Env + ?Sized>(code: &Code, env: &E) -> R<f64> {
    // most values of a loop are one or two steps (a call argument `[#<i>]`, a
    // condition `[#<j> LT 100]`): the same steps on one value, without the stack
    match code.ops.as_slice() {
        [a] => {
            if let Some(v) = push_step(a, code, env) {
                return v;
            }
        }
        [a, b] if is_top_step(b) => {
            if let Some(v) = push_step(a, code, env) {
                return top_step(b, v?);
            }
        }
        _ => {}
    }
    eval_stack(code, env)
}

/// A step that pushes a value onto an empty stack, as [`eval_stack`] does it;
/// `None` for a step that takes values from the stack.
fn push_step<E: Env + ?Sized>(op: &Op, code: &Code, env: &E) -> Option<R<f64>> {
    Some(match *op {
        Op::Num(v) => Ok(v),
        Op::Param(k) => Ok(env.numbered(k)),
        Op::ParamC(k, start) => check(env.numbered(k), start),
        Op::NamedC { at, name, start } => {
            named_value(code, name, at, false, env).and_then(|v| check(v, start))
        }
        Op::Named { at, name, exists } => named_value(code, name, at, exists, env),
        _ => return None,
    })
}

/// Whether [`top_step`] takes `op`.
fn is_top_step(op: &Op) -> bool {
    matches!(
        op,
        Op::BinNum(..) | Op::BinNumC(..) | Op::Check(_) | Op::Neg | Op::Func(..) | Op::FuncC(..)
    )
}

/// A step that replaces the top of a stack of one value `v`, as [`eval_stack`]
/// does it (only the steps [`is_top_step`] takes).
fn top_step(op: &Op, v: f64) -> R<f64> {
    match *op {
        Op::BinNum(op, right, at) => bin(op, v, right, at),
        Op::BinNumC(op, right, at, start) => check(bin(op, v, right, at)?, start),
        Op::Check(start) => check(v, start),
        Op::Neg => Ok(-v),
        Op::Func(f, at) => f.apply(v).or_else(|m| bad(at, m)),
        Op::FuncC(f, at, start) => check(f.apply(v).or_else(|m| bad(at, m))?, start),
        _ => unreachable!("is_top_step takes only the steps above"),
    }
}

/// [`eval`] of any code, on a fixed stack.
fn eval_stack<E: Env + ?Sized>(code: &Code, env: &E) -> R<f64> {
    // `compile` bounds the height by STACK, a power of two: masking the index
    // keeps it in the array without a bounds check
    const MASK: usize = STACK - 1;
    let mut stack = [0.0f64; STACK];
    let mut n = 0usize;
    macro_rules! top {
        () => {
            stack[n.wrapping_sub(1) & MASK]
        };
    }
    for op in &code.ops {
        match *op {
            Op::Num(v) => {
                stack[n & MASK] = v;
                n += 1;
            }
            Op::Param(k) => {
                stack[n & MASK] = env.numbered(k);
                n += 1;
            }
            Op::ParamC(k, start) => {
                stack[n & MASK] = check(env.numbered(k), start)?;
                n += 1;
            }
            Op::NamedC { at, name, start } => {
                stack[n & MASK] = check(named_value(code, name, at, false, env)?, start)?;
                n += 1;
            }
            Op::Named { at, name, exists } => {
                stack[n & MASK] = named_value(code, name, at, exists, env)?;
                n += 1;
            }
            Op::BinNum(op, right, at) => top!() = bin(op, top!(), right, at)?,
            Op::BinNumC(op, right, at, start) => {
                top!() = check(bin(op, top!(), right, at)?, start)?;
            }
            Op::Bin(op, at) => {
                let right = top!();
                n -= 1;
                top!() = bin(op, top!(), right, at)?;
            }
            Op::BinC(op, at, start) => {
                let right = top!();
                n -= 1;
                top!() = check(bin(op, top!(), right, at)?, start)?;
            }
            Op::FuncC(f, at, start) => {
                top!() = check(f.apply(top!()).or_else(|m| bad(at, m))?, start)?;
            }
            Op::Check(start) => {
                check(top!(), start)?;
            }
            Op::Neg => top!() = -top!(),
            Op::ParamAt { at, iat } => {
                let index = to_integer(top!()).ok_or_else(|| {
                    (
                        iat,
                        ErrorKind::Invalid("Non integer value for integer".into()),
                    )
                })?;
                if !(1..NUM_PARAMS as i32).contains(&index) {
                    return bad(at, "Parameter number out of range");
                }
                top!() = env.numbered(index as usize);
            }
            Op::ExistsAt { iat } => {
                let index = to_integer(top!()).ok_or_else(|| {
                    (
                        iat,
                        ErrorKind::Invalid("Non integer value for integer".into()),
                    )
                })?;
                top!() = if (1..NUM_PARAMS as i32).contains(&index) {
                    1.0
                } else {
                    0.0
                };
            }
            Op::Func(f, at) => top!() = f.apply(top!()).or_else(|m| bad(at, m))?,
            Op::Atan => {
                let right = top!();
                n -= 1;
                top!() = crate::x87::rad_to_deg(top!().atan2(right));
            }
            Op::Integer(at) => {
                let k = to_integer(top!()).ok_or_else(|| {
                    (
                        at,
                        ErrorKind::Invalid("Non integer value for integer".into()),
                    )
                })?;
                top!() = f64::from(k);
            }
        }
    }
    Ok(stack[0])
}

/// `read_real_value`'s end: `v`, or the error for a value that is not a number or
/// infinite (value at `start`).
fn check(v: f64, start: usize) -> R<f64> {
    if v.is_finite() {
        Ok(v)
    } else {
        not_finite(v, start)
    }
}

/// The error of [`check`].
#[cold]
fn not_finite(v: f64, start: usize) -> R<f64> {
    let what = if v.is_nan() {
        "not a number"
    } else {
        "infinity"
    };
    bad(start, format!("Calculation resulted in '{what}'"))
}

/// `left op right` (`BinOp::apply`, the commonest operations written out).
fn bin(op: BinOp, left: f64, right: f64, at: usize) -> R<f64> {
    Ok(match op {
        BinOp::Plus => left + right,
        BinOp::Minus => left - right,
        BinOp::Times => left * right,
        BinOp::Lt => f64::from(u8::from(left < right)),
        _ => op.apply(left, right).or_else(|m| bad(at, m))?,
    })
}

/// Named parameter `code.names[name]` (`#` at `at`), or whether it exists: by
/// slot where it is set in its scope (the same value the name gives), by name
/// otherwise (predefined, unset, …).
fn named_value<E: Env + ?Sized>(
    code: &Code,
    name: usize,
    at: usize,
    exists: bool,
    env: &E,
) -> R<f64> {
    let by_slot = match code.slots[name].get() {
        NO_SLOT => None,
        k => env.slot_value(k),
    };
    let found = match by_slot {
        Some(v) => Some(v),
        None => named(code, name, at, env)?,
    };
    match (exists, found) {
        (true, f) => Ok(if f.is_some() { 1.0 } else { 0.0 }),
        (false, Some(v)) => Ok(v),
        (false, None) if env.defining_sub() => Ok(0.0),
        (false, None) => bad(
            at,
            format!("Named parameter #<{}> not defined", code.names[name]),
        ),
    }
}

/// A named parameter read by its name (no slot yet, or unset in its slot's scope):
/// the name's slot is remembered once it has one.
#[cold]
fn named<E: Env + ?Sized>(code: &Code, name: usize, at: usize, env: &E) -> R<Option<f64>> {
    let slot = &code.slots[name];
    let name = &code.names[name];
    if slot.get() == NO_SLOT {
        if let Some(k) = env.named_slot(name) {
            slot.set(k);
            if let Some(v) = env.slot_value(k) {
                return Ok(Some(v));
            }
        }
    }
    env.named(name).map_err(|k| (at, k))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::Reader;
    use crate::norm::Norm;
    use proptest::prelude::*;
    use std::collections::HashMap;

    struct Vars(HashMap<String, f64>, Vec<f64>);
    impl Env for Vars {
        fn numbered(&self, i: usize) -> f64 {
            self.1.get(i).copied().unwrap_or(0.0)
        }
        fn named(&self, n: &str) -> Result<Option<f64>, ErrorKind> {
            if n == "_unsupported" {
                return Err(ErrorKind::Unsupported {
                    word: n.into(),
                    why: "test".into(),
                });
            }
            Ok(self.0.get(n).copied())
        }
    }

    fn env() -> Vars {
        let mut v = vec![0.0; NUM_PARAMS];
        v[1] = 2.0;
        v[2] = 3.5;
        v[3] = 1.0;
        v[4] = -1.0;
        v[5] = 0.0;
        Vars(
            [("x".to_string(), 7.0), ("z".to_string(), 0.0)]
                .into_iter()
                .collect(),
            v,
        )
    }

    /// The text reader's answer: value (bits) and end, or offset and message.
    fn by_text(b: &[u8], kind: Kind, e: &Vars) -> Result<(u64, usize), (usize, String)> {
        let mut r = Reader::new(b, 0, e);
        let v = match kind {
            Kind::Real => r.real_value(),
            Kind::Expression => r.expression(),
            Kind::Integer => r.integer_value().map(f64::from),
        };
        v.map(|v| (v.to_bits(), r.i))
            .map_err(|(at, k)| (at, k.to_string()))
    }

    fn by_code(code: &Code, e: &Vars) -> Result<(u64, usize), (usize, String)> {
        eval(code, e)
            .map(|v| (v.to_bits(), code.end))
            .map_err(|(at, k)| (at, k.to_string()))
    }

    fn norm(s: &str) -> Vec<u8> {
        let mut n = Norm::default();
        n.build(s.as_bytes());
        n.b
    }

    #[test]
    fn loop_lines_compile_and_evaluate_as_read() {
        let e = env();
        for s in [
            "[#1 * 0.5 + SIN[#2 * 3.6] * 2]",
            "[#<x> LT 100]",
            "[#<x> + 1]",
            "-#1",
            "#[#1 + 1]",
            "##3",
            "ATAN[#1]/[#2 - 4]",
            "[EXISTS[#<x>] + EXISTS[#<nope>] + EXISTS[#7000] * 2]",
            "[1 / #5]",
            "[#<nope> + 1]",
            "[SQRT[#4]]",
            "#[#1 + 0.5]",
            "#[#1 * 4000]",
            "[2 ** 0.5 MOD 1 XOR 0 AND 1 OR 0 GE 0 LE 1 EQ 1 NE 0 GT -1]",
            "[#<_unsupported>]",
            "[exp[1000]]",
        ] {
            let b = norm(s);
            let code = compile(&b, 0, Kind::Real).unwrap_or_else(|| panic!("{s} compiles"));
            assert_eq!(by_code(&code, &e), by_text(&b, Kind::Real, &e), "{s}");
        }
        let b = norm("[#1 + 0.00001]");
        let code = compile(&b, 0, Kind::Integer).unwrap();
        assert_eq!(by_code(&code, &e), by_text(&b, Kind::Integer, &e));
        assert_eq!(by_code(&code, &e).unwrap().0, 2.0f64.to_bits());
        let b = norm("[#2]");
        let code = compile(&b, 0, Kind::Integer).unwrap();
        assert_eq!(by_code(&code, &e), by_text(&b, Kind::Integer, &e));
        assert!(by_code(&code, &e).is_err());
    }

    #[test]
    fn short_values_take_the_stackless_steps_as_the_stack() {
        let e = env();
        for kind in [Kind::Real, Kind::Expression] {
            for s in [
                "[#<x>]",
                "[#<x> LT 100]",
                "[#<x> + 1]",
                "[#<z> / 0]",
                "[#<nope>]",
                "[#<_unsupported>]",
                "#1",
                "[#2 * 2]",
                "[SQRT[#4]]",
                "[SIN[#<x>]]",
                "[3]",
                "[EXISTS[#<x>]]",
            ] {
                if kind == Kind::Expression && !s.starts_with('[') {
                    continue;
                }
                let b = norm(s);
                let code = compile(&b, 0, kind).unwrap_or_else(|| panic!("{s} compiles"));
                assert!(code.ops.len() <= 2, "{s}: {:?}", code.ops);
                let by_stack = eval_stack(&code, &e)
                    .map(|v| (v.to_bits(), code.end))
                    .map_err(|(at, k)| (at, k.to_string()));
                assert_eq!(by_code(&code, &e), by_stack, "{s}");
                if kind == Kind::Real {
                    assert_eq!(by_code(&code, &e), by_text(&b, kind, &e), "{s}");
                }
            }
        }
    }

    #[test]
    fn constants_fold_and_failing_steps_stay() {
        let e = env();
        // SIN[30] * 2 and the checks of constants are done once, at compile time
        let b = norm("[#1 * 0.5 + SIN[30] * 2]");
        let code = compile(&b, 0, Kind::Real).unwrap();
        assert!(
            matches!(
                code.ops[..],
                [
                    Op::ParamC(1, _),
                    Op::BinNum(BinOp::Times, ..),
                    Op::BinNumC(BinOp::Plus, ..)
                ]
            ),
            "{:?}",
            code.ops
        );
        assert_eq!(by_code(&code, &e), by_text(&b, Kind::Real, &e));
        // a division by a constant zero, an infinite constant: still errors, where
        // the text reader gives them
        for s in ["[1 / 0]", "[#1 / [2 - 2]]", "[10 ** 400]", "[-SQRT[-1]]"] {
            let b = norm(s);
            let code = compile(&b, 0, Kind::Real).unwrap();
            assert!(by_code(&code, &e).is_err(), "{s}");
            assert_eq!(by_code(&code, &e), by_text(&b, Kind::Real, &e), "{s}");
        }
    }

    #[test]
    fn syntax_errors_and_deep_nesting_are_left_to_the_text_reader() {
        for s in [
            "",
            "[1 +]",
            "[1 foo 2]",
            "[1",
            "cot[1]",
            "atan[1]2",
            "#<x",
            "exists[1]",
            "[1+[1+[1+[1+[1+[1+[1+[1+[1+1]]]]]]]]]",
        ] {
            let b = norm(s);
            let compiled = compile(&b, 0, Kind::Real);
            if s.starts_with("[1+[1+") {
                // nine nested levels of two values each: within the stack
                assert!(compiled.is_some(), "{s}");
            } else {
                assert!(compiled.is_none(), "{s}");
            }
        }
        let deep = format!("{}1{}", "[".repeat(40), "]".repeat(40));
        assert!(compile(&norm(&deep), 0, Kind::Real).is_none());
    }

    /// Random value texts, most of them well formed, some not.
    fn value_text(depth: u32) -> BoxedStrategy<String> {
        let leaf = prop_oneof![
            (0u32..40).prop_map(|n| format!("{}", f64::from(n) / 4.0)),
            (0u32..7).prop_map(|n| format!("#{n}")),
            prop::sample::select(vec![
                "#<x>",
                "#<z>",
                "#<nope>",
                "##3",
                "#[#1+1]",
                "#0",
                "#7000",
                "-1.5",
                "+2",
                ".5",
                "1..2",
                "#<_unsupported>",
                "exists[#<x>]",
                "exists[#2]",
                "-#1",
                "+#2",
            ])
            .prop_map(String::from),
        ];
        if depth == 0 {
            return leaf.boxed();
        }
        let ops = prop::sample::select(vec![
            "+", "-", "*", "/", "**", " mod ", " and ", " or ", " xor ", " eq ", " ne ", " gt ",
            " ge ", " lt ", " le ", " foo ",
        ]);
        let funcs = prop::sample::select(vec![
            "abs", "acos", "asin", "cos", "exp", "fix", "fup", "ln", "round", "sin", "sqrt", "tan",
            "-", "",
        ]);
        let inner = value_text(depth - 1);
        prop_oneof![
            2 => leaf,
            2 => (inner.clone(), prop::collection::vec((ops, inner.clone()), 0..5)).prop_map(
                |(first, rest)| {
                    let mut s = format!("[{first}");
                    for (o, v) in rest {
                        s.push_str(o);
                        s.push_str(&v);
                    }
                    s.push(']');
                    s
                }
            ),
            1 => (funcs, inner.clone()).prop_map(|(f, v)| format!("{f}[{v}]")),
            1 => (inner.clone(), inner).prop_map(|(a, b)| format!("atan[{a}]/[{b}]")),
        ]
        .boxed()
    }

    proptest! {
        /// Compiled or not, a value reads exactly as the text reader reads it:
        /// the same bits and end, or the same error at the same offset.
        #[test]
        fn compiled_values_match_the_text_reader(s in value_text(3), cut in 0usize..4) {
            let e = env();
            let mut b = norm(&s);
            // now and then a truncated text (a syntax error)
            if cut == 0 && b.len() > 2 {
                b.truncate(b.len() - 1);
            }
            for kind in [Kind::Real, Kind::Integer, Kind::Expression] {
                let want = by_text(&b, kind, &e);
                if let Some(code) = compile(&b, 0, kind) {
                    prop_assert_eq!(by_code(&code, &e), want, "{:?}", String::from_utf8_lossy(&b));
                }
            }
        }
    }
}
