//! The operator gateway: how the members of the operator group operate a controller
//! that runs as its own user. iceoryx2 0.10 creates its files owner-only, so another
//! user cannot open the controller's services; `softncd` therefore serves a Unix
//! stream socket (`operators.socket` of the daemon configuration), made the operator
//! group's with mode 0660, and forwards each request line to the MMI with an operator
//! client of its own (an E-stop on both paths, as every client sends it). The
//! kernel refuses everyone else at `connect`; the peer's credentials (`SO_PEERCRED`)
//! are checked again against the group and logged with every request.
//! The wire is `softnc_client::gateway`'s.

use crate::config::Loaded;
use anyhow::{bail, Context, Result};
use softnc_client::config::OperatorsConfig;
use softnc_client::gateway::{answer_line, read_line, REQUEST_LINE_BYTES};
use softnc_client::Operator;
use softnc_ipc::ipc_guard::{effective_uid, peer_credentials, PeerCredentials};
use std::io::{BufReader, Write};
use std::os::unix::fs::{FileTypeExt, MetadataExt, PermissionsExt};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The socket's mode: the controller's user and the operator group.
const SOCKET_MODE: u32 = 0o660;
/// A connection silent this long is closed (a terminal UI polls every few tens of
/// milliseconds; a command line asks once).
const IDLE_CLOSE: Duration = Duration::from_secs(600);

/// A local group as `/etc/group` lists it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Group {
    /// Group id.
    pub gid: u32,
    /// Its members by name (supplementary membership).
    pub members: Vec<String>,
}

/// The group named `name` in the text of `/etc/group`.
pub fn find_group(etc_group: &str, name: &str) -> Option<Group> {
    etc_group.lines().find_map(|l| {
        let mut f = l.split(':');
        if f.next()? != name {
            return None;
        }
        let _password = f.next()?;
        let gid = f.next()?.trim().parse().ok()?;
        let members = f
            .next()
            .unwrap_or("")
            .split(',')
            .map(str::trim)
            .filter(|m| !m.is_empty())
            .map(String::from)
            .collect();
        Some(Group { gid, members })
    })
}

/// The name and primary group of user `uid` in the text of `/etc/passwd`.
pub fn find_user(etc_passwd: &str, uid: u32) -> Option<(String, u32)> {
    etc_passwd.lines().find_map(|l| {
        let f: Vec<&str> = l.split(':').collect();
        (f.len() >= 4 && f[2].parse() == Ok(uid))
            .then(|| Some((f[0].to_string(), f[3].parse().ok()?)))
            .flatten()
    })
}

/// Whether `peer` may operate the controller: root, the controller's own user, or a
/// member of `group` (its primary group, the group id it connected with, or a
/// supplementary member by name); `etc_passwd` is `/etc/passwd`'s text.
pub fn may_operate(peer: PeerCredentials, group: &Group, etc_passwd: &str) -> bool {
    if peer.uid == 0 || peer.uid == effective_uid() || peer.gid == group.gid {
        return true;
    }
    find_user(etc_passwd, peer.uid)
        .is_some_and(|(name, primary)| primary == group.gid || group.members.contains(&name))
}

/// The gateway of a running `softncd`: the socket is removed when it is dropped.
#[derive(Debug)]
pub struct Gateway {
    socket: PathBuf,
}

impl Drop for Gateway {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.socket);
    }
}

impl Gateway {
    /// Serve the operator gateway of configuration `cfg` if it has one: the socket
    /// made (a stale socket of this user replaced; anything else there refuses the
    /// start), given to the group with mode 0660, and a thread accepting on it.
    pub fn start(cfg: &Loaded) -> Result<Option<Gateway>> {
        let Some(ops) = cfg.config.operators.clone() else {
            return Ok(None);
        };
        let etc_group = std::fs::read_to_string("/etc/group").context("reading /etc/group")?;
        let Some(group) = find_group(&etc_group, &ops.group) else {
            bail!(
                "{}: operators.group: no local group {:?} (create it: groupadd {})",
                cfg.path.display(),
                ops.group,
                ops.group
            );
        };
        let listener = bind(&ops.socket, group.gid)?;
        let config_path = cfg.path.clone();
        let gateway = Gateway {
            socket: ops.socket.clone(),
        };
        std::thread::Builder::new()
            .name("operator-gateway".into())
            .spawn(move || accept_loop(listener, ops, group, config_path))
            .context("starting the operator gateway thread")?;
        Ok(Some(gateway))
    }
}

