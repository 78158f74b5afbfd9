//! Reading one line into a block of words, as LinuxCNC's `read_line`/`read_items` do:
//! case-insensitive, spaces and tabs ignored outside comments, `( )` and `;`
//! comments, block delete `/`, `N` numbers, words of a letter and a number.
//! Parameters, expressions and O-words are refused as unsupported, never misread.

use crate::error::ErrorKind;

/// One word: letter (upper case), value, 1-based column of the letter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Word {
    /// Letter, upper case.
    pub letter: u8,
    /// Value as written (program units).
    pub value: f64,
    /// 1-based column of the letter in the line.
    pub column: u32,
}

/// A lexed line.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Line {
    /// The line starts with `/` (block delete).
    pub block_delete: bool,
    /// The line is a `%` delimiter.
    pub percent: bool,
    /// Words in order (the N word excluded).
    pub words: Vec<Word>,
    /// A comment text of the `(MSG,`, `(DEBUG,` or `(PRINT,` kind, if any.
    pub message: Option<String>,
}

/// A lexing error with its column.
pub type LexError = (u32, ErrorKind);

fn invalid(col: usize, msg: &str) -> LexError {
    (col as u32 + 1, ErrorKind::Invalid(msg.to_string()))
}

fn unsupported(col: usize, word: &str, why: &str) -> LexError {
    (
        col as u32 + 1,
        ErrorKind::Unsupported {
            word: word.to_string(),
            why: why.to_string(),
        },
    )
}

/// Lex `text` into `out` (cleared first, its allocation reused).
pub fn lex_line(text: &str, out: &mut Line) -> Result<(), LexError> {
    out.block_delete = false;
    out.percent = false;
    out.words.clear();
    out.message = None;
    let b = text.as_bytes();
    let n = b.len();
    let mut i = 0;
    let skip_ws = |i: &mut usize| {
        while *i < n && (b[*i] == b' ' || b[*i] == b'\t' || b[*i] == b'\r') {
            *i += 1;
        }
    };
    skip_ws(&mut i);
    if i < n && b[i] == b'%' {
        let mut j = i + 1;
        skip_ws(&mut j);
        // LinuxCNC allows a comment after the percent sign
        out.percent = true;
        return Ok(());
    }
    if i < n && b[i] == b'/' {
        out.block_delete = true;
        i += 1;
    }
    let mut seen_word = false;
    loop {
        skip_ws(&mut i);
        if i >= n {
            break;
        }
        let c = b[i];
        match c {
            b'(' => {
                let start = i;
                i += 1;
                let body_start = i;
                while i < n && b[i] != b')' {
                    if b[i] == b'(' {
                        return Err(invalid(i, "Nested comment found"));
                    }
                    i += 1;
                }
                if i >= n {
                    return Err(invalid(start, "Unclosed comment found"));
                }
                let body = &text[body_start..i];
                let upper = body.trim_start().to_ascii_uppercase();
                for tag in ["MSG,", "DEBUG,", "PRINT,"] {
                    if upper.starts_with(tag) {
                        let t = body.trim_start();
                        out.message = Some(t[tag.len()..].to_string());
                    }
                }
                i += 1;
            }
            b';' => break,
            b'#' => return Err(unsupported(i, "#", "parameters are not supported yet")),
            b'[' => return Err(unsupported(i, "[", "expressions are not supported yet")),
            b'<' => {
                return Err(unsupported(
                    i,
                    "<",
                    "named parameters are not supported yet",
                ))
            }
            _ if c.is_ascii_alphabetic() => {
                let letter = c.to_ascii_uppercase();
                let col = i;
                i += 1;
                if letter == b'O' {
                    return Err(unsupported(
                        col,
                        &word_text(text, col),
                        "O-words (subroutines, loops) are not supported yet",
                    ));
                }
                skip_ws(&mut i);
                if i < n && (b[i] == b'#' || b[i] == b'[') {
                    let what = if b[i] == b'#' {
                        "parameters"
                    } else {
                        "expressions"
                    };
                    return Err(unsupported(
                        col,
                        &format!("{}{}", letter as char, b[i] as char),
                        &format!("{what} are not supported yet"),
                    ));
                }
                if i < n && b[i].is_ascii_alphabetic() {
                    // a function name such as `sin[`, `exists[`
                    return Err(unsupported(
                        col,
                        &word_text(text, col),
                        "expressions are not supported yet",
                    ));
                }
                let value =
                    read_number(b, &mut i).ok_or_else(|| invalid(col, "Bad number format"))?;
                if letter == b'N' {
                    if seen_word {
                        return Err(invalid(
                            col,
                            "Line number is not the first word on the line",
                        ));
                    }
                    seen_word = true;
                    continue;
                }
                if !b"ABCDFGHIJKLMNPQRSTUVWXYZ".contains(&letter) {
                    return Err(invalid(col, "Bad character used"));
                }
                seen_word = true;
                out.words.push(Word {
                    letter,
                    value,
                    column: col as u32 + 1,
                });
            }
            _ => return Err(invalid(i, "Bad character used")),
        }
    }
    Ok(())
}

