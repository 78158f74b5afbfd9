//! Command-sample round trip through iceoryx2 between two processes: this binary
//! publishes a sample, a child copy of it (started with SOFTNC_IPC_ECHO set) sends it
//! straight back, and the round trip time goes into a histogram. Prints p50/p99/p99.9/max.
//!
//! `cargo bench -p softnc-ipc --bench roundtrip`

use hdrhistogram::Histogram;
use iceoryx2::prelude::*;
use softnc_ipc::{CommandSample, ServiceNames};
use std::time::{Duration, Instant};

const SAMPLES: u64 = 50_000;
const WARMUP: u64 = 2_000;

fn services(
    node: &Node<ipc::Service>,
    names: &ServiceNames,
    dir: &str,
) -> iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, CommandSample, ()>
{
    node.service_builder(
        &format!("{}/{dir}", names.command())
            .as_str()
            .try_into()
            .unwrap(),
    )
    .publish_subscribe::<CommandSample>()
    .subscriber_max_buffer_size(16)
    .open_or_create()
    .unwrap()
}

fn main() {
    let instance = std::env::var("SOFTNC_IPC_ECHO").ok();
    let echo = instance.is_some();
    let instance = instance.unwrap_or_else(|| format!("bench{}", std::process::id()));
    let names = ServiceNames::new("softnc-bench", &instance);
    let node = NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .unwrap();
    let ping = services(&node, &names, "ping");
    let pong = services(&node, &names, "pong");
    if echo {
        let sub = ping.subscriber_builder().create().unwrap();
        let publ = pong.publisher_builder().create().unwrap();
        let mut n = 0;
        while n < SAMPLES + WARMUP {
            if let Some(s) = sub.receive().unwrap() {
                publ.send_copy(*s).unwrap();
                n += 1;
            } else {
                std::hint::spin_loop();
            }
        }
        return;
    }
    if std::env::args().any(|a| a == "--list") {
        return; // cargo bench --list
    }
    let publ = ping.publisher_builder().create().unwrap();
    let sub = pong.subscriber_builder().create().unwrap();
    let mut child = std::process::Command::new(std::env::current_exe().unwrap())
        .env("SOFTNC_IPC_ECHO", &instance)
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let mut h = Histogram::<u64>::new_with_bounds(1, 1_000_000_000, 3).unwrap();
    for k in 0..SAMPLES + WARMUP {
        let t0 = Instant::now();
        publ.send_copy(CommandSample::new(k, 1, k, [k as f64, 0.0, 0.0]))
            .unwrap();
        let back = loop {
            if let Some(s) = sub.receive().unwrap() {
                break *s;
            }
            if t0.elapsed() > Duration::from_secs(5) {
                panic!("echo process did not answer");
            }
            std::hint::spin_loop();
        };
        assert_eq!(back.seq, k);
        if k >= WARMUP {
            h.record(t0.elapsed().as_nanos() as u64).unwrap();
        }
    }
    let _ = child.wait();
    println!(
        "iceoryx2 CommandSample round trip between two processes, {SAMPLES} samples: p50 {:.1} µs, p99 {:.1} µs, p99.9 {:.1} µs, max {:.1} µs",
        h.value_at_quantile(0.5) as f64 / 1e3,
        h.value_at_quantile(0.99) as f64 / 1e3,
        h.value_at_quantile(0.999) as f64 / 1e3,
        h.max() as f64 / 1e3
    );
}
