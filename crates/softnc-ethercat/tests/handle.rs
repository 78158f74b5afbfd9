//! The backend's handle without a bus (no root, no network): the configuration
//! checked, the bus untouched until `enable`, a cycle on a bus not brought up
//! refused, a failed bring-up reported with its reason.

use softnc_ethercat::{
    EtherCatBackend, EtherCatConfig, ExpectedSubDevice, Identity, OpenError, Role,
};
use softnc_servo::{BackendError, BusFault, ServoBackend};
use std::time::Duration;

fn drive(axis: u8) -> ExpectedSubDevice {
    ExpectedSubDevice {
        identity: Identity {
            vendor_id: 1,
            product_code: 2,
            revision: 3,
        },
        role: Role::Drive {
            axis,
            counts_per_mm: 1000.0,
            direction: 1,
            following_error_window_counts: 100,
        },
        inputs: Vec::new(),
        outputs: Vec::new(),
        pdo: None,
    }
}

fn config(subdevices: Vec<ExpectedSubDevice>) -> EtherCatConfig {
    EtherCatConfig {
        interface: "softnc-no-such0".into(),
        cycle: Duration::from_millis(1),
        response_timeout: Duration::from_millis(5),
        subdevices,
    }
}

#[test]
fn the_handle_checks_its_configuration_and_opens_on_enable() {
    assert!(matches!(
        EtherCatBackend::new(&config(vec![drive(0), drive(2)])),
        Err(OpenError::Config(_))
    ));
    assert!(matches!(
        EtherCatBackend::new(&config(vec![drive(0), drive(0)])),
        Err(OpenError::Config(_))
    ));
    let mut b =
        EtherCatBackend::new(&config(vec![drive(0), drive(1)])).expect("a valid configuration");
    assert_eq!(b.axes(), 2);
    assert_eq!(b.mm_per_count(1), 1e-3);
    let not_open = BackendError::Bus {
        subdevice: None,
        axis: None,
        reason: BusFault::NotOpen,
    };
    assert_eq!(b.cycle(), Err(not_open));
    assert_eq!(b.enable(), Err(not_open));
    let e = b.last_open_error().expect("why").to_string();
    assert!(e.contains("softnc-no-such0"), "{e}");
}