/// Bind the socket at `path` for group `gid`.
fn bind(path: &Path, gid: u32) -> Result<UnixListener> {
    if let Ok(meta) = std::fs::symlink_metadata(path) {
        if meta.file_type().is_socket() && meta.uid() == effective_uid() {
            std::fs::remove_file(path)
                .with_context(|| format!("removing the stale socket {}", path.display()))?;
        } else {
            bail!(
                "{}: exists and is not a socket of this user: refused (the operator gateway's socket; remove it)",
                path.display()
            );
        }
    }
    let listener = UnixListener::bind(path)
        .with_context(|| format!("operator gateway socket {}", path.display()))?;
    std::os::unix::fs::chown(path, None, Some(gid))
        .with_context(|| format!("giving {} to group {gid}", path.display()))?;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(SOCKET_MODE))
        .with_context(|| format!("mode of {}", path.display()))?;
    tracing::info!(socket = %path.display(), gid, "operator gateway listening");
    Ok(listener)
}

fn accept_loop(listener: UnixListener, ops: OperatorsConfig, group: Group, config: PathBuf) {
    let active = Arc::new(AtomicUsize::new(0));
    for stream in listener.incoming() {
        let Ok(mut stream) = stream else { continue };
        let peer = match peer_credentials(&stream) {
            Ok(p) => p,
            Err(e) => {
                tracing::warn!("operator gateway: peer credentials unreadable ({e}): closed");
                continue;
            }
        };
        let passwd = std::fs::read_to_string("/etc/passwd").unwrap_or_default();
        if !may_operate(peer, &group, &passwd) {
            tracing::warn!(
                uid = peer.uid,
                pid = peer.pid,
                group = %ops.group,
                "operator gateway: refused a user outside the operator group"
            );
            let _ = stream.write_all(
                format!(
                    "err refused: user {} is not in the operator group {}\n",
                    peer.uid, ops.group
                )
                .as_bytes(),
            );
            continue;
        }
        if active.load(Ordering::Acquire) >= ops.max_connections {
            tracing::warn!(
                uid = peer.uid,
                "operator gateway: too many connections: refused"
            );
            let _ = stream.write_all(
                format!(
                    "err refused: {} operator connections are open already\n",
                    ops.max_connections
                )
                .as_bytes(),
            );
            continue;
        }
        active.fetch_add(1, Ordering::AcqRel);
        let active = Arc::clone(&active);
        let config = config.clone();
        let spawned = std::thread::Builder::new()
            .name("operator-conn".into())
            .spawn(move || {
                serve(stream, peer, &config);
                active.fetch_sub(1, Ordering::AcqRel);
            });
        if spawned.is_err() {
            tracing::warn!("operator gateway: no thread for a connection: closed");
        }
    }
}

/// Forward one connection's requests until it closes or stays silent.
fn serve(stream: UnixStream, peer: PeerCredentials, config: &Path) {
    tracing::info!(
        uid = peer.uid,
        pid = peer.pid,
        "operator gateway: connected"
    );
    let _ = stream.set_read_timeout(Some(IDLE_CLOSE));
    let Ok(mut writer) = stream.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(stream);
    let mut op: Option<Operator> = None;
    loop {
        let line = match read_line(&mut reader, REQUEST_LINE_BYTES) {
            Ok(Some(l)) => l,
            Ok(None) => break,
            Err(e) => {
                let _ =
                    writer.write_all(answer_line(&Err(format!("refused: {e}")), "?").as_bytes());
                break;
            }
        };
        let (name, answer) = match softnc_api::decode_request(&line) {
            Err(e) => ("?", Err(format!("unreadable request: {e}"))),
            Ok(request) => {
                let name = request.name();
                if op.is_none() {
                    op = Operator::connect_ipc(config).ok();
                }
                let answer = match &op {
                    Some(op) => op.request(&request).map_err(|e| format!("{e:#}")),
                    None => Err("no controller answers (softnc-mmi is not up): try again".into()),
                };
                if answer.is_err() {
                    op = None; // connect afresh next time (the MMI may have restarted)
                }
                (name, answer)
            }
        };
        tracing::info!(
            uid = peer.uid,
            pid = peer.pid,
            request = name,
            outcome = match &answer {
                Ok(r) if r.is_accepted() => "accepted",
                Ok(_) => "answered",
                Err(_) => "error",
            },
            "operator request through the gateway"
        );
        if writer
            .write_all(answer_line(&answer, name).as_bytes())
            .is_err()
        {
            break;
        }
    }
    tracing::info!(uid = peer.uid, pid = peer.pid, "operator gateway: closed");
}

