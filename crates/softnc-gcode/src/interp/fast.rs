//! The short way for the common block of CAM output: a motion line such as
//! `G1 X0.8000 Y0.0500`, `G2 X1.3 Y0.05 I0.25 J0` or `X3 Y4 F600` (LinuxCNC's
//! `read_items` for the words it holds, without the general lexer's steps for
//! everything else).
//!
//! [`words`] takes a line made only of an optional `N` number (digits alone) and
//! words of the letters `G` (motion codes 0 to 3, at most one), `X Y Z I J K R` and
//! `F` (each at most once, `F` not negative), every value a plain number as
//! [`crate::lexer`]'s `plain_number` reads it, with spaces, tabs and CRs between
//! them: the codes and values the general lexer and `Interp::sort_word` read from
//! such a line. [`run_line`] then does what `check` and `execute` do with
//! them, where that is the common way: a plain interpreter state and no error. For
//! anything else — a comment, a parameter, an expression, any other letter, a value
//! the general reader would read otherwise, a word or a motion the general reader
//! would refuse (a second motion code, a repeated letter, a negative or zero feed,
//! an arc without its words or with a radius that does not fit), inverse time, an
//! XY rotation — either says no before changing anything, and the line is read the
//! general way, which gives the same result or the same error as before.

use super::{
    arc_data_ijk, cos_asin_one, sc, Interp, CENTER_ARC_RADIUS_TOLERANCE_INCH,
    CENTER_ARC_RADIUS_TOLERANCE_MM, G_0, G_1, G_2, G_3, LINELEN, MM_PER_INCH,
    RADIUS_TOLERANCE_INCH, RADIUS_TOLERANCE_MM, TINY,
};
use crate::canon::{Motion, MotionKind, PathMode};
use crate::lexer::{plain_number, POW10};
use softnc_core::{Plane, Vec3};
use std::f64::consts::FRAC_PI_2;

/// Index of each value letter in [`Words::v`] and its bit in [`Words::set`]: the
/// axes X Y Z at 0 1 2, the centre offsets I J K at 3 4 5 (the axis index plus
/// [`IJK`]), R and F.
const X: usize = 0;
const IJK: usize = 3;
const R: usize = 6;
const F: usize = 7;
/// Number of value letters (a power of two: indices are masked with `VALUES - 1`).
const VALUES: usize = 8;
const _: () = assert!(VALUES.is_power_of_two());
/// [`Words::set`] bits of the axes and of the centre offsets.
const AXIS_BITS: u32 = 0b111 << X;
const IJK_BITS: u32 = 0b111 << IJK;

/// What [`words`] does with a byte where a word starts (index: the byte with bit 5
/// set, i.e. the lower-case letter; only letters map to letters that way): `G_WORD`
/// for G, the letter's index in [`Words::v`] plus one for a value letter, 0 (the
/// general reader takes the line) for anything else.
const LETTER: [u8; 256] = {
    let mut t = [0u8; 256];
    t[b'g' as usize] = G_WORD;
    let letters = *b"xyzijkrf";
    let mut k = 0;
    while k < letters.len() {
        t[letters[k] as usize] = k as u8 + 1;
        k += 1;
    }
    t
};
/// [`LETTER`]'s mark of the G word.
const G_WORD: u8 = 0xff;

/// What [`words`] does with a byte between words, by the byte itself: [`LETTER`]'s
/// entry for a letter of either case, [`BLANK`] for the bytes [`blank`] skips, 0
/// for anything else (one lookup for both tests).
const BYTE_KIND: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut c: usize = 0;
    while c < 256 {
        if (c as u8).is_ascii_alphabetic() {
            t[c] = LETTER[c | 0x20];
        }
        c += 1;
    }
    t[b' ' as usize] = BLANK;
    t[b'\t' as usize] = BLANK;
    t[b'\r' as usize] = BLANK;
    t
};
/// [`BYTE_KIND`]'s mark of a blank byte.
const BLANK: u8 = 0xfe;

/// The words of a common motion line, as [`words`] reads them.
pub(super) struct Words {
    /// The motion code × 10 of the line's G word (0, 10, 20, 30), or -1 without one.
    pub(super) g: i32,
    /// Which of [`Words::v`] the line gives (bit per index).
    pub(super) set: u32,
    /// The values of X Y Z I J K R F, at their indices (only those in `set` are
    /// written).
    pub(super) v: [f64; VALUES],
    /// The last number read after each letter (index as `v`), to be taken again
    /// where the same text follows the letter ([`number_kept`]).
    kept: [Kept; VALUES],
}

impl Default for Words {
    fn default() -> Self {
        Words {
            g: -1,
            set: 0,
            v: [0.0; VALUES],
            kept: [Kept::default(); VALUES],
        }
    }
}

/// A number [`number_in`] read from at most seven bytes: those bytes, and the byte
/// after them being neither a digit nor a point, alone decide what it reads (see
/// [`number_kept`]).
#[derive(Clone, Copy)]
struct Kept {
    /// The first eight bytes it was read from (those outside `mask` do not count).
    bytes: u64,
    /// The bytes of the number.
    mask: u64,
    /// What it read: the value and the number of bytes.
    value: f64,
    len: usize,
}

impl Default for Kept {
    /// `0` before a newline, as [`number_in`] reads it.
    fn default() -> Self {
        let mut head = [0u8; HEAD];
        head[..2].copy_from_slice(b"0\n");
        let mut kept = Kept {
            bytes: 0,
            mask: 0,
            value: 0.0,
            len: 0,
        };
        if let Num::Value(v, len) = number_in(&head) {
            kept.keep(&head, v, len);
        }
        kept
    }
}

impl Kept {
    /// Keep what [`number_in`] read from `head` where the number and the byte
    /// after it lie within its first eight bytes (`len` < 8).
    fn keep(&mut self, head: &[u8; HEAD], value: f64, len: usize) {
        if len < 8 {
            let mut lo = [0u8; 8];
            lo.copy_from_slice(&head[..8]);
            self.bytes = u64::from_le_bytes(lo);
            self.mask = u64::MAX >> (8 * (8 - len));
            self.value = value;
            self.len = len;
        }
    }
}

/// Whether a line starting with byte `c` may take the short way (a word's letter,
/// `N`, or white space): a cheap test before [`Interp::fast_lines`] is called.
pub(super) fn may_start(c: u8) -> bool {
    LETTER[usize::from(c | 0x20)] != 0 || c | 0x20 == b'n' || blank(c)
}

/// Spaces, tabs and CRs, which LinuxCNC ignores between words.
fn blank(c: u8) -> bool {
    matches!(c, b' ' | b'\t' | b'\r')
}

/// Every byte 0x30 (`'0'`): a word of ASCII digits XOR this holds their values.
const ZEROS: u64 = 0x3030_3030_3030_3030;
/// Added to bytes of 0 to 9, leaves them below 0x80; 10 and above reach it.
const DIGIT_LIMIT: u64 = 0x7676_7676_7676_7676;
/// The high bit of every byte.
const HIGHS: u64 = 0x8080_8080_8080_8080;
/// The point, XOR [`ZEROS`].
const POINT: u64 = (b'.' ^ b'0') as u64;

/// The bytes that go on with a number after its digits (the digits and the
/// point), by the byte: [`number_kept`]'s test of the byte after a kept number
/// in one lookup.
const GOES_ON: [bool; 256] = {
    let mut t = [false; 256];
    let mut c = b'0';
    while c <= b'9' {
        t[c as usize] = true;
        c += 1;
    }
    t[b'.' as usize] = true;
    t
};

/// The number of up to 8 decimal digits held one per byte in `v` (values 0 to 9,
/// the most significant in the lowest byte), in three multiplications (as
/// `fast_float`'s `parse_eight_digits_unrolled`).
fn eight_digits(v: u64) -> u64 {
    const MASK: u64 = 0x0000_00ff_0000_00ff;
    const MUL1: u64 = 100 + (1_000_000 << 32);
    const MUL2: u64 = 1 + (10_000 << 32);
    let v = v.wrapping_mul(10).wrapping_add(v >> 8);
    ((v & MASK)
        .wrapping_mul(MUL1)
        .wrapping_add(((v >> 16) & MASK).wrapping_mul(MUL2)))
        >> 32
}

/// The value after a word's letter at `t[start..]` and the offset after it, as
/// [`plain_number`] reads it on its line (`t` goes on after the line: its newline,
/// the next lines), where the line goes on with white space, a letter or nothing. An optional sign, then digits with at most one point within eight
/// bytes are read eight bytes at a time: which are digits, where the point is, and
/// the digits' value in one step ([`eight_digits`]); then the same integer
/// mantissa and the same correctly rounded division as `plain_number`. Longer
/// numbers (a ninth byte of digits) go to `plain_number`. `None` where it reads no number (the general
/// reader decides); a number followed by a digit, point or sign after white space
/// (`X1 2`, `X1.2.3`, `X1-2`) is left to the caller, whose next word must start
/// with a letter.
fn number(t: &[u8], start: usize) -> (f64, usize) {
    // a sign, eight bytes and the ninth after them within `t`; else (the last
    // bytes of the text) the same reading on a copy padded with zeros
    let Some(head) = t.get(start..start + HEAD) else {
        return number_near_end(t, start);
    };
    let Ok(head) = <&[u8; HEAD]>::try_from(head) else {
        return number_near_end(t, start);
    };
    match number_in(head) {
        Num::Value(v, len) => (v, start + len),
        Num::Long => long_number(t, start),
        Num::None => (0.0, NO_NUMBER),
    }
}

