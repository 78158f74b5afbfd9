//! The daemon's configuration (`config/default.ron`): one file for all processes.

use serde::{Deserialize, Serialize};
use softnc_core::config::{parse_ron, ConfigError};
use softnc_machine::MachineProfile;
use softnc_rt::RtOptions;
use std::path::{Path, PathBuf};

/// How the position loop keeps time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ClockMode {
    /// Wall clock: one cycle per period on absolute deadlines.
    Realtime,
    /// One cycle per available command sample, as fast as the machine allows
    /// (tests, CI, bit-identical comparison with `softnc sim`).
    Lockstep,
}

/// The whole daemon configuration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DaemonConfig {
    /// Instance name: services live under `<service_prefix>/<instance>/`.
    pub instance: String,
    /// Prefix of every service name.
    pub service_prefix: String,
    /// Machine profile, relative to this file's folder.
    pub machine: PathBuf,
    /// Clock mode of the position loop.
    pub clock: ClockMode,
    /// The servo backend the position process drives.
    #[serde(default)]
    pub backend: BackendKind,
    /// Samples the position process holds ahead of the current one before motion
    /// starts and keeps filled during motion (≥ the zero-lag filter's N).
    pub lookahead_samples: usize,
    /// Real-time options of the interpolation loop.
    #[serde(default)]
    pub interp_rt: RtOptions,
    /// Real-time options of the position loop.
    #[serde(default)]
    pub position_rt: RtOptions,
    /// Heartbeat period (s).
    pub heartbeat_period_s: f64,
    /// A process silent for this long is lost (s).
    pub heartbeat_timeout_s: f64,
    /// Following-error limit per axis (mm): over it, E-stop.
    pub following_error_limit_mm: f64,
    /// Where job history and learning stores live, relative to this file's folder.
    pub data_dir: PathBuf,
    /// Write a per-cycle trace of every job (CSV, the format of `softnc sim --trace`)
    /// into the data directory.
    #[serde(default)]
    pub trace: bool,
    /// Learning store the interpolation process reads learned corrections from
    /// (`softnc learn`), relative to this file's folder; default: `softnc learn`'s
    /// (`$SOFTNC_LEARNING_DIR`, `$XDG_DATA_HOME/softnc/learning`, …).
    #[serde(default)]
    pub learning_dir: Option<PathBuf>,
    /// iceoryx2 configuration, relative to this file's folder.
    pub iceoryx2_config: PathBuf,
    /// How `softncd` watches and restarts its processes.
    #[serde(default)]
    pub supervisor: SupervisorConfig,
    /// How long each part of a controlled stop (SIGTERM, shutdown) may take.
    #[serde(default)]
    pub stopping: StoppingConfig,
    /// How often the running job's record is written to the history (s).
    #[serde(default = "default_job_record_period_s")]
    pub job_record_period_s: f64,
    /// How long the axes get after a job's last sample to come within their
    /// in-position bands (s); the job then ends with an alarm.
    #[serde(default = "default_in_position_timeout_s")]
    pub in_position_timeout_s: f64,
    /// Largest job program the MMI takes (bytes).
    #[serde(default = "default_max_job_bytes")]
    pub max_job_bytes: u64,
    /// Folders searched, in order, for a subroutine `O<name> call` a program does not
    /// define (`name.ngc`; LinuxCNC's `[RS274NGC]SUBROUTINE_PATH`), relative to this
    /// file; after them the program's own folder.
    #[serde(default)]
    pub subroutine_path: Vec<PathBuf>,
    /// The folder of the user M codes M100–M199 (LinuxCNC's
    /// `[RS274NGC]USER_M_PATH`): for `M1nn P… Q…` the path comes to rest and the
    /// executable file `M1nn` there runs with P and Q as its two arguments
    /// (`%f`, −1 for a word not given, as LinuxCNC's `user_defined_add_m_code`);
    /// a job using one that is not there is refused at its check. Relative to
    /// this file; a folder named here must exist. Default: `mcodes` beside the
    /// data directory (`<data_dir>/../mcodes`), when it exists.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub user_m_path: Option<PathBuf>,
    /// The folder a program's `(LOGOPEN,name)`/`(LOGAPPEND,name)` write into
    /// (LinuxCNC writes them where its task runs): each name a plain file name
    /// there, written when the job is accepted, before motion. Relative to this
    /// file; made when first written. `None` (default): such a program is refused
    /// as unsupported.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gcode_log_dir: Option<PathBuf>,
    /// Longest a user M code may run (s): past it the executable is killed and the
    /// job stops along its path with a `MachineWait` alarm (LinuxCNC waits for
    /// it forever).
    #[serde(default = "default_user_m_timeout_s")]
    pub user_m_timeout_s: f64,
    /// No longer taken: the jog's dead-man is the machine profile's
    /// `jog.deadman_s` (bounded by its `jog.max_overrun_mm`). A file that still
    /// sets it is refused, saying where it went.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jog_deadman_s: Option<f64>,
    /// The position process stops what moves — a job along its path, a jog or a
    /// homing decelerating — when it has heard nothing from the MMI (heartbeat or
    /// command) for this long (s): a hung MMI can take no E-stop, no hold, no abort.
    #[serde(default = "default_mmi_silence_stop_s")]
    pub mmi_silence_stop_s: f64,
    /// A job's check (read, plan, soft limits) that takes longer than this is
    /// abandoned: the job is refused and later submits are taken (s). Its thread
    /// cannot be stopped; it ends on its own, and its result is dropped.
    #[serde(default = "default_check_timeout_s")]
    pub check_timeout_s: f64,
    /// New jobs, MDI and touch-offs are refused while this many abandoned checks
    /// still run (each holds a thread and its memory).
    #[serde(default = "default_max_abandoned_checks")]
    pub max_abandoned_checks: u32,
    /// How the real-time loops judge their own timing (realtime clock only).
    #[serde(default)]
    pub loop_timing: LoopTimingConfig,
    /// The operator group and the gateway socket `softncd` serves it on (`None`: only
    /// this user and root operate the controller; docs/operations.md, "Operators").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub operators: Option<softnc_client::config::OperatorsConfig>,
    /// The web operator panel `softnc-web`, started and supervised by `softncd`
    /// (`None`, the default: off; docs/web.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub web: Option<softnc_client::config::WebConfig>,
}

