//! The iceoryx2 services of one controller instance, opened or created the same way
//! by every process.

use crate::ipc_guard::IpcGuardError;
use crate::{
    Alarm, CommandSample, ControlCommand, EStopRequest, Heartbeat, LoopStats, PositionStatus,
    ServiceNames, SimPanel,
};
use iceoryx2::node::NodeCreationFailure;
use iceoryx2::port::publisher::{Publisher, PublisherCreateError};
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::subscriber::SubscriberCreateError;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenOrCreateError;
use iceoryx2::service::service_name::ServiceNameError;

/// Why a node, a service or a port could not be made.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    /// The node's name is not one iceoryx2 takes.
    #[error("node name {name}")]
    NodeName {
        /// The name.
        name: String,
        /// Why.
        source: SemanticStringError,
    },
    /// The node could not be created.
    #[error("creating node {name}")]
    Node {
        /// The node's name.
        name: String,
        /// Why.
        source: NodeCreationFailure,
    },
    /// iceoryx2's files could not be made safe ([`crate::ipc_guard::seal`]).
    #[error("iceoryx2 permissions")]
    Permissions(#[source] IpcGuardError),
    /// The service's name is not one iceoryx2 takes.
    #[error("service name {name}")]
    ServiceName {
        /// The name.
        name: String,
        /// Why.
        source: ServiceNameError,
    },
    /// The service could not be opened or created.
    #[error("opening service {name}")]
    Service {
        /// The service.
        name: String,
        /// Why.
        source: PublishSubscribeOpenOrCreateError,
    },
    /// A publisher could not be created.
    #[error("publisher on {service}")]
    Publisher {
        /// The service.
        service: String,
        /// Why.
        source: PublisherCreateError,
    },
    /// A subscriber could not be created.
    #[error("subscriber on {service}")]
    Subscriber {
        /// The service.
        service: String,
        /// Why.
        source: SubscriberCreateError,
    },
}

/// What the bus's functions return.
pub type Result<T> = std::result::Result<T, BusError>;

/// Publish-subscribe port types over the shared-memory service.
pub type Pub<T> = Publisher<ipc::Service, T, ()>;
/// Subscriber port type.
pub type Sub<T> = Subscriber<ipc::Service, T, ()>;

/// Subscriber buffer of the command service: the ring's future half and some slack.
pub const COMMAND_BUFFER: usize = 1200;
/// Subscriber buffer of the status/heartbeat/control/alarm services.
pub const SMALL_BUFFER: usize = 64;

/// Node and service factory of one process.
pub struct Bus {
    /// The process's node.
    pub node: Node<ipc::Service>,
    /// Service names.
    pub names: ServiceNames,
}

macro_rules! pubsub {
    ($fn_pub:ident, $fn_sub:ident, $t:ty, $name:ident, $buf:expr, $hist:expr) => {
        /// Publisher on this service.
        pub fn $fn_pub(&self) -> Result<Pub<$t>> {
            let svc = self.service::<$t>(&self.names.$name(), $buf, $hist)?;
            svc.publisher_builder()
                .create()
                .map_err(|source| BusError::Publisher {
                    service: self.names.$name(),
                    source,
                })
        }
        /// Subscriber on this service.
        pub fn $fn_sub(&self) -> Result<Sub<$t>> {
            let svc = self.service::<$t>(&self.names.$name(), $buf, $hist)?;
            svc.subscriber_builder()
                .buffer_size($buf)
                .create()
                .map_err(|source| BusError::Subscriber {
                    service: self.names.$name(),
                    source,
                })
        }
    };
}