/// Bytes [`number_in`] reads: a sign, eight bytes, the ninth after them.
const HEAD: usize = 10;

/// [`number`]'s offset where it reads no number.
const NO_NUMBER: usize = usize::MAX;

/// What [`number_in`] reads.
enum Num {
    /// The value and the number of bytes it takes (sign included).
    Value(f64, usize),
    /// A number of more than eight bytes: `plain_number` reads it.
    Long,
    /// No number the short way reads.
    None,
}

/// [`number`], taking again the number `kept` holds where the same bytes follow
/// the letter and then a byte that is neither a digit nor a point, and keeping
/// the number read otherwise. [`number_in`] reads a number of `len` bytes (sign
/// included) from those bytes alone: the sign, the digits and the point up to
/// the first other byte (which ends it; any byte but a digit or a point ends it
/// there), and the ninth byte only where that first other byte is not within the
/// first eight; [`Kept::keep`] keeps only numbers whose next byte is within them. So the same bits as [`number`] (test
/// `kept_numbers_read_as_number_reads_them`). CAM output repeats many values
/// line after line (`Y`, `Z`, `I`, `J`, `R`, `F`), each read once.
#[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
fn number_kept(t: &[u8], start: usize, kept: &mut Kept) -> (f64, usize) {
    let Some(head) = t.get(start..start + HEAD) else {
        return number_near_end(t, start);
    };
    let Ok(head) = <&[u8; HEAD]>::try_from(head) else {
        return number_near_end(t, start);
    };
    let mut lo = [0u8; 8];
    lo.copy_from_slice(&head[..8]);
    let lo = u64::from_le_bytes(lo);
    // the same bytes of the number, and after them a byte that ends it
    let after = (lo >> (8 * (kept.len & 7))) as u8;
    if (lo ^ kept.bytes) & kept.mask == 0 && !GOES_ON[usize::from(after)] {
        return (kept.value, start + kept.len);
    }
    match number_in(head) {
        Num::Value(v, len) => {
            kept.keep(head, v, len);
            (v, start + len)
        }
        Num::Long => long_number(t, start),
        Num::None => (0.0, NO_NUMBER),
    }
}

/// [`number`] on the first [`HEAD`] bytes after a word's letter.
#[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
fn number_in(head: &[u8; HEAD]) -> Num {
    let neg = head[0] == b'-';
    let signed = neg || head[0] == b'+';
    let i = usize::from(signed);
    let mut word = [0u8; 8];
    word.copy_from_slice(&head[i..i + 8]);
    let x = u64::from_le_bytes(word) ^ ZEROS;
    let ninth = if signed { head[9] } else { head[8] };
    // the high bit of each byte that is not a digit (a carry out of a byte only
    // comes from one that is not, and only reaches bytes above it)
    let not_digit = (x.wrapping_add(DIGIT_LIMIT) | x) & HIGHS;
    let int = not_digit.trailing_zeros() / 8; // digits before the first other byte
                                              // the digits, the number of them after the point, of them all, and of bytes
    let (digits, frac, count, len) = if int < 8 && (x >> (8 * int)) & 0xff == POINT {
        // the digits after the point, moved down over it
        let after = not_digit & (u64::MAX << (8 * int) << 8);
        let end = after.trailing_zeros() / 8;
        if end == 8 && ninth.is_ascii_digit() {
            return Num::Long; // a ninth byte goes on with the number
        }
        let low = (1u64 << (8 * int)) - 1;
        ((x & low) | ((x >> 8) & !low), end - int - 1, end - 1, end)
    } else {
        if int == 8 && (ninth.is_ascii_digit() || ninth == b'.') {
            return Num::Long;
        }
        (x, 0, int, int)
    };
    if count == 0 {
        return Num::None;
    }
    // the digits alone, the first one lowest: shifted up so that zeros (leading
    // zeros of the number) fill the bytes below them
    let mant = eight_digits(digits << (8 * (8 - count)));
    // at most seven digits after the point (eight bytes, one the point): the mask
    // only tells the compiler so (no bounds check)
    let v = mant as i64 as f64 / POW10[(frac & 7) as usize];
    Num::Value(if neg { -v } else { v }, i + len as usize)
}

/// [`number`] within the last [`HEAD`] bytes of the text: on a copy padded with
/// zeros (which are no digits, as the end of the text is none).
#[cold]
fn number_near_end(t: &[u8], start: usize) -> (f64, usize) {
    let mut head = [0u8; HEAD];
    let rest = t.get(start..).unwrap_or(&[]);
    head[..rest.len()].copy_from_slice(rest);
    match number_in(&head) {
        Num::Value(v, len) => (v, start + len),
        Num::Long => long_number(t, start),
        Num::None => (0.0, NO_NUMBER),
    }
}

/// [`plain_number`] from `start`, for numbers longer than eight bytes (kept out of
/// [`number`]: rare, and its registers would cost every number). `t` may go on
/// after the line: `plain_number` reads nothing across its newline.
#[cold]
fn long_number(t: &[u8], start: usize) -> (f64, usize) {
    plain_number(t, start).unwrap_or((0.0, NO_NUMBER))
}

/// The motion code (0 to 3) of a G word written as one digit (`G1 `, `G2` at the
/// end of the text): the digit at `t[at]`, where the byte after it (if any) is
/// neither a digit nor a point, which would go on with the number; `None`
/// otherwise ([`number`] reads it). [`number`] reads such a digit as that whole
/// number and ends after it, so [`words`] takes it as the same code.
fn one_digit_code(t: &[u8], at: usize) -> Option<i32> {
    let d = t.get(at)?.wrapping_sub(b'0');
    if d > 3 {
        return None;
    }
    match t.get(at + 1) {
        Some(&c) if GOES_ON[usize::from(c)] => None,
        _ => Some(i32::from(d)),
    }
}

/// The words of the line of `t` that starts at `s` (up to the next newline or the
/// end of `t`) into `w` (written over), if the line has the common shape (see the
/// module's documentation): then the offset of its end (of the newline, or the
/// length of `t`); `None` otherwise. Where it says yes, the general lexer and
/// `Interp::sort_word` read the same codes and values from the line without an
/// error.
#[inline(always)] // kept: the whole `softnc plan` measured slower without, docs/perf-log/speed-tricks.md
pub(super) fn words(t: &[u8], s: usize, w: &mut Words) -> Option<usize> {
    w.g = -1;
    w.set = 0;
    let n = t.len();
    let mut i = s;
    // a line that starts with a motion code of one digit and a space (`G1 `, the
    // most common start: what the loop below reads from it, in one test), or
    // with a word's letter (the common case) goes straight to the words; blanks,
    // a blank line and a line number first
    if let Some(&[letter, digit, b' ', ..]) = t.get(s..) {
        let code = digit.wrapping_sub(b'0');
        if letter | 0x20 == b'g' && code <= 3 {
            w.g = i32::from(code) * 10;
            i += 3;
        }
    }
    if i == s && matches!(BYTE_KIND[usize::from(*t.get(i)?)], 0 | BLANK) {
        while i < n && blank(t[i]) {
            i += 1;
        }
        if i == n || t[i] == b'\n' {
            return None; // a blank line: the general reader says so
        }
        if t[i] | 0x20 == b'n' {
            // a line number of digits alone (LinuxCNC reads and drops it); what
            // follows must start a word, which the loop below checks
            i += 1;
            let digits = i;
            while i < n && t[i].is_ascii_digit() {
                i += 1;
            }
            if i == digits {
                return None;
            }
        }
    }
    while i < n {
        let c = t[i];
        let kind = BYTE_KIND[usize::from(c)];
        // the kinds by how often they come: a value letter, G, a blank, the end
        if kind.wrapping_sub(1) < VALUES as u8 {
            // `k` < VALUES (a power of two): the mask only tells the compiler so
            let k = usize::from(kind - 1) & (VALUES - 1);
            let (value, next) = number_kept(t, i + 1, &mut w.kept[k]);
            if next == NO_NUMBER {
                return None;
            }
            let bit = 1 << k;
            // a repeated letter and a negative feed are errors: the general reader
            // gives them
            if w.set & bit != 0 || (k == F && value < 0.0) {
                return None;
            }
            w.set |= bit;
            w.v[k] = value;
            i = next;
            // the common blank before the next word, or the end of the line
            match t.get(i) {
                Some(b' ') => i += 1,
                Some(b'\n') => return Some(i),
                _ => {}
            }
            continue;
        }
        if kind == G_WORD {
            if let Some(code) = one_digit_code(t, i + 1) {
                // `G1`: what `number` and the test below make of it
                if w.g >= 0 {
                    return None;
                }
                w.g = code * 10;
                i += 2;
                if t.get(i) == Some(&b' ') {
                    i += 1; // the common blank before the next word
                }
                continue;
            }
            let (value, next) = number(t, i + 1);
            if next == NO_NUMBER {
                return None;
            }
            // `sort_word`: value × 10 rounded to a code; 0, 10, 20, 30 are motion
            // codes (group 1), supported, and at most one per line
            let code = value as i32;
            if f64::from(code) != value || !(0..=3).contains(&code) || w.g >= 0 {
                return None;
            }
            w.g = code * 10;
            i = next;
            continue;
        }
        if kind == BLANK {
            i += 1;
            continue;
        }
        // the end of the line, or what the general reader reads
        return (c == b'\n').then_some(i);
    }
    Some(n)
}

