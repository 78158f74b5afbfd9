//! Reading one line into words, as LinuxCNC 2.9's `read_text`, `close_and_downcase`
//! and `read_items` do:
//!
//! - trailing white space (including CR, form feed, vertical tab) is dropped; a NUL
//!   byte ends the line (LinuxCNC reads lines as C strings);
//! - outside comments, spaces, tabs and CRs are ignored everywhere, also inside
//!   numbers and between a letter and its value (`X 1 . 5` is `X1.5`), and letters are
//!   case-insensitive;
//! - `( … )` comments may not nest and must close on their line; `;` comments the rest
//!   of the line; of several `( )` comments only the last one counts (LinuxCNC keeps one
//!   comment per block);
//! - an optional `/` (block delete) and then an optional `N` number may start the
//!   line; `N` anywhere else is an error;
//! - a word is a letter and a real value: any number of leading signs (`X--1` is 1),
//!   digits with at most one decimal point; no exponent (`1e3` is `1` and an `E` word).
//!
//! A line with parameters (`#`), expressions (`[ ]`, `sin[…]`), an O-word or `M98`
//! is handed to the full reader ([`crate::expr`], the interpreter's O-word reader):
//! the lexer stops with the offset [`SLOW`]. Polar coordinates (`@`, `^`) and
//! spindle selection (`$`) are refused as unsupported, never misread. The lexer
//! allocates nothing: words go into a reused `Vec` ([`lex_line`]) or, for the
//! reader, straight into its block as they are read.

use crate::error::ErrorKind;

/// One word: letter (upper case), value, and where it starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Word {
    /// Letter, upper case.
    pub letter: u8,
    /// Value as written (program units).
    pub value: f64,
    /// Byte offset of the letter in the line.
    pub offset: u32,
}

/// A lexed line.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Line {
    /// The line has no words and no comment (blank or white space only).
    pub blank: bool,
    /// The line is a lone `%` (white space aside).
    pub percent: bool,
    /// The line starts with `/` (block delete).
    pub block_delete: bool,
    /// Words in order (the N word excluded).
    pub words: Vec<Word>,
    /// Byte range of the text of the last `( )` comment (without the parentheses).
    pub comment: Option<(u32, u32)>,
    /// Byte offset of the `(` of that comment.
    pub comment_offset: u32,
    /// The line starts with `;py,` (an embedded Python statement).
    pub python: bool,
}

/// A lexing error: byte offset in the line and what went wrong.
pub type LexError = (u32, ErrorKind);

/// The offset of the "error" by which the lexer says that the line needs the full
/// reader (parameters, expressions, O-words); its kind is an empty `Invalid`.
pub const SLOW: u32 = u32::MAX;

fn slow() -> LexError {
    (SLOW, ErrorKind::Invalid(String::new()))
}

fn invalid(off: usize, msg: impl Into<String>) -> LexError {
    (off as u32, ErrorKind::Invalid(msg.into()))
}

fn unsupported(off: usize, word: impl Into<String>, why: &str) -> LexError {
    (
        off as u32,
        ErrorKind::Unsupported {
            word: word.into(),
            why: why.to_string(),
        },
    )
}

/// How LinuxCNC names a character it cannot use.
pub(crate) fn bad_character(c: u8) -> String {
    if c.is_ascii_graphic() {
        format!("Bad character '{}' used", (c as char).to_ascii_lowercase())
    } else {
        format!("Bad character '\\{c:03o}' used")
    }
}

/// The significant content of a line: its bytes up to a NUL, without trailing white
/// space (C `isspace`).
pub fn significant(text: &[u8]) -> &[u8] {
    let b = if text.contains(&0) {
        &text[..text.iter().position(|&c| c == 0).unwrap_or(text.len())]
    } else {
        text
    };
    trim_end(b)
}

fn trim_end(b: &[u8]) -> &[u8] {
    let mut end = b.len();
    while end > 0 && matches!(b[end - 1], b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c) {
        end -= 1;
    }
    &b[..end]
}

/// A cursor over the line that skips spaces, tabs and CRs (outside comments).
struct Cursor<'a> {
    b: &'a [u8],
    i: usize,
}

