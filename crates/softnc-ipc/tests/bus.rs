//! The bus's errors say which step failed and name the service.

use iceoryx2::prelude::*;
use softnc_ipc::bus::{pubsub_service, BusError};
use softnc_ipc::Heartbeat;

#[test]
fn a_service_opened_with_other_limits_or_a_bad_name_is_an_error_naming_it() {
    let node = NodeBuilder::new().create::<ipc::Service>().unwrap();
    let name = format!("softnc-test/bus{}/heartbeat", std::process::id());
    let _first = pubsub_service::<Heartbeat>(&node, &name, 64, 1).unwrap();
    // a larger buffer than the service was made with: not the same limits
    let e = pubsub_service::<Heartbeat>(&node, &name, 128, 1).unwrap_err();
    assert!(matches!(e, BusError::Service { .. }), "{e:?}");
    assert_eq!(e.to_string(), format!("opening service {name}"));
    assert!(std::error::Error::source(&e).is_some());

    let e = pubsub_service::<Heartbeat>(&node, "", 64, 1).unwrap_err();
    assert!(matches!(e, BusError::ServiceName { .. }), "{e:?}");
}
