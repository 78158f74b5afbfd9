//! The operator client: sends `softnc-api` [`Request`]s to a controller's MMI
//! (`softnc-mmi`) over iceoryx2 request-response and reads the [`Reply`]s. The
//! `softnc` CLI, its terminal UI and the end-to-end tests use it; they see only
//! `softnc-api` types.
//!
//! The E-stop takes two paths: straight to the position process on the
//! instance's `estop` service, and to the MMI as every other
//! request. It stops the machine even when the MMI does not answer (hung, stopped);
//! the client then confirms it from the position process's own status.

use anyhow::{bail, Context, Result};
use iceoryx2::port::client::Client;
use iceoryx2::prelude::*;
pub use softnc_api::{
    Alarm, AlarmKind, JobRecord, MachineState, OffsetTable, Outcome, ProcessHealth, Reply, Request,
    Status, Tool, JOB_CHECK_TIMEOUT,
};
use softnc_ipc::{
    EStopRequest, FixedStr, OperatorReply, OperatorRequest, PositionStatus, ServiceNames,
};
use std::path::Path;

pub mod config;
pub mod gateway;
pub use config::ClientConfig;
use std::time::{Duration, Instant};

/// How long a request waits for the MMI's reply.
pub(crate) const REPLY_TIMEOUT: Duration = Duration::from_secs(5);

/// A connection to one controller instance's MMI over iceoryx2 (the controller's own
/// user).
struct IpcLink {
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

impl IpcLink {
    /// Connect to the instance of `loaded` over iceoryx2.
    fn connect(loaded: &ClientConfig) -> Result<Self> {
        loaded
            .setup_iceoryx2()
            .map_err(|e| anyhow::anyhow!("iceoryx2 configuration: {e}"))?;
        let names = ServiceNames::new(&loaded.service_prefix, &loaded.instance);
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .context("creating client node")?;
        softnc_ipc::ipc_guard::seal(node.config()).context("iceoryx2 permissions")?;
        let svc = node
            .service_builder(&names.operator().as_str().try_into()?)
            .request_response::<OperatorRequest, OperatorReply>()
            .max_clients(16)
            .open_or_create()
            .context("operator service")?;
        let client = svc.client_builder().create().context("operator client")?;
        Ok(IpcLink {
            node,
            instance: loaded.instance.clone(),
            svc,
            client,
            names,
            heartbeat_timeout_s: loaded.heartbeat_timeout_s,
        })
    }

    /// Send one request and wait for its reply (an E-stop also goes straight to the
    /// position process: [`Operator::estop`]). An error when no MMI answers or the
    /// request does not fit the wire (nothing is sent then).
    fn request(&self, request: &Request) -> Result<Reply> {
        if *request == Request::EStop {
            return self.estop();
        }
        let message = Self::encode(request)?;
        // no MMI serves the instance: no reply will ever come
        if !self.served() {
            bail!(self.no_controller());
        }
        let pending = self.client.send_copy(OperatorRequest { message })?;
        let timeout = if request.answered_after_check() {
            JOB_CHECK_TIMEOUT
        } else {
            REPLY_TIMEOUT
        };
        let t0 = Instant::now();
        loop {
            if let Some(r) = pending.receive()? {
                return Self::decode(&r);
            }
            // a long check goes on only while an MMI serves (none when it died)
            if t0.elapsed() > REPLY_TIMEOUT && !pending.is_connected() && !self.served() {
                bail!(self.no_controller());
            }
            if t0.elapsed() > timeout {
                bail!("no reply from softnc-mmi within {timeout:?}: is softncd running?");
            }
            let _ = self.node.wait(Duration::from_millis(2));
        }
    }

    /// A request as the payload carries it.
    fn encode(request: &Request) -> Result<FixedStr<{ OperatorRequest::MESSAGE_CAPACITY }>> {
        let text = softnc_api::encode_request(request, OperatorRequest::MESSAGE_CAPACITY)?;
        FixedStr::try_new(&text).map_err(|e| anyhow::anyhow!("request of {e}: nothing sent"))
    }