/// The word starting at `col` as written, for messages.
fn word_text(text: &str, col: usize) -> String {
    text[col..]
        .chars()
        .take_while(|c| !c.is_whitespace() && *c != '(' && *c != ';')
        .take(16)
        .collect()
}

/// A real number: optional sign, digits, optional point and digits; spaces and tabs
/// between the characters are ignored (as LinuxCNC does).
fn read_number(b: &[u8], i: &mut usize) -> Option<f64> {
    let n = b.len();
    let skip = |i: &mut usize| {
        while *i < n && (b[*i] == b' ' || b[*i] == b'\t') {
            *i += 1;
        }
    };
    skip(i);
    let mut buf = [0u8; 64];
    let mut len = 0;
    if *i < n && (b[*i] == b'+' || b[*i] == b'-') {
        buf[0] = b[*i];
        len = 1;
        *i += 1;
    }
    let (mut mant, mut digits, mut frac_digits, mut seen_point) = (0u64, 0u32, 0i32, false);
    loop {
        skip(i);
        if *i >= n {
            break;
        }
        let c = b[*i];
        if c.is_ascii_digit() {
            if digits < 19 {
                mant = mant * 10 + (c - b'0') as u64;
            }
            digits += 1;
            if seen_point {
                frac_digits += 1;
            }
        } else if c == b'.' && !seen_point {
            seen_point = true;
        } else {
            break;
        }
        if len < buf.len() {
            buf[len] = c;
            len += 1;
        }
        *i += 1;
    }
    if digits == 0 {
        return None;
    }
    let neg = buf[0] == b'-';
    let v = if digits <= 15 && frac_digits <= 22 {
        // exact integer mantissa, one correctly rounded division
        mant as f64 / 10f64.powi(frac_digits)
    } else {
        std::str::from_utf8(&buf[..len])
            .ok()?
            .trim_start_matches(['+', '-'])
            .parse::<f64>()
            .ok()?
    };
    Some(if neg { -v } else { v })
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
        assert_eq!(l.words[1].column, 8);
        assert!(lex("/G1 X1").unwrap().block_delete);
        assert!(lex("  %").unwrap().percent);
    }

    #[test]
    fn unsupported_and_bad_input() {
        let e = lex("G1 X#1").unwrap_err();
        assert_eq!(e.0, 4);
        assert!(matches!(e.1, ErrorKind::Unsupported { .. }));
        assert!(matches!(
            lex("o100 sub").unwrap_err().1,
            ErrorKind::Unsupported { .. }
        ));
        assert!(matches!(
            lex("G1 X[1+2]").unwrap_err().1,
            ErrorKind::Unsupported { .. }
        ));
        assert_eq!(
            lex("G1 X1 (open").unwrap_err().1,
            ErrorKind::Invalid("Unclosed comment found".into())
        );
        assert_eq!(
            lex("G1 X").unwrap_err().1,
            ErrorKind::Invalid("Bad number format".into())
        );
        assert_eq!(
            lex("G1 X1 $").unwrap_err().1,
            ErrorKind::Invalid("Bad character used".into())
        );
    }

    #[test]
    fn numbers() {
        for (s, v) in [
            ("X1", 1.0),
            ("X-0.25", -0.25),
            ("X+3.", 3.0),
            ("X.125", 0.125),
            ("X007", 7.0),
        ] {
            assert_eq!(lex(s).unwrap().words[0].value, v, "{s}");
        }
        assert!((lex("X123.456789").unwrap().words[0].value - 123.456789).abs() < 1e-12);
    }
}
