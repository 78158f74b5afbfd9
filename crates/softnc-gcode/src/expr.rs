//! Values as LinuxCNC 2.9 reads them where a plain number does not do: parameters
//! (`#5`, `##1`, `#[1+2]`, `#<name>`, `#<_global>`), expressions in brackets with
//! LinuxCNC's precedence and left-to-right evaluation, and the unary functions.
//!
//! Follows `read_real_value`, `read_real_expression`, `read_operation`,
//! `read_operation_unary`, `read_unary`, `read_atan`, `read_parameter`,
//! `read_named_parameter`, `read_integer_value`, `execute_binary1/2` and
//! `execute_unary` of `src/emc/rs274ngc/interp_read.cc` and `interp_execute.cc`,
//! with their error messages. The readers work on a line as LinuxCNC's
//! `close_and_downcase` leaves it ([`Norm`](crate::norm::Norm)): white space outside comments removed,
//! letters outside comments in lower case.

use crate::error::ErrorKind;

/// Two values compare `EQ` when they differ by less than this (LinuxCNC
/// `TOLERANCE_EQUAL`, `interp_internal.hh`).
pub const TOLERANCE_EQUAL: f64 = 1e-6;

/// A reading error: offset in the normalized line and what went wrong.
pub type ExprError = (usize, ErrorKind);

type R<T> = Result<T, ExprError>;

fn bad<T>(at: usize, msg: impl Into<String>) -> R<T> {
    Err((at, ErrorKind::Invalid(msg.into())))
}

/// Where parameter values come from.
pub trait Env {
    /// Numbered parameter `index` (1 ≤ index < [`crate::params::NUM_PARAMS`]).
    fn numbered(&self, index: usize) -> f64;
    /// Named parameter (name lower case, without `<>`): its value if it exists
    /// (locals of the current call level, globals starting with `_`, predefined).
    /// `Err` for a predefined name whose meaning softnc does not build.
    fn named(&self, name: &str) -> Result<Option<f64>, ErrorKind>;
    /// The slot of named parameter `name` where the environment keeps its named
    /// parameters by slot (a name's slot never changes); `None` otherwise.
    fn named_slot(&self, _name: &str) -> Option<u32> {
        None
    }
    /// The value of the named parameter of slot `slot` where it is set in its
    /// scope: then exactly what [`Env::named`] of its name gives. `None`: ask
    /// [`Env::named`].
    fn slot_value(&self, _slot: u32) -> Option<f64> {
        None
    }
    /// True while a subroutine definition is being skipped (undefined named
    /// parameters are then no error, as in LinuxCNC).
    fn defining_sub(&self) -> bool {
        false
    }
}

/// Binary operations, as LinuxCNC numbers their precedence (`precedence()`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BinOp {
    /// `]`: ends the expression.
    RightBracket,
    /// `and`
    And,
    /// `xor`
    Xor,
    /// `or`
    Or,
    /// `eq`
    Eq,
    /// `ne`
    Ne,
    /// `gt`
    Gt,
    /// `ge`
    Ge,
    /// `lt`
    Lt,
    /// `le`
    Le,
    /// `+`
    Plus,
    /// `-`
    Minus,
    /// `/`
    Div,
    /// `mod`
    Mod,
    /// `*`
    Times,
    /// `**`
    Power,
}

impl BinOp {
    /// LinuxCNC's `precedence()`.
    pub fn precedence(self) -> u8 {
        use BinOp::*;
        match self {
            RightBracket => 1,
            And | Xor | Or => 2,
            Eq | Ne | Gt | Ge | Lt | Le => 3,
            Plus | Minus => 4,
            Div | Mod | Times => 5,
            Power => 6,
        }
    }

