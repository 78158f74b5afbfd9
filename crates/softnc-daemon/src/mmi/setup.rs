//! Setting the machine up between jobs: jog (continuous with a dead-man, or by a
//! step), touch-off, the tool table, MDI files, and the checks that refuse a program
//! while the machine is not ready for one.

use super::program::CheckKind;
use super::{transition, MmiTask};
use crate::machine_store::{coords_number, MachineStore, Offsets};
use anyhow::Result;
use softnc_api::Reply;
use softnc_core::store::write_atomic;
use softnc_core::{Axes, MAX_AXES};
use softnc_ipc::{Alarm, AlarmCode, ControlKind, FixedStr, MachineState, ProcessId};
use std::time::Instant;

/// The machine's setup between jobs as the MMI keeps it: the parameter file and
/// the tool table, the parameters and modal state jobs start with, and why a file
/// cannot be used.
pub(super) struct Setup {
    /// The parameter file and the tool table.
    pub(super) store: MachineStore,
    /// The machine's parameters as last saved (`None`: the profile's offsets).
    pub(super) params: Option<softnc_gcode::Params>,
    /// Why the parameter file cannot be used: jobs, MDI and touch-off are refused.
    pub(super) params_error: Option<String>,
    /// The running job's parameters and modal state at its end: kept when it
    /// completes.
    pub(super) pending_params: Option<(u64, softnc_gcode::Params, String)>,
    /// The modal state (G-code) the last completed MDI command or job left: the
    /// next one starts with it, as in LinuxCNC.
    pub(super) modal: Option<String>,
    /// Why the modal state file cannot be used (anything but modal words in it):
    /// jobs, MDI and touch-off are refused until it is fixed or removed.
    pub(super) modal_error: Option<String>,
}

impl MmiTask {
    /// A continuous jog whose client stopped renewing it is stopped (the dead-man).
    pub(super) fn watch_jog(&mut self) -> Result<()> {
        let Some((axis, speed_mm_per_min, renewed)) = self.machine.jog_lease else {
            return Ok(());
        };
        let age = renewed.elapsed().as_secs_f64();
        let jogging = self.position_state() == MachineState::Jogging;
        if !jogging && age > self.cfg.config.heartbeat_timeout_s {
            // it ended (a soft limit, an abort, a stop)
            self.machine.jog_lease = None;
        } else if jogging && age > self.cfg.machine.jog.deadman_s {
            self.machine.jog_lease = None;
            self.send_control_axis(ControlKind::Jog, 0, axis, 0.0, "")?;
            let name = self.axis_name(axis);
            let deadman = self.cfg.machine.jog.deadman_s;
            super::oplog::deadman_stop(&name, speed_mm_per_min, deadman);
            self.ports.alarms_pub.send_copy(Alarm {
                code: AlarmCode::Other.wire(),
                axis,
                process: ProcessId::Mmi.wire(),
                job_id: 0,
                time_index: 0,
                pid: std::process::id(),
                raised_unix_ns: softnc_rt::unix_ns(),
                message: FixedStr::truncated(&format!(
                    "jog of {name} stopped: its client did not renew it for {deadman} s"
                )),
            })?;
        }
        Ok(())
    }

    /// The limit switches tripped in the position process's last status ("X
    /// max", "Z min").
    pub(super) fn limits_tripped(&self) -> Vec<String> {
        let Some(s) = self.machine.last else {
            return Vec::new();
        };
        let m = softnc_core::machine_io::MachineInputs::from(s.inputs);
        let mut out = Vec::new();
        for i in 0..self.cfg.machine.axes.len().min(32) as u32 {
            for (bits, end) in [(m.limit_min, "min"), (m.limit_max, "max")] {
                if bits >> i & 1 == 1 {
                    out.push(format!("{} {end}", self.axis_name(i)));
                }
            }
        }
        out
    }

