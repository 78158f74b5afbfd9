//! M70–M73: saving and restoring the modal state, as LinuxCNC 2.9's `save_settings`
//! and `restore_settings` (`interp_convert.cc`) do: the state is compared with the
//! saved one and the difference is run as G-code text (`gen_settings`,
//! `gen_m_codes`): first G20/G21, then one line ` F… S… G…` (feed with one decimal,
//! speed with none, the G codes of the groups that differ, G64 with its P and Q),
//! then the spindle M code. The motion mode is not restored (LinuxCNC does not either).

use super::{Block, Interp, GM_MODAL_0, GM_MOTION, G_80, R};
use crate::canon::PathMode;
use crate::error::ErrorKind;
use crate::lexer::{lex_line, Line};
use softnc_core::Plane;

/// The state M70 saves (the parts of LinuxCNC's `active_g_codes`,
/// `active_m_codes` and `active_settings` softnc keeps).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Modal {
    /// G codes × 10 in LinuxCNC's `active_g_codes` slots 3, 4, 6, 7, 8, 9, 10, 11,
    /// 14, 16.
    g: [(usize, i32); 10],
    inch: bool,
    /// G64 P (program units), if given.
    g64_p: Option<f64>,
    /// G64 Q, the naive-CAM tolerance (program units), if given (LinuxCNC's
    /// `naivecam_tolerance`, saved as `GM_FIELD_FLOAT_NAIVE_CAM_TOLERANCE`).
    g64_q: Option<f64>,
    feed: f64,
    speed: f64,
    /// M3, M4 or M5.
    spindle: i32,
}

/// ` G<code/10>` or ` G<code/10>.<code%10>`.
fn push_g(out: &mut String, code: i32) {
    if code % 10 != 0 {
        out.push_str(&format!(" G{}.{}", code / 10, code % 10));
    } else {
        out.push_str(&format!(" G{}", code / 10));
    }
}

/// G64 with its P and Q when the state blends (`gen_settings`), values by `fmt`.
fn push_g64(out: &mut String, m: &Modal, fmt: impl Fn(f64) -> String) {
    if m.g.iter().any(|&(slot, code)| slot == 11 && code == 640) {
        match (m.g64_p, m.g64_q) {
            (None, None) => out.push_str(" G64"),
            (Some(p), None) => out.push_str(&format!(" G64 P{}", fmt(p))),
            (p, Some(q)) => out.push_str(&format!(" G64 P{} Q{}", fmt(p.unwrap_or(0.0)), fmt(q))),
        }
    }
}