    /// `execute_binary1` / `execute_binary2`: `left op right`.
    pub fn apply(self, left: f64, right: f64) -> Result<f64, &'static str> {
        use BinOp::*;
        let b = |x: bool| if x { 1.0 } else { 0.0 };
        Ok(match self {
            Div => {
                if right == 0.0 {
                    return Err("Attempt to divide by zero");
                }
                left / right
            }
            Mod => {
                let m = left % right;
                if m < 0.0 {
                    m + right.abs()
                } else {
                    m
                }
            }
            Power => {
                if left < 0.0 && right.floor() != right {
                    return Err("Attempt to raise negative to non integer power");
                }
                left.powf(right)
            }
            Times => left * right,
            And => b(left != 0.0 && right != 0.0),
            Xor => b((left == 0.0) != (right == 0.0)),
            Or => b(left != 0.0 || right != 0.0),
            Plus => left + right,
            Minus => left - right,
            Lt => b(left < right),
            Eq => b((left - right).abs() < TOLERANCE_EQUAL),
            Ne => b((left - right).abs() >= TOLERANCE_EQUAL),
            Le => b((left - right).abs() < TOLERANCE_EQUAL || left <= right),
            Ge => b((left - right).abs() < TOLERANCE_EQUAL || left >= right),
            Gt => b(left > right),
            RightBracket => return Err("Bug unknown operation"),
        })
    }
}

/// Unary functions (`read_operation_unary`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Func {
    /// `abs`
    Abs,
    /// `acos` (degrees)
    Acos,
    /// `asin` (degrees)
    Asin,
    /// `atan[a]/[b]` (degrees)
    Atan,
    /// `cos` (degrees)
    Cos,
    /// `exists[#<name>]`
    Exists,
    /// `exp`
    Exp,
    /// `fix` (floor)
    Fix,
    /// `fup` (ceiling)
    Fup,
    /// `ln`
    Ln,
    /// `round` (half away from zero, through a C `int`)
    Round,
    /// `sin` (degrees)
    Sin,
    /// `sqrt`
    Sqrt,
    /// `tan` (degrees)
    Tan,
}

impl Func {
    /// `execute_unary` (not `Atan`, `Exists`).
    pub fn apply(self, x: f64) -> Result<f64, &'static str> {
        use Func::*;
        Ok(match self {
            Abs => x.abs(),
            Acos => {
                if !(-1.0..=1.0).contains(&x) {
                    return Err("Argument to acos out of range");
                }
                crate::x87::rad_to_deg(x.acos())
            }
            Asin => {
                if !(-1.0..=1.0).contains(&x) {
                    return Err("Argument to asin out of range");
                }
                crate::x87::rad_to_deg(x.asin())
            }
            // in long double, as LinuxCNC (crate::x87)
            Cos => crate::x87::cos_deg(x),
            Exp => x.exp(),
            Fix => x.floor(),
            Fup => x.ceil(),
            Ln => {
                if x <= 0.0 {
                    return Err("Zero or negative argument to ln");
                }
                x.ln()
            }
            Round => {
                // (double)(int)(x ± 0.5): C truncation toward zero; out of range,
                // x86's cvttsd2si gives its "integer indefinite", INT_MIN
                let r = (x + if x < 0.0 { -0.5 } else { 0.5 }).trunc();
                if (f64::from(i32::MIN)..=f64::from(i32::MAX)).contains(&r) {
                    f64::from(r as i32)
                } else {
                    f64::from(i32::MIN)
                }
            }
            Sin => crate::x87::sin_deg(x),
            Sqrt => {
                if x < 0.0 {
                    return Err("Negative argument to sqrt");
                }
                x.sqrt()
            }
            Tan => crate::x87::tan_deg(x),
            Atan | Exists => x,
        })
    }
}

/// A reader over a normalized line.
pub struct Reader<'a, E: Env + ?Sized> {
    /// The normalized line.
    pub b: &'a [u8],
    /// Current position.
    pub i: usize,
    /// Parameter values.
    pub env: &'a E,
}

/// Expression nesting deeper than this is refused (LinuxCNC recurses without a
/// limit; softnc must not overflow its stack on any input).
const MAX_DEPTH: u32 = 200;