impl Cursor<'_> {
    fn skip(&mut self) {
        while self.i < self.b.len() && matches!(self.b[self.i], b' ' | b'\t' | b'\r') {
            self.i += 1;
        }
    }
    /// Next significant byte (lower-cased), without consuming it.
    fn peek(&mut self) -> Option<u8> {
        self.skip();
        self.b.get(self.i).map(|c| c.to_ascii_lowercase())
    }
    /// The significant byte after the next one.
    fn peek2(&mut self) -> Option<u8> {
        self.skip();
        let mut j = self.i + 1;
        while j < self.b.len() && matches!(self.b[j], b' ' | b'\t' | b'\r') {
            j += 1;
        }
        self.b.get(j).map(|c| c.to_ascii_lowercase())
    }
    fn bump(&mut self) {
        self.skip();
        self.i += 1;
    }
}

/// Lex `text` (one line, without its newline) into `out` (cleared first, its
/// allocation reused).
pub fn lex_line(text: &str, out: &mut Line) -> Result<(), LexError> {
    let mut words = std::mem::take(&mut out.words);
    words.clear();
    let lexed = lex_words(text, out, true, |w| {
        words.push(w);
        Ok(())
    });
    out.words = words;
    lexed
}

/// [`lex_line`] handing each word to `on_word` as soon as it is read instead of
/// listing it in `out` (whose `words` stay untouched); an error from `on_word` stops
/// lexing and is returned. `maybe`: whether the line may contain a NUL byte or a `(`
/// at all (the reader checks the whole file once, sparing two searches per line).
#[allow(clippy::too_many_lines)]
pub(crate) fn lex_words(
    text: &str,
    out: &mut Line,
    maybe: bool,
    mut on_word: impl FnMut(Word) -> Result<(), LexError>,
) -> Result<(), LexError> {
    out.blank = false;
    out.percent = false;
    out.block_delete = false;
    out.comment = None;
    out.comment_offset = 0;
    out.python = false;
    let b = if maybe {
        significant(text.as_bytes())
    } else {
        trim_end(text.as_bytes())
    };
    if maybe && b.contains(&b'(') {
        check_comments(b)?;
    }
    let mut cur = Cursor { b, i: 0 };
    match cur.peek() {
        None => {
            out.blank = true;
            return Ok(());
        }
        Some(b'%') => {
            let mut c2 = Cursor { b, i: cur.i + 1 };
            if c2.peek().is_none() {
                out.percent = true;
                return Ok(());
            }
        }
        Some(b'/') => {
            out.block_delete = true;
            cur.bump();
        }
        _ => {}
    }
    out.python = b.len() >= 4 && b[..4].eq_ignore_ascii_case(b";py,");
    if cur.peek() == Some(b'n') {
        cur.bump();
        read_unsigned(&mut cur)?;
        if cur.peek() == Some(b'.') {
            cur.bump();
            read_unsigned(&mut cur)?;
        }
    }
    // O-words and M98 (subprogram call) are read as O-lines by LinuxCNC
    match cur.peek() {
        Some(b'o') => return Err(slow()),
        Some(b'm') => {
            let save = cur.i;
            cur.bump();
            match read_value(&mut cur, save) {
                Ok(v) if (v - 98.0).abs() < 1e-4 || (v - 99.0).abs() < 1e-4 => return Err(slow()),
                Err((SLOW, _)) => return Err(slow()),
                _ => {}
            }
            cur.i = save;
        }
        _ => {}
    }
    // the words: one pass over the bytes, most numbers read by `plain_number`
    let mut i = cur.i;
    while i < b.len() {
        let at = i;
        let c = b[i].to_ascii_lowercase();
        match c {
            b' ' | b'\t' | b'\r' => i += 1,
            b'a'..=b'z' | b'@' | b'^' if c != b'n' && c != b'o' => {
                let (value, next) = match plain_number(b, i + 1) {
                    Some(read) => read,
                    None => {
                        let mut cur = Cursor { b, i: i + 1 };
                        let value = read_value(&mut cur, at)?;
                        (value, cur.i)
                    }
                };
                on_word(Word {
                    letter: c.to_ascii_uppercase(),
                    value,
                    offset: at as u32,
                })?;
                i = next;
            }
            b'(' => {
                let start = at + 1;
                let end = start
                    + b[start..]
                        .iter()
                        .position(|&x| x == b')')
                        .unwrap_or(b.len() - start);
                out.comment = Some((start as u32, end as u32));
                out.comment_offset = at as u32;
                i = (end + 1).min(b.len());
            }
            b';' => break,
            b'#' => return Err(slow()),
            b'$' => {
                return Err(unsupported(
                    at,
                    word_text(b, at),
                    "spindle selection ($ words) is not supported",
                ))
            }
            _ => return Err(invalid(at, bad_character(b[at]))),
        }
    }
    Ok(())
}