impl Interp<'_> {
    /// The state now.
    fn modal_now(&self) -> Modal {
        let plane = match self.plane {
            Plane::XY => 170,
            Plane::XZ => 180,
            Plane::YZ => 190,
        };
        let coord = [540, 550, 560, 570, 580, 590, 591, 592, 593][self.coord.min(8)];
        let (control, g64_p, g64_q) = match self.path {
            PathMode::ExactStop => (self.exact_stop_code, None, None),
            PathMode::Blend {
                tolerance_mm,
                naive_cam_mm,
            } => (
                640,
                tolerance_mm.map(|t| t / self.scale()),
                naive_cam_mm.map(|t| t / self.scale()),
            ),
        };
        Modal {
            g: [
                (3, plane),
                (4, self.comp.code()),
                (6, if self.absolute { 900 } else { 910 }),
                (7, if self.inverse_time { 930 } else { 940 }),
                (8, coord),
                (9, if self.tool_offset_on { 430 } else { 490 }),
                (10, if self.retract_old_z { 980 } else { 990 }),
                (11, control),
                (14, if self.ijk_absolute { 901 } else { 911 }),
                (
                    16,
                    if self.params.get(5210) != 0.0 {
                        923
                    } else {
                        922
                    },
                ),
            ],
            inch: self.inch,
            g64_p,
            g64_q,
            feed: self.feed,
            speed: self.s_rpm,
            spindle: self.spindle_code,
        }
    }

    /// M70 / M73 (`save_settings`): save the state at this call level; M73 also
    /// restores it when the subroutine returns.
    pub(super) fn save_modal(&mut self, auto_restore: bool) {
        let level = self.ctl.level();
        let now = self.modal_now();
        let slots = &mut self.ctl.saved_modal;
        if slots.len() <= level {
            slots.resize(level + 1, (None, false));
        }
        slots[level] = (Some(now), auto_restore && level > 0);
    }

    /// M71: forget the state saved at this level.
    pub(super) fn invalidate_modal(&mut self) {
        let level = self.ctl.level();
        if let Some(s) = self.ctl.saved_modal.get_mut(level) {
            *s = (None, false);
        }
    }

    /// M72: restore the state saved at this level.
    pub(super) fn restore_modal_here(&mut self, line_no: u32, off: u32) -> R<()> {
        let level = self.ctl.level();
        match self.ctl.saved_modal.get(level).and_then(|s| s.0) {
            Some(saved) => self.restore_modal(line_no, &saved, off),
            None => Err((
                off,
                ErrorKind::Invalid(
                    "Cannot restore context from invalid stack frame - missing M70/M73?".into(),
                ),
            )),
        }
    }

    /// On a return from level `from`: restore its state if M73 asked for it, and
    /// forget it.
    pub(super) fn leave_modal(&mut self, from: usize, line_no: u32, off: u32) -> R<()> {
        let Some(slot) = self.ctl.saved_modal.get_mut(from) else {
            return Ok(());
        };
        let taken = std::mem::take(slot);
        if let (Some(saved), true) = taken {
            self.restore_modal(line_no, &saved, off)?;
        }
        Ok(())
    }

    /// A new call level starts with nothing saved.
    pub(super) fn enter_modal(&mut self) {
        let level = self.ctl.level();
        if let Some(slot) = self.ctl.saved_modal.get_mut(level) {
            *slot = (None, false);
        }
    }

    /// `restore_settings`: run the difference as G-code.
    fn restore_modal(&mut self, line_no: u32, saved: &Modal, off: u32) -> R<()> {
        let now = self.modal_now();
        if now.inch != saved.inch {
            self.run_text(line_no, if saved.inch { "G20" } else { "G21" }, off)?;
        }
        let now = self.modal_now();
        let mut cmd = format!(" F{:.1} S{:.0}", saved.feed, saved.speed);
        for (k, &(slot, code)) in saved.g.iter().enumerate() {
            if code == now.g[k].1 || slot == 11 && code == 640 {
                continue;
            }
            push_g(&mut cmd, code);
        }
        // gen_settings: " G64", " G64 P%f" or " G64 P%f Q%f"
        push_g64(&mut cmd, saved, |v| format!("{v:.6}"));
        self.run_text(line_no, &cmd, off)?;
        if saved.spindle != self.spindle_code {
            self.run_text(line_no, &format!("M{}", saved.spindle), off)?;
        }
        Ok(())
    }

    /// The modal state as G-code that sets it from any state (LinuxCNC's
    /// `gen_settings` against nothing, plus the motion mode): what the next MDI
    /// command or job starts with ([`crate::ReadOptions::preamble`]).
    pub(crate) fn modal_gcode(&self) -> String {
        let now = self.modal_now();
        let mut out = String::from(if now.inch { "G20\n" } else { "G21\n" });
        // the tool in the spindle stays there
        if self.tool_loaded != 0 {
            out.push_str(&format!("T{} M6\n", self.tool_loaded));
        }
        out.push_str(&format!("F{} S{}", now.feed, now.speed));
        for &(slot, code) in &now.g {
            // G92.x comes from the parameters the machine keeps
            if slot == 16 || slot == 11 && code == 640 {
                continue;
            }
            if slot == 4 {
                // cutter compensation is never carried (LinuxCNC's gen_restore_cmd
                // forces G40)
                push_g(&mut out, 400);
                continue;
            }
            if slot == 9 && code == 430 {
                // the tool length offset in force, whichever H or G43.x set it
                out.push_str(&format!(" G43.1 Z{}", self.tool_length_mm / self.scale()));
                continue;
            }
            push_g(&mut out, code);
        }
        push_g64(&mut out, &now, |v| v.to_string());
        out.push('\n');
        // a canned cycle's mode is not carried: its R, Z, P, Q and the level its
        // series began at are not part of this text, and a bare X Y of the next
        // command must not drill with values it cannot know (it starts in G80)
        // nor a probe move's: G38.x without an axis word is an error
        if let Some(m) = self.motion.filter(|m| {
            !super::cycles::is_cycle(*m) && !(super::G_38_2..=super::G_38_5).contains(m)
        }) {
            push_g(&mut out, m);
            out.push('\n');
        }
        if self.spindle_code != 5 {
            out.push_str(&format!("M{}\n", self.spindle_code));
        }
        // coolant: mist and flood
        if self.mist {
            out.push_str("M7\n");
        }
        if self.flood {
            out.push_str("M8\n");
        }
        out
    }

    /// Run one line of the modal preamble ([`Interp::modal_gcode`]) before a program.
    pub(crate) fn run_preamble(&mut self, text: &str) -> R<()> {
        let mut line = Line::default();
        lex_line(text, &mut line)?;
        let mut block = Block::default();
        for w in line.words.iter().copied() {
            self.sort_word_slow(w, &mut block)?;
        }
        if block.g_set == 1 << GM_MOTION && block.m_set == 0 && block.val_set == 0 {
            // the motion mode alone (the line `modal_gcode` writes for it): set, not
            // run. Run, it is a motion without axis words, which G1 with no feed rate
            // in force (a program that never set one) or G93 without its F refuses,
            // and every later program with it; the mode is what the last one left.
            let code = block.g[GM_MOTION].0;
            self.motion = (code != G_80).then_some(code);
            return Ok(());
        }
        self.check(&mut block)?;
        self.execute(0, &block)?;
        Ok(())
    }

    /// Read and run one line of G-code made by the interpreter itself; an error in
    /// it is reported at `off` of the line that asked for it.
    fn run_text(&mut self, line_no: u32, text: &str, off: u32) -> R<()> {
        let mut line = Line::default();
        let fail = |k: ErrorKind| {
            (
                off,
                ErrorKind::Invalid(format!(
                    "M7x: restore_settings failed executing: '{text}': {k}"
                )),
            )
        };
        lex_line(text, &mut line).map_err(|(_, k)| fail(k))?;
        let mut block = Block::default();
        for w in line.words.iter().copied() {
            self.sort_word_slow(w, &mut block)
                .map_err(|(_, k)| fail(k))?;
        }
        self.check(&mut block).map_err(|(_, k)| fail(k))?;
        debug_assert!(!block.has_g(GM_MODAL_0));
        self.execute(line_no, &block).map_err(|(_, k)| fail(k))?;
        Ok(())
    }
}