impl Interp<'_> {
    /// Read and run the lines of `t` from `pos` the short way, one after the other,
    /// while they take it: [`words`] reads each and [`run_line`] runs it. At most
    /// `max_lines` lines (the block limit left), and none once `chunk` motions wait
    /// for the caller. The first line numbered `line_no`. The offset of the first
    /// line not read (its start: the general reader reads it from there, with
    /// nothing changed by it) and the number of lines read; only the caller's count
    /// of lines and blocks are left to bring up to date. The caller makes sure that
    /// lines are read and run at all (no label is looked for).
    ///
    /// Nothing a line of the short way runs changes the interpreter's modes, so
    /// they are read once ([`Run`]); the current point, feed rate and motion mode
    /// are kept in locals ([`Moving`]) and the motions pushed onto the vector taken
    /// out of `self` for the run (the compiler need not read them again from
    /// `self` after each push), and all are put back at the end. The lines are
    /// read in [`lines`], one copy of the loop per plane (the plane is one of the
    /// modes), so that an arc's axes are constants.
    pub(super) fn fast_lines(
        &mut self,
        t: &[u8],
        pos: usize,
        line_no: usize,
        max_lines: u64,
        chunk: usize,
    ) -> (usize, u64) {
        if !self.short_way_understands_the_modes() {
            return (pos, 0);
        }
        // what a run changes, for the cross-check of debug builds
        #[cfg(debug_assertions)]
        let before = Before {
            pos: self.pos,
            canon_pos: self.canon_pos,
            feed: self.feed,
            motion: self.motion,
            line_no: self.line_no,
            moves_after_start: self.moves_after_start,
            motions: self.motions.len(),
        };
        let run = Run {
            absolute: self.absolute,
            ijk_absolute: self.ijk_absolute,
            inch: self.inch,
            scale: self.scale(),
            plane: self.plane,
            path: self.path,
            offset_mm: self.offset(),
            spindle_rpm: self.spindle_rpm(),
        };
        let mut st = Moving {
            pos: self.pos,
            feed: self.feed,
            motion: self.motion,
            pushed: 0,
            trig: Trig::default(),
        };
        #[cfg(debug_assertions)]
        let start = pos;
        let mut motions = std::mem::take(&mut self.motions);
        // one loop per plane, distance mode and unit: the axes, the distance
        // mode and the scale are constants there
        let lines = match run.plane {
            Plane::XY => lines_of::<XY>(run.absolute, run.inch),
            Plane::XZ => lines_of::<XZ>(run.absolute, run.inch),
            Plane::YZ => lines_of::<YZ>(run.absolute, run.inch),
        };
        let (pos, read) = lines(
            t,
            pos,
            line_no,
            max_lines,
            chunk,
            &run,
            &mut st,
            &mut motions,
        );
        self.motions = motions;
        if st.pushed > 0 {
            // `push`: the point moves with each motion, and the canonical point
            self.pos = st.pos;
            self.canon_pos = st.pos;
            self.moves_after_start += st.pushed;
        }
        self.feed = st.feed;
        self.motion = st.motion;
        if read > 0 {
            self.line_no = line_no + read as usize - 1;
        }
        #[cfg(debug_assertions)]
        if read > 0 {
            self.cross_check(&before, &t[start..pos], line_no);
        }
        (pos, read)
    }

    /// Whether the short way runs lines in the interpreter's present modes. An
    /// allow-list: the motion modes it knows (none, G0, G1, G2, G3) in units per
    /// minute (G94), no XY rotation, no position to re-read after a tool change, no
    /// run from line waiting for its start. Any other state, and any mode added to
    /// the language later (a canned cycle, cutter compensation, feed per
    /// revolution, ...), goes the general way until it is added here.
    fn short_way_understands_the_modes(&self) -> bool {
        matches!(self.motion, None | Some(G_0 | G_1 | G_2 | G_3))
            && !self.cycle.in_series()
            && !self.inverse_time
            && !self.sync_pending
            && self.rotation_deg == 0.0
            && !self.suppress
            && !self.before_the_last_probe_run()
            && !self.comp.busy()
    }

    /// Debug builds: the lines `text` the short way just ran, from the state
    /// `before` them, run again by the general reader (`lex_words`, `sort_word`,
    /// `check`, `execute`) give the same motions (to the bit), point, feed rate and
    /// motion mode. A line the short way takes but reads differently panics here,
    /// in every test that reads a program.
    #[cfg(debug_assertions)]
    fn cross_check(&self, was: &Before, text: &[u8], line_no: usize) {
        use super::Block;
        use crate::lexer::{lex_words, Line};
        let mut before = self.copy_for_cross_check();
        before.pos = was.pos;
        before.canon_pos = was.canon_pos;
        before.feed = was.feed;
        before.motion = was.motion;
        before.line_no = was.line_no;
        before.moves_after_start = was.moves_after_start;
        let text = std::str::from_utf8(text).expect("the short way reads ASCII");
        let mut l = Line::default();
        for (k, line) in text.lines().enumerate() {
            let no = line_no + k;
            let mut block = Block::default();
            let read = lex_words(line, &mut l, true, |w| before.sort_word(w, &mut block))
                .and_then(|()| before.check(&mut block))
                .and_then(|()| before.execute(no as u32, &block).map(|_| ()));
            before.line_no = no;
            assert!(
                read.is_ok(),
                "line {no} {line:?}: the short way ran it, the general reader says {read:?}"
            );
        }
        let bits = |m: &[Motion]| format!("{m:?}");
        assert_eq!(
            bits(&before.motions),
            bits(&self.motions[was.motions..]),
            "lines {line_no}.. {text:?}: the short way's motions differ from the general reader's"
        );
        assert_eq!(
            (
                before.pos,
                before.canon_pos,
                before.feed.to_bits(),
                before.motion,
                before.line_no,
                before.moves_after_start
            ),
            (
                self.pos,
                self.canon_pos,
                self.feed.to_bits(),
                self.motion,
                self.line_no,
                self.moves_after_start
            ),
            "lines {line_no}.. {text:?}: the short way's state differs from the general reader's"
        );
    }
}

/// What a run of [`Interp::fast_lines`] changes, as it stood before the run (the
/// cross-check of debug builds runs the lines again from there).
#[cfg(debug_assertions)]
struct Before {
    pos: Vec3,
    canon_pos: Vec3,
    feed: f64,
    motion: Option<i32>,
    line_no: usize,
    moves_after_start: u64,
    /// Motions pushed before the run.
    motions: usize,
}

/// [`lines`]' plane parameter: the index of a plane in [`PLANES`].
const XY: usize = 0;
const XZ: usize = 1;
const YZ: usize = 2;
/// The planes by [`lines`]' plane parameter.
const PLANES: [Plane; 3] = [Plane::XY, Plane::XZ, Plane::YZ];

/// [`lines`] as a function pointer.
type Lines =
    fn(&[u8], usize, usize, u64, usize, &Run, &mut Moving, &mut Vec<Motion>) -> (usize, u64);

/// [`lines`] in the plane `PLANES[P]` for a run's distance mode (`absolute`:
/// G90) and unit (`inch`: G20).
fn lines_of<const P: usize>(absolute: bool, inch: bool) -> Lines {
    match (absolute, inch) {
        (false, false) => lines::<P, false, false>,
        (false, true) => lines::<P, false, true>,
        (true, false) => lines::<P, true, false>,
        (true, true) => lines::<P, true, true>,
    }
}

/// The loop of [`Interp::fast_lines`] in the plane `PLANES[P]`, absolute
/// distances (G90) where `ABSOLUTE`, inches (G20) where `INCH` (the run's modes,
/// which no line of it changes; `run` holds the same): [`words`] reads each line
/// and [`run_line`] runs it, from `pos`, the first line numbered `line_no`, at
/// most `max_lines` lines and none once `chunk` motions wait. The offset of the
/// first line not read and the number of lines read. With these modes constants,
/// an arc's axes are constants (no point copied to memory to be indexed), and
/// so are the distance mode's test and the scale (mm: × 1, which the compiler
/// drops).
#[allow(clippy::too_many_arguments)]
fn lines<const P: usize, const ABSOLUTE: bool, const INCH: bool>(
    t: &[u8],
    mut pos: usize,
    line_no: usize,
    max_lines: u64,
    chunk: usize,
    run: &Run,
    st: &mut Moving,
    motions: &mut Vec<Motion>,
) -> (usize, u64) {
    // the words of the line being read (a local: its fields may stay in
    // registers)
    let w = &mut Words::default();
    let mut read = 0;
    while read < max_lines && motions.len() < chunk {
        let Some(e) = words(t, pos, w) else {
            break;
        };
        let newline = e < t.len();
        if e - pos + usize::from(newline) >= LINELEN - 1 {
            break; // too long: the general reader says so
        }
        let no = line_no + read as usize;
        if !run_line::<P, ABSOLUTE, INCH>(run, st, w, no as u32, motions) {
            break;
        }
        read += 1;
        pos = e + usize::from(newline);
    }
    (pos, read)
}