fn default_mmi_silence_stop_s() -> f64 {
    1.0
}

fn default_user_m_timeout_s() -> f64 {
    60.0
}

fn default_check_timeout_s() -> f64 {
    60.0
}

fn default_max_abandoned_checks() -> u32 {
    2
}

/// The loops' own watch over their timing (realtime clock only; a lockstep run has
/// no clock to miss). Each loop measures the period from one wake-up to the next.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LoopTimingConfig {
    /// A period longer than this (s) is a stall: the loop did not run (stopped,
    /// starved of the CPU) and the axes got no new command meanwhile. The position
    /// loop then stops the machine as a fault (jobs, jogs and homing; drives as on a
    /// following-error fault) rather than resume where it stood; the interpolation
    /// loop stops its job along the path. 0.1 s: a hundred cycles at 1 kHz, the
    /// lookahead ring's default depth and the sync-manager watchdog an EtherCAT
    /// drive trips on by default — beyond it a drive has faulted itself anyway.
    /// Far below `supervisor.watchdog_s`, which kills a process silent that long.
    pub stall_fault_s: f64,
    /// A period off the nominal by more than this (s) counts as a late cycle: an
    /// operator alarm (`LoopLate`) with the count and the worst, at most one per
    /// `late_alarm_period_s`.
    pub late_alarm_s: f64,
    /// At most one late-cycle alarm per loop in this long (s).
    pub late_alarm_period_s: f64,
}

impl Default for LoopTimingConfig {
    fn default() -> Self {
        LoopTimingConfig {
            stall_fault_s: 0.1,
            late_alarm_s: 0.01,
            late_alarm_period_s: 10.0,
        }
    }
}

