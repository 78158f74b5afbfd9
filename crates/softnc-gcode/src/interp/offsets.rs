//! Work offsets and stored positions as LinuxCNC 2.9 keeps them in its parameters
//! (`convert_coordinate_system`, `convert_axis_offsets`, `convert_setup`,
//! `convert_home`, `convert_savehome` of `interp_convert.cc`):
//!
//! - 5221 + 20·(n−1) … : G54 … G59.3 (n = 1 … 9) X, Y, Z (5210 + 20·n: XY rotation);
//!   5220: the active system (1 … 9);
//! - 5210: G92 applied; 5211 … 5213: G92/G52 X, Y, Z;
//! - 5161 … 5163: G28 position; 5181 … 5183: G30 position (machine coordinates).
//!
//! Parameters hold machine units (mm; LinuxCNC's `PROGRAM_TO_USER_LEN`), the
//! interpreter's offsets hold program units. Axes other than X, Y, Z are refused
//! where they are written.
//!
//! The XY rotation of a system (`G10 L2 R`, parameter 5210 + 20·n, degrees) turns
//! the program's X and Y about the G92 origin: machine = R(point + G92) + origin +
//! tool (`rotate_and_offset_pos` of `emccanon.cc`). The interpreter's current
//! point stays in the unrotated program frame, as LinuxCNC's `current_x`; each
//! place LinuxCNC rotates (`find_current_in_system`, `find_relative`,
//! `convert_setup`, `convert_savehome`, G53 in `find_ends`) rotates here too.

use super::{bad, rotate, unsup, Block, Interp, GM_MODAL_0, MM_PER_INCH, R};
use crate::canon::MotionKind;
use softnc_core::Vec3;

/// First parameter of coordinate system `n` (1 = G54 … 9 = G59.3).
fn base(n: usize) -> usize {
    5201 + 20 * n
}

