//! Service names: every service under one configurable prefix and instance name, so
//! two controllers can run side by side (`<prefix>/<instance>/<service>`).

/// The names of one controller instance's services.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServiceNames {
    base: String,
}

impl ServiceNames {
    /// Names under `<prefix>/<instance>/`.
    pub fn new(prefix: &str, instance: &str) -> Self {
        ServiceNames {
            base: format!("{prefix}/{instance}"),
        }
    }
    fn name(&self, s: &str) -> String {
        format!("{}/{s}", self.base)
    }
    /// Command samples, interpolation → position control (publish-subscribe).
    pub fn command(&self) -> String {
        self.name("command")
    }
    /// Position status/trace samples, position control → MMI (publish-subscribe).
    pub fn status(&self) -> String {
        self.name("status")
    }
    /// Control commands (job start, override, hold, abort, estop, reset), MMI →
    /// interpolation and position control (publish-subscribe).
    pub fn control(&self) -> String {
        self.name("control")
    }
    /// Emergency stops straight from operator clients to the position process,
    /// past the MMI (publish-subscribe).
    pub fn estop(&self) -> String {
        self.name("estop")
    }
    /// Settings on the simulated machine's panel, test → position
    /// (publish-subscribe).
    pub fn sim_panel(&self) -> String {
        self.name("sim_panel")
    }
    /// Heartbeats of every process (publish-subscribe).
    pub fn heartbeat(&self) -> String {
        self.name("heartbeat")
    }
    /// Per-loop timing statistics (publish-subscribe).
    pub fn loop_stats(&self) -> String {
        self.name("loop_stats")
    }
    /// Alarms (publish-subscribe).
    pub fn alarm(&self) -> String {
        self.name("alarm")
    }
    /// Operator requests and replies, client ↔ MMI (request-response).
    pub fn operator(&self) -> String {
        self.name("operator")
    }
    /// Node name of a process of this instance.
    pub fn node(&self, process: &str) -> String {
        format!("{}/{process}", self.base)
    }
}
