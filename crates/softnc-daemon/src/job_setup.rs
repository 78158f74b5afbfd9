//! How a job is read beyond its program text ([`JobSetup`]) and the operator's
//! program-flow switches ([`Switches`]): what the interpolation process starts a job
//! with, the machine's store restores, and the MMI checks a job with.

use softnc_ipc::ControlKind;
use softnc_planner::PlanOptions;

/// The operator's program-flow switches, read when a job starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Switches {
    /// Stop at the end of every block until `step`.
    pub single_block: bool,
    /// M1 stops (optional stop).
    pub optional_stop: bool,
    /// Lines starting with `/` are skipped.
    pub block_delete: bool,
}

impl Default for Switches {
    /// As LinuxCNC's controller starts (`emccanon.cc`: block delete and optional
    /// stop "enabled by default (previous EMC behaviour)"), single block off.
    fn default() -> Self {
        Switches {
            single_block: false,
            optional_stop: true,
            block_delete: true,
        }
    }
}

impl Switches {
    /// Take a switch command (`SingleBlock`, `OptionalStop`, `BlockDelete`, value 1
    /// on, 0 off); false for any other command.
    pub fn apply(&mut self, kind: ControlKind, value: f64) -> bool {
        let on = value != 0.0;
        match kind {
            ControlKind::SingleBlock => self.single_block = on,
            ControlKind::OptionalStop => self.optional_stop = on,
            ControlKind::BlockDelete => self.block_delete = on,
            _ => return false,
        }
        true
    }
}

/// How a job is read beyond its program text: where the machine is, the machine's
/// parameters (offsets, G92, active system), the operator's switches, and the line
/// to run from.
#[derive(Debug, Clone, Default)]
pub struct JobSetup {
    /// Where the machine is when the job starts (machine coordinates).
    pub start_mm: [f64; 3],
    /// The machine's parameters (`None`: the profile's offsets).
    pub params: Option<softnc_gcode::Params>,
    /// The program-flow switches.
    pub switches: Switches,
    /// Run from this line (LinuxCNC's run-from-line); `None`: from the start.
    pub from_line: Option<u32>,
    /// Folders searched for subroutine files.
    pub subroutine_path: Vec<std::path::PathBuf>,
    /// The user M codes' folder (`Loaded::user_m_dir`); `None`: every user M code
    /// is refused.
    pub user_m_codes: Option<std::path::PathBuf>,
    /// The modal state the last MDI command or job left (G-code run first).
    pub preamble: Option<String>,
    /// The file the preamble came from (for its errors).
    pub preamble_file: Option<String>,
    /// How subroutine files are taken in: bounded from the folders (the check), or
    /// the files the check took in (the run).
    pub subroutines: softnc_gcode::SubroutineFiles,
    /// `(LOGOPEN,…)` taken: the daemon has a log folder (`gcode_log_dir`).
    pub log_files: bool,
}

impl JobSetup {
    /// A job from `start_mm` with the profile's offsets and no switch on.
    pub fn at(start_mm: [f64; 3]) -> Self {
        JobSetup {
            start_mm,
            ..Default::default()
        }
    }

    /// The planner's options for it.
    pub fn plan_options(&self) -> PlanOptions {
        PlanOptions {
            start_mm: Some(self.start_mm),
            params: self.params.clone(),
            optional_stop: self.switches.optional_stop,
            block_delete: self.switches.block_delete,
            single_block: self.switches.single_block,
            from_line: self.from_line,
            // the daemon resumes a pause (`resume`, `step`)
            wait_at_program_stops: true,
            // and the machine stops (spindle at speed, tool change, M66) are
            // released by the machine sequencer
            wait_at_machine_stops: true,
            subroutine_path: self.subroutine_path.clone(),
            user_m_codes: self.user_m_codes.clone(),
            preamble: self.preamble.clone(),
            preamble_file: self.preamble_file.clone(),
            subroutines: self.subroutines.clone(),
            log_files: self.log_files,
            ..Default::default()
        }
    }
}