impl Bus {
    /// Create the node `<prefix>/<instance>/<process>`.
    pub fn new(names: ServiceNames, process: &str) -> Result<Self> {
        let node_name = names.node(process);
        let node = NodeBuilder::new()
            .name(
                &node_name
                    .as_str()
                    .try_into()
                    .map_err(|source| BusError::NodeName {
                        name: node_name.clone(),
                        source,
                    })?,
            )
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|source| BusError::Node {
                name: node_name.clone(),
                source,
            })?;
        crate::ipc_guard::seal(node.config()).map_err(BusError::Permissions)?;
        Ok(Bus { node, names })
    }

    fn service<T: std::fmt::Debug + ZeroCopySend + Copy + 'static>(
        &self,
        name: &str,
        buffer: usize,
        history: usize,
    ) -> Result<PubSubService<T>> {
        pubsub_service(&self.node, name, buffer, history)
    }

    /// Subscriber on the E-stop service (operator clients → position).
    pub fn estop_subscriber(&self) -> Result<Sub<EStopRequest>> {
        estop_service(&self.node, &self.names)?
            .subscriber_builder()
            .buffer_size(SMALL_BUFFER)
            .create()
            .map_err(|source| BusError::Subscriber {
                service: self.names.estop(),
                source,
            })
    }

    pubsub!(
        command_publisher,
        command_subscriber,
        CommandSample,
        command,
        COMMAND_BUFFER,
        0
    );
    pubsub!(
        status_publisher,
        status_subscriber,
        PositionStatus,
        status,
        SMALL_BUFFER,
        1
    );
    pubsub!(
        control_publisher,
        control_subscriber,
        ControlCommand,
        control,
        SMALL_BUFFER,
        0
    );
    pubsub!(
        sim_panel_publisher,
        sim_panel_subscriber,
        SimPanel,
        sim_panel,
        SMALL_BUFFER,
        0
    );
    pubsub!(
        heartbeat_publisher,
        heartbeat_subscriber,
        Heartbeat,
        heartbeat,
        SMALL_BUFFER,
        0
    );
    pubsub!(
        alarm_publisher,
        alarm_subscriber,
        Alarm,
        alarm,
        SMALL_BUFFER,
        8
    );
    pubsub!(
        loop_stats_publisher,
        loop_stats_subscriber,
        LoopStats,
        loop_stats,
        SMALL_BUFFER,
        1
    );
}

/// A publish-subscribe service's port factory.
pub type PubSubService<T> =
    iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>;

/// Open (or create) publish-subscribe service `name` on `node` the way every
/// process does (the same limits, or opening it fails).
pub fn pubsub_service<T: std::fmt::Debug + ZeroCopySend + Copy + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
    buffer: usize,
    history: usize,
) -> Result<PubSubService<T>> {
    pubsub_service_for(node, name, buffer, history, 8)
}

fn pubsub_service_for<T: std::fmt::Debug + ZeroCopySend + Copy + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
    buffer: usize,
    history: usize,
    max_publishers: usize,
) -> Result<PubSubService<T>> {
    node.service_builder(&name.try_into().map_err(|source| BusError::ServiceName {
        name: name.to_string(),
        source,
    })?)
    .publish_subscribe::<T>()
    .subscriber_max_buffer_size(buffer)
    .history_size(history)
    .max_publishers(max_publishers)
    .max_subscribers(8)
    .max_nodes(max_publishers + 8)
    .open_or_create()
    .map_err(|source| BusError::Service {
        name: name.to_string(),
        source,
    })
}

/// Operator clients that may hold an E-stop publisher at once.
pub const MAX_ESTOP_CLIENTS: usize = 16;

/// The instance's E-stop service: any operator client publishes on it (its
/// publisher lives while it waits for the stop to show), the position process
/// reads it every cycle.
pub fn estop_service(
    node: &Node<ipc::Service>,
    names: &ServiceNames,
) -> Result<PubSubService<EStopRequest>> {
    pubsub_service_for(node, &names.estop(), SMALL_BUFFER, 0, MAX_ESTOP_CLIENTS)
}

/// Remove the shared-memory resources of dead nodes (after a `kill -9`).
pub fn clean_dead_nodes() -> usize {
    let mut cleaned = 0;
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::<ipc::Service>::Dead(view) = state {
            if view.try_remove_stale_resources().is_ok() {
                cleaned += 1;
            }
        }
        CallbackProgression::Continue
    });
    cleaned
}
