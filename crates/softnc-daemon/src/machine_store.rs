//! The machine's own state that outlives jobs and restarts (docs/operations.md):
//! the parameter file — work offsets G54–G59.3 with their rotations, G92, the G28
//! and G30 positions and the active coordinate system, LinuxCNC's persistent
//! parameters 5161–5390 — and the tool table. Both live in the daemon's `data_dir`,
//! one per machine instance, and are written atomically (a crash leaves the old
//! file or the new one). The MMI writes them, only between jobs; the MMI's check
//! and the interpolator's plan of a job both read them, so a job runs with the
//! offsets it was checked with.

use softnc_core::config::ToolEntry;
use softnc_core::store::write_atomic;
use softnc_gcode::Params;
use softnc_machine::MachineProfile;
use std::path::{Path, PathBuf};

/// The parameter file in `data_dir` (LinuxCNC's `.var` format).
pub const PARAMS_FILE: &str = "softnc.var";
/// The tool table in `data_dir` (RON: a list of the profile's tool entries).
pub const TOOLS_FILE: &str = "tools.ron";
/// The modal state the last MDI command or job left, as G-code, in `data_dir`.
pub const MODAL_FILE: &str = "modal.ngc";
/// The jobs' program copies and checked setups, in `data_dir`.
pub const PROGRAMS_DIR: &str = "programs";

/// Parameter numbers (LinuxCNC 2.9's numbered parameters).
mod param {
    /// 5210: G92 offsets applied (1) or not (0).
    pub const G92_ON: usize = 5210;
    /// 5211–5213: G92 offset X, Y, Z.
    pub const G92_X: usize = 5211;
    /// 5220: the active coordinate system, 1 (G54) … 9 (G59.3).
    pub const COORDS: usize = 5220;
    /// 5221: G54's X; each system takes 20 parameters (X, Y, Z, A, B, C, U, V, W, R).
    pub const G54_X: usize = 5221;
    /// Parameters per coordinate system.
    pub const PER_SYSTEM: usize = 20;
    /// Offset of R (XY rotation, degrees) within a system's parameters.
    pub const ROTATION: usize = 9;
    /// 5400: tool in the spindle.
    pub const TOOL: usize = 5400;
    /// 5401–5403: tool offset in effect, X, Y, Z.
    pub const TOOL_X: usize = 5401;
}

/// Coordinate systems by number (1 … 9), as programs name them.
pub const COORDS_NAMES: [&str; 9] = [
    "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
];

/// The number (1 … 9) of a coordinate system named `G54` … `G59.3` (case-insensitive).
pub fn coords_number(name: &str) -> Option<usize> {
    COORDS_NAMES
        .iter()
        .position(|n| n.eq_ignore_ascii_case(name.trim()))
        .map(|i| i + 1)
}

/// The name of coordinate system `n` (1 … 9).
pub fn coords_name(n: usize) -> &'static str {
    COORDS_NAMES
        .get(n.wrapping_sub(1))
        .copied()
        .unwrap_or("G54")
}

/// Where the parameter file and the tool table live.
#[derive(Debug, Clone)]
pub struct MachineStore {
    dir: PathBuf,
}

impl MachineStore {
    /// The store in `data_dir`.
    pub fn new(data_dir: &Path) -> Self {
        MachineStore {
            dir: data_dir.to_path_buf(),
        }
    }

    /// The parameter file.
    pub fn params_path(&self) -> PathBuf {
        self.dir.join(PARAMS_FILE)
    }

    /// The tool table.
    pub fn tools_path(&self) -> PathBuf {
        self.dir.join(TOOLS_FILE)
    }

    /// The modal state file.
    pub fn modal_path(&self) -> PathBuf {
        self.dir.join(MODAL_FILE)
    }

