//! The operator client: talks to `softnc-mmi` over iceoryx2 request-response.
//! Used by the `softnc` binary and by the end-to-end tests.
//!
//! The E-stop takes two paths: straight to the position process on the
//! instance's `estop` service, and to the MMI as every other
//! request. It stops the machine even when the MMI does not answer (hung, stopped);
//! the client then confirms it from the position process's own status.

use crate::config::DaemonConfig;
use anyhow::{bail, Context, Result};
use iceoryx2::port::client::Client;
use iceoryx2::prelude::*;
use softnc_ipc::{
    ControlKind, EStopRequest, FixedStr, MachineState, OperatorReply, OperatorRequest,
    PositionStatus, ServiceNames,
};
use std::path::Path;
use std::time::{Duration, Instant};

/// How long a request waits for the MMI's reply.
const REPLY_TIMEOUT: Duration = Duration::from_secs(5);
/// A job is answered once it is read and checked (a long program takes a while).
pub const JOB_CHECK_TIMEOUT: Duration = Duration::from_secs(300);

/// A connection to one controller instance's MMI.
pub struct Operator {
    node: Node<ipc::Service>,
    /// The instance, for messages.
    instance: String,
    /// The operator service (whether any MMI serves it).
    svc: iceoryx2::service::port_factory::request_response::PortFactory<
        ipc::Service,
        OperatorRequest,
        (),
        OperatorReply,
        (),
    >,
    client: Client<ipc::Service, OperatorRequest, (), OperatorReply, ()>,
    names: ServiceNames,
    /// How long a process may be silent before it counts as lost (s): an E-stop
    /// confirmed by the position process waits this long for the MMI's reply.
    heartbeat_timeout_s: f64,
}

impl Operator {
    /// Connect using the instance named in `config`.
    pub fn connect(config: &Path) -> Result<Self> {
        let loaded = DaemonConfig::load(config)?;
        loaded
            .setup_iceoryx2()
            .map_err(|e| anyhow::anyhow!("iceoryx2 configuration: {e}"))?;
        let names = ServiceNames::new(&loaded.config.service_prefix, &loaded.config.instance);
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .context("creating client node")?;
        crate::ipc_guard::seal(node.config()).context("iceoryx2 permissions")?;
        let svc = node
            .service_builder(&names.operator().as_str().try_into()?)
            .request_response::<OperatorRequest, OperatorReply>()
            .max_clients(16)
            .open_or_create()
            .context("operator service")?;
        let client = svc.client_builder().create().context("operator client")?;
        Ok(Operator {
            node,
            instance: loaded.config.instance.clone(),
            svc,
            client,
            names,
            heartbeat_timeout_s: loaded.config.heartbeat_timeout_s,
        })
    }

    /// Send one request and wait for the reply.
    pub fn request(&self, kind: ControlKind, value: f64, path: &str) -> Result<OperatorReply> {
        self.request_axis(kind, u32::MAX, value, path)
    }

    /// [`Operator::request`] naming an axis (or a tool, or a line: see
    /// [`OperatorRequest::axis`]).
    pub fn request_axis(
        &self,
        kind: ControlKind,
        axis: u32,
        value: f64,
        path: &str,
    ) -> Result<OperatorReply> {
        self.send_request(kind, axis, value, 0, path)
    }

    /// Submit job `path`, from line `from_line` (0: the start), with job options
    /// `flags` (bits: [`softnc_ipc::JOB_ADAPTIVE_FORCE`]).
    pub fn submit_job(&self, path: &str, from_line: u32, flags: u32) -> Result<OperatorReply> {
        self.send_request(ControlKind::StartJob, from_line, 0.0, flags, path)
    }

