//! The language around the words: lines with parameters and expressions (LinuxCNC's
//! `read_items` / `read_one_item` / `read_parameter_setting` on a normalized line),
//! O-lines (`read_o`) and their control flow (`convert_control_functions`,
//! `execute_call`, `execute_return`, `control_back_to` in `interp_o_word.cc`).
//!
//! The program is read with a program counter (file, byte offset, line number):
//! loops and calls jump back to the O-line they recorded, skips read forward and
//! look only at O-lines, as LinuxCNC does.

use super::{bad, Block, Interp, R};
use crate::compiled::{Code, Item, Kind, OPlan, Plan};
use crate::error::ErrorKind;
use crate::expr::{Env, Reader};
use crate::lexer::{bad_character, check_comments, significant, Line, Word};
use crate::norm::Norm;
use crate::oword::OKind;
use crate::params::{is_readonly, NUM_PARAMS, SUB_PARAMS};

/// A parameter name or an O-word label as read: shared, so that a kept line's
/// names are read once and passing them on (frames, labels, skips) allocates
/// nothing.
pub type Name = std::rc::Rc<str>;

/// LinuxCNC `INTERP_SUB_ROUTINE_LEVELS`: calls nest at most this deep.
pub const MAX_CALL_LEVEL: usize = 10;

/// The O-word keywords and what each does, in LinuxCNC's order of comparison
/// (`read_o`: "elseif" before "else").
const O_KEYWORDS: [(&[u8], OKind); 15] = [
    (b"sub", OKind::Sub),
    (b"endsub", OKind::EndSub),
    (b"call", OKind::Call),
    (b"do", OKind::Do),
    (b"while", OKind::While),
    (b"repeat", OKind::Repeat),
    (b"if", OKind::If),
    (b"elseif", OKind::ElseIf),
    (b"else", OKind::Else),
    (b"endif", OKind::EndIf),
    (b"break", OKind::Break),
    (b"continue", OKind::Continue),
    (b"endwhile", OKind::EndWhile),
    (b"endrepeat", OKind::EndRepeat),
    (b"return", OKind::Return),
];

/// An O-line as read.
#[derive(Debug, Clone)]
pub struct OLine {
    /// What it does.
    pub kind: OKind,
    /// Its label, qualified as LinuxCNC does (`sub#label` for local labels).
    pub name: Name,
    /// Condition, repeat count or return value, where given and evaluated.
    pub value: Option<f64>,
    /// Raw byte offset of the `o`.
    pub at: u32,
    /// M98: the L word (repeats), if given.
    pub repeat: Option<f64>,
}

/// Where a label was seen (LinuxCNC `offset_struct`).
#[derive(Debug, Clone)]
struct Label {
    kind: OKind,
    file: usize,
    pos: usize,
    line_no: usize,
    repeat_count: i64,
}

/// What [`Interp::read_head`] read.
enum Head {
    /// An O-line (or none, skipped): nothing more on the line is read.
    Done(Option<OLine>),
    /// The words start at this offset.
    Items(usize),
}

/// One call level (LinuxCNC `context`).
#[derive(Debug, Clone)]
struct Frame {
    sub_name: Name,
    /// Where to go on return: file, byte offset of the line after the call, and
    /// the call's line number.
    ret: (usize, usize, usize),
    /// Called with M98 (Fanuc style: ends with M99, `#1…#30` passed on).
    m98: bool,
}

/// Control-flow state (the `skipping_o`, `defining_sub`, … of LinuxCNC's setup).
#[derive(Debug, Default)]
pub struct Control {
    /// Labels by [`label_key`] of their (interned) name.
    labels: std::collections::HashMap<u64, Label, std::hash::BuildHasherDefault<super::KeyHasher>>,
    /// Every label and parameter name read, once ([`Interp::intern`]): equal
    /// names are one [`Name`], so a label is found by its name's address (one
    /// multiplication, no hashing of its text).
    names: std::cell::RefCell<
        std::collections::HashSet<Name, std::hash::BuildHasherDefault<crate::params::Fnv>>,
    >,
    frames: Vec<Frame>,
    /// M98 L repeats left, per call level of the caller (-1: none running).
    m98_loops: Vec<i64>,
    /// M70/M73 state saved per call level, and whether M73 restores it on return.
    pub(super) saved_modal: Vec<(Option<super::modal::Modal>, bool)>,
    /// Skipping forward to this label.
    pub skipping: Option<Name>,
    /// Skipping forward to this subroutine's `sub` line (a call).
    skipping_to_sub: Option<Name>,
    /// Line where the skip started (messages).
    pub skipping_start: usize,
    /// A subroutine definition is being skipped at level 0.
    pub defining_sub: bool,
    sub_name: Option<Name>,
    executed_if: bool,
    doing_break: bool,
    doing_continue: bool,
    /// `_value` and `_value_returned`.
    pub return_value: f64,
    /// Whether the last return gave a value.
    pub value_returned: bool,
}

impl Control {
    /// Call level (0: main program).
    pub fn level(&self) -> usize {
        self.frames.len()
    }
}

/// Where the reader goes next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Jump {
    /// The next line.
    Next,
    /// File, byte offset of a line, its line number.
    To(usize, usize, usize),
    /// Open the subroutine file for this call (its name), then skip to its `sub`.
    OpenSub,
    /// A lone `%` while skipping: LinuxCNC's end of file, an error.
    Percent,
}

/// Where the reader is (the interpreter's view of the program counter).
#[derive(Debug, Clone, Copy)]
pub struct Pc {
    /// File index (0: the main program).
    pub file: usize,
    /// Byte offset of the current line's start.
    pub pos: usize,
    /// Byte offset of the next line's start.
    pub next: usize,
    /// 1-based number of the current line.
    pub line_no: usize,
}

impl Env for Interp<'_> {
    fn numbered(&self, index: usize) -> f64 {
        // parameters LinuxCNC keeps up to date from its state: the tool in the
        // spindle (5400, its length 5403, user units) and, as each line is read, the
        // current point (5420-5422, program units)
        match index {
            5400 => f64::from(self.tool_loaded),
            5403 => self.spindle_length_mm / if self.user_inch { 25.4 } else { 1.0 },
            5420..=5428 if self.comp.on() => {
                // LinuxCNC refuses the read (`read_parameter`): the line fails
                self.position_read_in_comp.set(true);
                if index <= 5422 {
                    self.pos[index - 5420]
                } else {
                    self.params.get(index)
                }
            }
            5420..=5422 => self.pos[index - 5420],
            5399 => {
                if self.m66_unknown_since.is_some() {
                    self.m66_read.set(true);
                }
                self.params.get(index)
            }
            _ => self.params.get(index),
        }
    }
    fn named(&self, name: &str) -> Result<Option<f64>, ErrorKind> {
        if let Some(v) = self.params.named(name) {
            return Ok(Some(v));
        }
        if name.starts_with('_') {
            if let Some(v) = self.predefined(name)? {
                return Ok(Some(v));
            }
        }
        // assigned earlier on this line: it exists, with the value 0 (see
        // `read_items_slow`)
        if self
            .line_named
            .borrow()
            .split_terminator('>')
            .any(|n| n == name)
        {
            return Ok(Some(0.0));
        }
        Ok(None)
    }
    fn defining_sub(&self) -> bool {
        self.ctl.defining_sub
    }
    fn named_slot(&self, name: &str) -> Option<u32> {
        self.params.slot(name)
    }
    fn slot_value(&self, slot: u32) -> Option<f64> {
        self.params.slot_value(slot)
    }
}