fn default_in_position_timeout_s() -> f64 {
    2.0
}

fn default_max_job_bytes() -> u64 {
    64 << 20
}

fn default_job_record_period_s() -> f64 {
    1.0
}

/// The controlled stop's time limits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StoppingConfig {
    /// How long `softncd` gives its children to stop (a running job decelerates
    /// along its path first) before it kills them (s).
    pub children_grace_s: f64,
    /// How long the position process, asked to stop itself, gives the interpolator
    /// to stop the job along its path before the axes stop on what its ring holds (s).
    pub interp_grace_s: f64,
    /// How long the MMI, asked to stop, waits for the running job to stop so that
    /// its record says how it ended (s).
    pub record_wait_s: f64,
}

impl Default for StoppingConfig {
    fn default() -> Self {
        StoppingConfig {
            children_grace_s: 5.0,
            interp_grace_s: 2.0,
            record_wait_s: 4.0,
        }
    }
}

/// How `softncd` watches and restarts its processes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SupervisorConfig {
    /// A process that has sent no heartbeat for this long is killed and handled as
    /// dead (s); long enough for the longest job check or plan.
    pub watchdog_s: f64,
    /// More restarts than this of one process within `restart_window_s`: it is not
    /// restarted again, the machine is faulted until `reset`.
    pub restart_limit: u32,
    /// The window the restarts are counted in (s).
    pub restart_window_s: f64,
    /// Wait before the first restart (s); doubled for each further one in the window.
    pub restart_delay_s: f64,
    /// Longest wait before a restart (s).
    pub restart_delay_max_s: f64,
}

impl Default for SupervisorConfig {
    fn default() -> Self {
        SupervisorConfig {
            watchdog_s: 10.0,
            restart_limit: 5,
            restart_window_s: 60.0,
            restart_delay_s: 0.1,
            restart_delay_max_s: 5.0,
        }
    }
}

/// Which servo backend (`softnc_servo::ServoBackend`) the position process drives.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub enum BackendKind {
    /// The profile's simulated machine (`softnc_sim::SimBackend`), seeded by the
    /// profile: a lockstep run equals `softnc sim` bit for bit.
    #[default]
    Simulated,
    /// Axes that follow the command exactly (`softnc_servo::LoopbackBackend`): dry
    /// runs without dynamics.
    Loopback,
    /// CiA 402 drives on an EtherCAT bus (`softnc_ethercat::EtherCatBackend`,
    /// docs/ethercat.md), at the profile's interpolation cycle.
    EtherCat(softnc_ethercat::EtherCatSettings),
}

pub use softnc_core::ring::MAX_LOOKAHEAD_SAMPLES;

/// A loaded configuration with its machine profile and resolved paths.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The configuration.
    pub config: DaemonConfig,
    /// The machine profile it names.
    pub machine: MachineProfile,
    /// Absolute path of the machine profile.
    pub machine_path: PathBuf,
    /// Absolute data directory.
    pub data_dir: PathBuf,
    /// The learning store's folder.
    pub learning_dir: PathBuf,
    /// Absolute subroutine folders (`subroutine_path`).
    pub subroutine_path: Vec<PathBuf>,
    /// The user M-code folder (`user_m_path`, or its default; it may not exist).
    pub user_m_dir: PathBuf,
    /// The programs' log folder (`gcode_log_dir`), absolute; `None`: none.
    pub gcode_log_dir: Option<PathBuf>,
    /// The machine profile file's bytes as loaded (the learning store's key).
    pub machine_bytes: Vec<u8>,
    /// The configuration file.
    pub path: PathBuf,
    /// Absolute path of the iceoryx2 configuration.
    pub iceoryx2_config: PathBuf,
}

