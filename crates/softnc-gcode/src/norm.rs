//! A line as LinuxCNC's `close_and_downcase` leaves it ([`Norm`]): white space outside
//! comments removed, letters outside comments in lower case, each byte's offset in
//! the raw line kept for columns in messages; and, for a line kept to be read again
//! (a loop's or subroutine's), what is compiled and remembered of it
//! ([`crate::compiled`]) so later passes read it without walking the text again.

use crate::compiled::{Code, Kind, Plan};

/// A label qualified on a kept line: the label's offset, the subroutine it was
/// read in and the qualified name (`sub#label`).
pub type Qualified = (usize, std::rc::Rc<str>, std::rc::Rc<str>);

/// A kept O-line's head ([`Norm::o_head`]): its label, the offset after the
/// label, and the index of its keyword in the O-line reader's table.
pub type OHead = (std::rc::Rc<str>, usize, Option<u8>);

/// A line as `close_and_downcase` leaves it, with the byte offset in the raw line of
/// each byte (for columns in messages).
#[derive(Debug, Default, Clone)]
pub struct Norm {
    /// The normalized bytes.
    pub b: Vec<u8>,
    /// `at[i]`: offset in the raw line of `b[i]`; one more entry for the end.
    pub at: Vec<u32>,
    /// Whether the line is kept to be read again (a line of a loop or subroutine):
    /// its values are then compiled once, into `code`, and evaluated on each pass.
    pub keep: bool,
    /// The values compiled so far: offset where each starts, how it is read, and its
    /// code (`None`: it does not compile and is read from the text).
    pub code: std::cell::RefCell<Vec<(usize, Kind, Option<Code>)>>,
    /// For a kept line: the names read so far (parameter names of assignments,
    /// O-word labels), by the offset where each starts, with the offset after it,
    /// so that later passes neither scan nor allocate them again.
    pub names: std::cell::RefCell<Vec<(usize, usize, std::rc::Rc<str>)>>,
    /// For a kept line: O-word labels qualified with the subroutine they were read
    /// in (`sub#label`), by label offset and subroutine name.
    pub qualified: std::cell::RefCell<Vec<Qualified>>,
    /// For a kept line: the parameter slot ([`crate::params::Params::slot`]) of
    /// the name assigned at an offset, once it has one.
    pub slots: std::cell::RefCell<Vec<(usize, u32)>>,
    /// For a kept O-line whose label is remembered in `names`: the label, the
    /// offset after it, and the index of the keyword after it in the O-line
    /// reader's table (`None`: no keyword) — all fixed by the text, so later
    /// passes neither look the label up nor compare keywords again.
    pub o_head: std::cell::RefCell<Option<OHead>>,
    /// For a kept line of words, assignments and comments: its items compiled
    /// whole the first time it reads without error, so that later passes
    /// evaluate them in order without walking the text again.
    pub plan: std::cell::RefCell<Plan>,
}

impl Norm {
    /// Normalize `raw` (the significant part of a line, comments already checked to
    /// close): spaces, tabs and CRs outside comments dropped, letters outside
    /// comments lowered. Buffers are reused.
    pub fn build(&mut self, raw: &[u8]) {
        self.b.clear();
        self.at.clear();
        self.keep = false;
        self.code.get_mut().clear();
        self.names.get_mut().clear();
        self.qualified.get_mut().clear();
        self.slots.get_mut().clear();
        *self.o_head.get_mut() = None;
        *self.plan.get_mut() = Plan::Unread;
        self.b.reserve(raw.len());
        self.at.reserve(raw.len() + 1);
        let mut in_comment = false;
        for (i, &c) in raw.iter().enumerate() {
            if in_comment {
                self.b.push(c);
                self.at.push(i as u32);
                if c == b')' {
                    in_comment = false;
                }
                continue;
            }
            match c {
                b' ' | b'\t' | b'\r' => continue,
                b'(' => in_comment = true,
                b';' => {
                    // the rest is a comment: kept as written
                    for (j, &d) in raw.iter().enumerate().skip(i) {
                        self.b.push(d);
                        self.at.push(j as u32);
                    }
                    break;
                }
                _ => {}
            }
            self.b.push(c.to_ascii_lowercase());
            self.at.push(i as u32);
        }
        self.at.push(raw.len() as u32);
    }

    /// Raw offset of normalized offset `i`.
    pub fn raw(&self, i: usize) -> u32 {
        self.at
            .get(i)
            .or(self.at.last())
            .copied()
            .unwrap_or_default()
    }
}