impl<'a, E: Env + ?Sized> Reader<'a, E> {
    /// A reader at `i`.
    pub fn new(b: &'a [u8], i: usize, env: &'a E) -> Self {
        Reader { b, i, env }
    }

    /// Byte at `i` (0 past the end, as a C string).
    pub fn at(&self, i: usize) -> u8 {
        self.b.get(i).copied().unwrap_or(0)
    }

    fn cur(&self) -> u8 {
        self.at(self.i)
    }

    /// `read_real_value`.
    pub fn real_value(&mut self) -> R<f64> {
        self.real_value_d(0)
    }

    fn real_value_d(&mut self, depth: u32) -> R<f64> {
        let start = self.i;
        if depth > MAX_DEPTH {
            return Err((
                start,
                ErrorKind::Unsupported {
                    word: "[".into(),
                    why: format!("expressions nested deeper than {MAX_DEPTH} levels"),
                },
            ));
        }
        let c = self.cur();
        if c == 0 {
            return bad(start, "No characters found in reading real value");
        }
        let c1 = self.at(self.i + 1);
        let v = if c == b'[' {
            self.expression_d(depth + 1)?
        } else if c == b'#' {
            self.parameter(false, depth + 1)?
        } else if c == b'+' && c1 != 0 && !c1.is_ascii_digit() && c1 != b'.' {
            self.i += 1;
            self.real_value_d(depth + 1)?
        } else if c == b'-' && c1 != 0 && !c1.is_ascii_digit() && c1 != b'.' {
            self.i += 1;
            -self.real_value_d(depth + 1)?
        } else if c.is_ascii_lowercase() {
            self.unary(depth + 1)?
        } else {
            self.real_number()?
        };
        if v.is_nan() {
            return bad(start, "Calculation resulted in 'not a number'");
        }
        if v.is_infinite() {
            return bad(start, "Calculation resulted in 'infinity'");
        }
        Ok(v)
    }