    /// Override the limit switches (LinuxCNC's override limits): refused while
    /// none is tripped; the position process lets the machine be switched on and
    /// jogged off (away from the switch only) until every switch is released.
    pub(super) fn override_limits(&mut self, state: MachineState) -> Result<Reply> {
        let tripped = self.limits_tripped();
        if tripped.is_empty() {
            return Ok(Self::reply(
                false,
                0,
                "OverrideLimits refused: no limit switch is tripped",
            ));
        }
        if let Err(why) = super::transition(ControlKind::OverrideLimits, state) {
            return Ok(Self::reply(
                false,
                0,
                &format!("OverrideLimits refused ({state:?}): {why}"),
            ));
        }
        self.send_control(ControlKind::OverrideLimits, 0, 0.0, "")?;
        self.machine.limits_overridden = true;
        Ok(Self::reply(
            true,
            0,
            &format!(
                "limit switches overridden ({}) until all are released: switch on and jog off away from the switch",
                tripped.join(", ")
            ),
        ))
    }

    pub(super) fn axis_name(&self, axis: u32) -> String {
        self.cfg
            .machine
            .axes
            .get(axis as usize)
            .map_or_else(|| format!("axis {axis}"), |a| a.name.clone())
    }

    /// Which axes are homed, as the position process reports them.
    pub fn homed(&self) -> Axes<bool> {
        let mask = self.machine.last.map_or(0, |s| s.homed);
        Axes::from_fn(|a| mask & (1 << a.index()) != 0)
    }

    /// Why a job, MDI or touch-off cannot be taken in now, if it cannot.
    pub(super) fn refuse_program(&mut self, state: MachineState, what: &str) -> Option<String> {
        if self.setup.modal_error.is_some() {
            // fixed or removed since: used again
            match self.setup.store.load_modal() {
                Ok(m) => {
                    self.setup.modal = m;
                    self.setup.modal_error = None;
                }
                Err(e) => self.setup.modal_error = Some(e),
            }
        }
        if self.shutdown {
            return Some(format!("shutting down; {what} not started"));
        }
        if state == MachineState::Off {
            return Some(format!("the machine is off; {what} not started"));
        }
        if state != MachineState::Idle || self.job_active() {
            return Some(format!("machine is busy ({state:?}); {what} not started"));
        }
        if let Some(e) = &self.setup.params_error {
            return Some(format!("{e}; {what} not started"));
        }
        if let Some(e) = &self.setup.modal_error {
            return Some(format!("{e}; {what} not started"));
        }
        if let Some(e) = self.history.unsaved.params() {
            return Some(format!(
                "the machine's parameters are not saved ({}: {e}); {what} not started until they are (tried again every {} s)",
                self.setup.store.params_path().display(),
                self.cfg.config.job_record_period_s
            ));
        }
        let homed = self.homed();
        if homed.iter().any(|h| !h) {
            let missing: Vec<String> = (0..MAX_AXES)
                .filter(|&i| !homed[i])
                .map(|i| self.axis_name(i as u32))
                .collect();
            return Some(format!(
                "not homed ({}): home first (`softnc home`); {what} not started",
                missing.join(", ")
            ));
        }
        for p in [ProcessId::Interp, ProcessId::Position] {
            if self.peer_status(p) != softnc_api::ProcessHealth::Alive {
                return Some(format!(
                    "the {} process is {}; {what} not started",
                    p.name(),
                    self.peer_status(p)
                ));
            }
        }
        if let Some(c) = &self.checks.checking {
            return Some(format!("{} is being checked; {what} not started", c.path));
        }
        let abandoned = self.checks.abandoned_running();
        if abandoned >= self.cfg.config.max_abandoned_checks as usize {
            let paths: Vec<&str> = self
                .checks
                .abandoned
                .iter()
                .filter(|(_, t)| !t.is_finished())
                .map(|(p, _)| p.as_str())
                .collect();
            return Some(format!(
                "{abandoned} abandoned checks still run ({}; over check_timeout_s), at most {} (max_abandoned_checks): wait until they end; {what} not started",
                paths.join(", "),
                self.cfg.config.max_abandoned_checks
            ));
        }
        None
    }

    /// MDI text (or a touch-off's block) as a program file the check takes in.
    pub(super) fn mdi_file(&self, text: &str) -> std::result::Result<String, String> {
        let dir = self.cfg.data_dir.join("mdi");
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let path = dir.join("mdi.ngc");
        // between percent signs: the program ends without M2, whose reset of the
        // modal state (G54, G90, …) an MDI block must not make
        let program = format!("%\n{text}\n%\n");
        write_atomic(&path, program.as_bytes()).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(path.display().to_string())
    }