/// LinuxCNC checks comments over the whole line before reading any word.
pub(crate) fn check_comments(b: &[u8]) -> Result<(), LexError> {
    let mut open: Option<usize> = None;
    for (i, &c) in b.iter().enumerate() {
        match (open, c) {
            (None, b';') => return Ok(()),
            (None, b'(') => open = Some(i),
            (Some(_), b')') => open = None,
            (Some(_), b'(') => return Err(invalid(i, "Nested comment found")),
            _ => {}
        }
    }
    match open {
        Some(i) => Err(invalid(i, "Unclosed comment found")),
        None => Ok(()),
    }
}

/// The word starting at `at` as written (white space dropped, upper case), for
/// messages: up to the next word's letter outside brackets, a comment or 24 characters.
fn word_text(b: &[u8], at: usize) -> String {
    let mut s = String::new();
    let (mut depth, mut value_seen) = (0i32, false);
    for &c in &b[at..] {
        match c {
            b' ' | b'\t' | b'\r' => continue,
            b'(' | b';' => break,
            b'[' => depth += 1,
            b']' => {
                depth -= 1;
                value_seen = true;
            }
            c if (c.is_ascii_alphabetic() || matches!(c, b'@' | b'^' | b'$'))
                && depth <= 0
                && value_seen =>
            {
                break
            }
            c if c.is_ascii_digit() => value_seen = true,
            _ => {}
        }
        if s.len() >= 24 {
            break;
        }
        s.push(if c.is_ascii() {
            c.to_ascii_uppercase() as char
        } else {
            '?'
        });
    }
    if s.is_empty() {
        s.push('?');
    }
    s
}

fn read_unsigned(cur: &mut Cursor) -> Result<(), LexError> {
    let start = cur.i;
    let mut n = 0;
    while let Some(c) = cur.peek() {
        if !c.is_ascii_digit() {
            break;
        }
        cur.bump();
        n += 1;
    }
    if n == 0 {
        return Err(invalid(start, "Bad format unsigned integer"));
    }
    Ok(())
}

/// LinuxCNC's `read_real_value` for a plain number: signs, then digits and points.
/// `word_at` is the offset of the word's letter (for messages).
fn read_value(cur: &mut Cursor, word_at: usize) -> Result<f64, LexError> {
    // fast path: a plain number right after the letter
    let b = cur.b;
    let i = cur.i;
    if i < b.len() {
        let c = b[i];
        let next_is_number = |j: usize| j < b.len() && (b[j].is_ascii_digit() || b[j] == b'.');
        if c.is_ascii_digit() || (matches!(c, b'-' | b'+' | b'.') && next_is_number(i + 1)) {
            return read_number(cur);
        }
    }
    let mut negative = false;
    loop {
        let Some(c) = cur.peek() else {
            return Err(invalid(
                word_at,
                "No characters found in reading real value",
            ));
        };
        match c {
            b'[' | b'#' => return Err(slow()),
            b'+' | b'-' => {
                let c1 = cur.peek2();
                if matches!(c1, Some(d) if d.is_ascii_digit() || d == b'.') || c1.is_none() {
                    break;
                }
                negative ^= c == b'-';
                cur.bump();
            }
            b'a'..=b'z' => {
                // a function name such as `sin[`, `exists[`
                let mut probe = Cursor { b: cur.b, i: cur.i };
                while matches!(probe.peek(), Some(b'a'..=b'z')) {
                    probe.bump();
                }
                if probe.peek() == Some(b'[') {
                    return Err(slow());
                }
                return Err(invalid(
                    cur.i,
                    "Unknown word where unary operation could be",
                ));
            }
            _ => break,
        }
    }
    let v = read_number(cur)?;
    Ok(if negative { -v } else { v })
}