    fn send_request(
        &self,
        kind: ControlKind,
        axis: u32,
        value: f64,
        flags: u32,
        path: &str,
    ) -> Result<OperatorReply> {
        let path = FixedStr::try_new(path)
            .map_err(|e| anyhow::anyhow!("path of {e}: refused, nothing sent"))?;
        if kind == ControlKind::EStop {
            return self.estop();
        }
        let no_controller = || self.no_controller();
        let served = || self.served();
        // no MMI serves the instance: no reply will ever come
        if !served() {
            bail!(no_controller());
        }
        let pending = self.client.send_copy(OperatorRequest {
            kind: kind.wire(),
            axis,
            value,
            flags,
            path,
        })?;
        let timeout = match kind {
            ControlKind::StartJob | ControlKind::Mdi | ControlKind::TouchOff => JOB_CHECK_TIMEOUT,
            _ => REPLY_TIMEOUT,
        };
        let t0 = Instant::now();
        loop {
            if let Some(r) = pending.receive()? {
                return Ok(*r);
            }
            // a long check goes on only while an MMI serves (none when it died)
            if t0.elapsed() > REPLY_TIMEOUT && !pending.is_connected() && !served() {
                bail!(no_controller());
            }
            if t0.elapsed() > timeout {
                bail!("no reply from softnc-mmi within {timeout:?}: is softncd running?");
            }
            let _ = self.node.wait(Duration::from_millis(2));
        }
    }

    /// Whether an MMI serves the instance's operator service.
    fn served(&self) -> bool {
        self.svc.dynamic_config().number_of_servers() > 0
    }

    /// The error of a command with no controller to take it.
    fn no_controller(&self) -> anyhow::Error {
        anyhow::anyhow!(
            "no controller running for instance {:?} (no softnc-mmi serves it): is softncd running?",
            self.instance
        )
    }

    /// The E-stop on both paths: published straight to the position process
    /// first, then asked of the MMI. The MMI's reply is the answer;
    /// without one, the position process's status showing the E-stop latched is
    /// (the MMI learns it from that status when it answers again). An error only
    /// if neither confirms it within the reply timeout.
    pub fn estop(&self) -> Result<OperatorReply> {
        let direct = self.estop_direct();
        if let Err(e) = &direct {
            tracing::warn!("E-stop past the MMI not sent: {e:#}");
        }
        let pending = self.client.send_copy(OperatorRequest {
            kind: ControlKind::EStop.wire(),
            axis: u32::MAX,
            value: 0.0,
            flags: 0,
            path: FixedStr::empty(),
        });
        let t0 = Instant::now();
        let mut confirmed_at: Option<Instant> = None;
        loop {
            if let Ok(p) = &pending {
                if let Some(r) = p.receive()? {
                    return Ok(*r);
                }
            }
            if let Ok((_, status)) = &direct {
                if confirmed_at.is_none() {
                    while let Some(s) = status.receive()? {
                        if MachineState::from_wire(s.state) == Some(MachineState::EStopped) {
                            confirmed_at = Some(Instant::now());
                        }
                    }
                }
            }
            let mmi_waited = confirmed_at.is_some_and(|t| {
                t.elapsed().as_secs_f64() > self.heartbeat_timeout_s
                    || pending.is_err()
                    || !self.served()
            });
            // no MMI serves and no position process confirmed within its heartbeat
            // timeout: no controller runs (the E-stop was published all the same)
            if confirmed_at.is_none()
                && !self.served()
                && t0.elapsed().as_secs_f64() > self.heartbeat_timeout_s.min(1.0)
            {
                bail!(self.no_controller());
            }
            if mmi_waited {
                return Ok(OperatorReply {
                    accepted: 1,
                    job_id: 0,
                    message: FixedStr::truncated(&format!(
                        "emergency stop (EStopped): taken by the position process directly; the MMI did not answer within {:.1} s",
                        t0.elapsed().as_secs_f64()
                    )),
                });
            }
            if t0.elapsed() > REPLY_TIMEOUT {
                let direct = match &direct {
                    Ok(_) => "sent to the position process directly, not confirmed".to_string(),
                    Err(e) => format!("not sent to the position process directly ({e:#})"),
                };
                bail!(
                    "E-stop {direct}, and no reply from softnc-mmi within {REPLY_TIMEOUT:?}: is softncd running?"
                );
            }
            let _ = self.node.wait(Duration::from_millis(1));
        }
    }

