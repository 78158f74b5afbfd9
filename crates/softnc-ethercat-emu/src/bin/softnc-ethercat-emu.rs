//! `softnc-ethercat-emu --iface IFACE [--drives N] [--io N]`: a segment of emulated
//! EtherCAT SubDevices (N CiA 402 drives, then N I/O terminals; 3 and 1 by
//! default) answering frames on IFACE. Commands on standard input, one a line:
//! `link-down`, `link-up`, `drop N`, `fault POS CODE`, `leave-op POS`, `wkc POS FRAMES`,
//! `home-switch POS COUNTS`, `inputs POS BITS`, `clock-step POS NS`, `status`.

use softnc_ethercat_emu::{control::Command, DeviceKind, Emulator};
use std::io::BufRead;

const USAGE: &str = "usage: softnc-ethercat-emu --iface IFACE [--drives N] [--io N]";

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (mut iface, mut drives, mut io) = (None, 3usize, 1usize);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let v = it.next();
        match (a.as_str(), v) {
            ("--iface", Some(v)) => iface = Some(v.clone()),
            ("--drives", Some(v)) => drives = v.parse().unwrap_or_else(|_| fail(USAGE)),
            ("--io", Some(v)) => io = v.parse().unwrap_or_else(|_| fail(USAGE)),
            _ => fail(USAGE),
        }
    }
    let iface = iface.unwrap_or_else(|| fail(USAGE));
    let mut kinds = vec![DeviceKind::Drive; drives];
    kinds.extend(std::iter::repeat_n(DeviceKind::Io, io));
    let emu = Emulator::spawn(&iface, &kinds).unwrap_or_else(|e| fail(&e.to_string()));
    println!("ready: {} SubDevices on {iface}", kinds.len());
    for line in std::io::stdin().lock().lines() {
        let Ok(line) = line else { break };
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        if line == "status" {
            for v in emu.views() {
                println!("{v:?}");
            }
            println!("{:?}", emu.stats());
            continue;
        }
        match line.parse::<Command>() {
            Ok(c) => {
                emu.command(c);
                println!("ok");
            }
            Err(e) => println!("error: {e}"),
        }
    }
}

fn fail(msg: &str) -> ! {
    eprintln!("softnc-ethercat-emu: {msg}");
    std::process::exit(2)
}
