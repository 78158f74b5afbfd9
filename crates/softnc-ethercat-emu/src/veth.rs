//! A `veth` pair for tests (root needed): one end for the MainDevice, the other for
//! the emulator, removed when dropped; and the check whether this process is root.

use std::process::Command;
use std::sync::atomic::{AtomicU32, Ordering};

static NEXT: AtomicU32 = AtomicU32::new(0);

/// Whether the effective user is root (from /proc/self/status).
pub fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("Uid:"))
                .and_then(|l| l.split_whitespace().nth(2).map(|e| e == "0"))
        })
        .unwrap_or(false)
}

/// Two linked interfaces, `main` and `sub`, up.
#[derive(Debug)]
pub struct VethPair {
    /// The MainDevice's end.
    pub main: String,
    /// The emulator's end.
    pub sub: String,
}

fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("ip {}: {e}", args.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

impl VethPair {
    /// A pair with names unique to this process (`ecmPID_N`/`ecsPID_N`, within
    /// the 15 characters an interface name has).
    pub fn create() -> Result<Self, String> {
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let id = format!("{}{}", std::process::id() % 1_000_000, n);
        let pair = VethPair {
            main: format!("ecm{id}"),
            sub: format!("ecs{id}"),
        };
        ip(&[
            "link", "add", &pair.main, "type", "veth", "peer", "name", &pair.sub,
        ])?;
        for i in [&pair.main, &pair.sub] {
            // no IPv6 chatter on the wire
            let _ = std::fs::write(format!("/proc/sys/net/ipv6/conf/{i}/disable_ipv6"), "1");
            ip(&["link", "set", i, "up"])?;
        }
        Ok(pair)
    }
}

impl Drop for VethPair {
    fn drop(&mut self) {
        let _ = ip(&["link", "del", &self.main]);
    }
}