/// An assignment read on a line.
pub enum Setting {
    /// `#n=…`
    Numbered(usize, f64),
    /// `#<name>=…` where the name has no parameter slot yet.
    Named(Name, f64),
    /// `#<name>=…` by the name's parameter slot ([`crate::params::Params::set_slot`]): no name
    /// carried (nor its reference count touched).
    Slot(u32, f64),
}

impl Interp<'_> {
    /// LinuxCNC's read-only predefined named parameters (`init_named_parameters`),
    /// those whose meaning softnc builds; the others are refused as unsupported.
    fn predefined(&self, name: &str) -> Result<Option<f64>, ErrorKind> {
        let b = |x: bool| Some(if x { 1.0 } else { 0.0 });
        let v = match name {
            "_line" => Some(self.line_no as f64),
            "_motion_mode" => Some(f64::from(self.motion.unwrap_or(800))),
            "_plane" => Some(match self.plane {
                softnc_core::Plane::XY => 170.0,
                softnc_core::Plane::XZ => 180.0,
                softnc_core::Plane::YZ => 190.0,
            }),
            "_ccomp" => Some(f64::from(self.comp.code())),
            "_metric" => b(!self.inch),
            "_imperial" => b(self.inch),
            "_absolute" => b(self.absolute),
            "_incremental" => b(!self.absolute),
            "_inverse_time" => b(self.inverse_time),
            "_units_per_minute" => b(!self.inverse_time),
            "_units_per_rev" => b(false),
            "_coord_system" => Some(if self.coord < 6 {
                530.0 + 10.0 * (self.coord + 1) as f64
            } else {
                584.0 + (self.coord + 1) as f64
            }),
            "_tool_offset" => b(self.tool_length_mm != 0.0),
            "_spindle_rpm_mode" => b(true),
            "_spindle_css_mode" => b(false),
            "_ijk_absolute_mode" => b(self.ijk_absolute),
            "_lathe_diameter_mode" => b(false),
            "_lathe_radius_mode" => b(true),
            "_spindle_on" => b(self.spindle_on),
            "_spindle_cw" => b(self.spindle_on && self.spindle_code == 3),
            "_mist" => b(self.mist),
            "_flood" => b(self.flood),
            "_current_tool" => Some(f64::from(self.tool_loaded)),
            "_abs_x" | "_abs_y" | "_abs_z" => {
                // the machine position: through G92, the XY rotation, the origin
                // and the tool length (interp_namedparams.cc, NP_ABS_X …)
                let k = usize::from(name.as_bytes()[5] - b'x');
                let g = self.g92;
                let (x, y) =
                    super::rotate(self.pos[0] + g[0], self.pos[1] + g[1], self.rotation_deg);
                let v = [
                    x,
                    y,
                    self.pos[2] + g[2] + self.tool_length_mm / self.scale(),
                ];
                Some(v[k] + self.origin[k])
            }
            "_abs_a" | "_abs_b" | "_abs_c" | "_abs_u" | "_abs_v" | "_abs_w" => Some(0.0),
            "_feed" => Some(self.feed),
            "_rpm" => Some(self.s_rpm),
            "_x" => Some(self.pos[0]),
            "_y" => Some(self.pos[1]),
            "_z" => Some(self.pos[2]),
            "_a" | "_b" | "_c" | "_u" | "_v" | "_w" => Some(0.0),
            "_selected_tool" => Some(f64::from(self.tool_selected)),
            "_value" => Some(self.ctl.return_value),
            "_value_returned" => b(self.ctl.value_returned),
            "_call_level" => Some(self.ctl.level() as f64),
            "_remap_level" => Some(0.0),
            "_task" => Some(0.0),
            "_retract_r_plane" => b(!self.retract_old_z),
            "_retract_old_z" => b(self.retract_old_z),
            "_control_mode" | "_speed_override" | "_feed_override" | "_adaptive_feed"
            | "_feed_hold" | "_current_pocket" | "_selected_pocket" => {
                return Err(ErrorKind::Unsupported {
                    word: format!("#<{name}>"),
                    why: "this predefined parameter is not supported yet".into(),
                })
            }
            _ if name.starts_with("_ini[") || name.starts_with("_hal[") => {
                return Err(ErrorKind::Unsupported {
                    word: format!("#<{name}>"),
                    why: "INI and HAL parameters are not supported".into(),
                })
            }
            _ => None,
        };
        Ok(v)
    }

    /// A line while skipping: only an O-line is read (LinuxCNC's `read_items`
    /// with `skipping_o` set), and run if it is the one looked for.
    #[cold]
    pub(super) fn skip_line(
        &mut self,
        raw: &str,
        norm: &mut Norm,
        block: &mut Block,
        line: &mut Line,
        sets: &mut Vec<Setting>,
        pc: &Pc,
    ) -> R<Jump> {
        let sig = significant(raw.as_bytes());
        // comments are checked and a lone `%` read on every line, as read_text does
        if sig.contains(&b'(') {
            check_comments(sig)?;
        }
        if sig
            .iter()
            .filter(|c| !matches!(c, b' ' | b'\t' | b'\r'))
            .eq(b"%".iter())
        {
            return Ok(Jump::Percent);
        }
        // read_items reads the N word, M98 (its P and L) and M99 and the O-word on
        // every line; a line with none of these letters has nothing to read
        if !sig
            .iter()
            .any(|c| matches!(c.to_ascii_lowercase(), b'o' | b'n' | b'm'))
        {
            return Ok(Jump::Next);
        }
        norm.build(sig);
        block.clear();
        let head = self.read_head(norm, block, line, sets);
        // the assignments of a skipped line are never made
        sets.clear();
        match head? {
            Head::Done(Some(o)) => self.control(&o, pc),
            Head::Done(None) | Head::Items(_) => Ok(Jump::Next),
        }
    }

    /// The value of kind `kind` at `norm.b[i]` and the offset after it: compiled
    /// once and evaluated for a line kept to be read again ([`Norm::keep`]), read
    /// from the text otherwise (and where it does not compile). Errors as the
    /// text reader's, offsets in the normalized line.
    pub(super) fn value(
        &self,
        norm: &Norm,
        i: usize,
        kind: Kind,
    ) -> Result<(f64, usize), crate::expr::ExprError> {
        if norm.keep {
            let mut cache = norm.code.borrow_mut();
            let k = match cache.iter().position(|(s, kd, _)| *s == i && *kd == kind) {
                Some(k) => k,
                None => {
                    cache.push((i, kind, crate::compiled::compile(&norm.b, i, kind)));
                    cache.len() - 1
                }
            };
            if let Some(code) = &cache[k].2 {
                return Ok((crate::compiled::eval(code, self)?, code.end));
            }
        }
        let mut r = Reader::new(&norm.b, i, self);
        let v = match kind {
            Kind::Real => r.real_value()?,
            Kind::Expression => r.expression()?,
            Kind::Integer => f64::from(r.integer_value()?),
        };
        Ok((v, r.i))
    }

    /// A kept O-line compiled whole ([`Plan::O`]) run as [`Self::read_norm`] then
    /// [`Self::control`] would run it, with the read `OLine` built here and lent
    /// to `control` (not moved through `Option`s and `Result`s on its way back to
    /// the reader's loop). `None` where the line is not such a line, or is to be
    /// read from its text (a definition skipped, a label skipped to): read it with
    /// [`Self::read_norm`].
    pub(super) fn run_kept_o(&mut self, norm: &Norm, line: &mut Line, pc: &Pc) -> Option<R<Jump>> {
        if !norm.keep || self.ctl.defining_sub || self.ctl.skipping.is_some() {
            return None;
        }
        let plan = norm.plan.borrow();
        let Plan::O(p) = &*plan else {
            return None;
        };
        // what `read_norm` resets for every line
        line.comment = None;
        self.line_named.get_mut().clear();
        Some(match self.run_o(norm, p) {
            Ok(o) => self.control(&o, pc),
            Err(e) => Err(e),
        })
    }

    /// `read_items` on a normalized line (`Norm`), for a line the fast lexer
    /// hands over; `block` is empty (the caller clears it).
    pub(super) fn read_norm(
        &self,
        norm: &Norm,
        block: &mut Block,
        line: &mut Line,
        sets: &mut Vec<Setting>,
    ) -> R<Option<OLine>> {
        line.comment = None;
        self.line_named.borrow_mut().clear();
        if norm.keep {
            match &*norm.plan.borrow() {
                Plan::Items(items) => {
                    return self
                        .run_items(norm, items, block, line, sets)
                        .map(|()| None)
                }
                // read from the text while a definition is skipped (that line
                // reads differently then)
                Plan::O(o) if !self.ctl.defining_sub && self.ctl.skipping.is_none() => {
                    return self.run_o(norm, o).map(Some)
                }
                _ => {}
            }
        }
        self.read_items_slow(norm, block, line, sets)
    }

    /// [`Self::read_o`] for a kept O-line compiled whole (not skipping, no
    /// definition being skipped): its label and keyword as read before, its values
    /// evaluated, with the same checks and errors.
    fn run_o(&self, norm: &Norm, p: &OPlan) -> R<OLine> {
        let re = |(k, e): (usize, ErrorKind)| (norm.raw(k), e);
        let ctl = &self.ctl;
        let name = if p.kind.global() {
            p.label.clone()
        } else {
            // qualified by the subroutine it runs in, kept for the last one (by its
            // interned name's address, as labels are found; 0: the main program)
            let sub = ctl.frames.last().map(|f| &f.sub_name);
            let key = sub.map_or(0, label_key);
            let last = p
                .qualified
                .borrow()
                .as_ref()
                .filter(|(k, _)| *k == key)
                .map(|(_, q)| q.clone());
            match last {
                Some(q) => q,
                None => {
                    let q = self.qualified(norm, p.label_at, sub.map_or("", |s| s), &p.label);
                    *p.qualified.borrow_mut() = Some((key, q.clone()));
                    q
                }
            }
        };
        let mut o = OLine {
            kind: p.kind,
            name,
            value: None,
            at: p.at,
            repeat: None,
        };
        match p.kind {
            OKind::Sub => {
                if let Some(f) = ctl.frames.last() {
                    if f.sub_name != o.name {
                        return bad(
                            o.at,
                            format!(
                                "Nested subroutine definition: 'O{} sub' found inside called subroutine 'O{}'",
                                o.name, f.sub_name
                            ),
                        );
                    }
                }
            }
            OKind::Call => {
                let mut args = self.call_args.borrow_mut();
                args.clear();
                for code in &p.args {
                    args.push(crate::compiled::eval(code, self).map_err(re)?);
                }
            }
            _ => {
                if let Some(code) = &p.value {
                    o.value = Some(crate::compiled::eval(code, self).map_err(re)?);
                }
            }
        }
        Ok(o)
    }

    /// The head of `read_items`: the block delete slash, the N word, then an O-line
    /// (`o…`, `M98`, `M99` at a call level) read whole, or where the words start.
    /// LinuxCNC reads it on every line, also on one being skipped.
    fn read_head(
        &self,
        norm: &Norm,
        block: &mut Block,
        line: &mut Line,
        sets: &mut Vec<Setting>,
    ) -> R<Head> {
        let b = &norm.b[..];
        let raw = |i: usize| norm.raw(i);
        let mut i = 0;
        if b.first() == Some(&b'/') {
            i += 1;
        }
        if b.get(i) == Some(&b'n') {
            i += 1;
            let s = i;
            while b.get(i).is_some_and(u8::is_ascii_digit) {
                i += 1;
            }
            if i == s {
                return bad(raw(s), "Bad format unsigned integer");
            }
            if b.get(i) == Some(&b'.') {
                i += 1;
                let s = i;
                while b.get(i).is_some_and(u8::is_ascii_digit) {
                    i += 1;
                }
                if i == s {
                    return bad(raw(s), "Bad format unsigned integer");
                }
            }
        }
        if b.get(i) == Some(&b'm') {
            let mut r = Reader::new(b, i + 1, self);
            match r.integer_value() {
                Ok(98) => {
                    return self
                        .read_m98(norm, i, block, line, sets)
                        .map(|o| Head::Done(Some(o)))
                }
                Ok(99) if self.ctl.level() > 0 => {
                    if self.ctl.defining_sub {
                        return bad(raw(i), "Found 'M99' instead of 'O endsub' after 'O sub'");
                    }
                    let name = self
                        .ctl
                        .frames
                        .last()
                        .map_or_else(|| self.intern(""), |f| f.sub_name.clone());
                    return Ok(Head::Done(Some(OLine {
                        kind: OKind::M99,
                        name,
                        value: None,
                        at: raw(i),
                        repeat: None,
                    })));
                }
                _ => {}
            }
        }
        if b.get(i) == Some(&b'o') {
            return self.read_o(norm, &mut i, line).map(Head::Done);
        }
        Ok(Head::Items(i))
    }

    /// `read_items` for a line the fast lexer hands over (parameters, expressions,
    /// O-words): words go into `block` in order, assignments into `sets`, the
    /// comment into `line`. Returns the O-line, if it is one.
    #[allow(clippy::too_many_lines)]
    pub(super) fn read_items_slow(
        &self,
        norm: &Norm,
        block: &mut Block,
        line: &mut Line,
        sets: &mut Vec<Setting>,
    ) -> R<Option<OLine>> {
        let b = &norm.b[..];
        let raw = |i: usize| norm.raw(i);
        let re = |(i, k): (usize, ErrorKind)| (norm.raw(i), k);
        let mut i = match self.read_head(norm, block, line, sets)? {
            Head::Done(o) => return Ok(o),
            Head::Items(i) => i,
        };
        // a kept line read whole the first time: its items are recorded (an `M`
        // first may be M99, which reads as an O-line at a call level: not recorded)
        let recording =
            norm.keep && b.get(i) != Some(&b'm') && matches!(*norm.plan.borrow(), Plan::Unread);
        let mut rec: Option<Vec<Item>> = recording.then(Vec::new);
        while i < b.len() {
            let c = b[i];
            match c {
                b'a'..=b'z' | b'@' | b'^' if c != b'n' && c != b'o' => {
                    let (value, next) = self.value(norm, i + 1, Kind::Real).map_err(re)?;
                    self.sort_word_slow(
                        Word {
                            letter: c.to_ascii_uppercase(),
                            value,
                            offset: raw(i),
                        },
                        block,
                    )?;
                    if rec.is_some() {
                        record(
                            &mut rec,
                            compiled_at(norm, i + 1, Kind::Real).map(|code| Item::Word {
                                letter: c.to_ascii_uppercase(),
                                code,
                                offset: raw(i),
                            }),
                        );
                    }
                    i = next;
                }
                b'#' => {
                    let at = i;
                    let mut r = Reader::new(b, i + 1, self);
                    if r.at(r.i) == b'<' {
                        let (name, next) = self.name_at(norm, r.i).map_err(re)?;
                        r.i = next;
                        // read_named_parameter_setting: LinuxCNC creates the
                        // parameter (value 0) as soon as it reads the name, so the
                        // rest of the line reads it as 0 (add_named_param)
                        {
                            let mut names = self.line_named.borrow_mut();
                            names.push_str(&name);
                            names.push('>');
                        }
                        if r.at(r.i) != b'=' {
                            return bad(raw(r.i), "Equal sign missing in parameter setting");
                        }
                        let next_eq = r.i + 1;
                        let (v, next) = self.value(norm, next_eq, Kind::Real).map_err(re)?;
                        if name.starts_with('_') && self.predefined(&name).ok().flatten().is_some()
                        {
                            return bad(
                                raw(at),
                                format!("Cannot assign to read-only parameter #<{name}>"),
                            );
                        }
                        if rec.is_some() {
                            record(
                                &mut rec,
                                compiled_at(norm, next_eq, Kind::Real).map(|code| Item::Named {
                                    name: name.clone(),
                                    code,
                                    at,
                                    slot: Default::default(),
                                }),
                            );
                        }
                        i = next;
                        sets.push(match self.assigned_slot(norm, at, &name) {
                            Some(k) => Setting::Slot(k, v),
                            None => Setting::Named(name, v),
                        });
                    } else {
                        let index_at = r.i;
                        let (index, next) = self.value(norm, r.i, Kind::Integer).map_err(re)?;
                        r.i = next;
                        let index = index as i32;
                        if index < 1 || index as usize >= NUM_PARAMS {
                            return bad(raw(at), "Parameter number out of range");
                        }
                        if is_readonly(index as usize) {
                            return bad(raw(at), "Parameter is readonly");
                        }
                        if r.at(r.i) != b'=' {
                            return bad(raw(r.i), "Equal sign missing in parameter setting");
                        }
                        let (v, next) = self.value(norm, r.i + 1, Kind::Real).map_err(re)?;
                        if rec.is_some() {
                            let index = compiled_at(norm, index_at, Kind::Integer);
                            let code = compiled_at(norm, r.i + 1, Kind::Real);
                            record(
                                &mut rec,
                                index.zip(code).map(|(index, code)| Item::Numbered {
                                    index,
                                    code,
                                    at,
                                }),
                            );
                        }
                        i = next;
                        sets.push(Setting::Numbered(index as usize, v));
                    }
                }
                b'(' => {
                    let end = b[i..]
                        .iter()
                        .position(|&x| x == b')')
                        .map_or(b.len(), |k| i + k);
                    line.comment = Some((raw(i) + 1, raw(end)));
                    line.comment_offset = raw(i);
                    if rec.is_some() {
                        record(
                            &mut rec,
                            Some(Item::Comment {
                                text: (raw(i) + 1, raw(end)),
                                offset: raw(i),
                            }),
                        );
                    }
                    i = (end + 1).min(b.len());
                }
                b';' => break,
                b'$' => {
                    return Err((
                        raw(i),
                        ErrorKind::Unsupported {
                            word: "$".into(),
                            why: "spindle selection ($ words) is not supported".into(),
                        },
                    ))
                }
                _ => {
                    // the raw byte (comments aside, the line is lower case)
                    return bad(raw(i), bad_character(c));
                }
            }
        }
        if recording {
            *norm.plan.borrow_mut() = rec.map_or(Plan::Text, Plan::Items);
        }
        Ok(None)
    }

    /// [`Self::read_items_slow`] for a kept line compiled whole: its items in
    /// order, with the same values, side effects and errors as read from its text.
    fn run_items(
        &self,
        norm: &Norm,
        items: &[Item],
        block: &mut Block,
        line: &mut Line,
        sets: &mut Vec<Setting>,
    ) -> R<()> {
        let re = |(i, k): (usize, ErrorKind)| (norm.raw(i), k);
        for item in items {
            match item {
                Item::Word {
                    letter,
                    code,
                    offset,
                } => {
                    let value = crate::compiled::eval(code, self).map_err(re)?;
                    self.sort_word_slow(
                        Word {
                            letter: *letter,
                            value,
                            offset: *offset,
                        },
                        block,
                    )?;
                }
                Item::Named {
                    name,
                    code,
                    at,
                    slot,
                } => {
                    // created (value 0) as soon as its name is read: see
                    // `read_items_slow`
                    {
                        let mut names = self.line_named.borrow_mut();
                        names.push_str(name);
                        names.push('>');
                    }
                    let v = crate::compiled::eval(code, self).map_err(re)?;
                    if name.starts_with('_') && self.predefined(name).ok().flatten().is_some() {
                        return bad(
                            norm.raw(*at),
                            format!("Cannot assign to read-only parameter #<{name}>"),
                        );
                    }
                    let k = slot.get().or_else(|| {
                        let k = self.assigned_slot(norm, *at, name);
                        slot.set(k);
                        k
                    });
                    sets.push(match k {
                        Some(k) => Setting::Slot(k, v),
                        None => Setting::Named(name.clone(), v),
                    });
                }
                Item::Numbered { index, code, at } => {
                    let index = crate::compiled::eval(index, self).map_err(re)? as i32;
                    if index < 1 || index as usize >= NUM_PARAMS {
                        return bad(norm.raw(*at), "Parameter number out of range");
                    }
                    if is_readonly(index as usize) {
                        return bad(norm.raw(*at), "Parameter is readonly");
                    }
                    let v = crate::compiled::eval(code, self).map_err(re)?;
                    sets.push(Setting::Numbered(index as usize, v));
                }
                Item::Comment { text, offset } => {
                    line.comment = Some(*text);
                    line.comment_offset = *offset;
                }
            }
        }
        Ok(())
    }

    /// `read_o` for `M98 P… [L…]` at `b[i]`: the rest of the line is read as
    /// words (P names the subprogram, L repeats it).
    fn read_m98(
        &self,
        norm: &Norm,
        i: usize,
        block: &mut Block,
        line: &mut Line,
        sets: &mut Vec<Setting>,
    ) -> R<OLine> {
        let at = norm.raw(i);
        // the words after "m98"
        let skip = (i + 3).min(norm.b.len());
        let rest = Norm {
            b: norm.b[skip..].to_vec(),
            at: norm.at[skip..].to_vec(),
            ..Default::default()
        };
        self.read_items_slow(&rest, block, line, sets)?;
        if !block.has(b'P') {
            return bad(at, "Found 'm98' code with no P-word");
        }
        let p = block.p_number;
        let n = p.floor();
        let n = if p - n > 0.9999 {
            p.ceil()
        } else if p - n > 0.0001 {
            return bad(block.off(b'P'), "Non integer value for integer");
        } else {
            n
        };
        Ok(OLine {
            kind: OKind::M98,
            name: self.intern(&format!("{}", n as i64)),
            value: None,
            at,
            repeat: block.get(b'L'),
        })
    }

    /// `read_o`: the O-line at `b[*i]` (an `o`). Conditions and arguments are
    /// evaluated only where LinuxCNC evaluates them (not while skipping to another
    /// label).
    #[allow(clippy::too_many_lines)]
    pub(super) fn read_o(&self, norm: &Norm, i: &mut usize, line: &mut Line) -> R<Option<OLine>> {
        let b = &norm.b[..];
        let re = |(k, e): (usize, ErrorKind)| (norm.raw(k), e);
        let at = norm.raw(*i);
        *i += 1;
        let label_at = *i;
        // a kept line's label and keyword, read on an earlier pass
        let head = if norm.keep {
            norm.o_head.borrow().clone()
        } else {
            None
        };
        let (label, found) = match head {
            Some((label, next, found)) => {
                *i = next;
                (label, found)
            }
            None => {
                let (label, next) = if b.get(*i) == Some(&b'<') {
                    self.name_at(norm, *i).map_err(re)?
                } else {
                    self.number_label(norm, *i).map_err(re)?
                };
                *i = next;
                let rest = &b[next.min(b.len())..];
                // in LinuxCNC's order of comparison ("elseif" before "else")
                // (the first byte compared alone first: most keywords differ there)
                let first = rest.first().copied();
                let found = O_KEYWORDS
                    .iter()
                    .position(|(kw, _)| Some(kw[0]) == first && rest.starts_with(kw))
                    .map(|k| k as u8);
                // remembered where the label is (a name, or a number of digits
                // alone): an expression's label is evaluated on every pass
                if norm.keep && norm.names.borrow().iter().any(|(s, _, _)| *s == label_at) {
                    *norm.o_head.borrow_mut() = Some((label.clone(), next, found));
                }
                (label, found)
            }
        };
        let rest = &b[(*i).min(b.len())..];
        let Some(&(kw, kind)) = found.map(|k| &O_KEYWORDS[usize::from(k)]) else {
            if !matches!(rest.first(), None | Some(b'(' | b';')) {
                return bad(at, "Unknown control command in o word");
            }
            // a Fanuc-style program start, "O1234" alone
            let ctl = &self.ctl;
            if ctl.defining_sub {
                return bad(at, "Nested subroutine definition");
            }
            if let (Some(f), None) = (ctl.frames.last(), &ctl.skipping) {
                if *f.sub_name != *label {
                    return bad(
                        at,
                        format!(
                            "Nested subroutine definition: 'O{label} sub' found inside called subroutine 'O{}'",
                            f.sub_name
                        ),
                    );
                }
            }
            return Ok(Some(OLine {
                kind: OKind::Bare,
                name: label,
                value: None,
                at,
                repeat: None,
            }));
        };
        *i += kw.len();
        let ctl = &self.ctl;
        let name = if kind.global() {
            label
        } else {
            let sub: &str = if let Some(f) = ctl.frames.last() {
                &f.sub_name
            } else if ctl.defining_sub {
                ctl.sub_name.as_deref().unwrap_or("")
            } else {
                ""
            };
            self.qualified(norm, label_at, sub, &label)
        };
        let mut o = OLine {
            kind,
            name,
            value: None,
            at,
            repeat: None,
        };
        let skip_other = ctl.skipping.as_ref().is_some_and(|s| *s != o.name);
        // a kept line with a kept head read whole (not skipping): where its values
        // are, to keep them compiled with the head (`Plan::O`)
        let recording = norm.keep
            && ctl.skipping.is_none()
            && !ctl.defining_sub
            && norm.o_head.borrow().is_some()
            && matches!(*norm.plan.borrow(), Plan::Unread);
        let mut value_at = None;
        let mut arg_ats = Vec::new();
        let mut comment_in_args = false;
        match kind {
            OKind::Sub => {
                if ctl.defining_sub {
                    return bad(at, "Nested subroutine definition");
                }
                if let (Some(f), None) = (ctl.frames.last(), &ctl.skipping) {
                    if f.sub_name != o.name {
                        return bad(
                            at,
                            format!(
                                "Nested subroutine definition: 'O{} sub' found inside called subroutine 'O{}'",
                                o.name, f.sub_name
                            ),
                        );
                    }
                }
            }
            OKind::EndSub | OKind::Return => {
                if skip_other {
                    return Ok(Some(o));
                }
                if b.get(*i) == Some(&b'[') {
                    value_at = Some(*i);
                    let (v, next) = self.value(norm, *i, Kind::Expression).map_err(re)?;
                    o.value = Some(v);
                    *i = next;
                }
            }
            OKind::Call => {
                if ctl.skipping.is_some() {
                    return Ok(None);
                }
                let mut args = self.call_args.borrow_mut();
                args.clear();
                while matches!(b.get(*i), Some(b'[' | b'(')) {
                    if b[*i] == b'(' {
                        comment_in_args = true;
                        let end = b[*i..]
                            .iter()
                            .position(|&x| x == b')')
                            .map_or(b.len(), |k| *i + k);
                        line.comment = Some((norm.raw(*i) + 1, norm.raw(end)));
                        line.comment_offset = norm.raw(*i);
                        *i = (end + 1).min(b.len());
                        continue;
                    }
                    if args.len() >= SUB_PARAMS {
                        return bad(norm.raw(*i), "Too many subroutine parameters");
                    }
                    if recording {
                        arg_ats.push(*i);
                    }
                    let (v, next) = self.value(norm, *i, Kind::Expression).map_err(re)?;
                    args.push(v);
                    *i = next;
                }
            }
            OKind::While | OKind::Repeat | OKind::If | OKind::ElseIf => {
                if skip_other {
                    return Ok(Some(o));
                }
                if b.get(*i) != Some(&b'[') {
                    return bad(
                        norm.raw(*i),
                        format!("Left bracket missing after '{}'", kind.name()),
                    );
                }
                value_at = Some(*i);
                let (v, next) = self.value(norm, *i, Kind::Expression).map_err(re)?;
                o.value = Some(v);
                *i = next;
            }
            _ => {}
        }
        if ctl.defining_sub && !matches!(kind, OKind::Sub | OKind::EndSub | OKind::Return) {
            // LinuxCNC cannot evaluate inside a definition: the line counts as none
            return Ok(None);
        }
        if ctl.skipping.is_some() {
            return Ok(Some(o));
        }
        if recording && *i == b.len() && !comment_in_args {
            // nothing after the values: kept whole where they compile
            let value = match value_at {
                Some(k) => compiled_at(norm, k, Kind::Expression).map(Some),
                None => Some(None),
            };
            let args: Option<Vec<Code>> = arg_ats
                .iter()
                .map(|&k| compiled_at(norm, k, Kind::Expression))
                .collect();
            if let (Some(value), Some(args)) = (value, args) {
                let label = norm.o_head.borrow().as_ref().map(|h| h.0.clone());
                *norm.plan.borrow_mut() = Plan::O(OPlan {
                    qualified: Default::default(),
                    kind,
                    label: label.unwrap_or_else(|| o.name.clone()),
                    label_at,
                    at,
                    value,
                    args,
                });
            }
        }
        // after the O-word only comments may follow
        while *i < b.len() {
            match b[*i] {
                b';' => break,
                b'(' => {
                    let end = b[*i..]
                        .iter()
                        .position(|&x| x == b')')
                        .map_or(b.len(), |k| *i + k);
                    line.comment = Some((norm.raw(*i) + 1, norm.raw(end)));
                    line.comment_offset = norm.raw(*i);
                    *i = end + 1;
                }
                _ => return bad(norm.raw(*i), "Unexpected character after O-word"),
            }
        }
        Ok(Some(o))
    }

    fn save_label(&mut self, o: &OLine, pc: &Pc) {
        let label = Label {
            kind: o.kind,
            file: pc.file,
            pos: pc.pos,
            line_no: pc.line_no,
            repeat_count: -1,
        };
        // a loop saves its label on every pass: no new key then
        self.ctl.labels.insert(label_key(&o.name), label);
    }

    /// `control_save_offset` for a `sub` line: a name recorded before is an error,
    /// "illegal location" when it was this very line (a definition after a forward
    /// call to it, or inside a loop), "redefining sub" otherwise.
    fn save_sub_label(&mut self, o: &OLine, pc: &Pc) -> R<()> {
        if let Some(l) = self.ctl.labels.get(&label_key(&o.name)) {
            let here = l.file == pc.file && l.pos == pc.pos;
            let why = if here {
                format!("sub: o<{}> found in illegal location", o.name)
            } else {
                format!(
                    "redefining sub: o<{}> already defined in line {}",
                    o.name, l.line_no
                )
            };
            return bad(o.at, why);
        }
        self.save_label(o, pc);
        Ok(())
    }

    fn back_to(&self, name: &Name) -> Option<Jump> {
        self.ctl
            .labels
            .get(&label_key(name))
            .map(|l| Jump::To(l.file, l.pos, l.line_no))
    }

    fn label_of(&self, o: &OLine, what: &str) -> R<&Label> {
        let Some(l) = self.ctl.labels.get(&label_key(&o.name)) else {
            return bad(o.at, format!("undefined O-word label: '{}'", o.name));
        };
        let ok = match o.kind {
            OKind::ElseIf | OKind::Else | OKind::EndIf => l.kind == OKind::If,
            OKind::Break | OKind::Continue => matches!(l.kind, OKind::While | OKind::Do),
            OKind::EndWhile => l.kind == OKind::While,
            OKind::EndRepeat => l.kind == OKind::Repeat,
            _ => true,
        };
        if !ok {
            return bad(
                o.at,
                format!(
                    "no matching {what} label: '{}' (found '{}' in line {})",
                    o.name,
                    l.kind.name(),
                    l.line_no
                ),
            );
        }
        Ok(l)
    }

    /// `convert_control_functions`: run an O-line read at `pc`.
    #[allow(clippy::too_many_lines)]
    pub(super) fn control(&mut self, o: &OLine, pc: &Pc) -> R<Jump> {
        if self.ctl.skipping.as_ref().is_some_and(|s| *s != o.name) {
            return Ok(Jump::Next);
        }
        if self.ctl.skipping_to_sub.is_some() && !matches!(o.kind, OKind::Sub | OKind::Bare) {
            return Ok(Jump::Next);
        }
        let test = o.value.unwrap_or(0.0);
        match o.kind {
            OKind::Bare => {
                if self.ctl.frames.last().is_some_and(|f| !f.m98) {
                    return bad(o.at, "Fanuc 'O....' subroutine must be called with 'M98'");
                }
                if self.ctl.skipping.is_some() {
                    self.save_label(o, pc);
                    self.ctl.skipping = None;
                }
                self.ctl.skipping_to_sub = None;
            }
            OKind::Sub => {
                if self.ctl.frames.last().is_some_and(|f| f.m98) {
                    return bad(
                        o.at,
                        "'O.... sub' subroutine must be called with 'O.... call'",
                    );
                }
                if self.ctl.skipping.is_some() {
                    self.save_sub_label(o, pc)?;
                    self.ctl.skipping = None;
                }
                self.ctl.skipping_to_sub = None;
                if self.ctl.level() == 0 {
                    // a definition: remember it, skip to its end
                    self.save_sub_label(o, pc)?;
                    self.ctl.skipping = Some(o.name.clone());
                    self.ctl.skipping_start = pc.line_no;
                    self.ctl.defining_sub = true;
                    self.ctl.sub_name = Some(o.name.clone());
                }
            }
            OKind::EndSub | OKind::Return | OKind::M99 => {
                match (self.ctl.frames.last().map(|f| f.m98), o.kind) {
                    (Some(true), OKind::EndSub | OKind::Return) => {
                        return bad(o.at, "Fanuc 'O....' subroutine definition must end with 'M99'")
                    }
                    (Some(false), OKind::M99) => {
                        return bad(
                            o.at,
                            "'O.... endsub' or 'O.... return' must follow 'O.... sub' subroutine definition",
                        )
                    }
                    _ => {}
                }
                if self.ctl.level() == 0 && !self.ctl.defining_sub {
                    return bad(
                        o.at,
                        format!(
                            "not in a subroutine definition: 'O{} {}'",
                            o.name,
                            o.kind.name()
                        ),
                    );
                }
                if o.kind != OKind::M99 {
                    // read_o: every endsub or return read sets them, even in a
                    // definition being skipped; a call does not clear them
                    self.ctl.return_value = test;
                    self.ctl.value_returned = o.value.is_some();
                }
                if self.ctl.level() == 0 {
                    // in a definition: its endsub ends it, a return changes nothing else
                    if o.kind == OKind::EndSub {
                        self.ctl.defining_sub = false;
                        self.ctl.sub_name = None;
                        self.ctl.skipping = None;
                    }
                    return Ok(Jump::Next);
                }
                if o.kind == OKind::EndSub {
                    self.ctl.skipping = None;
                }
                if o.kind == OKind::M99 {
                    self.ctl.return_value = 0.0;
                    self.ctl.value_returned = false;
                }
                let from = self.ctl.level();
                let Some(frame) = self.ctl.frames.pop() else {
                    return Ok(Jump::Next);
                };
                if frame.m98 {
                    self.params.leave_keep();
                } else {
                    self.params.leave();
                }
                self.leave_modal(from, pc.line_no as u32, o.at)?;
                let (f, pos, line_no) = frame.ret;
                return Ok(Jump::To(f, pos, line_no + 1));
            }
            OKind::Call | OKind::M98 => {
                // enter_context: the level is raised, then checked (`>= 10`): nine
                // nested calls run, the tenth is the error
                if self.ctl.level() + 1 >= MAX_CALL_LEVEL {
                    return bad(o.at, "Too many subroutine levels");
                }
                self.ctl.skipping = None;
                let m98 = o.kind == OKind::M98;
                let mut ret = (pc.file, pc.next, pc.line_no);
                if let (true, Some(l)) = (m98, o.repeat) {
                    let level = self.ctl.level();
                    if self.ctl.m98_loops.len() <= level {
                        self.ctl.m98_loops.resize(level + 1, -1);
                    }
                    let left = &mut self.ctl.m98_loops[level];
                    if *left == -1 {
                        *left = i64::from(super::round_to_int(l));
                    }
                    if *left <= 0 {
                        // L0: no call at all
                        *left = -1;
                        return Ok(Jump::Next);
                    }
                    *left -= 1;
                    if *left > 0 {
                        // come back to this M98 line for the next repeat
                        ret = (pc.file, pc.pos, pc.line_no - 1);
                    } else {
                        *left = -1;
                    }
                }
                if m98 {
                    self.params.enter_keep();
                } else {
                    // the arguments of this call, read by `read_o` just before
                    let args = self.call_args.borrow();
                    self.params.enter(&args);
                }
                self.ctl.frames.push(Frame {
                    sub_name: o.name.clone(),
                    ret,
                    m98,
                });
                self.enter_modal();
                if let Some(j) = self.back_to(&o.name) {
                    return Ok(j);
                }
                self.ctl.skipping = Some(o.name.clone());
                self.ctl.skipping_to_sub = Some(o.name.clone());
                self.ctl.skipping_start = pc.line_no;
                return Ok(Jump::OpenSub);
            }
            OKind::Do => {
                self.ctl.skipping = None;
                if !self.ctl.labels.contains_key(&label_key(&o.name)) {
                    self.save_label(o, pc);
                }
            }
            OKind::Repeat => {
                self.check_duplicate(o, pc)?;
                self.ctl.skipping = None;
                let l = self.ctl.labels.get_mut(&label_key(&o.name));
                if let Some(l) = l.filter(|l| l.kind == OKind::Repeat) {
                    if l.repeat_count == -1 {
                        l.repeat_count = i64::from(super::round_to_int(test));
                    }
                    if l.repeat_count > 0 {
                        l.repeat_count -= 1;
                    } else {
                        l.repeat_count = -1;
                        self.ctl.skipping = Some(o.name.clone());
                        self.ctl.skipping_start = pc.line_no;
                    }
                }
            }
            OKind::While => {
                let existing = self
                    .ctl
                    .labels
                    .get(&label_key(&o.name))
                    .map(|l| (l.kind, l.line_no));
                match existing {
                    Some((OKind::Do, _)) => {
                        self.ctl.skipping = None;
                        if test != 0.0 && !self.ctl.doing_break {
                            return Ok(self.back_to(&o.name).unwrap_or(Jump::Next));
                        }
                        self.ctl.doing_break = false;
                    }
                    _ => {
                        self.check_duplicate(o, pc)?;
                        self.ctl.skipping = None;
                        if test == 0.0 {
                            self.ctl.skipping = Some(o.name.clone());
                            self.ctl.skipping_start = pc.line_no;
                        }
                    }
                }
            }
            OKind::If => {
                self.check_duplicate(o, pc)?;
                if test != 0.0 {
                    self.ctl.skipping = None;
                    self.ctl.executed_if = true;
                } else {
                    self.ctl.skipping = Some(o.name.clone());
                    self.ctl.skipping_start = pc.line_no;
                    self.ctl.executed_if = false;
                }
            }
            OKind::ElseIf => {
                self.label_of(o, "'if'")?;
                if self.ctl.executed_if {
                    self.ctl.skipping = Some(o.name.clone());
                    self.ctl.skipping_start = pc.line_no;
                } else if test != 0.0 {
                    self.ctl.skipping = None;
                    self.ctl.executed_if = true;
                }
            }
            OKind::Else => {
                self.label_of(o, "'if'")?;
                if self.ctl.executed_if {
                    self.ctl.skipping = Some(o.name.clone());
                    self.ctl.skipping_start = pc.line_no;
                } else if self.ctl.skipping.is_some() {
                    self.ctl.executed_if = true;
                    self.ctl.skipping = None;
                }
            }
            OKind::EndIf => {
                self.label_of(o, "")?;
                self.ctl.skipping = None;
                self.ctl.executed_if = true;
            }
            OKind::Break => {
                self.label_of(o, "while/do")?;
                self.ctl.skipping = Some(o.name.clone());
                self.ctl.skipping_start = pc.line_no;
                self.ctl.doing_break = true;
            }
            OKind::Continue => {
                self.label_of(o, "while/do")?;
                if self.ctl.skipping.is_none() {
                    self.ctl.skipping = Some(o.name.clone());
                    self.ctl.skipping_start = pc.line_no;
                    self.ctl.doing_continue = true;
                }
            }
            OKind::EndWhile | OKind::EndRepeat => {
                // the label found is the one `back_to` would look up again
                let l = self.label_of(o, "")?;
                let back = Jump::To(l.file, l.pos, l.line_no);
                if self.ctl.skipping.is_some() {
                    self.ctl.skipping = None;
                    if self.ctl.doing_continue {
                        self.ctl.doing_continue = false;
                        return Ok(back);
                    }
                    return Ok(Jump::Next);
                }
                return Ok(back);
            }
        }
        Ok(Jump::Next)
    }

    /// The same label on another line is a duplicate (LinuxCNC `duplicate O-word
    /// label`); a new one is recorded.
    fn check_duplicate(&mut self, o: &OLine, pc: &Pc) -> R<()> {
        match self.ctl.labels.get(&label_key(&o.name)) {
            Some(l) if l.file != pc.file || l.pos != pc.pos => {
                if o.kind == OKind::While && l.kind == OKind::Do {
                    return Ok(());
                }
                bad(
                    o.at,
                    format!(
                        "duplicate O-word label: '{}' - defined in line {}",
                        o.name, l.line_no
                    ),
                )
            }
            Some(_) => Ok(()),
            None => {
                self.save_label(o, pc);
                Ok(())
            }
        }
    }

    /// Apply the assignments read on a line.
    pub(super) fn commit(&mut self, sets: &mut Vec<Setting>) {
        self.line_named.get_mut().clear();
        for s in sets.iter() {
            match s {
                Setting::Numbered(i, v) => self.params.set(*i, *v),
                Setting::Slot(k, v) => self.params.set_slot(*k, *v),
                Setting::Named(n, v) => self.params.set_named(n, *v),
            }
        }
        sets.clear();
    }

    /// The label a call is looking for (when it must open a file).
    pub(super) fn wanted_sub(&self) -> Option<&str> {
        self.ctl.skipping_to_sub.as_deref()
    }
}

