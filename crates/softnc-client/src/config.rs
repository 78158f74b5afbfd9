//! What the client reads from the daemon's configuration file (`config/default.ron`):
//! the instance's service names, its heartbeat timeout and its iceoryx2
//! configuration. The daemon's other fields (the machine profile, the loops, …) are
//! the daemon's and are skipped here.

use serde::Deserialize;
use softnc_core::config::{parse_ron, read_text, ConfigError};
use std::path::{Path, PathBuf};

/// The daemon configuration's fields the client uses (the file's other fields are
/// read over).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename = "DaemonConfig")]
pub struct ClientConfig {
    /// Instance name: services live under `<service_prefix>/<instance>/`.
    pub instance: String,
    /// Prefix of every service name.
    pub service_prefix: String,
    /// A process silent for this long is lost (s).
    pub heartbeat_timeout_s: f64,
    /// iceoryx2 configuration; relative to the file's folder as written, absolute
    /// after [`ClientConfig::load`].
    pub iceoryx2_config: PathBuf,
    /// The operator group and its gateway socket (`None`: only the controller's own
    /// user and root operate it).
    #[serde(default)]
    pub operators: Option<OperatorsConfig>,
    /// The data directory (relative to the file's folder as written, absolute after
    /// [`ClientConfig::load`]; the web panel keeps its uploads there).
    #[serde(default)]
    pub data_dir: PathBuf,
    /// The web operator panel `softnc-web` (`None`: off; docs/web.md).
    #[serde(default)]
    pub web: Option<WebConfig>,
}

/// The web operator panel `softnc-web`, which `softncd` starts and supervises when
/// the configuration has it (docs/web.md).
#[derive(Debug, Clone, PartialEq, serde::Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WebConfig {
    /// Address and port it listens on (default `127.0.0.1:8080`: this host only).
    #[serde(default = "default_web_listen")]
    pub listen: String,
    /// The operator token's file (one line; relative to the configuration file's
    /// folder as written, absolute after loading): every command needs it.
    pub token_file: PathBuf,
    /// Status, programs and history need the token too (default: readable without).
    #[serde(default)]
    pub status_needs_token: bool,
    /// Largest program upload (bytes).
    #[serde(default = "default_web_max_upload_bytes")]
    pub max_upload_bytes: u64,
    /// How often the live status goes to each page (Hz).
    #[serde(default = "default_web_status_hz")]
    pub status_hz: f64,
}

fn default_web_listen() -> String {
    "127.0.0.1:8080".into()
}

fn default_web_max_upload_bytes() -> u64 {
    8 << 20
}

fn default_web_status_hz() -> f64 {
    25.0
}

/// The live status's rate bounds (Hz): the operator's refresh rate at least, and
/// no more than the MMI can answer beside the other clients.
const WEB_STATUS_HZ: std::ops::RangeInclusive<f64> = 20.0..=100.0;

/// The largest upload the panel may be configured to take (bytes).
const WEB_MAX_UPLOAD_BYTES: u64 = 64 << 20;

impl WebConfig {
    /// Check the fields (`file`: the configuration, for the error) and make the
    /// token file's path absolute against the configuration's folder `dir`.
    pub fn resolve(&mut self, file: &str, dir: &Path) -> Result<(), ConfigError> {
        if self.listen.parse::<std::net::SocketAddr>().is_err() {
            return Err(ConfigError::invalid(
                file,
                "web.listen",
                format!(
                    "{:?} is not an address and port (e.g. \"127.0.0.1:8080\")",
                    self.listen
                ),
            ));
        }
        if self.token_file.as_os_str().is_empty() {
            return Err(ConfigError::invalid(
                file,
                "web.token_file",
                "must not be empty",
            ));
        }
        if !(1..=WEB_MAX_UPLOAD_BYTES).contains(&self.max_upload_bytes) {
            return Err(ConfigError::invalid(
                file,
                "web.max_upload_bytes",
                format!("must be 1 to {WEB_MAX_UPLOAD_BYTES}"),
            ));
        }
        if !WEB_STATUS_HZ.contains(&self.status_hz) {
            return Err(ConfigError::invalid(
                file,
                "web.status_hz",
                format!(
                    "must be {} to {} Hz",
                    WEB_STATUS_HZ.start(),
                    WEB_STATUS_HZ.end()
                ),
            ));
        }
        self.token_file = dir.join(&self.token_file);
        Ok(())
    }
}

/// Who operates the controller besides its own user and root: the members of a
/// local group, through a socket `softncd` serves (iceoryx2 0.10 makes its files
/// owner-only, so a group cannot share them).
#[derive(Debug, Clone, PartialEq, serde::Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatorsConfig {
    /// The operator group (a local group name, e.g. `softnc`).
    pub group: String,
    /// The gateway socket: relative to the configuration file's folder as written,
    /// absolute after loading. Its folder must let the group through (mode 0750
    /// with the group, as systemd's `RuntimeDirectory` with `Group=`).
    pub socket: PathBuf,
    /// At most this many operator connections at once (each holds a thread and an
    /// iceoryx2 client in `softncd`).
    #[serde(default = "default_max_connections")]
    pub max_connections: usize,
}

