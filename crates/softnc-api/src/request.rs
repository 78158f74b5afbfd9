//! What an operator client asks of the MMI.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use softnc_core::Axis;

/// One operator command, with its arguments. On the wire: `{"command":
/// "<snake_case name>", <arguments>}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum Request {
    /// Submit the G-code program `path` (a path the controller reads): read, checked
    /// and planned before anything moves, then run.
    SubmitJob {
        /// The program file.
        path: String,
        /// Run from this line (1-based; `None`: the start).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        from_line: Option<u32>,
        /// Adaptive feed (the profile's `force.adaptive_feed` drives the override).
        #[serde(default)]
        adaptive_force: bool,
    },
    /// Feed hold.
    Hold,
    /// Resume after a hold or a pause.
    Resume,
    /// Single block: run the next block.
    Step,
    /// Stop the running job along its path (it ends aborted).
    Abort,
    /// Set the feed override.
    FeedOverride {
        /// Fraction of the programmed feed (1.0: 100 %).
        fraction: f64,
    },
    /// Set the rapid override: traverses run at this fraction of their speed
    /// (LinuxCNC's rapid override, beside the feed override).
    RapidOverride {
        /// Fraction of the traverse speed (0.0 ..= 1.0).
        fraction: f64,
    },
    /// Set the spindle override.
    SpindleOverride {
        /// Fraction of the programmed speed.
        fraction: f64,
    },
    /// Emergency stop (the client also sends it straight to the position process).
    EStop,
    /// Reset after a fault or an E-stop; clears the machine's alarms.
    Reset,
    /// Machine on: drives enabled, holding position.
    MachineOn,
    /// Machine off: drives disabled.
    MachineOff,
    /// Override the limit switches (LinuxCNC's override limits,
    /// `halui.joint.N.override-limits`): with a limit switch tripped, the machine
    /// may be switched on and jogged off it (away from it only) without the
    /// switch stopping it; the override ends by itself once every limit switch is
    /// released. Refused while no limit switch is tripped.
    OverrideLimits,
    /// Home one axis, or all in the profile's order.
    Home {
        /// The axis (`None`: all).
        #[serde(
            default,
            skip_serializing_if = "Option::is_none",
            with = "axis_letter::option"
        )]
        axis: Option<Axis>,
    },
    /// Continuous jog, renewed by the client within the MMI's dead-man time.
    Jog {
        /// The axis.
        #[serde(with = "axis_letter")]
        axis: Axis,
        /// Signed speed (mm/min); 0 stops the jog.
        speed_mm_per_min: f64,
    },
    /// Incremental jog at the profile's jog speed.
    JogStep {
        /// The axis.
        #[serde(with = "axis_letter")]
        axis: Axis,
        /// Signed distance (mm).
        distance_mm: f64,
    },
    /// Run MDI block(s) with the machine's offsets and parameters.
    Mdi {
        /// The blocks, one per line.
        blocks: String,
    },
    /// Set a work offset so that the current position reads `value_mm` on `axis`
    /// (G10 L20).
    TouchOff {
        /// The axis.
        #[serde(with = "axis_letter")]
        axis: Axis,
        /// The value the current position gets (mm).
        value_mm: f64,
        /// The coordinate system, G54 … G59.3 (`None`: the active one).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        coords: Option<String>,
    },
    /// Set a tool's length (and diameter) in the tool table.
    ToolSet {
        /// The tool number (> 0).
        tool: u32,
        /// Length offset (mm).
        length_mm: f64,
        /// Diameter (mm; `None`: unchanged, 0 for a new tool).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        diameter_mm: Option<f64>,
    },
    /// The work offsets ([`crate::Reply::Offsets`]).
    Offsets,
    /// The tool table ([`crate::Reply::Tools`]).
    Tools,
    /// Single block switch.
    SingleBlock {
        /// On or off.
        on: bool,
    },
    /// Optional stop (M1) switch.
    OptionalStop {
        /// On or off.
        on: bool,
    },
    /// Block delete switch.
    BlockDelete {
        /// On or off.
        on: bool,
    },
    /// The machine's status ([`crate::Reply::Status`]).
    Status,
    /// A page of the job history, newest first ([`crate::Reply::Jobs`]).
    Jobs {
        /// Newest records to skip.
        #[serde(default)]
        offset: u64,
    },
    /// Shut the controller down.
    Shutdown,
}

impl Request {
    /// Its name on the wire (`"submit_job"`, …), for messages.
    pub fn name(&self) -> &'static str {
        match self {
            Request::SubmitJob { .. } => "submit_job",
            Request::Hold => "hold",
            Request::Resume => "resume",
            Request::Step => "step",
            Request::Abort => "abort",
            Request::FeedOverride { .. } => "feed_override",
            Request::SpindleOverride { .. } => "spindle_override",
            Request::RapidOverride { .. } => "rapid_override",
            Request::EStop => "e_stop",
            Request::Reset => "reset",
            Request::MachineOn => "machine_on",
            Request::MachineOff => "machine_off",
            Request::OverrideLimits => "override_limits",
            Request::Home { .. } => "home",
            Request::Jog { .. } => "jog",
            Request::JogStep { .. } => "jog_step",
            Request::Mdi { .. } => "mdi",
            Request::TouchOff { .. } => "touch_off",
            Request::ToolSet { .. } => "tool_set",
            Request::Offsets => "offsets",
            Request::Tools => "tools",
            Request::SingleBlock { .. } => "single_block",
            Request::OptionalStop { .. } => "optional_stop",
            Request::BlockDelete { .. } => "block_delete",
            Request::Status => "status",
            Request::Jobs { .. } => "jobs",
            Request::Shutdown => "shutdown",
        }
    }

    /// The request is answered once a program is read and checked (a long one takes
    /// a while), not at once.
    pub fn answered_after_check(&self) -> bool {
        matches!(
            self,
            Request::SubmitJob { .. } | Request::Mdi { .. } | Request::TouchOff { .. }
        )
    }
}

/// An [`Axis`] on the wire: its letter (`"X"`), read in either case.
pub mod axis_letter {
    use super::*;

    /// Write the letter.
    pub fn serialize<S: Serializer>(a: &Axis, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(a.name())
    }

    /// Read a letter.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Axis, D::Error> {
        let text = String::deserialize(d)?;
        let mut chars = text.chars();
        match (chars.next(), chars.next()) {
            (Some(c), None) => Axis::from_letter(c),
            _ => None,
        }
        .ok_or_else(|| serde::de::Error::custom(format!("{text:?} is not an axis letter")))
    }

    /// An optional axis.
    pub mod option {
        use super::*;

        /// Write the letter or nothing.
        pub fn serialize<S: Serializer>(a: &Option<Axis>, s: S) -> Result<S::Ok, S::Error> {
            match a {
                Some(a) => s.serialize_some(a.name()),
                None => s.serialize_none(),
            }
        }

        /// Read a letter or `null`.
        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Axis>, D::Error> {
            #[derive(Deserialize)]
            struct Letter(#[serde(with = "super")] Axis);
            Ok(Option::<Letter>::deserialize(d)?.map(|l| l.0))
        }
    }
}