impl Interp<'_> {
    /// The name of `<name>` at `norm.b[i]` (the `<`) and the offset after its `>`
    /// (LinuxCNC's `read_name`). A kept line remembers it: later passes neither
    /// scan nor allocate it again.
    fn name_at(&self, norm: &Norm, i: usize) -> Result<(Name, usize), crate::expr::ExprError> {
        if norm.keep {
            if let Some((_, end, n)) = norm.names.borrow().iter().find(|(s, _, _)| *s == i) {
                return Ok((n.clone(), *end));
            }
        }
        let mut r = Reader::new(&norm.b, i, self);
        let name = self.intern(&r.name()?);
        if norm.keep {
            norm.names.borrow_mut().push((i, r.i, name.clone()));
        }
        Ok((name, r.i))
    }

    /// The parameter slot of `name`, assigned by the `#` at `norm.b[at]`, where it
    /// has one (then a kept line remembers it: no lookup by name on later passes).
    fn assigned_slot(&self, norm: &Norm, at: usize, name: &str) -> Option<u32> {
        if !norm.keep {
            return None;
        }
        if let Some(&(_, k)) = norm.slots.borrow().iter().find(|(s, _)| *s == at) {
            return Some(k);
        }
        let k = self.params.slot(name)?;
        norm.slots.borrow_mut().push((at, k));
        Some(k)
    }

    /// A numbered O-word label at `norm.b[i]` (`read_integer_value`, as text) and
    /// the offset after it. A label of digits alone is remembered by a kept line
    /// (its value cannot change); an expression is evaluated on every pass.
    fn number_label(&self, norm: &Norm, i: usize) -> Result<(Name, usize), crate::expr::ExprError> {
        if norm.keep {
            if let Some((_, end, n)) = norm.names.borrow().iter().find(|(s, _, _)| *s == i) {
                return Ok((n.clone(), *end));
            }
        }
        let (n, next) = self.value(norm, i, Kind::Integer)?;
        let name = self.intern(&(n as i32).to_string());
        if norm.keep && next > i && norm.b[i..next].iter().all(u8::is_ascii_digit) {
            norm.names.borrow_mut().push((i, next, name.clone()));
        }
        Ok((name, next))
    }
}