    /// The modal state the last completed MDI command or job left (`None`: the
    /// interpreter's defaults).
    /// A file holding anything but modal words (a motion, an axis word, an O-word,
    /// a parameter, …) is refused by file, line and column.
    pub fn load_modal(&self) -> Result<Option<String>, String> {
        let path = self.modal_path();
        match std::fs::read_to_string(&path) {
            Ok(t) => {
                softnc_gcode::preamble::check(&t, &path.display().to_string()).map_err(|e| {
                    format!("{e} (the machine's modal state; fix it or remove it to start from the interpreter's defaults)")
                })?;
                Ok(Some(t))
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(format!("{}: {e}", self.modal_path().display())),
        }
    }

    /// Keep `gcode` as the machine's modal state (atomically).
    pub fn save_modal(&self, gcode: &str) -> Result<(), String> {
        write_atomic(&self.modal_path(), gcode.as_bytes())
            .map_err(|e| format!("{}: {e}", self.modal_path().display()))
    }

    /// Forget the modal state (a controller starting: the interpreter's defaults,
    /// as LinuxCNC starts).
    pub fn clear_modal(&self) {
        let _ = std::fs::remove_file(self.modal_path());
    }

    /// The parameters as last saved; `None` before the first save (the reader then
    /// starts from the profile's work offsets). A file that cannot be used is an
    /// error that names it and the line or the parameter: unreadable, a bad line,
    /// or — as LinuxCNC's `restore_parameters` refuses it, "required parameter
    /// missing" — a file without one of the parameters LinuxCNC always writes
    /// (G28/G30 positions, G92, the active system, G54 … G59.3: a file cut short).
    /// Nothing runs on offsets that may be wrong; the file is left as it is.
    pub fn load_params(&self) -> Result<Option<Params>, String> {
        let path = self.params_path();
        if !path.exists() {
            return Ok(None);
        }
        let fix = "(the machine's parameter file; fix it or move it aside to start from the profile's offsets)";
        let params = Params::load(&path).map_err(|e| format!("{e} {fix}"))?;
        if let Some(missing) = params.missing_required() {
            return Err(format!(
                "{}: required parameter missing: #{missing} {fix}",
                path.display()
            ));
        }
        Ok(Some(params))
    }

    /// Save `params`: the persistent ones, atomically.
    pub fn save_params(&self, params: &Params) -> Result<(), String> {
        params.save(&self.params_path()).map_err(|e| e.to_string())
    }

    /// The tool table: the saved one, or the profile's before the first edit.
    pub fn load_tools(&self, profile: &MachineProfile) -> Result<Vec<ToolEntry>, String> {
        let path = self.tools_path();
        match std::fs::read_to_string(&path) {
            Ok(text) => ron::from_str::<Vec<ToolEntry>>(&text)
                .map_err(|e| format!("{}: {e} (the machine's tool table)", path.display())),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(profile.tools.clone()),
            Err(e) => Err(format!("{}: cannot read: {e}", path.display())),
        }
    }

    /// Save the tool table atomically.
    pub fn save_tools(&self, tools: &[ToolEntry]) -> Result<(), String> {
        let text = ron::ser::to_string_pretty(tools, ron::ser::PrettyConfig::default())
            .map_err(|e| e.to_string())?;
        write_atomic(&self.tools_path(), text.as_bytes())
            .map_err(|e| format!("{}: {e}", self.tools_path().display()))
    }

    /// How job `job_id` is read, as the MMI checked it: `profile` with the machine's
    /// tool table, and the setup from `start_mm` with the switches and the line to
    /// run from given, and the job's checked setup
    /// ([`crate::jobfile::CheckedSetup`]: the modal preamble, the parameters and the
    /// subroutine files the check took in). What the interpolator and the position
    /// process's preparation both read a job with.
    pub fn job_setup(
        &self,
        profile: &MachineProfile,
        start_mm: [f64; 3],
        switches: crate::job_setup::Switches,
        from_line: Option<u32>,
        job_id: u64,
    ) -> Result<(MachineProfile, crate::job_setup::JobSetup), String> {
        let checked = crate::jobfile::CheckedSetup::load(&self.programs_dir(), job_id)
            .map_err(|e| e.to_string())?;
        let params = match &checked.params {
            Some(text) => Some(
                Params::from_var_text(
                    text,
                    &crate::jobfile::setup_path(&self.programs_dir(), job_id)
                        .display()
                        .to_string(),
                )
                .map_err(|e| e.to_string())?,
            ),
            None => None,
        };
        let files = checked.subroutine_files().map_err(|e| e.to_string())?;
        let setup = crate::job_setup::JobSetup {
            start_mm,
            params,
            switches,
            from_line,
            subroutine_path: Vec::new(),
            user_m_codes: None,
            preamble: checked.preamble,
            preamble_file: checked.preamble_file,
            subroutines: softnc_gcode::SubroutineFiles {
                max_bytes: None,
                snapshot: Some(std::sync::Arc::new(files)),
            },
            // the interpolator's reading sets it from its configuration
            log_files: false,
        };
        Ok((self.profile(profile)?, setup))
    }

    /// The folder of program copies and checked setups.
    pub fn programs_dir(&self) -> PathBuf {
        self.dir.join(PROGRAMS_DIR)
    }

    /// `profile` with the machine's tool table: what programs are read with.
    pub fn profile(&self, profile: &MachineProfile) -> Result<MachineProfile, String> {
        let mut p = profile.clone();
        p.tools = self.load_tools(profile)?;
        Ok(p)
    }
}

/// The offsets in effect, from the parameters: machine = rotate(work + G92) + G5x +
/// tool offset (LinuxCNC's order).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Offsets {
    /// Active coordinate system, 1 (G54) … 9 (G59.3).
    pub coords: usize,
    /// Its origin in machine coordinates.
    pub g5x_mm: [f64; 3],
    /// Its XY rotation (degrees).
    pub rotation_deg: f64,
    /// G92 offset (zero when not applied).
    pub g92_mm: [f64; 3],
    /// Tool in the spindle (0 none).
    pub tool: u32,
    /// Tool offset in effect (G43).
    pub tool_mm: [f64; 3],
}