impl Loaded {
    /// Write this configuration as another instance `instance` into `dir` (its file
    /// `dir/softncd.ron`, its data directory `dir/data`), every path absolute: a
    /// controller of its own beside this one (`softnc demo`) that shares nothing with
    /// it but the machine profile and the learning store.
    pub fn write_instance_copy(&self, dir: &Path, instance: &str) -> std::io::Result<PathBuf> {
        self.write_instance_copy_on(dir, instance, self.config.backend.clone())
    }

    /// [`Loaded::write_instance_copy`] on servo backend `backend`.
    pub fn write_instance_copy_on(
        &self,
        dir: &Path,
        instance: &str,
        backend: BackendKind,
    ) -> std::io::Result<PathBuf> {
        let abs = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
        let mut c = self.config.clone();
        c.instance = instance.to_string();
        c.backend = backend;
        c.machine = abs(&self.machine_path);
        c.iceoryx2_config = abs(&self.iceoryx2_config);
        c.learning_dir = Some(abs(&self.learning_dir));
        c.subroutine_path = self.subroutine_path.iter().map(|p| abs(p)).collect();
        c.user_m_path = self.user_m_dir.is_dir().then(|| abs(&self.user_m_dir));
        c.gcode_log_dir = self.gcode_log_dir.clone();
        std::fs::create_dir_all(dir.join("data"))?;
        c.data_dir = abs(&dir.join("data"));
        // a private instance: no operator gateway (the original's socket is its own)
        c.operators = None;
        // and no web panel (its port is the original's)
        c.web = None;
        let text = ron::ser::to_string_pretty(&c, ron::ser::PrettyConfig::default())
            .map_err(std::io::Error::other)?;
        let path = dir.join("softncd.ron");
        softnc_core::store::write_atomic(&path, text.as_bytes())?;
        Ok(path)
    }

    /// Make the shipped iceoryx2 configuration the process's global one (before any
    /// node is created), its root folder checked and unsafe node-id files removed
    /// ([`softnc_ipc::ipc_guard::prepare`]).
    pub fn setup_iceoryx2(&self) -> Result<(), String> {
        softnc_ipc::ipc_guard::setup_global_config(&self.iceoryx2_config)
    }
}