#[cfg(test)]
mod tests {
    use super::*;

    const GROUP: &str = "root:x:0:\nsoftnc:x:990:alice, bob\nother:x:991:\n";
    const PASSWD: &str = "root:x:0:0:root:/root:/bin/bash\nalice:x:1001:1001::/home/alice:/bin/sh\ncarol:x:1003:990::/home/carol:/bin/sh\nmallory:x:1004:1004::/:/bin/sh\n";

    fn peer(uid: u32, gid: u32) -> PeerCredentials {
        PeerCredentials { pid: 1, uid, gid }
    }

    #[test]
    fn groups_and_users_are_read_from_their_files() {
        let g = find_group(GROUP, "softnc").unwrap();
        assert_eq!(g.gid, 990);
        assert_eq!(g.members, ["alice", "bob"]);
        assert_eq!(find_group(GROUP, "nosuch"), None);
        assert_eq!(
            find_group(GROUP, "other").unwrap().members,
            Vec::<String>::new()
        );
        assert_eq!(find_user(PASSWD, 1003), Some(("carol".into(), 990)));
        assert_eq!(find_user(PASSWD, 4242), None);
    }

    #[test]
    fn only_root_this_user_and_the_group_may_operate() {
        let g = find_group(GROUP, "softnc").unwrap();
        assert!(may_operate(peer(0, 0), &g, PASSWD), "root");
        assert!(
            may_operate(peer(effective_uid(), 4242), &g, PASSWD),
            "the controller's own user"
        );
        assert!(
            may_operate(peer(1001, 1001), &g, PASSWD),
            "a supplementary member"
        );
        assert!(may_operate(peer(1003, 1003), &g, PASSWD), "primary group");
        assert!(
            may_operate(peer(1005, 990), &g, PASSWD),
            "connected with the group's id"
        );
        if effective_uid() != 1004 {
            assert!(
                !may_operate(peer(1004, 1004), &g, PASSWD),
                "outside the group"
            );
            assert!(!may_operate(peer(4242, 4242), &g, PASSWD), "unknown user");
        }
    }

    /// What a shop's scripts or an attacker send: garbage, a request with no
    /// controller behind, an endless line — each answered on one line, the last
    /// closing the connection; nothing reaches a controller.
    #[test]
    fn bad_lines_get_one_line_answers() {
        use std::io::{BufRead, Read};
        let (mut client, server) = UnixStream::pair().unwrap();
        let me = PeerCredentials {
            pid: 1,
            uid: effective_uid(),
            gid: 0,
        };
        let t = std::thread::spawn(move || serve(server, me, Path::new("/nonexistent/softnc.ron")));
        let mut reader = BufReader::new(client.try_clone().unwrap());
        let mut answer = || {
            let mut l = String::new();
            reader.read_line(&mut l).unwrap();
            l
        };
        client.write_all(b"{not json\n").unwrap();
        assert!(answer().starts_with("err unreadable request"));
        let status = softnc_api::encode_request(&softnc_api::Request::Status, 4096).unwrap();
        client.write_all(format!("{status}\n").as_bytes()).unwrap();
        let a = answer();
        assert!(a.starts_with("err no controller answers"), "{a}");
        client
            .write_all(&vec![b'x'; REQUEST_LINE_BYTES + 10])
            .unwrap();
        let a = answer();
        assert!(a.starts_with("err refused: a line longer than"), "{a}");
        let mut rest = Vec::new();
        client.read_to_end(&mut rest).unwrap();
        assert!(rest.is_empty(), "the connection is closed after it");
        t.join().unwrap();
    }
}