impl Offsets {
    /// The offsets `params` hold; `None` parameters: the profile's G54, nothing else.
    pub fn from_params(params: Option<&Params>, profile: &MachineProfile) -> Offsets {
        let Some(p) = params else {
            return Offsets {
                coords: 1,
                g5x_mm: profile.work_offsets_mm.first().copied().unwrap_or([0.0; 3]),
                rotation_deg: 0.0,
                g92_mm: [0.0; 3],
                tool: 0,
                tool_mm: [0.0; 3],
            };
        };
        let coords = (p.get(param::COORDS).round() as usize).clamp(1, 9);
        let g92_on = p.get(param::G92_ON) != 0.0;
        Offsets {
            coords,
            g5x_mm: system_mm(p, coords),
            rotation_deg: p.get(system_base(coords) + param::ROTATION),
            g92_mm: if g92_on {
                [0, 1, 2].map(|i| p.get(param::G92_X + i))
            } else {
                [0.0; 3]
            },
            tool: p.get(param::TOOL).max(0.0) as u32,
            tool_mm: [0, 1, 2].map(|i| p.get(param::TOOL_X + i)),
        }
    }

    /// With the tool in the spindle and the tool length offset in force that the
    /// machine's modal state says (`T<n> M6`, `G43.1 Z<len>`; the reader writes
    /// them, [`softnc_gcode::Program::end_modal`]).
    pub fn with_modal(mut self, modal: Option<&str>) -> Offsets {
        let Some(m) = modal else { return self };
        let inch = m.lines().next().is_some_and(|l| l.trim() == "G20");
        let words: Vec<&str> = m.split_whitespace().collect();
        for (i, w) in words.iter().enumerate() {
            if let Some(t) = w.strip_prefix('T') {
                if words.get(i + 1) == Some(&"M6") {
                    self.tool = t.parse().unwrap_or(self.tool);
                }
            }
            if *w == "G43.1" {
                let z = words
                    .get(i + 1)
                    .and_then(|z| z.strip_prefix('Z'))
                    .and_then(|z| z.parse::<f64>().ok());
                if let Some(z) = z {
                    self.tool_mm[2] = if inch { z * 25.4 } else { z };
                }
            }
        }
        self
    }

    /// Work coordinates (the active system's, G92 and tool offset taken off) of
    /// machine position `machine_mm`.
    pub fn work_mm(&self, machine_mm: [f64; 3]) -> [f64; 3] {
        let r = [0, 1, 2].map(|i| machine_mm[i] - self.g5x_mm[i] - self.tool_mm[i]);
        let (s, c) = (-self.rotation_deg).to_radians().sin_cos();
        let unrotated = [r[0] * c - r[1] * s, r[0] * s + r[1] * c, r[2]];
        [0, 1, 2].map(|i| unrotated[i] - self.g92_mm[i])
    }

    /// The active system's name.
    pub fn coords_name(&self) -> &'static str {
        coords_name(self.coords)
    }
}

fn system_base(n: usize) -> usize {
    param::G54_X + (n - 1) * param::PER_SYSTEM
}

/// Origin of coordinate system `n` (1 … 9) in machine coordinates.
fn system_mm(p: &Params, n: usize) -> [f64; 3] {
    let base = system_base(n);
    [0, 1, 2].map(|i| p.get(base + i))
}