    /// `read_real_number`: `strspn("+-")`, `strspn("0123456789.")`, then a C++
    /// stream conversion that must use every character.
    pub fn real_number(&mut self) -> R<f64> {
        let start = self.i;
        let mut j = start;
        while matches!(self.at(j), b'+' | b'-') {
            j += 1;
        }
        while matches!(self.at(j), b'0'..=b'9' | b'.') {
            j += 1;
        }
        let text = &self.b[start..j];
        self.i = j;
        // a stream reads one sign, digits with at most one point
        let mut k = 0;
        if matches!(text.first(), Some(b'+' | b'-')) {
            k = 1;
        }
        let body = &text[k..];
        if let Some(v) = crate::lexer::plain_decimal(body) {
            // the common case, bit-identical to the general reading below
            return Ok(if text[0] == b'-' { -v } else { v });
        }
        let digits = body.iter().filter(|c| c.is_ascii_digit()).count();
        let points = body.iter().filter(|&&c| c == b'.').count();
        let first_bad = body.iter().position(|c| !matches!(c, b'0'..=b'9' | b'.'));
        let shown = String::from_utf8_lossy(text).into_owned();
        if digits == 0 || first_bad == Some(0) {
            return bad(
                start,
                format!("bad number format (conversion failed) parsing '{shown}'"),
            );
        }
        if first_bad.is_some() || points > 1 {
            return bad(
                start,
                format!("bad number format (trailing characters) parsing '{shown}'"),
            );
        }
        let s = std::str::from_utf8(text).unwrap_or("0");
        let s = s.strip_prefix('+').unwrap_or(s);
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => bad(
                start,
                format!("bad number format (conversion failed) parsing '{shown}'"),
            ),
        }
    }

    /// `read_real_expression`: `[` … `]`, the classical two-stack evaluation with
    /// left-to-right evaluation of operations of equal precedence.
    pub fn expression(&mut self) -> R<f64> {
        self.expression_d(1)
    }

    fn expression_d(&mut self, depth: u32) -> R<f64> {
        if self.cur() != b'[' {
            return bad(self.i, "Bug function should not have been called");
        }
        self.i += 1;
        // the operator stack holds strictly rising precedences after each reduction
        // (six levels), so both stacks fit in eight entries: no allocation
        let mut values = [0.0f64; 8];
        let mut ops = [BinOp::RightBracket; 8];
        values[0] = self.real_value_d(depth)?;
        ops[0] = self.operation()?;
        let mut n = 1; // entries on both stacks
        while ops[0] != BinOp::RightBracket {
            if n >= 8 {
                return bad(self.i, "Bug: expression stack overflow");
            }
            values[n] = self.real_value_d(depth)?;
            let op_at = self.i;
            ops[n] = self.operation()?;
            n += 1;
            // reduce while the latest operator binds no tighter than the one before
            while n >= 2 && ops[n - 1].precedence() <= ops[n - 2].precedence() {
                let v = ops[n - 2]
                    .apply(values[n - 2], values[n - 1])
                    .or_else(|m| bad(op_at, m))?;
                values[n - 2] = v;
                ops[n - 2] = ops[n - 1];
                n -= 1;
            }
        }
        Ok(values[0])
    }

    /// `read_operation`.
    fn operation(&mut self) -> R<BinOp> {
        let at = self.i;
        let c = self.cur();
        self.i += 1;
        let n1 = self.cur();
        let n2 = self.at(self.i + 1);
        let mut two = |op: BinOp, a: u8, b: u8, msg: &str| -> R<BinOp> {
            if n1 == a && n2 == b {
                self.i += 2;
                Ok(op)
            } else {
                bad(at, msg.to_string())
            }
        };
        use BinOp::*;
        match c {
            b'+' => Ok(Plus),
            b'-' => Ok(Minus),
            b'/' => Ok(Div),
            b'*' => {
                if n1 == b'*' {
                    self.i += 1;
                    Ok(Power)
                } else {
                    Ok(Times)
                }
            }
            b']' => Ok(RightBracket),
            b'a' => two(And, b'n', b'd', "Unknown operation name starting with a"),
            b'm' => two(Mod, b'o', b'd', "Unknown operation name starting with m"),
            b'x' => two(Xor, b'o', b'r', "Unknown operation name starting with x"),
            b'o' | b'e' | b'n' | b'g' | b'l' => {
                let op = match (c, n1) {
                    (b'o', b'r') => Or,
                    (b'e', b'q') => Eq,
                    (b'n', b'e') => Ne,
                    (b'g', b'e') => Ge,
                    (b'g', b't') => Gt,
                    (b'l', b'e') => Le,
                    (b'l', b't') => Lt,
                    _ => {
                        return bad(
                            at,
                            format!("Unknown operation name starting with {}", c as char),
                        )
                    }
                };
                self.i += 1;
                Ok(op)
            }
            0 => bad(at, "Unclosed expression"),
            _ => bad(at, "Unknown operation"),
        }
    }

    /// `read_operation_unary` then `read_unary`.
    fn unary(&mut self, depth: u32) -> R<f64> {
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
            c @ (b'a' | b'c' | b'e' | b'f' | b'l' | b'r' | b's' | b't') => {
                return bad(at, format!("Unknown word starting with {}", c as char))
            }
            _ => return bad(at, "Unknown word where unary operation could be"),
        };
        self.i += len;
        if self.cur() != b'[' {
            return bad(self.i, "Left bracket missing after unary operation name");
        }
        if func == Func::Exists {
            // read_bracketed_parameter
            self.i += 1;
            if self.cur() != b'#' {
                return bad(self.i, "Expected # reading parameter");
            }
            let v = self.parameter(true, depth)?;
            if self.cur() != b']' {
                return bad(self.i, "Expected ] reading bracketed parameter");
            }
            self.i += 1;
            return Ok(v);
        }
        let v = self.expression_d(depth)?;
        if func == Func::Atan {
            if self.cur() != b'/' {
                return bad(self.i, "Slash missing after first atan argument");
            }
            self.i += 1;
            if self.cur() != b'[' {
                return bad(self.i, "Left bracket missing after slash with atan");
            }
            let w = self.expression_d(depth)?;
            return Ok(crate::x87::rad_to_deg(v.atan2(w)));
        }
        func.apply(v).or_else(|m| bad(at, m))
    }

    /// `read_integer_value`.
    pub fn integer_value(&mut self) -> R<i32> {
        let at = self.i;
        let v = self.real_value()?;
        to_integer(v).ok_or_else(|| {
            (
                at,
                ErrorKind::Invalid("Non integer value for integer".into()),
            )
        })
    }

    /// `read_name`: `<` … `>`, the name without the brackets.
    pub fn name(&mut self) -> R<std::borrow::Cow<'a, str>> {
        let at = self.i;
        self.i += 1; // '<'
        let b: &'a [u8] = self.b;
        let rest = &b[self.i.min(b.len())..];
        match rest.iter().position(|&c| c == b'>') {
            Some(k) => {
                // borrowed from the line: no allocation per parameter read
                let name = String::from_utf8_lossy(&rest[..k]);
                self.i += k + 1;
                Ok(name)
            }
            None => bad(at, "Named parameter not terminated"),
        }
    }

    /// `read_parameter` (with `check_exists` for `EXISTS`).
    fn parameter(&mut self, exists: bool, depth: u32) -> R<f64> {
        let at = self.i;
        self.i += 1; // '#'
        if self.cur() == b'<' {
            let name = self.name()?;
            let found = self.env.named(&name).map_err(|k| (at, k))?;
            return match (exists, found) {
                (true, f) => Ok(if f.is_some() { 1.0 } else { 0.0 }),
                (false, Some(v)) => Ok(v),
                (false, None) if self.env.defining_sub() => Ok(0.0),
                (false, None) => bad(at, format!("Named parameter #<{name}> not defined")),
            };
        }
        let iat = self.i;
        let v = self.real_value_d(depth)?;
        let index = to_integer(v).ok_or_else(|| {
            (
                iat,
                ErrorKind::Invalid("Non integer value for integer".into()),
            )
        })?;
        if exists {
            return Ok(if (1..crate::params::NUM_PARAMS as i32).contains(&index) {
                1.0
            } else {
                0.0
            });
        }
        if !(1..crate::params::NUM_PARAMS as i32).contains(&index) {
            return bad(at, "Parameter number out of range");
        }
        Ok(self.env.numbered(index as usize))
    }
}