    /// A continuous jog (speed in mm/min, 0 stops it; renewed by its client within
    /// `jog.deadman_s` of the profile) or an incremental one (a distance in mm), checked against the
    /// axis's limits and, once homed, its soft limits.
    #[allow(clippy::too_many_lines)]
    pub(super) fn jog(
        &mut self,
        kind: ControlKind,
        axis: u32,
        value: f64,
        state: MachineState,
    ) -> Result<Reply> {
        let axes = self.cfg.machine.axes.len().min(3) as u32;
        if axis >= axes {
            return Ok(Self::reply(false, 0, "jog: no such axis"));
        }
        if !value.is_finite() {
            return Ok(Self::reply(false, 0, "jog: the value is not a number"));
        }
        let i = axis as usize;
        let a = self.cfg.machine.axes[i].clone();
        let name = a.name.clone();
        let homed = self.homed()[i];
        let pos_mm = self.machine.last.map_or(0.0, |s| s.cmd_mm[i]);
        let deadman = self.cfg.machine.jog.deadman_s;
        if kind == ControlKind::Jog {
            let speed = value;
            if speed == 0.0 {
                if state != MachineState::Jogging {
                    return Ok(Self::reply(
                        false,
                        0,
                        &format!("jog {name} 0: nothing is jogging"),
                    ));
                }
                self.machine.jog_lease = None;
                self.send_control_axis(kind, 0, axis, 0.0, "")?;
                return Ok(Self::reply(true, 0, &format!("jog of {name} stopping")));
            }
            let max = a.max_vel_mm_per_s * 60.0;
            if speed.abs() > max {
                return Ok(Self::reply(
                    false,
                    0,
                    &format!("jog speed {speed} mm/min over {name}'s limit {max} mm/min"),
                ));
            }
            if let Some(lease) = self.machine.jog_lease.as_mut() {
                if state == MachineState::Jogging && lease.0 == axis && lease.1 == speed {
                    lease.2 = Instant::now();
                    return Ok(Self::reply(true, 0, &format!("jog of {name} renewed")));
                }
            }
            if let Err(why) = transition(kind, state) {
                return Ok(Self::reply(
                    false,
                    0,
                    &format!("jog refused ({state:?}): {why}"),
                ));
            }
            if state == MachineState::Jogging && self.machine.jog_lease.is_none_or(|l| l.0 != axis)
            {
                return Ok(Self::reply(
                    false,
                    0,
                    "another jog is under way: stop it first",
                ));
            }
            let at_limit =
                (speed > 0.0 && pos_mm >= a.max_mm) || (speed < 0.0 && pos_mm <= a.min_mm);
            if homed && at_limit {
                return Ok(Self::reply(
                    false,
                    0,
                    &format!("jog refused: {name} is at its soft limit ({pos_mm:.4} mm)"),
                ));
            }
            self.machine.jog_lease = Some((axis, speed, Instant::now()));
            self.machine.jog_target = None;
            self.send_control_axis(kind, 0, axis, speed, "")?;
            self.ask_state(MachineState::Jogging);
            let until = if homed {
                "to its soft limit"
            } else {
                "(not homed: no soft limits)"
            };
            return Ok(Self::reply(
                true,
                0,
                &format!(
                    "jogging {name} at {speed} mm/min {until}; renew within {deadman} s, `softnc jog {name} 0` stops"
                ),
            ));
        }
        // incremental
        if let Err(why) = transition(kind, state) {
            return Ok(Self::reply(
                false,
                0,
                &format!("jog refused ({state:?}): {why}"),
            ));
        }
        if value == 0.0 {
            return Ok(Self::reply(false, 0, "jog: a step of 0 mm"));
        }
        let target_mm = pos_mm + value;
        if homed && !(a.min_mm..=a.max_mm).contains(&target_mm) {
            return Ok(Self::reply(
                false,
                0,
                &format!(
                    "jog beyond the soft limit: {name} would reach {target_mm:.4} mm, outside [{}, {}] mm",
                    a.min_mm, a.max_mm
                ),
            ));
        }
        self.send_control_axis(kind, 0, axis, value, "")?;
        self.ask_state(MachineState::Jogging);
        self.machine.jog_target = Some((i, target_mm));
        Ok(Self::reply(
            true,
            0,
            &format!("jogging {name} by {} mm to {target_mm:.4} mm", value),
        ))
    }