/// The interpreter's modes for a run of [`Interp::fast_lines`] (no line of the
/// run changes them).
struct Run {
    absolute: bool,
    ijk_absolute: bool,
    inch: bool,
    /// mm per program unit (`Interp::scale`).
    scale: f64,
    plane: Plane,
    path: PathMode,
    offset_mm: Vec3,
    spindle_rpm: f64,
}

/// What the lines of a run of [`Interp::fast_lines`] change, kept in locals: the
/// current point (program units), the feed rate, the motion mode, and how many
/// motions were pushed.
struct Moving {
    pos: Vec3,
    feed: f64,
    motion: Option<i32>,
    pushed: u64,
    /// The sine and cosine of the last radius-format arc's angle.
    trig: Trig,
}

/// `check` and `execute` for a line [`words`] read, where they take the common way:
/// the interpreter in a plain state (no inverse time, no XY rotation, no position
/// to re-read after a tool change, no run from line waiting for its start: the
/// caller checks) and a line they accept without an error. Then the line's feed
/// rate, motion mode, motion (pushed onto `motions`) and point are as `check` and
/// `execute` leave them, and `true`. Otherwise nothing is changed and `false`: the
/// general reader reads the line (and gives its error, if any).
#[allow(clippy::too_many_lines)]
fn run_line<const P: usize, const ABSOLUTE: bool, const INCH: bool>(
    run: &Run,
    st: &mut Moving,
    w: &Words,
    line_no: u32,
    motions: &mut Vec<Motion>,
) -> bool {
    let has = |k: usize| w.set & (1 << k) != 0;
    let axis = w.set & AXIS_BITS != 0;
    let ijk = w.set & IJK_BITS != 0;
    // `check`: the motion of the block (LinuxCNC's `motion_to_be`)
    let motion = if w.g >= 0 {
        w.g
    } else if axis {
        match st.motion {
            Some(m) => m,
            None => return false, // axis words without a motion: an error
        }
    } else if ijk && matches!(st.motion, Some(G_2 | G_3)) {
        st.motion.unwrap_or(G_2)
    } else {
        -1
    };
    let arc = motion == G_2 || motion == G_3;
    if (ijk || has(R)) && !arc {
        return false; // I, J, K or R without an arc: an error
    }
    // `execute`'s short way: the feed rate, then the motion
    let feed = if has(F) { w.v[F] } else { st.feed };
    if motion < 0 {
        st.feed = feed;
        return true;
    }
    if motion != G_0 && feed == 0.0 {
        return false; // zero feed rate: an error
    }
    // `find_ends`
    let pos = st.pos;
    // each axis by itself (scalars the compiler keeps in registers)
    let end_on = |a: usize| {
        if !has(X + a) {
            pos.0[a]
        } else if ABSOLUTE {
            w.v[X + a]
        } else {
            pos.0[a] + w.v[X + a]
        }
    };
    let end = Vec3([end_on(0), end_on(1), end_on(2)]);
    // `Interp::scale` of the run's unit (`run.scale`), a constant
    let s = if INCH { MM_PER_INCH } else { 1.0 };
    debug_assert!(
        s.to_bits() == run.scale.to_bits() && (ABSOLUTE, INCH) == (run.absolute, run.inch)
    );
    // `push` (no rotation) and `keep` (no run from line waiting), written out in
    // each branch below (the motion built in place)
    let mut push = |kind: MotionKind, center: Vec3| {
        motions.push(Motion {
            line: line_no,
            start: sc(pos, s),
            kind,
            offset_mm: run.offset_mm,
            path_mode: run.path,
            inch: INCH,
            canon_end: end,
            canon_center: center,
            spindle_rpm: run.spindle_rpm,
        });
    };
    if !arc {
        let kind = if motion == G_0 {
            MotionKind::Traverse { end: sc(end, s) }
        } else {
            MotionKind::Feed {
                end: sc(end, s),
                feed_mm_per_min: feed * s,
            }
        };
        push(kind, Vec3::ZERO);
    } else {
        // `arc`, with its checks in its order (each failing one an error)
        if !has(R) && !ijk || has(R) && ijk {
            return false;
        }
        let plane = PLANES[P];
        let (a1, a2, an) = plane.axes();
        let inch = INCH;
        let (c1, c2, turns) = if ijk {
            if has(IJK + an) || (run.ijk_absolute && !(has(IJK + a1) && has(IJK + a2))) {
                return false;
            }
            let o = |a: usize| if has(IJK + a) { w.v[IJK + a] } else { 0.0 };
            let (rtol, stol) = if inch {
                (RADIUS_TOLERANCE_INCH, CENTER_ARC_RADIUS_TOLERANCE_INCH)
            } else {
                (RADIUS_TOLERANCE_MM, CENTER_ARC_RADIUS_TOLERANCE_MM)
            };
            let names = [b'X', b'Y', b'Z'];
            match arc_ijk(
                motion,
                (pos[a1], pos[a2]),
                (end[a1], end[a2]),
                run.ijk_absolute,
                (o(a1), o(a2)),
                rtol,
                stol,
                [names[a1] as char, names[a2] as char],
            ) {
                Some(c) => c,
                None => return false,
            }
        } else {
            if !has(X + a1) && !has(X + a2) {
                return false;
            }
            let tol = if inch {
                RADIUS_TOLERANCE_INCH
            } else {
                RADIUS_TOLERANCE_MM
            };
            match arc_r(
                motion,
                (pos[a1], pos[a2]),
                (end[a1], end[a2]),
                w.v[R],
                tol,
                &mut st.trig,
            ) {
                Some(c) => c,
                None => return false,
            }
        };
        let mut center = pos;
        center[a1] = c1;
        center[a2] = c2;
        let kind = MotionKind::Arc {
            end: sc(end, s),
            center: sc(center, s),
            plane,
            turns,
            feed_mm_per_min: feed * s,
        };
        push(kind, center);
    }
    st.feed = feed;
    st.motion = Some(motion);
    st.pushed += 1;
    st.pos = end;
    true
}

/// The sine and cosine of the last angle [`arc_r`] turned to (a pure function of
/// the angle's bits: the same bits as computing them again). Arcs of a chord along
/// an axis turn to ±π/2, 0 or π, so most lookups of CAM output find it.
pub(super) struct Trig {
    /// The angle (rad) whose sine and cosine are kept.
    theta: f64,
    sin: f64,
    cos: f64,
    /// [`cos_asin_one`], read once (not through its `OnceLock` per arc).
    cos_asin_one: f64,
}

impl Default for Trig {
    fn default() -> Self {
        let theta = FRAC_PI_2;
        Trig {
            theta,
            sin: theta.sin(),
            cos: theta.cos(),
            cos_asin_one: cos_asin_one(),
        }
    }
}

impl Trig {
    /// `(theta.sin(), theta.cos())`, kept for the last `theta` (compared by bits).
    fn sin_cos(&mut self, theta: f64) -> (f64, f64) {
        if theta.to_bits() != self.theta.to_bits() {
            self.theta = theta;
            self.sin = theta.sin();
            self.cos = theta.cos();
        }
        (self.sin, self.cos)
    }
}

/// Relative bound on how far `(a * a + b * b).sqrt()` may be from `a.hypot(b)`
/// (both within a few units in the last place where nothing overflows or
/// underflows: 1e-14 is about 45 of them), used where only a comparison of the
/// radius matters.
const HYPOT_SLACK: f64 = 1e-14;

/// [`arc_data_ijk`] (the checks of its radii, then its centre and turns) on the
/// short way's values (`p` = 1): the same centre, or `None` where it gives an
/// error. The radii to the start and the end count only through the checks, so
/// where `sqrt` of the sum of squares passes them with a margin of
/// [`HYPOT_SLACK`] (`hypot` would too) their `hypot`s are not computed; otherwise
/// `arc_data_ijk` itself decides. Test `arcs_the_short_way_as_arc_data`.
#[allow(clippy::too_many_arguments)]
fn arc_ijk(
    mode: i32,
    cur: (f64, f64),
    end: (f64, f64),
    absolute: bool,
    ij: (f64, f64),
    radius_tolerance: f64,
    spiral_tolerance: f64,
    names: [char; 2],
) -> Option<(f64, f64, i32)> {
    let (cx, cy) = if absolute {
        ij
    } else {
        (cur.0 + ij.0, cur.1 + ij.1)
    };
    let (a1, b1) = (cx - cur.0, cy - cur.1);
    let (a2, b2) = (cx - end.0, cy - end.1);
    let r1 = (a1 * a1 + b1 * b1).sqrt();
    let r2 = (a2 * a2 + b2 * b2).sqrt();
    let slack = HYPOT_SLACK * (r1 + r2);
    // both radii surely above the zero-radius tolerance, their difference surely
    // within the spiral tolerance (then no error: the relative test needs both);
    // NaN or infinite radii fail these tests
    if r1 - slack > radius_tolerance
        && r2 - slack > radius_tolerance
        && (r1 - r2).abs() + slack < spiral_tolerance
    {
        return Some((cx, cy, if mode == G_2 { -1 } else { 1 }));
    }
    arc_data_ijk(
        mode,
        cur,
        end,
        absolute,
        ij,
        1,
        radius_tolerance,
        spiral_tolerance,
        names,
    )
    .ok()
}