    /// A reply as the payload carries it.
    fn decode(r: &OperatorReply) -> Result<Reply> {
        let text = r.message.as_str();
        softnc_api::decode_reply(text).with_context(|| {
            format!(
                "unreadable reply from softnc-mmi ({} bytes): {:?}",
                text.len(),
                &text[..text.floor_char_boundary_compat(120)]
            )
        })
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
    fn estop(&self) -> Result<Reply> {
        let direct = self.estop_direct();
        if let Err(e) = &direct {
            tracing::warn!("E-stop past the MMI not sent: {e:#}");
        }
        let pending = self.client.send_copy(OperatorRequest {
            message: Self::encode(&Request::EStop)?,
        });
        let t0 = Instant::now();
        let mut confirmed_at: Option<Instant> = None;
        loop {
            if let Ok(p) = &pending {
                if let Some(r) = p.receive()? {
                    return Self::decode(&r);
                }
            }
            if let Ok((_, status)) = &direct {
                if confirmed_at.is_none() {
                    while let Some(s) = status.receive()? {
                        if softnc_ipc::MachineState::from_wire(s.state)
                            == Some(softnc_ipc::MachineState::EStopped)
                        {
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
                return Ok(Reply::accepted(
                    None,
                    format!(
                        "emergency stop (EStopped): taken by the position process directly; the MMI did not answer within {:.1} s",
                        t0.elapsed().as_secs_f64()
                    ),
                ));
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
        softnc_ipc::bus::Sub<PositionStatus>,
    )> {
        use softnc_ipc::bus;
        let status = bus::pubsub_service::<PositionStatus>(
            &self.node,
            &self.names.status(),
            bus::SMALL_BUFFER,
            1,
        )?
        .subscriber_builder()
        .buffer_size(bus::SMALL_BUFFER)
        .create()
        .context("position status subscriber")?;
        let publisher = bus::estop_service(&self.node, &self.names)?
            .publisher_builder()
            .create()
            .context("E-stop publisher")?;
        publisher.send_copy(EStopRequest {
            sender_pid: std::process::id(),
            sent_unix_ns: softnc_rt::unix_ns(),
        })?;
        Ok((publisher, status))
    }
}

/// A connection to one controller instance's MMI: over iceoryx2 for the controller's
/// own user, through `softncd`'s operator gateway socket for root and the members of
/// its operator group ([`ClientConfig::operators`]; iceoryx2 0.10 gives no group
/// access to its files).
pub struct Operator {
    link: Link,
}

enum Link {
    Ipc(Box<IpcLink>),
    Gateway(std::cell::RefCell<gateway::GatewayLink>),
}

impl Operator {
    /// Connect using the instance named in `config` (the daemon's configuration):
    /// through the operator gateway when the configuration has one and this user is
    /// not the controller's own user (the socket's owner), else over iceoryx2.
    pub fn connect(config: &Path) -> Result<Self> {
        let loaded = ClientConfig::load(config)?;
        if let Some(socket) = loaded.gateway_socket_for_this_user() {
            let link = gateway::GatewayLink::connect(&socket, &loaded.instance)?;
            return Ok(Operator {
                link: Link::Gateway(std::cell::RefCell::new(link)),
            });
        }
        Self::connect_ipc(config)
    }

    /// Connect over iceoryx2 whatever the configuration says (the gateway itself
    /// forwards so).
    pub fn connect_ipc(config: &Path) -> Result<Self> {
        let loaded = ClientConfig::load(config)?;
        Ok(Operator {
            link: Link::Ipc(Box::new(IpcLink::connect(&loaded)?)),
        })
    }

    /// Whether this connection goes through the operator gateway.
    pub fn through_gateway(&self) -> bool {
        matches!(self.link, Link::Gateway(_))
    }

    /// Send one request and wait for its reply (an E-stop also goes straight to the
    /// position process: [`Operator::estop`]). An error when no MMI answers or the
    /// request does not fit the wire (nothing is sent then).
    pub fn request(&self, request: &Request) -> Result<Reply> {
        match &self.link {
            Link::Ipc(l) => l.request(request),
            Link::Gateway(g) => g.borrow_mut().request(request),
        }
    }

    /// The E-stop on both paths: published straight to the position process
    /// first, then asked of the MMI (through the gateway: `softncd` does both). The
    /// MMI's reply is the answer; without one, the position process's status showing
    /// the E-stop latched is. An error only if neither confirms it within the reply
    /// timeout.
    pub fn estop(&self) -> Result<Reply> {
        self.request(&Request::EStop)
    }

    /// Switch the machine on if it is off (the daemon starts off) and wait until it
    /// reports on; an error if it refuses or does not within `timeout`.
    pub fn machine_on(&self, timeout: Duration) -> Result<()> {
        let t0 = Instant::now();
        // the alarms standing before the request: a new one of kind `MachineOn`
        // (the drives did not come on, a limit switch is tripped) or `EStop` (the
        // E-stop input is open) is its failure
        let mut before: Option<Vec<Alarm>> = None;
        loop {
            let s = self.status()?;
            match s.state {
                // the position process has not reported yet
                _ if s.machine_mm.is_none() => {}
                MachineState::Off if before.is_none() => {
                    before = Some(s.alarms.clone());
                    let r = self.request(&Request::MachineOn)?;
                    if !r.is_accepted() {
                        bail!("machine on refused: {}", r.message());
                    }
                }
                MachineState::Off => {
                    let failed = s.alarms.iter().find(|a| {
                        matches!(a.code, AlarmKind::MachineOn | AlarmKind::EStop)
                            && !before.as_ref().is_some_and(|b| b.contains(a))
                    });
                    if let Some(a) = failed {
                        bail!("the machine did not come on: {}", a.message);
                    }
                }
                MachineState::Faulted | MachineState::EStopped => {
                    bail!("the machine is {:?}: reset it first", s.state)
                }
                // on as asked, not yet as the position process says
                _ if s.pending.is_some() => {}
                _ => return Ok(()),
            }
            if t0.elapsed() > timeout {
                bail!(
                    "the machine did not come on within {timeout:?}: {}",
                    s.state
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The whole job history, newest first, page by page.
    pub fn jobs(&self) -> Result<Vec<JobRecord>> {
        let mut all = Vec::new();
        loop {
            let page = match self.request(&Request::Jobs {
                offset: all.len() as u64,
            })? {
                Reply::Jobs(page) => page,
                other => bail!("job history: {}", other.message()),
            };
            let empty = page.jobs.is_empty();
            all.extend(page.jobs);
            if all.len() as u64 >= page.total || empty {
                return Ok(all);
            }
        }
    }

    /// The machine's status.
    pub fn status(&self) -> Result<Status> {
        match self.request(&Request::Status)? {
            Reply::Status(s) => Ok(*s),
            other => bail!("status: {}", other.message()),
        }
    }

    /// The work offsets.
    pub fn offsets(&self) -> Result<OffsetTable> {
        match self.request(&Request::Offsets)? {
            Reply::Offsets(o) => Ok(o),
            other => bail!("offsets: {}", other.message()),
        }
    }

    /// The tool table.
    pub fn tools(&self) -> Result<Vec<Tool>> {
        match self.request(&Request::Tools)? {
            Reply::Tools(t) => Ok(t),
            other => bail!("tool table: {}", other.message()),
        }
    }

    /// Wait until the controller is up: the MMI answers and reports the
    /// interpolation and position processes alive (daemon starting up).
    pub fn wait_ready(config: &Path, timeout: Duration) -> Result<Self> {
        let t0 = Instant::now();
        loop {
            let attempt = Operator::connect(config).and_then(|op| {
                let s = op.status()?;
                let p = s.processes;
                if p.interp == ProcessHealth::Alive && p.position == ProcessHealth::Alive {
                    Ok(op)
                } else {
                    bail!(
                        "processes not all up yet: interpolation {}, position {}",
                        p.interp,
                        p.position
                    )
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

/// The byte index at or below `max` that is a char boundary (for short excerpts).
trait FloorCharBoundary {
    fn floor_char_boundary_compat(&self, max: usize) -> usize;
}

impl FloorCharBoundary for str {
    fn floor_char_boundary_compat(&self, max: usize) -> usize {
        let mut i = max.min(self.len());
        while !self.is_char_boundary(i) {
            i -= 1;
        }
        i
    }
}