    /// Publish the E-stop on the `estop` service; the publisher is kept (with a
    /// subscriber to the position status that confirms it) while the caller waits.
    #[allow(clippy::type_complexity)]
    fn estop_direct(
        &self,
    ) -> Result<(
        iceoryx2::port::publisher::Publisher<ipc::Service, EStopRequest, ()>,
        crate::bus::Sub<PositionStatus>,
    )> {
        let status = crate::bus::pubsub_service::<PositionStatus>(
            &self.node,
            &self.names.status(),
            crate::bus::SMALL_BUFFER,
            1,
        )?
        .subscriber_builder()
        .buffer_size(crate::bus::SMALL_BUFFER)
        .create()
        .context("position status subscriber")?;
        let publisher = crate::bus::estop_service(&self.node, &self.names)?
            .publisher_builder()
            .create()
            .context("E-stop publisher")?;
        publisher.send_copy(EStopRequest {
            sender_pid: std::process::id(),
            sent_unix_ns: softnc_rt::unix_ns(),
        })?;
        Ok((publisher, status))
    }

    /// Switch the machine on if it is off (the daemon starts off) and wait until it
    /// reports on; an error if it refuses or does not within `timeout`.
    pub fn machine_on(&self, timeout: Duration) -> Result<()> {
        let t0 = Instant::now();
        let mut asked = false;
        loop {
            let s = self.status()?;
            match s["state"].as_str() {
                // the position process has not reported yet
                _ if s["machine_mm"].is_null() => {}
                Some("Off") if !asked => {
                    let r = self.request(ControlKind::MachineOn, 0.0, "")?;
                    if r.accepted != 1 {
                        bail!("machine on refused: {}", r.message.as_str());
                    }
                    asked = true;
                }
                Some("Off") | None => {}
                Some(_) => return Ok(()),
            }
            if t0.elapsed() > timeout {
                bail!("the machine did not come on within {timeout:?}: {s}");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The whole job history, newest first, page by page.
    pub fn jobs(&self) -> Result<Vec<serde_json::Value>> {
        let mut all = Vec::new();
        loop {
            let r = self.request(ControlKind::Jobs, all.len() as f64, "")?;
            if r.accepted != 1 {
                bail!("job history: {}", r.message.as_str());
            }
            let page: serde_json::Value = serde_json::from_str(r.message.as_str())
                .context("unreadable job history page from softnc-mmi")?;
            let jobs = page["jobs"].as_array().cloned().unwrap_or_default();
            let total = page["total"].as_u64().unwrap_or(0) as usize;
            let empty = jobs.is_empty();
            all.extend(jobs);
            if all.len() >= total || empty {
                return Ok(all);
            }
        }
    }

    /// The status as JSON.
    pub fn status(&self) -> Result<serde_json::Value> {
        let r = self.request(ControlKind::Status, 0.0, "")?;
        let text = r.message.as_str();
        serde_json::from_str(text).with_context(|| {
            format!(
                "unreadable status from softnc-mmi ({} bytes): {:?}",
                text.len(),
                &text[..text.len().min(120)]
            )
        })
    }

    /// Wait until the controller is up: the MMI answers and reports the
    /// interpolation and position processes alive (daemon starting up).
    pub fn wait_ready(config: &Path, timeout: Duration) -> Result<Self> {
        let t0 = Instant::now();
        loop {
            let attempt = Operator::connect(config).and_then(|op| {
                let s = op.status()?;
                let up = |p: &str| s["processes"][p] == "alive";
                if up("interp") && up("position") {
                    Ok(op)
                } else {
                    bail!("processes not all up yet: {}", s["processes"])
                }
            });
            match attempt {
                Ok(op) => return Ok(op),
                Err(e) if t0.elapsed() > timeout => {
                    return Err(e.context("softnc-mmi did not answer"))
                }
                Err(_) => std::thread::sleep(Duration::from_millis(100)),
            }
        }
    }
}