/// LinuxCNC's integer conversion (`read_integer_value`): within 0.0001 of an
/// integer, else `None`.
pub fn to_integer(v: f64) -> Option<i32> {
    let f = v.floor();
    let r = if v - f > 0.9999 {
        v.ceil()
    } else if v - f > 0.0001 {
        return None;
    } else {
        f
    };
    (r.abs() <= 2.0e9).then_some(r as i32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    struct Vars(HashMap<String, f64>, Vec<f64>);
    impl Env for Vars {
        fn numbered(&self, i: usize) -> f64 {
            self.1.get(i).copied().unwrap_or(0.0)
        }
        fn named(&self, n: &str) -> Result<Option<f64>, ErrorKind> {
            Ok(self.0.get(n).copied())
        }
    }

    fn env() -> Vars {
        let mut v = vec![0.0; 40];
        v[1] = 2.0;
        v[2] = 3.0;
        v[3] = 1.0;
        Vars([("x".to_string(), 7.0)].into_iter().collect(), v)
    }

    fn eval(s: &str) -> Result<f64, String> {
        let mut n = crate::norm::Norm::default();
        n.build(s.as_bytes());
        let e = env();
        let mut r = Reader::new(&n.b, 0, &e);
        r.real_value().map_err(|(_, k)| k.to_string())
    }

    #[test]
    fn precedence_and_functions_as_linuxcnc() {
        for (s, v) in [
            ("[1+2*3]", 7.0),
            ("[2**3**2]", 64.0), // left to right
            ("[1-2-3]", -4.0),
            ("[8/4/2]", 1.0),
            ("[1+2 eq 3]", 1.0),
            ("[1 lt 2 and 3 gt 2]", 1.0),
            ("[-7 mod 3]", 2.0),
            ("[7 mod -3]", 1.0),
            ("[#1 * #2]", 6.0),
            ("##3", 2.0),
            ("#[#3+1]", 3.0),
            ("#<x>", 7.0),
            ("#<X>", 7.0),
            ("-#1", -2.0),
            // sinl of the long double argument, stored: 0.5 exactly, as in LinuxCNC
            ("sin[30]", 0.5),
            ("atan[1]/[1]", 45.0),
            ("round[-2.5]", -3.0),
            ("fix[-2.5]", -3.0),
            ("fup[2.1]", 3.0),
            ("abs[-3]", 3.0),
            ("exists[#<x>]", 1.0),
            ("exists[#<y>]", 0.0),
            ("[1 eq 1.0000001]", 1.0),
            ("[3 xor 0]", 1.0),
            ("[0 or 0]", 0.0),
            ("sqrt[16]", 4.0),
            ("[2 ** 0.5 ** 2]", 2.0000000000000004),
        ] {
            assert_eq!(eval(s), Ok(v), "{s}");
        }
    }

    #[test]
    fn errors_as_linuxcnc() {
        for (s, m) in [
            ("[1/0]", "Attempt to divide by zero"),
            ("sqrt[-1]", "Negative argument to sqrt"),
            ("ln[0]", "Zero or negative argument to ln"),
            ("acos[2]", "Argument to acos out of range"),
            ("asin[-2]", "Argument to asin out of range"),
            (
                "[[-2]**0.5]",
                "Attempt to raise negative to non integer power",
            ),
            ("[1+2", "Unclosed expression"),
            ("[1 & 2]", "Unknown operation"),
            ("[1 ab 2]", "Unknown operation name starting with a"),
            ("#<y>", "Named parameter #<y> not defined"),
            ("#<y", "Named parameter not terminated"),
            ("#6000", "Parameter number out of range"),
            ("#1.5", "Non integer value for integer"),
            ("sin 5", "Left bracket missing after unary operation name"),
            ("atan[1]", "Slash missing after first atan argument"),
            ("atan[1]/2", "Left bracket missing after slash with atan"),
            ("cot[1]", "Unknown word starting with c"),
            ("q[1]", "Unknown word where unary operation could be"),
            ("exp[1000]", "Calculation resulted in 'infinity'"),
            ("", "No characters found in reading real value"),
        ] {
            assert_eq!(eval(s), Err(m.to_string()), "{s}");
        }
    }

    #[test]
    fn deep_nesting_is_refused_not_a_crash() {
        let s = format!("{}1{}", "[".repeat(5000), "]".repeat(5000));
        assert!(eval(&s).unwrap_err().contains("nested deeper"));
    }

    /// An independent reference: precedence climbing over a token list (LinuxCNC's
    /// stack evaluation is left-associative at every level), with the operators'
    /// meaning written out again from LinuxCNC's manual.
    fn reference(tokens: &[Tok]) -> Result<f64, &'static str> {
        fn op(o: BinOp, a: f64, b: f64) -> Result<f64, &'static str> {
            use BinOp::*;
            let t = |x: bool| f64::from(u8::from(x));
            Ok(match o {
                Plus => a + b,
                Minus => a - b,
                Times => a * b,
                Div if b == 0.0 => return Err("div"),
                Div => a / b,
                Mod => a.rem_euclid(b),
                Power if a < 0.0 && b.fract() != 0.0 => return Err("pow"),
                Power => a.powf(b),
                Eq => t((a - b).abs() < 1e-6),
                Ne => t((a - b).abs() >= 1e-6),
                Lt => t(a < b),
                Gt => t(a > b),
                Le => t(a <= b || (a - b).abs() < 1e-6),
                Ge => t(a >= b || (a - b).abs() < 1e-6),
                And => t(a != 0.0 && b != 0.0),
                Or => t(a != 0.0 || b != 0.0),
                Xor => t((a != 0.0) ^ (b != 0.0)),
                RightBracket => unreachable!(),
            })
        }
        fn prim(t: &[Tok], i: &mut usize) -> Result<f64, &'static str> {
            let v = match t[*i] {
                Tok::Num(v) => {
                    *i += 1;
                    v
                }
                Tok::Open => {
                    *i += 1;
                    let v = climb(t, i, 2)?;
                    *i += 1; // ']'
                    v
                }
                Tok::Op(_) | Tok::Close => unreachable!(),
            };
            if v.is_finite() {
                Ok(v)
            } else {
                Err("not finite")
            }
        }
        fn climb(t: &[Tok], i: &mut usize, min: u8) -> Result<f64, &'static str> {
            let mut left = prim(t, i)?;
            while let Some(Tok::Op(o)) = t.get(*i).copied() {
                if o.precedence() < min {
                    break;
                }
                *i += 1;
                let right = climb(t, i, o.precedence() + 1)?;
                left = op(o, left, right)?;
            }
            Ok(left)
        }
        prim(tokens, &mut 0)
    }

    #[derive(Debug, Clone, Copy)]
    enum Tok {
        Num(f64),
        Op(BinOp),
        Open,
        Close,
    }

    fn text(t: &[Tok]) -> String {
        use BinOp::*;
        t.iter()
            .map(|t| match t {
                Tok::Num(v) => format!("{v}"),
                Tok::Open => "[".into(),
                Tok::Close => "]".into(),
                Tok::Op(o) => match o {
                    And => " and ",
                    Xor => " xor ",
                    Or => " or ",
                    Eq => " eq ",
                    Ne => " ne ",
                    Gt => " gt ",
                    Ge => " ge ",
                    Lt => " lt ",
                    Le => " le ",
                    Plus => "+",
                    Minus => "-",
                    Div => "/",
                    Mod => " mod ",
                    Times => "*",
                    Power => "**",
                    RightBracket => "]",
                }
                .into(),
            })
            .collect()
    }

    use proptest::prelude::*;

    fn expr_tokens(depth: u32) -> BoxedStrategy<Vec<Tok>> {
        use BinOp::*;
        let ops = prop::sample::select(vec![
            And, Xor, Or, Eq, Ne, Gt, Ge, Lt, Le, Plus, Minus, Div, Mod, Times, Power,
        ]);
        let leaf = (0u32..40).prop_map(|n| vec![Tok::Num(f64::from(n) / 4.0)]);
        let atom = if depth == 0 {
            leaf.boxed()
        } else {
            prop_oneof![3 => leaf, 1 => expr_tokens(depth - 1)].boxed()
        };
        (atom.clone(), prop::collection::vec((ops, atom), 0..5))
            .prop_map(|(first, rest)| {
                let mut t = vec![Tok::Open];
                t.extend(first);
                for (op, a) in rest {
                    t.push(Tok::Op(op));
                    t.extend(a);
                }
                t.push(Tok::Close);
                t
            })
            .boxed()
    }

    proptest! {
        #[test]
        fn random_expressions_match_a_reference_evaluator(t in expr_tokens(2)) {
            let s = text(&t);
            let want = reference(&t);
            match (eval(&s), want) {
                (Ok(a), Ok(b)) => prop_assert!(a == b || (a - b).abs() <= 1e-12 * b.abs().max(1.0), "{s}: {a} vs {b}"),
                (Err(_), Err(_)) => {}
                (a, b) => prop_assert!(false, "{s}: {a:?} vs {b:?}"),
            }
        }
    }
}