/// Exact powers of ten for the fast path.
pub(crate) const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// The common case of [`read_number`] in one tight pass, from byte `i` of the line:
/// an optional sign, 1 to 15 digits with at most one point, and then (after any white
/// space) neither a digit, a point nor a sign. The value and the offset after the
/// white space, or None (the general readers decide) for anything else.
pub(crate) fn plain_number(b: &[u8], mut i: usize) -> Option<(f64, usize)> {
    let n = b.len();
    let neg = match b.get(i) {
        Some(b'-') => {
            i += 1;
            true
        }
        Some(b'+') => {
            i += 1;
            false
        }
        _ => false,
    };
    let mut mant = 0u64; // wraps beyond 19 digits, but is used only up to 15
    let int_start = i;
    i = read_digits(b, i, &mut mant);
    let mut digits = i - int_start;
    let mut frac = 0;
    if i < n && b[i] == b'.' {
        i += 1;
        let frac_start = i;
        i = read_digits(b, i, &mut mant);
        frac = i - frac_start;
        digits += frac;
    }
    if digits == 0 || digits > 15 {
        return None;
    }
    while i < n && matches!(b[i], b' ' | b'\t' | b'\r') {
        i += 1;
    }
    if i < n && (b[i].is_ascii_digit() || matches!(b[i], b'.' | b'+' | b'-')) {
        return None;
    }
    // an exact integer mantissa (< 10^15 < 2^53; as a signed integer its conversion is
    // one instruction) and one correctly rounded division
    let v = mant as i64 as f64 / POW10[frac];
    Some((if neg { -v } else { v }, i))
}

/// `strspn("+-")`, `strspn("0123456789.")`, then a C++ stream conversion: one
/// optional sign, digits with at most one point, at least one digit, nothing left.
fn read_number(cur: &mut Cursor) -> Result<f64, LexError> {
    if let Some((v, next)) = plain_number(cur.b, cur.i) {
        cur.i = next;
        return Ok(v);
    }
    let b = cur.b;
    let n = b.len();
    let mut i = cur.i;
    let start = i;
    let (mut neg, mut signs) = (false, 0);
    while i < n && matches!(b[i], b'+' | b'-' | b' ' | b'\t' | b'\r') {
        if b[i] != b' ' && b[i] != b'\t' && b[i] != b'\r' {
            neg = b[i] == b'-';
            signs += 1;
        }
        i += 1;
    }
    let (mut mant, mut digits, mut frac) = (0u64, 0u32, 0i32);
    let (mut point, mut trailing) = (false, false);
    while i < n {
        let c = b[i];
        let d = c.wrapping_sub(b'0');
        if d < 10 {
            if digits < 19 {
                mant = mant * 10 + u64::from(d);
                frac += i32::from(point);
            }
            digits += 1;
        } else if c == b'.' {
            if point {
                trailing = true;
                break;
            }
            point = true;
        } else if !matches!(c, b' ' | b'\t' | b'\r') {
            break;
        }
        i += 1;
    }
    if trailing {
        // a second point: the C++ conversion stops there and LinuxCNC sees the rest
        while i < n && (b[i].is_ascii_digit() || matches!(b[i], b'.' | b' ' | b'\t' | b'\r')) {
            i += 1;
        }
    }
    cur.i = i;
    if signs > 1 || digits == 0 {
        return Err(invalid(start, "Bad number format (conversion failed)"));
    }
    if trailing {
        return Err(invalid(start, "Bad number format (trailing characters)"));
    }
    let v = if digits <= 15 {
        // an exact integer mantissa and one correctly rounded division
        mant as f64 / POW10[frac as usize]
    } else {
        // long numbers: the standard library's correctly rounded conversion
        let text: String = b[start..i]
            .iter()
            .filter(|c| c.is_ascii_digit() || **c == b'.')
            .map(|&c| c as char)
            .collect();
        text.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| invalid(start, "Bad number format (conversion failed)"))?
    };
    Ok(if neg { -v } else { v })
}

/// 1-based character column of byte offset `off` in `line`.
pub fn column(line: &str, off: u32) -> u32 {
    let off = (off as usize).min(line.len());
    let b = &line.as_bytes()[..off];
    1 + b.iter().filter(|&&c| (c & 0xC0) != 0x80).count() as u32
}

/// `b` as a number when it is 1 to 15 digits with at most one point and nothing
/// else (no sign): the fast path of [`plain_number`], bit-identical to
/// `str::parse::<f64>`. `None` for anything else.
#[inline]
pub(crate) fn plain_decimal(b: &[u8]) -> Option<f64> {
    let mut mant = 0u64;
    let mut i = read_digits(b, 0, &mut mant);
    let mut digits = i;
    let mut frac = 0;
    if i < b.len() && b[i] == b'.' {
        i += 1;
        let s = i;
        i = read_digits(b, i, &mut mant);
        frac = i - s;
        digits += frac;
    }
    if i != b.len() || digits == 0 || digits > 15 {
        return None;
    }
    Some(mant as i64 as f64 / POW10[frac])
}