/// The compiled value of kind `kind` at `norm.b[i]` of a kept line, once read
/// ([`Interp::value`] compiles it): `None` where it does not compile.
fn compiled_at(norm: &Norm, i: usize, kind: Kind) -> Option<Code> {
    norm.code
        .borrow()
        .iter()
        .find(|(s, k, _)| *s == i && *k == kind)
        .and_then(|(_, _, c)| c.clone())
}

/// Record `item` of a line being compiled whole; `None` (a value that does not
/// compile) ends the recording: the line is read from its text.
fn record(rec: &mut Option<Vec<Item>>, item: Option<Item>) {
    match item {
        Some(item) => {
            if let Some(r) = rec {
                r.push(item);
            }
        }
        None => *rec = None,
    }
}

/// The key of an interned name in [`Control::labels`]: its address (its low bits,
/// always 0 by alignment, dropped).
fn label_key(name: &Name) -> u64 {
    (std::rc::Rc::as_ptr(name).cast::<u8>() as usize as u64) >> LABEL_KEY_ALIGN_BITS
}

/// Bits of a name's address that its alignment leaves 0 (the allocator's 16
/// bytes); dropping them spreads keys over the table's low bits.
const LABEL_KEY_ALIGN_BITS: u32 = 4;

impl Interp<'_> {
    /// The one [`Name`] of `s` (made the first time it is read).
    fn intern(&self, s: &str) -> Name {
        let mut names = self.ctl.names.borrow_mut();
        if let Some(n) = names.get(s) {
            return n.clone();
        }
        let n = Name::from(s);
        names.insert(n.clone());
        n
    }

    /// A local label qualified as LinuxCNC does (`sub#label`); a kept line remembers it
    /// per subroutine name (the label at offset `at` of it).
    fn qualified(&self, norm: &Norm, at: usize, sub: &str, label: &str) -> Name {
        if norm.keep {
            if let Some((_, _, q)) = norm
                .qualified
                .borrow()
                .iter()
                .find(|(s, ctx, _)| *s == at && **ctx == *sub)
            {
                return q.clone();
            }
        }
        let mut q = String::with_capacity(sub.len() + 1 + label.len());
        q.push_str(sub);
        q.push('#');
        q.push_str(label);
        let q = self.intern(&q);
        if norm.keep {
            norm.qualified
                .borrow_mut()
                .push((at, Name::from(sub), q.clone()));
        }
        q
    }
}