impl Interp<'_> {
    /// mm per user unit: parameters hold user units (LinuxCNC's external length
    /// unit: the machine's, mm; inches for `rs274` run without an INI file).
    fn user_mm(&self) -> f64 {
        if self.user_inch {
            MM_PER_INCH
        } else {
            1.0
        }
    }

    /// User units → program units (`USER_TO_PROGRAM_LEN`).
    fn to_prog(&self, user: f64) -> f64 {
        user * self.user_mm() / self.scale()
    }

    /// Program units → user units (`PROGRAM_TO_USER_LEN`).
    fn to_user(&self, v: f64) -> f64 {
        v * self.scale() / self.user_mm()
    }

    /// The machine profile's work offsets as parameters 5221 … (no parameter file).
    pub(super) fn params_from_profile(&mut self) {
        for n in 1..=9 {
            let o = self.tables.work_offset_mm(n - 1);
            for (k, v) in o.iter().enumerate() {
                self.params.set(base(n) + k, *v / self.user_mm());
            }
        }
        self.params.set(5220, 1.0);
    }

    /// Offsets at the start: the system in 5220 (G54 if unset) and G92 from
    /// 5211 … when 5210 says it is applied (LinuxCNC `init`).
    pub(super) fn init_offsets(&mut self) {
        let n = self.params.get(5220).round();
        let n = if (1.0..=9.0).contains(&n) {
            n as usize
        } else {
            1
        };
        self.coord = n - 1;
        self.params.set(5220, n as f64);
        self.rotation_deg = self.params.get(base(n) + 9);
        self.origin = Vec3([
            self.to_prog(self.params.get(base(n))),
            self.to_prog(self.params.get(base(n) + 1)),
            self.to_prog(self.params.get(base(n) + 2)),
        ]);
        if self.params.get(5210) != 0.0 {
            self.g92 = Vec3([
                self.to_prog(self.params.get(5211)),
                self.to_prog(self.params.get(5212)),
                self.to_prog(self.params.get(5213)),
            ]);
        }
        self.refresh_offset();
    }

    /// Recompute the canonical → machine offset (mm).
    pub(super) fn refresh_offset(&mut self) {
        let s = self.scale();
        let mut o = (self.origin + self.g92) * s;
        o[2] += self.tool_length_mm;
        self.offset_mm = o;
    }

    /// The origin of system `n` (program units).
    fn origin_of(&self, n: usize) -> Vec3 {
        Vec3([
            self.to_prog(self.params.get(base(n))),
            self.to_prog(self.params.get(base(n) + 1)),
            self.to_prog(self.params.get(base(n) + 2)),
        ])
    }

    /// `find_current_in_system`: the current point as system `n` would give it
    /// (program units): out through G92, the rotation and the active origin, in
    /// through system `n`'s origin and rotation and the G92 offset in 5211 …
    /// (when 5210 says it is applied).
    fn current_in_system(&self, n: usize) -> Vec3 {
        let g = self.g92;
        let (x, y) = rotate(self.pos[0] + g[0], self.pos[1] + g[1], self.rotation_deg);
        let mut c = Vec3([x, y, self.pos[2] + g[2]]) + self.origin - self.origin_of(n);
        let (x, y) = rotate(c[0], c[1], -self.params.get(base(n) + 9));
        c[0] = x;
        c[1] = y;
        if self.params.get(5210) != 0.0 {
            for k in 0..3 {
                c[k] -= self.to_prog(self.params.get(5211 + k));
            }
        }
        c
    }

    /// G54 … G59.3 (`idx` 0 … 8), as `convert_coordinate_system`: nothing when
    /// the system is already in use.
    pub(super) fn select_coord(&mut self, idx: usize) {
        if idx == self.coord {
            return;
        }
        let n = idx + 1;
        let new = self.origin_of(n);
        self.pos = self.current_in_system(n);
        // rs274's canonical interface shifts its point by the origin change only
        self.canon_pos += self.origin - new;
        self.origin = new;
        self.rotation_deg = self.params.get(base(n) + 9);
        self.coord = idx;
        self.params.set(5220, n as f64);
        self.refresh_offset();
    }

    /// Shift the current point by `d` (program units) as an offset change does.
    fn shift(&mut self, d: Vec3) {
        self.pos += d;
        self.canon_pos += d;
    }

    /// The axis words of the block (program units) that are present.
    fn axis_words(b: &Block) -> [Option<f64>; 3] {
        [b.get(b'X'), b.get(b'Y'), b.get(b'Z')]
    }

    /// G10, G28, G28.1, G30, G30.1, G52, G92, G92.1, G92.2, G92.3.
    #[cold]
    pub(super) fn modal_0(&mut self, line_no: u32, code: i32, b: &Block) -> R<()> {
        let off = b.g_off(GM_MODAL_0);
        match code {
            100 => self.g10(b, off),
            280 | 300 => self.home(line_no, code, b),
            281 | 301 if self.comp.on() => bad(
                off,
                "Cannot set reference point with cutter compensation in effect",
            ),
            520 | 920 if self.comp.on() => {
                // convert_axis_offsets (G92.1, G92.2, G92.3 are allowed)
                bad(off, "Cannot change axis offsets with cutter radius comp")
            }
            281 | 301 => {
                // convert_savehome
                let first = if code == 281 { 5161 } else { 5181 };
                let g = self.g92;
                let (x, y) = rotate(self.pos[0] + g[0], self.pos[1] + g[1], self.rotation_deg);
                let machine = Vec3([x, y, self.pos[2] + g[2]]) + self.origin;
                for k in 0..3 {
                    let tool = if k == 2 { self.tool_length_mm } else { 0.0 };
                    let v = self.to_user(machine[k]) + tool / self.user_mm();
                    self.params.set(first + k, v);
                }
                Ok(())
            }
            520 | 920 => {
                self.params.set(5210, 1.0);
                for (k, w) in Self::axis_words(b).into_iter().enumerate() {
                    let Some(v) = w else { continue };
                    if code == 520 {
                        self.pos[k] += self.g92[k] - v;
                        self.canon_pos[k] += self.g92[k] - v;
                        self.g92[k] = v;
                    } else {
                        let old = self.g92[k];
                        self.g92[k] = self.pos[k] + old - v;
                        self.canon_pos[k] += v - self.pos[k];
                        self.pos[k] = v;
                    }
                }
                for k in 0..3 {
                    self.params.set(5211 + k, self.to_user(self.g92[k]));
                }
                self.refresh_offset();
                Ok(())
            }
            921 | 922 => {
                self.params.set(5210, 0.0);
                let g = self.g92;
                self.shift(g);
                self.g92 = Vec3::ZERO;
                if code == 921 {
                    for k in 5211..=5219 {
                        self.params.set(k, 0.0);
                    }
                }
                self.refresh_offset();
                Ok(())
            }
            923 => {
                self.params.set(5210, 1.0);
                let new = Vec3([
                    self.to_prog(self.params.get(5211)),
                    self.to_prog(self.params.get(5212)),
                    self.to_prog(self.params.get(5213)),
                ]);
                let d = self.g92 - new;
                self.shift(d);
                self.g92 = new;
                self.refresh_offset();
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// `convert_setup`: G10 L2 / L20 (work offsets); L1, L10, L11 (tool table)
    /// are refused.
    fn g10(&mut self, b: &Block, off: u32) -> R<()> {
        let l = b.get(b'L').map_or(0, |l| l as i32);
        if matches!(l, 1 | 10 | 11) {
            return self.g10_tool(l, b, off);
        }
        if l != 2 && l != 20 {
            return unsup(off, format!("G10 L{l}"), "G10 L0 is not supported");
        }
        if b.has(b'I') || b.has(b'J') {
            return bad(off, "I J words not allowed with G10 L2");
        }
        let mut p = (b.p_number + 0.0001) as usize;
        if p == 0 {
            p = self.coord + 1;
        }
        if self.comp.on() && p == self.coord + 1 {
            return bad(
                off,
                "Cannot change the active coordinate system with cutter radius compensation on",
            );
        }
        let c = self.current_in_system(p);
        let r = match b.get(b'R') {
            Some(_) if l == 20 => return bad(off, "R not allowed in G10 L20"),
            Some(r) => {
                self.params.set(base(p) + 9, r);
                r
            }
            None => self.params.get(base(p) + 9),
        };
        let active = p == self.coord + 1;
        let old = self.origin_of(p);
        let mut new = old;
        let [wx, wy, wz] = Self::axis_words(b);
        if l == 20 {
            // the wanted point and the current one, both out of the rotated system
            let (ox, oy) = rotate(c[0], c[1], r);
            let (x, y) = rotate(wx.unwrap_or(c[0]), wy.unwrap_or(c[1]), r);
            new[0] = ox + old[0] - x;
            new[1] = oy + old[1] - y;
            self.params.set(base(p), self.to_user(new[0]));
            self.params.set(base(p) + 1, self.to_user(new[1]));
            if active {
                let (x, y) = rotate(self.pos[0], self.pos[1], self.rotation_deg);
                self.pos[0] = x;
                self.pos[1] = y;
                self.rotation_deg = 0.0;
            }
        } else {
            for (k, w) in [wx, wy].into_iter().enumerate() {
                if let Some(v) = w {
                    new[k] = v;
                    self.params.set(base(p) + k, self.to_user(v));
                }
            }
        }
        if let Some(v) = wz {
            new[2] = if l == 20 { c[2] + old[2] - v } else { v };
            self.params.set(base(p) + 2, self.to_user(new[2]));
        }
        if active {
            // the current point: out of the old system, into the new one
            let (x, y) = rotate(self.pos[0], self.pos[1], self.rotation_deg);
            self.pos = Vec3([x, y, self.pos[2]]) + self.origin - new;
            let (x, y) = rotate(self.pos[0], self.pos[1], -r);
            self.pos[0] = x;
            self.pos[1] = y;
            self.rotation_deg = r;
            // rs274's canonical interface shifts its point by the origin change only
            self.canon_pos += self.origin - new;
            self.origin = new;
            self.refresh_offset();
        }
        Ok(())
    }

    /// `convert_setup_tool`: G10 L1 (set), L10 (so that the current point is Z in
    /// the active system), L11 (… in G59.3) a tool's length; X/Y offsets refused.
    fn g10_tool(&mut self, l: i32, b: &Block, off: u32) -> R<()> {
        let p = b.p_number;
        let tool = p.round();
        if (p - tool).abs() > 0.0001 {
            return bad(off, "P value not an integer with G10");
        }
        let tool = tool as i32;
        self.tool_length(tool, off)?; // find_tool_index: the tool must be in the table
        if !(b.has(b'X')
            || b.has(b'Y')
            || b.has(b'Z')
            || b.has(b'R')
            || b.q_number != -1.0
            || b.has(b'I')
            || b.has(b'J'))
        {
            return bad(off, "G10 L1 without offsets has no effect");
        }
        if b.has(b'X') || b.has(b'Y') {
            return unsup(
                off,
                format!("G10 L{l}"),
                "X and Y tool offsets are not supported (Z only)",
            );
        }
        if b.q_number != -1.0 {
            let q = b.q_number.round();
            if (b.q_number - q).abs() > 0.0001 {
                return bad(off, "Q number in G10 is not an integer");
            }
            if q > 9.0 {
                return bad(off, "Invalid tool orientation");
            }
        }
        let number = if tool == 0 {
            self.tool_loaded
        } else {
            tool as u32
        };
        if b.has(b'R') || b.q_number != -1.0 {
            // the diameter (R: the radius, program units) and the orientation (Q)
            let (mut diameter_mm, mut orientation) = self.tool_shape(tool, off)?;
            if let Some(r) = b.get(b'R') {
                diameter_mm = r * self.scale() * 2.0;
            }
            if b.q_number != -1.0 {
                orientation = b.q_number.round() as i32;
            }
            self.tool_shape_edits
                .insert(number, (diameter_mm, orientation));
            if number == self.tool_loaded {
                self.spindle_shape = (diameter_mm, orientation);
            }
        }
        if let Some(z) = b.get(b'Z') {
            let s = self.scale();
            let len_mm = if l == 1 {
                z * s
            } else {
                // find_current_in_system_without_tlo
                let n = if l == 11 { 9 } else { self.coord + 1 };
                let mut tz = self.pos[2] + self.g92[2] + self.origin[2]
                    - self.to_prog(self.params.get(base(n) + 2))
                    + self.tool_length_mm / s;
                if l == 11 && self.params.get(5210) != 0.0 {
                    tz += self.to_prog(self.params.get(5213));
                }
                (tz - z) * s
            };
            self.tool_edits.insert(number, len_mm);
            if number == self.tool_loaded {
                self.spindle_length_mm = len_mm;
            }
        }
        Ok(())
    }

    /// `convert_home`: G28 / G30, through the point given (a traverse, also when
    /// it is where the tool is), then to the stored position.
    fn home(&mut self, line_no: u32, code: i32, b: &Block) -> R<()> {
        let waypoint = self.find_ends(b)?;
        if self.comp.on() {
            return bad(
                b.g_off(super::GM_MODAL_0),
                "Cannot use g28 or g30 with cutter radius comp",
            );
        }
        let s = self.scale();
        self.push(
            line_no,
            MotionKind::Traverse { end: waypoint * s },
            waypoint,
            Vec3::ZERO,
        );
        let first = if code == 280 { 5161 } else { 5181 };
        // find_relative: machine → this system, back through the rotation
        let stored = Vec3([0, 1, 2].map(|k| self.to_prog(self.params.get(first + k))));
        let d = stored - self.origin;
        let (x, y) = rotate(d[0], d[1], -self.rotation_deg);
        let home = Vec3([
            x - self.g92[0],
            y - self.g92[1],
            d[2] - self.g92[2] - self.tool_length_mm / self.scale(),
        ]);
        let words = Self::axis_words(b);
        let mut end = waypoint;
        let none = words.iter().all(Option::is_none);
        for k in 0..3 {
            if none || words[k].is_some() {
                end[k] = home[k];
            }
        }
        self.push(
            line_no,
            MotionKind::Traverse { end: end * s },
            end,
            Vec3::ZERO,
        );
        Ok(())
    }
}
