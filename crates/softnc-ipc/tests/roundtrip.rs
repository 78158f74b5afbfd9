//! Command samples through an iceoryx2 publish-subscribe service arrive complete and
//! in order.

use iceoryx2::prelude::*;
use softnc_ipc::{CommandSample, ServiceNames};

#[test]
fn command_samples_round_trip_in_order() -> Result<(), Box<dyn std::error::Error>> {
    let names = ServiceNames::new("softnc-test", &format!("rt{}", std::process::id()));
    let node = NodeBuilder::new().create::<ipc::Service>()?;
    let service = node
        .service_builder(&names.command().as_str().try_into()?)
        .publish_subscribe::<CommandSample>()
        .subscriber_max_buffer_size(256)
        .history_size(0)
        .open_or_create()?;
    let publisher = service.publisher_builder().max_loaned_samples(4).create()?;
    let subscriber = service.subscriber_builder().buffer_size(256).create()?;
    let mut got = Vec::new();
    for k in 0..1000u64 {
        let mut s = CommandSample::new(k, 42, k, [k as f64 * 0.001, 0.0, -1.0]);
        if k == 999 {
            s.flags |= CommandSample::FLAG_END_OF_JOB;
        }
        publisher.send_copy(s)?;
        if k % 100 == 99 {
            while let Some(r) = subscriber.receive()? {
                got.push(*r);
            }
        }
    }
    assert_eq!(got.len(), 1000);
    for (k, s) in got.iter().enumerate() {
        assert_eq!(s.seq, k as u64);
        assert_eq!(s.pos_mm[0], k as f64 * 0.001);
    }
    assert!(got.last().unwrap().is_end());
    Ok(())
}
