//! `softnc ethercat scan --iface IFACE [--json]`: the SubDevices on an EtherCAT bus,
//! in order, with their identities (vendor id, product code, revision, serial) as
//! the daemon configuration's expected SubDevices name them (docs/ethercat.md).
//! Needs CAP_NET_RAW (root).

use anyhow::Result;
use serde::Serialize;
use std::process::ExitCode;

/// Arguments of `softnc ethercat`.
#[derive(clap::Args)]
pub struct EthercatArgs {
    #[command(subcommand)]
    what: EthercatWhat,
}

#[derive(clap::Subcommand)]
enum EthercatWhat {
    /// List the SubDevices on the bus with their identities (brings them to PRE-OP).
    Scan(ScanArgs),
}

#[derive(clap::Args)]
struct ScanArgs {
    /// Network interface of the bus.
    #[arg(long)]
    iface: String,
    /// One JSON object a line instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Row<'a> {
    position: usize,
    station_address: u16,
    name: &'a str,
    vendor_id: u32,
    product_code: u32,
    revision: u32,
    serial: u32,
}

/// Runs `softnc ethercat …`.
pub fn run(args: EthercatArgs) -> Result<ExitCode> {
    let EthercatWhat::Scan(a) = args.what;
    let found = softnc_ethercat::scan(&a.iface)?;
    if !a.json {
        println!("{} SubDevices on {}", found.len(), a.iface);
    }
    for f in &found {
        if a.json {
            let row = Row {
                position: f.position,
                station_address: f.station_address,
                name: &f.name,
                vendor_id: f.identity.vendor_id,
                product_code: f.identity.product_code,
                revision: f.identity.revision,
                serial: f.serial,
            };
            println!("{}", serde_json::to_string(&row)?);
        } else {
            println!(
                "{:>3}  {:#06x}  {}  serial {}  {}",
                f.position, f.station_address, f.identity, f.serial, f.name
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