    /// Touch off an axis: a `G10 L20` block for the active (or a named) coordinate
    /// system, checked and run as MDI; only at rest.
    pub(super) fn touch_off(
        &mut self,
        axis: u32,
        value: f64,
        coords: &str,
        state: MachineState,
    ) -> Result<Option<Reply>> {
        let axes = self.cfg.machine.axes.len().min(3) as u32;
        if axis >= axes {
            return Ok(Some(Self::reply(false, 0, "touch-off: no such axis")));
        }
        if !value.is_finite() {
            return Ok(Some(Self::reply(
                false,
                0,
                "touch-off: the value is not a number",
            )));
        }
        let p = if coords.is_empty() {
            0 // the active system
        } else {
            match coords_number(coords) {
                Some(n) => n,
                None => {
                    return Ok(Some(Self::reply(
                        false,
                        0,
                        &format!("touch-off: {coords:?} is not a coordinate system (G54 … G59.3)"),
                    )))
                }
            }
        };
        if matches!(
            state,
            MachineState::Running
                | MachineState::Held
                | MachineState::Paused
                | MachineState::Stopping
                | MachineState::Mdi
                | MachineState::Homing
                | MachineState::Jogging
        ) {
            return Ok(Some(Self::reply(
                false,
                0,
                &format!("touch-off refused ({state:?}): the axes are moving; touch off at rest"),
            )));
        }
        if let Some(why) = self.refuse_program(state, "touch-off") {
            return Ok(Some(Self::reply(false, 0, &why)));
        }
        let name = self.axis_name(axis);
        let block = format!("G10 L20 P{p} {name}{:.6}", value);
        let what = format!(
            "touch-off {name} = {:.4} in {}",
            value,
            if p == 0 {
                Offsets::from_params(self.setup.params.as_ref(), &self.cfg.machine).coords_name()
            } else {
                crate::machine_store::coords_name(p)
            }
        );
        let path = match self.mdi_file(&block) {
            Ok(p) => p,
            Err(e) => return Ok(Some(Self::reply(false, 0, &format!("touch-off: {e}")))),
        };
        Ok(self.begin_check(path, CheckKind::TouchOff { what }))
    }

    /// Set a tool's length (and diameter) in the tool table; only between jobs.
    pub(super) fn tool_set(
        &mut self,
        tool: u32,
        length_mm: f64,
        diameter_mm: Option<f64>,
    ) -> Result<Option<Reply>> {
        if self.job_active() || self.checks.checking.is_some() {
            return Ok(Some(Self::reply(
                false,
                0,
                "tool table: a job is running; edit it between jobs",
            )));
        }
        if let Some(d) = diameter_mm.filter(|d| !(d.is_finite() && *d >= 0.0)) {
            return Ok(Some(Self::reply(
                false,
                0,
                &format!("tool table: diameter {d} is not a number ≥ 0"),
            )));
        }
        if !length_mm.is_finite() || tool == 0 || tool == u32::MAX {
            return Ok(Some(Self::reply(
                false,
                0,
                "tool table: a tool number > 0 and a finite length are needed",
            )));
        }
        let mut tools = match self.setup.store.load_tools(&self.cfg.machine) {
            Ok(t) => t,
            Err(e) => return Ok(Some(Self::reply(false, 0, &e))),
        };
        match tools.iter_mut().find(|t| t.number == tool) {
            Some(t) => {
                t.length_mm = length_mm;
                if let Some(d) = diameter_mm {
                    t.diameter_mm = d;
                }
            }
            None => tools.push(softnc_core::config::ToolEntry {
                number: tool,
                length_mm,
                diameter_mm: diameter_mm.unwrap_or(0.0),
            }),
        }
        tools.sort_by_key(|t| t.number);
        Ok(Some(match self.setup.store.save_tools(&tools) {
            Ok(()) => Self::reply(
                true,
                0,
                &format!("tool {}: length {:.4} mm", tool, length_mm),
            ),
            Err(e) => Self::reply(false, 0, &e),
        }))
    }
}