fn default_max_connections() -> usize {
    8
}

impl OperatorsConfig {
    /// Check the fields (`file`: the configuration, for the error) and make the
    /// socket path absolute against the configuration's folder `dir`.
    pub fn resolve(&mut self, file: &str, dir: &Path) -> Result<(), ConfigError> {
        if self.group.is_empty() || self.group.contains([':', '/', '\n']) {
            return Err(ConfigError::invalid(
                file,
                "operators.group",
                "must be a local group name",
            ));
        }
        if self.socket.as_os_str().is_empty() {
            return Err(ConfigError::invalid(
                file,
                "operators.socket",
                "must not be empty",
            ));
        }
        if !(1..=64).contains(&self.max_connections) {
            return Err(ConfigError::invalid(
                file,
                "operators.max_connections",
                "must be 1 to 64",
            ));
        }
        self.socket = dir.join(&self.socket);
        Ok(())
    }
}

impl ClientConfig {
    /// Read the client's fields of the daemon configuration at `path`, checked as
    /// the daemon checks them (a bad file is an error naming it and the field).
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let (file, text) = read_text(path)?;
        let mut config: ClientConfig = parse_ron(&text, &file)?;
        if config.instance.is_empty() || config.instance.contains('/') {
            return Err(ConfigError::invalid(
                &file,
                "instance",
                "must be a non-empty name without '/'",
            ));
        }
        if config.service_prefix.is_empty() {
            return Err(ConfigError::invalid(
                &file,
                "service_prefix",
                "must not be empty",
            ));
        }
        if !(config.heartbeat_timeout_s > 0.0 && config.heartbeat_timeout_s.is_finite()) {
            return Err(ConfigError::invalid(
                &file,
                "heartbeat_timeout_s",
                "must be a finite number > 0",
            ));
        }
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        config.iceoryx2_config = dir.join(&config.iceoryx2_config);
        if !config.iceoryx2_config.is_file() {
            return Err(ConfigError::invalid(
                &file,
                "iceoryx2_config",
                format!("{} does not exist", config.iceoryx2_config.display()),
            ));
        }
        if let Some(o) = config.operators.as_mut() {
            o.resolve(&file, &dir)?;
        }
        if let Some(w) = config.web.as_mut() {
            w.resolve(&file, &dir)?;
        }
        config.data_dir = dir.join(&config.data_dir);
        Ok(config)
    }

    /// The gateway socket this process must go through: when the configuration has
    /// an operator group, its socket exists, and this user is not the socket's owner
    /// (the controller's own user, who talks iceoryx2 directly). Root goes through
    /// it too: the installed service keeps iceoryx2's folder in its private `/tmp`
    /// (docs/operations.md, "Operators").
    pub fn gateway_socket_for_this_user(&self) -> Option<PathBuf> {
        use std::os::unix::fs::MetadataExt;
        let socket = &self.operators.as_ref()?.socket;
        let owner = std::fs::symlink_metadata(socket).ok()?.uid();
        (softnc_ipc::ipc_guard::effective_uid() != owner).then(|| socket.clone())
    }

    /// Make the iceoryx2 configuration the process's global one (before any node is
    /// created), its root folder checked and unsafe node-id files removed
    /// ([`softnc_ipc::ipc_guard::prepare`]).
    pub fn setup_iceoryx2(&self) -> Result<(), String> {
        softnc_ipc::ipc_guard::setup_global_config(&self.iceoryx2_config)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn repo() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
    }

    /// The shipped daemon configuration: the client's fields, the others read over.
    #[test]
    fn reads_the_shipped_daemon_configuration() {
        let c = ClientConfig::load(&repo().join("config/default.ron")).unwrap();
        assert_eq!(c.instance, "mill1");
        assert_eq!(c.service_prefix, "softnc");
        assert_eq!(c.heartbeat_timeout_s, 0.5);
        assert!(c.iceoryx2_config.ends_with("iceoryx2.toml"));
        assert!(c.iceoryx2_config.is_file());
    }

    /// A missing file and a bad field name the file.
    #[test]
    fn errors_name_the_file() {
        let missing = repo().join("config/no-such-file.ron");
        let e = ClientConfig::load(&missing).unwrap_err().to_string();
        assert!(
            e.contains("no-such-file.ron") && e.contains("cannot read"),
            "{e}"
        );

        let dir = std::env::temp_dir().join(format!("softnc-client-cfg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let text = std::fs::read_to_string(repo().join("config/default.ron")).unwrap();
        let bad = dir.join("bad.ron");
        std::fs::write(
            &bad,
            text.replace("instance: \"mill1\"", "instance: \"a/b\""),
        )
        .unwrap();
        let e = ClientConfig::load(&bad).unwrap_err().to_string();
        assert!(e.contains("bad.ron") && e.contains("instance"), "{e}");
        std::fs::write(
            &bad,
            text.replace("heartbeat_timeout_s: 0.5", "heartbeat_timeout_s: \"x\""),
        )
        .unwrap();
        let e = ClientConfig::load(&bad).unwrap_err().to_string();
        assert!(
            e.contains("bad.ron") && e.contains("heartbeat_timeout_s"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