/// Append the decimal digits at `b[i..]` to `mant` (wrapping); the index after them.
fn read_digits(b: &[u8], mut i: usize, mant: &mut u64) -> usize {
    while let Some(d) = b.get(i).map(|c| c.wrapping_sub(b'0')).filter(|&d| d < 10) {
        *mant = mant.wrapping_mul(10).wrapping_add(u64::from(d));
        i += 1;
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lex(s: &str) -> Result<Line, LexError> {
        let mut l = Line::default();
        lex_line(s, &mut l).map(|()| l)
    }

    #[test]
    fn words_comments_spaces_and_case() {
        let l = lex("n10 g0 x 1 . 5 y-.5 (move) ; rest").unwrap();
        assert_eq!(l.words.len(), 3);
        assert_eq!((l.words[1].letter, l.words[1].value), (b'X', 1.5));
        assert_eq!((l.words[2].letter, l.words[2].value), (b'Y', -0.5));
        assert_eq!(l.words[1].offset, 7);
        assert!(lex("/G1 X1").unwrap().block_delete);
        assert!(lex("  % ").unwrap().percent);
        assert!(lex("  \t\r").unwrap().blank);
        assert!(!lex("(only a comment)").unwrap().blank);
        assert_eq!(lex("G0 X1\u{c}").unwrap().words.len(), 2);
        assert_eq!(lex("G0 X1\0 garbage").unwrap().words.len(), 2);
    }

    #[test]
    fn signs_and_numbers() {
        for (s, v) in [
            ("X1", 1.0),
            ("X-0.25", -0.25),
            ("X+3.", 3.0),
            ("X.125", 0.125),
            ("X007", 7.0),
            ("X--1", 1.0),
            ("X-+1", -1.0),
            ("X+-1", -1.0),
            ("X---1", -1.0),
            ("X 1 2 . 5", 12.5),
            ("X12345678901234567890", 12345678901234567890.0),
        ] {
            assert_eq!(lex(s).unwrap().words[0].value, v, "{s}");
        }
        assert!((lex("X123.456789").unwrap().words[0].value - 123.456789).abs() < 1e-12);
        // long numbers round as the standard library (and C++ streams) do
        let long = "0.1234567890123456789";
        assert_eq!(
            lex(&format!("X{long}")).unwrap().words[0].value,
            long.parse::<f64>().unwrap()
        );
        let e = lex("X1e3").unwrap();
        assert_eq!((e.words[1].letter, e.words[1].value), (b'E', 3.0));
    }

    #[test]
    fn unsupported_and_bad_input() {
        // the full reader takes over for parameters, expressions and O-words
        for s in [
            "G1 X#1",
            "o100 sub",
            "G1 X[1+2]",
            "G1 Xsin[1]",
            "#1=2",
            "M98 P100",
        ] {
            assert_eq!(lex(s).unwrap_err().0, SLOW, "{s}");
        }
        assert!(matches!(
            lex("M3 $1").unwrap_err().1,
            ErrorKind::Unsupported { .. }
        ));
        // the polar words are words like the letters
        let polar = lex("G1 @1 ^2").unwrap();
        assert_eq!(
            polar
                .words
                .iter()
                .map(|w| (w.letter, w.value))
                .collect::<Vec<_>>(),
            [(b'G', 1.0), (b'@', 1.0), (b'^', 2.0)]
        );
        let inv = |s: &str| match lex(s).unwrap_err().1 {
            ErrorKind::Invalid(m) => m,
            k => panic!("{s}: {k:?}"),
        };
        assert_eq!(inv("G1 X1 (open"), "Unclosed comment found");
        assert_eq!(inv("G1 X1 (a (b) c)"), "Nested comment found");
        assert_eq!(inv("G1 X"), "No characters found in reading real value");
        assert_eq!(inv("G1 X."), "Bad number format (conversion failed)");
        assert_eq!(inv("G1 X1.2.3"), "Bad number format (trailing characters)");
        assert_eq!(inv("G1 X1 %"), "Bad character '%' used");
        assert_eq!(inv("G1 X1 N5"), "Bad character 'n' used");
        assert_eq!(inv("G1 X1 \u{e9}"), "Bad character '\\303' used");
        assert_eq!(inv("G1 XY1"), "Unknown word where unary operation could be");
    }

    #[test]
    fn columns_count_characters() {
        assert_eq!(column("(\u{e9}) G1", 5), 5);
        assert_eq!(column("G1 X1", 3), 4);
    }
}