/// [`arc_data_r`](super::arc_data_r) (`p` = 1) with the same bits, `None` where it gives an error:
/// half the chord is taken as the radius without its `hypot` where `sqrt` of the
/// sum of squares shows it within the tolerance and above `1 - TINY` of the
/// radius with a margin of [`HYPOT_SLACK`] (then `arc_data_r` takes the radius for
/// it too, and its bits do not count); the sine and cosine of the angle kept in
/// `trig`. Test `arcs_the_short_way_as_arc_data`.
fn arc_r(
    mode: i32,
    cur: (f64, f64),
    end: (f64, f64),
    radius: f64,
    tolerance: f64,
    trig: &mut Trig,
) -> Option<(f64, f64, i32)> {
    if end == cur {
        return None;
    }
    let abs_radius = radius.abs();
    let mid = ((end.0 + cur.0) / 2.0, (end.1 + cur.1) / 2.0);
    let (dx, dy) = (mid.0 - end.0, mid.1 - end.1);
    let near = (dx * dx + dy * dy).sqrt();
    // `half / abs_radius`, which is 1 where half the chord is taken as the
    // radius and that is neither 0 nor infinite (x / x)
    let ratio = if near * (1.0 + HYPOT_SLACK) - abs_radius < tolerance
        && near * (1.0 - HYPOT_SLACK) > abs_radius * (1.0 - TINY / 2.0)
        && abs_radius != 0.0
    {
        1.0
    } else {
        let mut half = dx.hypot(dy);
        if half - abs_radius > tolerance {
            return None;
        }
        if half / abs_radius > 1.0 - TINY {
            half = abs_radius;
        }
        half / abs_radius
    };
    let heading = (end.1 - cur.1).atan2(end.0 - cur.0);
    let theta = if (mode == G_2 && radius > 0.0) || (mode == G_3 && radius < 0.0) {
        heading - FRAC_PI_2
    } else {
        heading + FRAC_PI_2
    };
    let offset = abs_radius
        * if ratio == 1.0 {
            trig.cos_asin_one
        } else {
            ratio.asin().cos()
        };
    let (sin, cos) = trig.sin_cos(theta);
    let (cx, cy) = (mid.0 + offset * cos, mid.1 + offset * sin);
    if !(cx.is_finite() && cy.is_finite()) {
        return None;
    }
    Some((cx, cy, if mode == G_2 { -1 } else { 1 }))
}

#[cfg(test)]
mod tests {
    use super::super::{Block, Interp, GM_MOTION, SLOTS};
    use super::{number, words, Words, LETTER, NO_NUMBER};
    use crate::lexer::plain_number;
    use crate::lexer::{lex_words, Line};
    use softnc_core::MotionProfile;