impl Interp<'_> {
    /// `convert_param_comment`: a (DEBUG,…), (PRINT,…) or (LOG,…) text with `#n`
    /// and `#<name>` replaced by their values, formatted `%lf` or as the last
    /// `%d`, `%f`, `%.Nf` before them asks.
    pub(super) fn expand_comment(&self, text: &str) -> Result<String, ErrorKind> {
        let not_terminated = || ErrorKind::Invalid("Named parameter not terminated".into());
        let b = text.as_bytes();
        let mut out: Vec<u8> = Vec::with_capacity(b.len() + 16);
        let mut decimals = 6usize;
        let mut i = 0;
        while i < b.len() {
            match b[i] {
                b'%' => {
                    i += 1;
                    match b.get(i) {
                        Some(b'd') => {
                            i += 1;
                            decimals = 0;
                        }
                        Some(b'f') => {
                            i += 1;
                            decimals = 4;
                        }
                        Some(b'.') => {
                            i += 1;
                            match (b.get(i), b.get(i + 1)) {
                                (Some(d), Some(b'f')) if d.is_ascii_digit() => {
                                    decimals = usize::from(d - b'0');
                                    i += 2;
                                }
                                _ => out.push(b'.'),
                            }
                        }
                        _ => out.push(b'%'),
                    }
                }
                b'#' => {
                    i += 1;
                    let Some(&c) = b.get(i) else {
                        return Err(not_terminated());
                    };
                    let value = if c.is_ascii_digit() {
                        let s = i;
                        while b.get(i).is_some_and(u8::is_ascii_digit) {
                            i += 1;
                        }
                        let n: usize = text[s..i].parse().unwrap_or(usize::MAX);
                        if n == 5399 && self.m66_unknown_since.is_some() {
                            // M66's result: filled in when the machine gets here
                            // (`crate::write_message`), not a read of the plan's guess
                            let mut mark = [0u8; 4];
                            out.extend_from_slice(
                                crate::M66_RESULT_MARK.encode_utf8(&mut mark).as_bytes(),
                            );
                            out.push(b'0' + decimals.min(9) as u8);
                            continue;
                        }
                        (n < NUM_PARAMS).then(|| Env::numbered(self, n))
                    } else if c == b'<' {
                        i += 1;
                        let mut name = String::new();
                        while let Some(&d) = b.get(i) {
                            if d == b'>' || d == b')' {
                                break;
                            }
                            if !d.is_ascii_whitespace() {
                                name.push(d.to_ascii_lowercase() as char);
                            }
                            i += 1;
                        }
                        if b.get(i) != Some(&b'>') {
                            return Err(not_terminated());
                        }
                        i += 1;
                        Env::named(self, &name).ok().flatten()
                    } else {
                        out.push(b'#');
                        continue;
                    };
                    let mut shown = String::new();
                    match value {
                        Some(v) => {
                            let _ = crate::write_param_value(&mut shown, v, decimals);
                        }
                        None => shown.push_str("######"),
                    }
                    out.extend_from_slice(shown.as_bytes());
                }
                // (a mark of the program's own is not one of ours)
                1 => {
                    out.extend_from_slice("\u{FFFD}".as_bytes());
                    i += 1;
                }
                c => {
                    out.push(c);
                    i += 1;
                }
            }
        }
        Ok(String::from_utf8_lossy(&out).into_owned())
    }
}