impl DaemonConfig {
    /// Load, validate, and load the machine profile it names.
    #[allow(clippy::too_many_lines)]
    pub fn load(path: &Path) -> Result<Loaded, ConfigError> {
        let (file, text) = softnc_core::config::read_text(path)?;
        let config: DaemonConfig = parse_ron(&text, &file)?;
        let bad = |p: &str, r: &str| ConfigError::Invalid {
            file: file.clone(),
            path: p.into(),
            reason: r.into(),
        };
        if config.instance.is_empty() || config.instance.contains('/') {
            return Err(bad("instance", "must be a non-empty name without '/'"));
        }
        if config.service_prefix.is_empty() {
            return Err(bad("service_prefix", "must not be empty"));
        }
        if config.lookahead_samples == 0 || config.lookahead_samples > MAX_LOOKAHEAD_SAMPLES {
            return Err(bad(
                "lookahead_samples",
                &format!("must be 1..={MAX_LOOKAHEAD_SAMPLES}"),
            ));
        }
        if !(config.heartbeat_period_s > 0.0
            && config.heartbeat_timeout_s > 2.0 * config.heartbeat_period_s)
        {
            return Err(bad(
                "heartbeat_timeout_s",
                "must be more than twice heartbeat_period_s (> 0)",
            ));
        }
        let sv = config.supervisor;
        if !(sv.watchdog_s.is_finite() && sv.watchdog_s > config.heartbeat_timeout_s) {
            return Err(bad(
                "supervisor.watchdog_s",
                "must be a finite number above heartbeat_timeout_s",
            ));
        }
        if !(sv.restart_window_s > 0.0
            && sv.restart_delay_s >= 0.0
            && sv.restart_delay_max_s >= sv.restart_delay_s
            && sv.restart_delay_max_s.is_finite())
        {
            return Err(bad(
                "supervisor",
                "restart_window_s > 0 and 0 <= restart_delay_s <= restart_delay_max_s (finite)",
            ));
        }
        let st = config.stopping;
        if !(st.interp_grace_s > 0.0
            && st.record_wait_s > st.interp_grace_s
            && st.children_grace_s > st.record_wait_s
            && st.children_grace_s.is_finite())
        {
            return Err(bad(
                "stopping",
                "0 < interp_grace_s < record_wait_s < children_grace_s (finite): each part of a stop waits for the one inside it",
            ));
        }
        if !(config.job_record_period_s > 0.0 && config.job_record_period_s.is_finite()) {
            return Err(bad("job_record_period_s", "must be a finite number > 0"));
        }
        if !(config.check_timeout_s > 0.0
            && config.check_timeout_s < softnc_api::JOB_CHECK_TIMEOUT.as_secs_f64())
        {
            return Err(bad(
                "check_timeout_s",
                &format!(
                    "must be > 0 and below the {} s a client waits for a job's check",
                    softnc_api::JOB_CHECK_TIMEOUT.as_secs()
                ),
            ));
        }
        if config.max_abandoned_checks == 0 {
            return Err(bad("max_abandoned_checks", "must be at least 1"));
        }
        if config.jog_deadman_s.is_some() {
            return Err(bad(
                "jog_deadman_s",
                "the jog's dead-man is the machine profile's jog.deadman_s now (bounded by its jog.max_overrun_mm): remove it here",
            ));
        }
        if !(config.mmi_silence_stop_s >= 2.0 * config.heartbeat_period_s
            && config.mmi_silence_stop_s.is_finite())
        {
            return Err(bad(
                "mmi_silence_stop_s",
                "must be finite and at least two heartbeat periods (heartbeat_period_s)",
            ));
        }
        let lt = config.loop_timing;
        if !(lt.late_alarm_s > 0.0
            && lt.stall_fault_s > lt.late_alarm_s
            && lt.stall_fault_s < sv.watchdog_s
            && lt.late_alarm_period_s > 0.0
            && lt.late_alarm_period_s.is_finite())
        {
            return Err(bad(
                "loop_timing",
                "0 < late_alarm_s < stall_fault_s < supervisor.watchdog_s, late_alarm_period_s finite > 0",
            ));
        }
        if !(config.following_error_limit_mm > 0.0 && config.following_error_limit_mm.is_finite()) {
            return Err(bad(
                "following_error_limit_mm",
                "must be a finite number > 0",
            ));
        }
        if let BackendKind::EtherCat(e) = &config.backend {
            if let Err((p, reason)) = e.validate() {
                return Err(bad(&format!("backend.EtherCat.{p}"), &reason));
            }
        }
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let machine_path = dir.join(&config.machine);
        let machine = MachineProfile::load(&machine_path)?;
        // a client renews a continuous jog every JOG_RENEW_PERIOD: the dead-man
        // must be longer, or a living client's jog would stop
        let renew_s = softnc_api::JOG_RENEW_PERIOD.as_secs_f64();
        if machine.jog.deadman_s <= renew_s {
            return Err(ConfigError::Invalid {
                file: machine_path.display().to_string(),
                path: "jog.deadman_s".into(),
                reason: format!(
                    "{} s is not longer than the {renew_s} s at which clients renew a jog",
                    machine.jog.deadman_s
                ),
            });
        }
        let machine_bytes = std::fs::read(&machine_path).map_err(|source| ConfigError::Io {
            file: machine_path.display().to_string(),
            source,
        })?;
        // the position process must hold the command filters' window (paper 002)
        let needed = (0..softnc_core::MAX_AXES)
            .filter_map(|i| machine.axis_servo(i).command_filter.map(|f| f.order))
            .max()
            .unwrap_or(0);
        let window = softnc_core::ring::window_for_lookahead(config.lookahead_samples);
        if needed > window {
            return Err(bad(
                "lookahead_samples",
                &format!(
                    "the machine's command filter reads {needed} samples ahead, the position \
                     process keeps {window} for {} lookahead samples: raise it to at least {}",
                    config.lookahead_samples,
                    softnc_core::ring::lookahead_for_window(needed)
                ),
            ));
        }
        // the controller stacks must design (PDC eq 11–13, filters) before any process starts
        if let Err(e) = softnc_servo::CycleEngine::try_new(
            &machine,
            softnc_sim::SimBackend::new(&machine, machine.servo.seed, Default::default()),
        ) {
            return Err(ConfigError::Invalid {
                file: machine_path.display().to_string(),
                path: match &e {
                    softnc_servo::EngineError::Compensation(c) => {
                        format!("servo.axes[{}].compensation", c.axis)
                    }
                    softnc_servo::EngineError::Filter { axis, .. } => {
                        format!("servo.axes[{axis}].command_filter")
                    }
                },
                reason: e.to_string(),
            });
        }
        let mut config = config;
        if let Some(o) = config.operators.as_mut() {
            o.resolve(&path.display().to_string(), &dir)?;
        }
        if let Some(w) = config.web.as_mut() {
            w.resolve(&path.display().to_string(), &dir)?;
        }
        let data_dir = dir.join(&config.data_dir);
        let learning_dir = softnc_learning::store_dir(
            config.learning_dir.as_ref().map(|d| dir.join(d)).as_deref(),
        );
        let subroutine_path = config.subroutine_path.iter().map(|p| dir.join(p)).collect();
        let user_m_dir = match &config.user_m_path {
            Some(p) => {
                let d = dir.join(p);
                if !d.is_dir() {
                    return Err(bad(
                        "user_m_path",
                        &format!(
                            "{} is not a folder (the user M codes' folder: make it, or leave \
                             the field out for `mcodes` beside the data directory)",
                            d.display()
                        ),
                    ));
                }
                d
            }
            None => data_dir
                .parent()
                .map_or_else(|| PathBuf::from("mcodes"), |d| d.join("mcodes")),
        };
        let gcode_log_dir = config.gcode_log_dir.as_ref().map(|p| dir.join(p));
        if !(config.user_m_timeout_s.is_finite() && config.user_m_timeout_s > 0.0) {
            return Err(bad(
                "user_m_timeout_s",
                "must be a positive number of seconds",
            ));
        }
        let iceoryx2_config = dir.join(&config.iceoryx2_config);
        if !iceoryx2_config.is_file() {
            return Err(bad(
                "iceoryx2_config",
                &format!("{} does not exist", iceoryx2_config.display()),
            ));
        }
        Ok(Loaded {
            config,
            machine,
            machine_path,
            data_dir,
            learning_dir,
            subroutine_path,
            user_m_dir,
            gcode_log_dir,
            machine_bytes,
            path: path.to_path_buf(),
            iceoryx2_config,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped configuration with `edits`, beside a copy of its machine profile.
    fn load_edited(tag: &str, edits: &[(&str, &str)]) -> Result<Loaded, ConfigError> {
        let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let dir = std::env::temp_dir().join(format!("softnc-config-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("machines")).unwrap();
        std::fs::copy(
            repo.join("config/machines/default.ron"),
            dir.join("machines/default.ron"),
        )
        .unwrap();
        std::fs::copy(repo.join("config/iceoryx2.toml"), dir.join("iceoryx2.toml")).unwrap();
        let mut text = std::fs::read_to_string(repo.join("config/default.ron")).unwrap();
        for (from, to) in edits {
            assert!(text.contains(from), "no {from:?} in config/default.ron");
            text = text.replace(from, to);
        }
        std::fs::write(dir.join("default.ron"), text).unwrap();
        let r = DaemonConfig::load(&dir.join("default.ron"));
        let _ = std::fs::remove_dir_all(&dir);
        r
    }

    #[test]
    fn the_shipped_configuration_loads_with_its_backend_and_stop_limits() {
        let c = load_edited("shipped", &[]).unwrap().config;
        assert_eq!(c.backend, BackendKind::Simulated);
        assert_eq!(c.stopping, StoppingConfig::default());
        assert_eq!(c.job_record_period_s, 1.0);
        let c = load_edited("loopback", &[("backend: Simulated", "backend: Loopback")])
            .unwrap()
            .config;
        assert_eq!(c.backend, BackendKind::Loopback);
        let ethercat = r#"backend: EtherCat((interface: "ecat0", subdevices: [
            (identity: (vendor_id: 0x5f7, product_code: 0x402, revision: 0x10000),
             role: Drive(axis: 0, counts_per_mm: 10000.0, direction: -1, following_error_window_counts: 50000)),
            (identity: (vendor_id: 0x5f7, product_code: 0x80808, revision: 0x10000), role: Io),
        ]))"#;
        let c = load_edited("ethercat", &[("backend: Simulated", ethercat)])
            .unwrap()
            .config;
        let BackendKind::EtherCat(s) = c.backend else {
            panic!("not EtherCat: {:?}", c.backend)
        };
        assert_eq!(s.interface, "ecat0");
        assert_eq!(
            s.response_timeout_s,
            softnc_ethercat::config::DEFAULT_RESPONSE_TIMEOUT_S
        );
        assert_eq!(s.subdevices.len(), 2);
        assert_eq!(s.subdevices[1].role, softnc_ethercat::Role::Io);
        assert!(matches!(
            s.subdevices[0].role,
            softnc_ethercat::Role::Drive { direction: -1, .. }
        ));
    }

    #[test]
    fn a_bad_backend_or_stop_limit_is_refused_with_its_ron_path() {
        let e = load_edited("badbackend", &[("backend: Simulated", "backend: Ethercat")])
            .unwrap_err()
            .to_string();
        assert!(e.contains("backend") && e.contains("Loopback"), "{e}");
        let e = load_edited("badstop", &[("record_wait_s: 4.0", "record_wait_s: 9.0")])
            .unwrap_err()
            .to_string();
        assert!(e.contains("stopping"), "{e}");
        let e = load_edited(
            "badperiod",
            &[("job_record_period_s: 1.0", "job_record_period_s: 0.0")],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("job_record_period_s"), "{e}");
    }

    /// The EtherCAT section's wiring and PDO mapping: a non-default mapping and
    /// wired bits load; each bad entry is refused with its RON path.
    #[test]
    fn an_ethercat_mapping_or_wiring_is_checked_with_its_ron_path() {
        let section = |drive: &str, io: &str| {
            format!(
                r#"backend: EtherCat((interface: "ecat0", subdevices: [
            (identity: (vendor_id: 0x5f7, product_code: 0x402, revision: 0x10000),
             role: Drive(axis: 0, counts_per_mm: 10000.0, direction: 1, following_error_window_counts: 50000){drive}),
            (identity: (vendor_id: 0x5f7, product_code: 0x80808, revision: 0x10000), role: Io{io}),
        ]))"#
            )
        };
        let good = section(
            ", inputs: [(bit: 2, line: 23)], pdo: Some((rx: [TargetPosition, ControlWord], tx: [PositionActual, StatusWord, DigitalInputs, Other(index: 0x2001, sub: 1, bits: 16)]))",
            ", inputs: [(bit: 0, line: 16)], outputs: [(bit: 4, line: 4)]",
        );
        let c = load_edited("ecgood", &[("backend: Simulated", good.as_str())])
            .unwrap()
            .config;
        let BackendKind::EtherCat(s) = c.backend else {
            panic!("not EtherCat: {:?}", c.backend)
        };
        let m = s.subdevices[0].pdo.clone().unwrap();
        assert_eq!(m.tx.len(), 4);
        assert_eq!(
            m.offset_of(softnc_ethercat::PdoObject::DigitalInputs),
            Some(6)
        );
        for (drive, io, path) in [
            (
                ", pdo: Some((rx: [TargetPosition], tx: [StatusWord, PositionActual]))",
                "",
                "backend.EtherCat.subdevices[0].pdo.rx",
            ),
            (
                ", pdo: Some((rx: [ControlWord, TargetPosition, StatusWord], tx: [StatusWord, PositionActual]))",
                "",
                "backend.EtherCat.subdevices[0].pdo.rx[2]",
            ),
            (
                ", pdo: Some((rx: [ControlWord, TargetPosition], tx: [StatusWord, PositionActual, Other(index: 0x2000, sub: 0, bits: 12)]))",
                "",
                "backend.EtherCat.subdevices[0].pdo.tx[2]",
            ),
            (
                ", inputs: [(bit: 2, line: 23)], pdo: Some((rx: [ControlWord, TargetPosition], tx: [StatusWord, PositionActual]))",
                "",
                "backend.EtherCat.subdevices[0].inputs",
            ),
            ("", ", inputs: [(bit: 0, line: 128)]", "backend.EtherCat.subdevices[1].inputs[0].line"),
            (
                ", inputs: [(bit: 2, line: 16)]",
                ", inputs: [(bit: 0, line: 16)]",
                "backend.EtherCat.subdevices[1].inputs[0].line",
            ),
            (
                "",
                ", pdo: Some((rx: [ControlWord, TargetPosition], tx: [StatusWord, PositionActual]))",
                "backend.EtherCat.subdevices[1].pdo",
            ),
        ] {
            let bad = section(drive, io);
            let e = load_edited("ecbad", &[("backend: Simulated", bad.as_str())])
                .unwrap_err()
                .to_string();
            assert!(e.contains(path), "{path} not in: {e}");
        }
    }

    #[test]
    fn the_web_panel_is_off_by_default_and_a_bad_field_names_its_ron_path() {
        let l = load_edited("webdefault", &[]).unwrap();
        assert_eq!(l.config.web, None);
        let on = "    // web: Some((listen: \"127.0.0.1:8080\", token_file: \"web-token\")),";
        let l = load_edited(
            "webon",
            &[(on, "    web: Some((token_file: \"web-token\")),")],
        )
        .unwrap();
        let w = l.config.web.unwrap();
        assert_eq!(w.listen, "127.0.0.1:8080");
        assert!(w.token_file.is_absolute() && w.token_file.ends_with("web-token"));
        assert!(!w.status_needs_token);
        assert_eq!(w.max_upload_bytes, 8 << 20);
        assert_eq!(w.status_hz, 25.0);
        for (field, value) in [
            ("listen", "\"localhost\""),
            ("status_hz", "5.0"),
            ("max_upload_bytes", "0"),
        ] {
            let edit = format!("    web: Some((token_file: \"t\", {field}: {value})),");
            let e = load_edited("webbad", &[(on, edit.as_str())])
                .unwrap_err()
                .to_string();
            assert!(e.contains(&format!("web.{field}")), "{e}");
        }
        let e = load_edited(
            "webunknown",
            &[(on, "    web: Some((token_file: \"t\", port: 80)),")],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("port"), "{e}");
    }

    #[test]
    fn the_user_m_folder_defaults_beside_the_data_dir_and_a_named_one_must_exist() {
        let l = load_edited("userm", &[]).unwrap();
        assert_eq!(l.config.user_m_path, None);
        assert_eq!(l.user_m_dir, l.data_dir.parent().unwrap().join("mcodes"));
        assert_eq!(l.config.user_m_timeout_s, 60.0);
        let e = load_edited(
            "usermmissing",
            &[(
                "subroutine_path: [\"../subroutines\"],",
                "subroutine_path: [\"../subroutines\"], user_m_path: Some(\"no-such-mcodes\"),",
            )],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("user_m_path") && e.contains("no-such-mcodes") && e.contains("not a folder"),
            "{e}"
        );
        let e = load_edited(
            "usermtimeout",
            &[(
                "subroutine_path: [\"../subroutines\"],",
                "subroutine_path: [\"../subroutines\"], user_m_timeout_s: 0.0,",
            )],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("user_m_timeout_s"), "{e}");
    }
}