/// Every coordinate system's origin and rotation, G92, the tool and its offset (from
/// the modal state), as JSON.
pub fn offsets_json(
    params: Option<&Params>,
    modal: Option<&str>,
    profile: &MachineProfile,
) -> serde_json::Value {
    let active = Offsets::from_params(params, profile).with_modal(modal);
    let systems: Vec<serde_json::Value> = (1..=9)
        .map(|n| {
            let (origin, rot) = match params {
                Some(p) => (system_mm(p, n), p.get(system_base(n) + param::ROTATION)),
                None => (
                    profile
                        .work_offsets_mm
                        .get(n - 1)
                        .copied()
                        .unwrap_or([0.0; 3]),
                    0.0,
                ),
            };
            serde_json::json!({"coords": coords_name(n), "origin_mm": origin,
                "rotation_deg": rot, "active": n == active.coords})
        })
        .collect();
    serde_json::json!({
        "active": active.coords_name(),
        "systems": systems,
        "g92_mm": active.g92_mm,
        "tool": active.tool,
        "tool_offset_mm": active.tool_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn profile() -> MachineProfile {
        MachineProfile::load(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/machines/default.ron"),
        )
        .unwrap()
    }

    #[test]
    fn work_coordinates_take_off_g5x_rotation_g92_and_tool() {
        let mut p = Params::default();
        p.set(param::COORDS, 2.0);
        let g55 = system_base(2);
        p.set(g55, 10.0);
        p.set(g55 + 1, 20.0);
        p.set(g55 + 2, -5.0);
        p.set(g55 + param::ROTATION, 90.0);
        p.set(param::G92_ON, 1.0);
        p.set(param::G92_X, 1.0);
        p.set(param::TOOL_X + 2, 3.0);
        let o = Offsets::from_params(Some(&p), &profile());
        assert_eq!(o.coords_name(), "G55");
        // work (1, 0, 0) + G92 (1, 0, 0) = (2, 0, 0), rotated 90° = (0, 2, 0),
        // + G55 (10, 20, -5) + tool (0, 0, 3) = (10, 22, -2)
        let w = o.work_mm([10.0, 22.0, -2.0]);
        for (got, want) in w.iter().zip([1.0, 0.0, 0.0]) {
            assert!((got - want).abs() < 1e-12, "{w:?}");
        }
    }

    #[test]
    fn the_store_round_trips_and_refuses_a_corrupt_file_by_name() {
        let dir = std::env::temp_dir().join(format!("softnc-store-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let store = MachineStore::new(&dir);
        assert!(store.load_params().unwrap().is_none(), "no file: none");
        let mut p = Params::default();
        p.set(system_base(1), 12.5);
        store.save_params(&p).unwrap();
        let back = store.load_params().unwrap().unwrap();
        assert_eq!(back.get(system_base(1)), 12.5);
        std::fs::write(store.params_path(), "5221\tnot-a-number\n").unwrap();
        let e = store.load_params().unwrap_err();
        assert!(e.contains(PARAMS_FILE), "{e}");
        // cut short: as LinuxCNC, a required parameter missing, by number
        let whole = p.to_var_text();
        let cut: String = whole.lines().take(50).map(|l| format!("{l}\n")).collect();
        std::fs::write(store.params_path(), &cut).unwrap();
        let e = store.load_params().unwrap_err();
        assert!(e.contains("required parameter missing: #5262"), "{e}");
        assert_eq!(std::fs::read_to_string(store.params_path()).unwrap(), cut);
        // tools: the profile's until edited, then the edited table
        let prof = profile();
        assert_eq!(store.load_tools(&prof).unwrap(), prof.tools);
        let mut tools = prof.tools.clone();
        tools[0].length_mm = 42.0;
        store.save_tools(&tools).unwrap();
        assert_eq!(store.profile(&prof).unwrap().tools[0].length_mm, 42.0);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_tool_and_its_offset_come_from_the_modal_state() {
        let o = Offsets::from_params(None, &profile())
            .with_modal(Some("G21\nT3 M6\nF0 S0 G17 G43.1 Z32.3342 G91.1\n"));
        assert_eq!((o.tool, o.tool_mm), (3, [0.0, 0.0, 32.3342]));
        let o = Offsets::from_params(None, &profile()).with_modal(Some("G20\nF0 G43.1 Z1\n"));
        assert_eq!(o.tool_mm[2], 25.4);
    }

    #[test]
    fn coordinate_systems_are_named_as_programs_name_them() {
        assert_eq!(coords_number("g55"), Some(2));
        assert_eq!(coords_number("G59.3"), Some(9));
        assert_eq!(coords_number("G60"), None);
        assert_eq!(coords_name(7), "G59.1");
    }
}