    /// A xorshift64 stream from `seed`: `next(m)` draws an index below `m` (the
    /// tests' deterministic random inputs).
    fn xorshift(seed: u64) -> impl FnMut(usize) -> usize {
        let mut state = seed;
        move |m: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % m as u64) as usize
        }
    }

    fn profile() -> MotionProfile {
        MotionProfile::load(
            &std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../config/machines/default.ron"),
        )
        .unwrap()
    }

    /// The general reader's block for `line`, or its error.
    fn general(it: &Interp, line: &str) -> Result<Block, String> {
        let mut block = Block::default();
        let mut l = Line::default();
        lex_words(line, &mut l, true, |w| it.sort_word(w, &mut block))
            .map(|()| block)
            .map_err(|(off, k)| format!("{off}: {k:?}"))
    }

    /// The block the general reader would make of `w` (offsets aside).
    fn as_block(w: &Words) -> Block {
        let mut b = Block::default();
        if w.g >= 0 {
            b.set_g(GM_MOTION, w.g, 0);
        }
        for (l, &k) in LETTER.iter().enumerate() {
            if k != 0 && k != super::G_WORD && w.set & (1 << (k - 1)) != 0 {
                b.set_val((l as u8).to_ascii_uppercase(), w.v[usize::from(k - 1)], 0);
            }
        }
        b
    }

    /// What a block holds, comparably (the values by their bits, offsets aside).
    fn contents(b: &Block) -> Vec<(String, u64)> {
        let mut v = Vec::new();
        for g in 0..super::super::G_GROUPS {
            if b.has_g(g) {
                v.push((format!("g{g}"), b.g[g].0 as u64));
            }
        }
        for m in 0..super::super::M_GROUPS {
            if b.has_m(m) {
                v.push((format!("m{m}"), b.m[m].0 as u64));
            }
        }
        for s in 0..SLOTS {
            if b.val_set & (1 << s) != 0 {
                v.push((format!("v{s}"), b.val[s].0.to_bits()));
            }
        }
        v.push(("p".into(), b.p_number.to_bits()));
        v.push(("q".into(), b.q_number.to_bits()));
        v.push(("m".into(), b.m_count as u64));
        v
    }

    /// Where the short way takes a line, the block is the general reader's; where
    /// it does not, the general reader reads the line (as before).
    fn same_as_general(it: &Interp, line: &str) -> bool {
        let mut w = Words::default();
        let taken = words(line.as_bytes(), 0, &mut w).is_some();
        if taken {
            let want = general(it, line)
                .unwrap_or_else(|e| panic!("{line:?}: fast path taken, general reader fails: {e}"));
            assert_eq!(contents(&as_block(&w)), contents(&want), "{line:?}");
        }
        taken
    }

    #[test]
    fn common_lines_take_the_short_way_as_the_general_reader_reads_them() {
        let p = profile();
        let it = Interp::new("t.ngc", p.tables());
        for line in [
            "G1 X0.8000 Y0.0500",
            "G2 X1.3000 Y0.0500 I0.25 J0",
            "G3 X2.6000 Y0.1000 R0.25",
            "g1x1y2z3f600",
            "  G01 X-1. Y+.5\tZ-0 F1200\r",
            "N10 G0 X1",
            "n5G1X1",
            "X1 Y2",
            "I0.5 J-0.5",
            "G1 X123456789012345",
            "G1 X0.00000000000001",
            "G0",
            "R-2",
            "F0",
            "G-0 X1",
            "G1.0 X1",
        ] {
            assert!(
                same_as_general(&it, line),
                "{line:?} should take the short way"
            );
        }
        let mut w = Words::default();
        assert_eq!(words(b"G2 X1.3 Y0.05 I0.25 J0\nG1", 0, &mut w), Some(22));
        assert_eq!((w.g, w.set), (20, 0b1_1011));
    }

    #[test]
    fn anything_else_is_left_to_the_general_reader() {
        let p = profile();
        let it = Interp::new("t.ngc", p.tables());
        for line in [
            "",
            "   \r",
            "G1 X1 (comment)",
            "G1 X1 ; comment",
            "G1 X#1",
            "G1 X[1+2]",
            "#1 = 2",
            "o100 sub",
            "M3 S1000",
            "G90 G1 X1",
            "G1 G2 X1",
            "G1 X1 X2",
            "G1 X1 F-5",
            "G1 X1 2",
            "G1 X 1",
            "G1 X1-2",
            "G1 X1.2.3",
            "G1 X1234567890123456",
            "G1 X",
            "G0.5 X1",
            "G4 P1",
            "G1 A1",
            "N10.5 G1 X1",
            "N G1 X1",
            "G1 N10 X1",
            "/G1 X1",
            "%",
            "G1 X1\u{b}",
            "G1 X1\0 junk",
            "G1 X1 $1",
            "G1 @1 ^2",
            "G1 X1 P2",
            "G1 X1e3",
        ] {
            assert!(
                !same_as_general(&it, line),
                "{line:?} should take the general way"
            );
        }
    }

    /// Numbers of every shape up to 12 characters, before a letter, white space, a
    /// newline, a point, a sign or nothing: where the word-at-a-time reading takes
    /// one and a letter or nothing follows it, `plain_number` reads the same bits;
    /// numbers of up to eight bytes it always takes.
    #[test]
    fn numbers_read_eight_bytes_at_a_time_as_plain_number_reads_them() {
        let mut next = xorshift(0x1234_5678_9abc_def1u64);
        let alphabet = b"0123456789012345678901234567890123456789.";
        for _ in 0..200_000 {
            let mut line = b"X".to_vec();
            line.extend_from_slice(["", "-", "+", "--"][next(4)].as_bytes());
            let len = next(13);
            for _ in 0..len {
                line.push(alphabet[next(alphabet.len())]);
            }
            let n = line.len();
            let after = [
                &b" Y1"[..],
                b"Y",
                b"\n",
                b"\nG1 X12345.678 Y1 Z2",
                b"",
                b".5",
                b"-1",
                b" ",
                b"\t",
                b"\r",
            ];
            line.extend_from_slice(after[next(after.len())]);
            let line_end = if line.get(n) == Some(&b'\n') {
                n
            } else {
                line.len()
            };
            let plain = plain_number(&line[..line_end], 1);
            let (v, end) = number(&line, 1);
            if end == NO_NUMBER {
                let text = String::from_utf8_lossy(&line[1..n]);
                let simple = n - 1 <= 8
                    && text.matches('.').count() <= 1
                    && text
                        .trim_start_matches(['-', '+'])
                        .chars()
                        .any(|c| c.is_ascii_digit())
                    && !text.starts_with("--");
                assert!(!simple || plain.is_none(), "{text:?} not read");
                continue;
            }
            let mut k = end;
            while k < line_end && matches!(line[k], b' ' | b'\t' | b'\r') {
                k += 1;
            }
            if k < line_end && !line[k].is_ascii_alphabetic() {
                continue; // the caller leaves the line to the general reader
            }
            let (want, _) = plain.unwrap_or_else(|| {
                panic!(
                    "{:?}: read, plain_number does not",
                    String::from_utf8_lossy(&line)
                )
            });
            assert_eq!(
                v.to_bits(),
                want.to_bits(),
                "{:?}",
                String::from_utf8_lossy(&line)
            );
        }
    }

    /// `BYTE_KIND` (one lookup by the byte) gives what `blank` and `LETTER` (by the
    /// byte with bit 5 set) give, for every byte.
    #[test]
    fn byte_kinds_are_blanks_and_letters() {
        use super::{blank, BLANK, BYTE_KIND};
        for c in 0..=255u8 {
            let want = if blank(c) {
                BLANK
            } else {
                LETTER[usize::from(c | 0x20)]
            };
            assert_eq!(BYTE_KIND[usize::from(c)], want, "byte {c:#x}");
        }
    }

    /// Every line start of three bytes around the short way's shortcuts (`G1 ` in
    /// one test, a line starting with a word's letter, blanks and `N` first) with
    /// what may follow, in a text that goes on after the line's newline: where
    /// [`words`] takes the line, it ends at its newline and the general reader
    /// reads the same words from it.
    #[test]
    fn line_starts_read_as_the_general_reader_reads_them() {
        let p = profile();
        let it = Interp::new("t.ngc", p.tables());
        let (mut taken, mut g_starts) = (0, 0);
        for c0 in "Gg XNn\t".chars() {
            for c1 in "0123456789.-+ \nX".chars() {
                for c2 in " \n\t0.5X\r".chars() {
                    for rest in ["", "X1", "X1 Y2", "1 X2", " Y.5\n", "G2"] {
                        let text = format!("{c0}{c1}{c2}{rest}\nG1 X1\n");
                        let mut w = Words::default();
                        let Some(e) = words(text.as_bytes(), 0, &mut w) else {
                            continue;
                        };
                        assert_eq!(Some(e), text.find('\n'), "{text:?}");
                        let line = &text[..e];
                        let want = general(&it, line).unwrap_or_else(|err| {
                            panic!("{line:?}: fast path taken, general reader fails: {err}")
                        });
                        assert_eq!(contents(&as_block(&w)), contents(&want), "{line:?}");
                        taken += 1;
                        g_starts += usize::from(c0 == 'G' && c2 == ' ' && c1.is_ascii_digit());
                    }
                }
            }
        }
        assert!(
            taken > 300 && g_starts >= 16,
            "{taken} lines, {g_starts} G starts"
        );
    }

    /// `GOES_ON` holds the test it replaces (a digit or a point) for every byte.
    #[test]
    fn bytes_going_on_with_a_number_are_digits_and_the_point() {
        use super::GOES_ON;
        for c in 0..=255u8 {
            let want = c.wrapping_sub(b'0') <= 9 || c == b'.';
            assert_eq!(GOES_ON[usize::from(c)], want, "byte {c:#x}");
        }
    }

    /// `number_kept` against `number` (bits and end) on 400,000 numbers read one
    /// after the other through one `Kept`, drawn from a small set of texts so that
    /// most repeat: the same digits before other bytes (a space, a newline, a
    /// letter, a point, a digit, a sign, the end of the text), prefixes of each
    /// other, signs, numbers of seven to ten bytes.
    #[test]
    fn kept_numbers_read_as_number_reads_them() {
        use super::{number_kept, Kept};
        let mut next = xorshift(0x6a09_e667_f3bc_c909u64);
        let numbers = [
            "0",
            "0.25",
            "0.2",
            "0.250",
            "-0.25",
            "+0.25",
            "1",
            "10",
            "0.0500",
            "-0.0500",
            "0.05",
            "1234567",
            "1234.567",
            "12345678",
            "1.234567",
            "123456789",
            ".5",
            "5.",
            "-",
            ".",
            "",
        ];
        let after = [
            "", " ", "\n", "\nG1 X1", " Y0.05", "Y", "5", "0", ".", ".5", "-1", "\t", "\r\n",
            "  J0", "00000000",
        ];
        let mut kept = Kept::default();
        let (mut hits, mut reads) = (0, 0);
        for _ in 0..400_000 {
            let text = format!(
                "X{}{}",
                numbers[next(numbers.len())],
                after[next(after.len())]
            );
            let t = text.as_bytes();
            let before = (kept.bytes, kept.mask, kept.len);
            let (v, end) = number_kept(t, 1, &mut kept);
            let (want, want_end) = number(t, 1);
            assert_eq!(end, want_end, "{text:?}");
            if end != NO_NUMBER {
                assert_eq!(v.to_bits(), want.to_bits(), "{text:?}");
                reads += 1;
                hits += usize::from(before == (kept.bytes, kept.mask, kept.len));
            }
        }
        assert!(
            hits > 10_000 && reads > 100_000,
            "{hits} of {reads} numbers kept"
        );
    }

    /// Lines of the short way's letters with numbers of every shape: where it takes
    /// one, it reads it as the general reader does.
    #[test]
    fn generated_lines_read_as_the_general_reader_reads_them() {
        let p = profile();
        let it = Interp::new("t.ngc", p.tables());
        let letters = [
            "G", "g", "X", "y", "Z", "I", "j", "K", "R", "F", "f", "N", "M", "A",
        ];
        let numbers = [
            "0",
            "1",
            "2",
            "3",
            "4",
            "01",
            "1.",
            ".5",
            "-0.25",
            "+3",
            "--1",
            "1.0",
            "2.5",
            "0.8000",
            "-12.3456",
            "123456789012345",
            "1234567890123456",
            ".",
            "",
            " 1",
        ];
        let seps = ["", " ", "  ", "\t", "\r"];
        let mut next = xorshift(0x2545_f491_4f6c_dd1du64);
        let mut taken = 0;
        for _ in 0..20_000 {
            let mut line = String::new();
            for _ in 0..1 + next(5) {
                line += seps[next(seps.len())];
                line += letters[next(letters.len())];
                line += numbers[next(numbers.len())];
            }
            line += seps[next(seps.len())];
            taken += usize::from(same_as_general(&it, &line));
        }
        assert!(taken > 1000, "only {taken} lines took the short way");
    }

    /// A random program of motion lines among mode changes, tool changes, XY
    /// rotations, inverse time, comments and (rarely) lines that fail: read with the
    /// short way and read with every line the general way, the results (motions,
    /// warnings, end state, parameters, or the error) are the same.
    #[allow(clippy::too_many_lines)]
    #[test]
    fn programs_read_the_short_way_as_the_general_way() {
        let p = profile();
        let modes = [
            "G17",
            "G18",
            "G19",
            "G20",
            "G21",
            "G61",
            "G64 P0.1",
            "M6 T1",
            "M6 T2",
            "M3 S1000",
            "M5",
            "G10 L2 P1 R30",
            "G10 L2 P1 R0",
            "G10 L2 P1 X1 Y2",
            "G43 H1",
            "G49",
            "G92 X1",
            "G92.1",
            "(a comment)",
            "",
            "F600",
            "N10 G1 X1",
            "g1 x2 y3",
            "G90.1",
            "G91.1",
            "G91",
            "G90",
            "G4 P0.5",
            "M0",
            "G54",
            "G55",
        ];
        let failing = [
            "F0",
            "G1 X1 X2",
            "G2 X5",
            "R1",
            "G1 X1 F-1",
            "I1",
            "G2 X1 Y2 R0.1",
            "G0 X#1",
            "G1 K1",
            "G2 I1 J1 K1",
            "G3 X1 Y1 I0 J0",
        ];
        let values = [
            "0", "1", "2", "-1", "0.5", "-0.5", "0.25", "1.5", "10", "-2.5", ".75", "1.", "0.0001",
            "100", "0.8000", "-12.3456", "+3",
        ];
        let mut next = xorshift(0x9e37_79b9_7f4a_7c15u64);
        let (mut fast_lines, mut total, mut read_whole, mut motions) = (0, 0, 0, 0);
        for _ in 0..1000 {
            let mut text = String::from("G21 G90 G17 F1000\n");
            // the plane's axes and centre letters, as the program selects them
            let mut plane = (["X", "Y"], ["I", "J"]);
            for _ in 0..next(150) + 5 {
                let line = match next(100) {
                    0 => failing[next(failing.len())].to_string(),
                    1..=10 => {
                        let m = modes[next(modes.len())];
                        match m {
                            "G17" => plane = (["X", "Y"], ["I", "J"]),
                            "G18" => plane = (["Z", "X"], ["K", "I"]),
                            "G19" => plane = (["Y", "Z"], ["J", "K"]),
                            _ => {}
                        }
                        m.to_string()
                    }
                    11..=13 => format!(
                        "G93\nG1 X{} F{}\nG2 {}1 {}0 F2\nG94 F1000",
                        values[next(values.len())],
                        ["2", "0.5", "10"][next(3)],
                        plane.1[0],
                        plane.1[1]
                    ),
                    14..=30 => {
                        // a whole circle (ends where it starts), a helix with Z
                        let mut l = format!(
                            "{} {}{} {}{}",
                            ["G2", "G3"][next(2)],
                            plane.1[0],
                            values[next(values.len())],
                            plane.1[1],
                            values[next(values.len())]
                        );
                        if next(3) == 0 {
                            l += &format!(" Z{}", values[next(values.len())]);
                        }
                        if next(4) == 0 {
                            l += &format!(" F{}", ["100", "2000", "0.5"][next(3)]);
                        }
                        if next(10) == 0 {
                            l += " P2";
                        }
                        l
                    }
                    31..=40 => format!(
                        "G91\n{} {}{} {}{} R{}\nG90",
                        ["G2", "G3"][next(2)],
                        plane.0[0],
                        ["1", "-1", "0.5"][next(3)],
                        plane.0[1],
                        ["0", "1", "-0.25"][next(3)],
                        ["1", "-1", "2", "5"][next(4)]
                    ),
                    _ => {
                        let mut l = ["G0 ", "G1 ", "G01 ", "g0", "N20 G1 "][next(5)].to_string();
                        let axes = 1 + next(7); // a non-empty set of X, Y, Z
                        for (a, letter) in [["X", "x"], ["Y", "y"], ["Z", "z"]].iter().enumerate() {
                            if axes & (1 << a) != 0 {
                                l += letter[next(2)];
                                l += values[next(values.len())];
                                l += [" ", "", "\t", "  "][next(4)];
                            }
                        }
                        if next(5) == 0 {
                            l += &format!("F{}", ["600", "1200.5", "30"][next(3)]);
                        }
                        l
                    }
                };
                text += &line;
                text += "\n";
            }
            text += "M2\n";
            // every fourth program run from a line (motions before it left out)
            let options = crate::ReadOptions {
                from_line: (next(4) == 0).then(|| next(20) as u32 + 2),
                ..Default::default()
            };
            let read = |fast: bool| {
                let mut motions = Vec::new();
                let read = super::super::read_lines(
                    &text,
                    "t.ngc",
                    p.tables(),
                    &options,
                    7,
                    &mut |chunk| motions.append(chunk),
                    fast,
                );
                (read.is_ok(), motions.len(), format!("{read:?} {motions:?}"))
            };
            let (short, general) = (read(true), read(false));
            assert_eq!(short, general, "{text}");
            read_whole += usize::from(short.0);
            motions += short.1;
            let mut w = Words::default();
            for line in text.lines() {
                total += 1;
                fast_lines += usize::from(words(line.as_bytes(), 0, &mut w).is_some());
            }
        }
        eprintln!(
            "{read_whole} programs read whole, {motions} motions, {fast_lines} of {total} lines of the short way's shape"
        );
        assert!(fast_lines * 2 > total, "{fast_lines} of {total} lines");
        assert!(
            read_whole > 100 && motions > 10_000,
            "{read_whole} read whole, {motions} motions"
        );
    }

    /// Every G code (G0 to G99.9 by tenths) and M code (M0 to M199) the general
    /// reader accepts, alone or with words, in a program of lines of the short
    /// way's shape after it (bare axis words, arcs by centre, motions), and random
    /// pairs of them: each program reads the same with the short way as without it.
    /// The codes are found, not listed: a mode the language gains later (a canned
    /// cycle, cutter compensation, feed per revolution) is tried here as it lands,
    /// and the short way must step aside for it or read the lines as the general
    /// reader does.
    #[test]
    fn every_modal_code_then_short_lines_reads_as_the_general_way() {
        let p = profile();
        // bare axis words in the mode the code left, then motions: lines and a
        // rapid, or also two half circles by centre in XY (the second with the
        // mode's bare words)
        let tails = [
            "X3 Y3\nX4 Z-2\nG1 X5 Y3\nX6\nG0 X1\nZ3\n",
            "X3 Y3\nX4 Z-2\nG1 X5 Y3\nG2 X6 Y3 I0.5 J0\nX7 I0.5 J0\nG1 Y6\nX8\nG0 X1\nZ3\n",
        ];
        let read = |text: &str, fast: bool| {
            let mut motions = Vec::new();
            let read = super::super::read_lines(
                text,
                "t.ngc",
                p.tables(),
                &Default::default(),
                7,
                &mut |chunk| motions.append(chunk),
                fast,
            );
            (read.is_ok(), format!("{read:?} {motions:?}"))
        };
        // whether the program of `code` then each tail reads the same both ways
        // (an error included: the same error after the same motions), and whether
        // one of them reads whole
        let same = |code: &str| {
            let mut whole = false;
            for tail in tails {
                let text = format!("G21 G90 G17 F600\nG0 X1 Y1 Z1\n{code}\n{tail}M2\n");
                let (short, general) = (read(&text, true), read(&text, false));
                assert_eq!(short, general, "{text}");
                whole |= short.0;
            }
            whole
        };
        let g = (0..1000).map(|k| {
            if k % 10 == 0 {
                format!("G{}", k / 10)
            } else {
                format!("G{}.{}", k / 10, k % 10)
            }
        });
        let m = (0..200).map(|k| format!("M{k}"));
        let mut accepted = Vec::new();
        for code in g.chain(m) {
            for line in [
                code.clone(),
                format!("{code} X2 Y2 Z-1 R2 F300"),
                format!("{code} X2 Y2 Z-1 R2 P1 Q0.5 L1 F300"),
                format!("{code} P1"),
            ] {
                if same(&line) {
                    accepted.push(line);
                }
            }
        }
        // the core's modes (planes, units, distance modes, feed modes, path
        // control, offsets, spindle, coolant, ...) are among them
        assert!(
            accepted.len() > 50,
            "only {} codes read: {accepted:?}",
            accepted.len()
        );
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        for _ in 0..3000 {
            let a = &accepted[next(accepted.len())];
            let b = &accepted[next(accepted.len())];
            same(&format!("{a}\n{b}"));
        }
    }

    /// Every combination of the modal groups' states (plane, distance mode, unit,
    /// canned-cycle retract, path mode, feed mode, spindle, cutter compensation)
    /// with every motion mode —
    /// G0 to G3, G80 and each canned cycle with its words — then lines of the short
    /// way's shape (bare axis words, which a cycle runs as another hole, motion
    /// codes, arcs): each program reads the same, motions, state and errors, with
    /// the short way and without it. The short way runs G0–G3 only: in any other
    /// motion mode, or in a series of cycles, it must leave the lines to the general
    /// reader (and its debug cross-check would catch a line read otherwise); while
    /// cutter compensation is on, and until the move after its exit, it leaves
    /// every line to the general reader.
    #[test]
    fn every_modal_state_then_short_lines_reads_as_the_general_way() {
        let p = profile();
        let tails = [
            "X3 Y3\nX4 Z-2\nG1 X5 Y3\nX6\nG0 X1\nZ3\n",
            "X3 Y3 Z-3\nY4\nG1 Y6 F500\nX8\nG81 X2 Y2 Z-1 R2 F400\nX3\nY2 R3\nG0 Z3\nX1\n",
            "X3 Y3\nX8 Y2\nG40 G1 X5 Y3\nX6\nG2 X7 Y3 I0.5 J0\nG1 X9\nG0 X1\nZ3\n",
        ];
        let groups: [&[&str]; 8] = [
            &["G17", "G18", "G19"],
            &["G90", "G91"],
            &["G21", "G20"],
            &["G99", "G98"],
            &["G64", "G61", "G64 P0.1 Q0.05"],
            &["G94 F600", "G93"],
            &["M3 S1000", "M4 S500", "M5"],
            // last: with compensation on, the groups before it could not change
            &["G40", "G41 D1", "G42.1 D2"],
        ];
        let motions = [
            "G0 X1",
            "G1 X1 F300",
            "G1 X6 Y-2 F300",
            "G2 X2 Y1 Z1 R2 F300",
            "G80",
            "G81 X1 Y1 Z-1 R5 F300",
            "G81 X1 Y1 Z-1 R5 L3 F300",
            "G82 X1 Y1 Z-1 R5 P0.5 F300",
            "G83 X1 Y1 Z-1 R5 Q0.4 F300",
            "G73 X1 Y1 Z-1 R5 Q0.4 F300",
            "G84 X1 Y1 Z-1 R5 F300",
            "G74 X1 Y1 Z-1 R5 F300",
            "G85 X1 Y1 Z-1 R5 F300",
            "G86 X1 Y1 Z-1 R5 P0.2 F300",
            "G87 X1 Y1 Z-1 R5 I0.5 J0.5 K-0.5 F300",
            "G89 X1 Y1 Z-1 R5 P0.2 F300",
        ];
        let read = |text: &str, fast: bool| {
            let mut motions = Vec::new();
            let read = super::super::read_lines(
                text,
                "t.ngc",
                p.tables(),
                &Default::default(),
                7,
                &mut |chunk| motions.append(chunk),
                fast,
            );
            (read.is_ok(), motions.len(), format!("{read:?} {motions:?}"))
        };
        let (mut programs, mut whole, mut cycles_whole, mut moved) = (0, 0, 0, 0);
        // the programs of the states and motions before compensation was added
        let (mut before, mut before_whole, mut comp_whole) = (0, 0, 0);
        let total: usize = groups.iter().map(|g| g.len()).product();
        for k in 0..total {
            // the k-th combination of one state per group
            let mut rest = k;
            let mut modes = String::new();
            for g in groups {
                modes += g[rest % g.len()];
                modes += "\n";
                rest /= g.len();
            }
            for motion in motions {
                for tail in tails {
                    let text =
                        format!("G21 G90 G17 F600\nG0 X1 Y1 Z1\n{modes}{motion}\n{tail}M2\n");
                    let (short, general) = (read(&text, true), read(&text, false));
                    assert_eq!(short, general, "{text}");
                    programs += 1;
                    whole += usize::from(short.0);
                    moved += short.1;
                    if short.0 && !motion.starts_with("G0") && motion.contains('R') {
                        cycles_whole += 1;
                    }
                    if short.0 && modes.contains("G4") && !modes.contains("G40") {
                        comp_whole += 1;
                    }
                    if modes.contains("G40") && !tail.contains("G40") && motion != "G1 X6 Y-2 F300"
                    {
                        before += 1;
                        before_whole += usize::from(short.0);
                    }
                }
            }
        }
        eprintln!("{programs} programs, {whole} read whole ({cycles_whole} with a cycle, {comp_whole} with compensation), {moved} motions");
        // the states are reached: many programs read whole, cycles among them
        assert!(
            before_whole > before / 5,
            "{before_whole} of {before} read whole ({whole} of {programs} in all)"
        );
        assert!(
            cycles_whole > 500,
            "{cycles_whole} programs with a cycle read whole"
        );
        assert!(
            comp_whole > 400,
            "{comp_whole} programs with compensation read whole"
        );
    }

    /// A random double of every kind the arcs meet: small integers and halves,
    /// CAM-like decimals, values of any exponent, signed zeros, and neighbours
    /// (a few units in the last place away) of each.
    fn any_value(next: &mut impl FnMut(usize) -> usize) -> f64 {
        let v = match next(6) {
            0 => (next(41) as f64 - 20.0) / 4.0,
            1 => (next(2_000_001) as f64 - 1e6) / 1e4,
            2 => f64::from_bits(((next(1 << 30) as u64) << 34) | next(1 << 30) as u64),
            3 => [0.0, -0.0, 0.25, -0.25, 0.5, 1e-300, 1e300][next(7)],
            _ => (next(20_001) as f64 - 1e4) / 1e3,
        };
        if next(3) == 0 {
            f64::from_bits(v.to_bits().wrapping_add(next(9) as u64).wrapping_sub(4))
        } else {
            v
        }
    }

    /// `arc_ijk` and `arc_r` against `arc_data_ijk` and `arc_data_r` (the centre's
    /// bits, the turns, or an error) on 300,000 arcs each: chords along the axes and
    /// not, half circles and radii at the tolerances' edges, centres off by a few
    /// units in the last place, mm and inch tolerances, one `Trig` for them all.
    #[test]
    fn arcs_the_short_way_as_arc_data() {
        use super::super::{arc_data_ijk, arc_data_r};
        use super::{
            arc_ijk, arc_r, Trig, CENTER_ARC_RADIUS_TOLERANCE_INCH, CENTER_ARC_RADIUS_TOLERANCE_MM,
            G_2, G_3, RADIUS_TOLERANCE_INCH, RADIUS_TOLERANCE_MM, TINY,
        };
        let mut next = xorshift(0x1f83_d9ab_fb41_bd6bu64);
        let bits = |r: Result<(f64, f64, i32), String>| {
            r.ok().map(|(x, y, t)| (x.to_bits(), y.to_bits(), t))
        };
        let fast_bits =
            |r: Option<(f64, f64, i32)>| r.map(|(x, y, t)| (x.to_bits(), y.to_bits(), t));
        let mut trig = Trig::default();
        let (mut ok_ijk, mut ok_r) = (0, 0);
        for _ in 0..300_000 {
            let mode = [G_2, G_3][next(2)];
            let inch = next(4) == 0;
            let (rtol, stol) = if inch {
                (RADIUS_TOLERANCE_INCH, CENTER_ARC_RADIUS_TOLERANCE_INCH)
            } else {
                (RADIUS_TOLERANCE_MM, CENTER_ARC_RADIUS_TOLERANCE_MM)
            };
            let cur = (any_value(&mut next), any_value(&mut next));
            // a centre offset, and an end at the same radius (or off it by a
            // little, by about the tolerances, or anywhere)
            let ij = (any_value(&mut next), any_value(&mut next));
            let (cx, cy) = (cur.0 + ij.0, cur.1 + ij.1);
            let r = ij.0.hypot(ij.1);
            let turn = (next(3600) as f64).to_radians();
            let dr = match next(5) {
                0 => 0.0,
                1 => {
                    stol * [
                        1.0,
                        -1.0,
                        100.0,
                        -100.0,
                        0.999_999_999_999,
                        1.000_000_000_001,
                    ][next(6)]
                }
                2 => rtol * [1.0, 0.5, 2.0][next(3)] - r,
                3 => any_value(&mut next) * 1e-3,
                _ => any_value(&mut next),
            };
            let mut end = (cx + (r + dr) * turn.cos(), cy + (r + dr) * turn.sin());
            match next(4) {
                0 => end.1 = cur.1, // a chord along X
                1 => end.0 = cur.0, // along Y
                _ => {}
            }
            if next(10) == 0 {
                end = cur;
            }
            let absolute = next(5) == 0;
            let ijv = if absolute { (cx, cy) } else { ij };
            let names = ['X', 'Y'];
            let want = bits(arc_data_ijk(
                mode, cur, end, absolute, ijv, 1, rtol, stol, names,
            ));
            let got = fast_bits(arc_ijk(mode, cur, end, absolute, ijv, rtol, stol, names));
            assert_eq!(
                got, want,
                "ijk {mode} {cur:?} {end:?} {absolute} {ijv:?} {inch}"
            );
            ok_ijk += usize::from(want.is_some());
            // a radius of half the chord (give or take the tolerances and TINY),
            // or any
            let half = (end.0 - cur.0).hypot(end.1 - cur.1) / 2.0;
            let radius = match next(6) {
                0 => half,
                1 => half * (1.0 - TINY * [0.25, 0.5, 0.75, 1.0, 1.5, 4.0][next(6)]),
                2 => half - rtol * [0.5, 1.0, 1.5][next(3)],
                3 => f64::from_bits(
                    half.to_bits()
                        .wrapping_add(next(65) as u64)
                        .wrapping_sub(32),
                ),
                4 => half * (1.0 + any_value(&mut next).abs()),
                _ => any_value(&mut next),
            } * [1.0, -1.0][next(2)];
            let want = bits(arc_data_r(mode, cur, end, radius, 1, rtol));
            let got = fast_bits(arc_r(mode, cur, end, radius, rtol, &mut trig));
            assert_eq!(got, want, "r {mode} {cur:?} {end:?} {radius:e}");
            ok_r += usize::from(want.is_some());
        }
        assert!(
            ok_ijk > 50_000 && ok_r > 50_000,
            "{ok_ijk} {ok_r} arcs without error"
        );
    }

    /// `arc_r` against `arc_data_r` where the chord is shorter than the radius
    /// tolerance and the radius is zero, subnormal or about half the chord: the
    /// short way's ratio of 1 (taken without dividing) must not hide the 0 / 0 of
    /// a zero radius.
    #[test]
    fn arcs_of_tiny_chords_and_zero_radii_as_arc_data_r() {
        use super::super::arc_data_r;
        use super::{arc_r, Trig, G_2, G_3, RADIUS_TOLERANCE_INCH, RADIUS_TOLERANCE_MM};
        let mut next = xorshift(0x5be0_cd19_137e_2179u64);
        let mut trig = Trig::default();
        let mut zero_radius = 0;
        for _ in 0..100_000 {
            let mode = [G_2, G_3][next(2)];
            let tol = [RADIUS_TOLERANCE_MM, RADIUS_TOLERANCE_INCH][next(2)];
            let cur = (any_value(&mut next), any_value(&mut next));
            let d = tol * [0.0, 1e-300, 1e-9, 0.1, 0.5, 1.0, 1.9, 2.0, 2.1][next(9)];
            let end = match next(3) {
                0 => (cur.0 + d, cur.1),
                1 => (cur.0, cur.1 - d),
                _ => (cur.0 + d, cur.1 + d),
            };
            let half = (end.0 - cur.0).hypot(end.1 - cur.1) / 2.0;
            let radius = [0.0, -0.0, 5e-324, half, half * 0.5, -half][next(6)];
            zero_radius += usize::from(radius == 0.0);
            let want = arc_data_r(mode, cur, end, radius, 1, tol)
                .ok()
                .map(|(x, y, t)| (x.to_bits(), y.to_bits(), t));
            let got = arc_r(mode, cur, end, radius, tol, &mut trig)
                .map(|(x, y, t)| (x.to_bits(), y.to_bits(), t));
            assert_eq!(got, want, "{mode} {cur:?} {end:?} {radius:e}");
        }
        assert!(zero_radius > 20_000, "{zero_radius} zero radii");
    }
}
