//! Writing a secured site's files: the router's configuration with the ACL,
//! the user/password dictionary, and one client configuration per identity.
//! Every file is created new (never over an existing one), readable by its
//! owner only (0600), in a directory only the owner can enter (0700).

use std::io::Write;
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

use rand::TryRngCore;
use serde_json::{Value, json};

use super::SecureError;
use super::identity::Identity;

/// The router's configuration file in a secured directory (the first
/// router's; the others' are `router-<k>.json5`).
pub const ROUTER_FILE: &str = "router.json5";

/// The configuration file of router `k` (from 1).
pub fn router_file(k: usize) -> String {
    if k <= 1 {
        ROUTER_FILE.to_string()
    } else {
        format!("router-{k}.json5")
    }
}
/// The user/password dictionary the router checks clients against.
pub const USERS_FILE: &str = "users.txt";
/// The directory of the client configurations, one per identity.
pub const CLIENTS_DIR: &str = "clients";
/// The directory of what nodes get of the TLS setup: the site CA's
/// certificate and each identity's key and certificate.
pub const TLS_DIR: &str = "tls";
/// The directory of the site CA's private key (and certificate): it signs
/// certificates and is kept apart, never copied to a node.
pub const CA_DIR: &str = "ca";
/// The CA's certificate, in [`CA_DIR`] and [`TLS_DIR`].
pub const CA_CERT_FILE: &str = "ca.crt";
/// The CA's private key, in [`CA_DIR`].
pub const CA_KEY_FILE: &str = "ca.key";

/// The TLS files one end of a link uses: the CA it trusts, its own
/// certificate and key.
#[derive(Debug, Clone)]
pub struct TlsFiles {
    /// The site CA's certificate.
    pub ca: PathBuf,
    /// This identity's certificate.
    pub cert: PathBuf,
    /// This identity's private key.
    pub key: PathBuf,
}

impl TlsFiles {
    /// The files of the identity named `name` (its certificate's common
    /// name) in the secured directory `dir`.
    pub fn of(dir: &Path, name: &str) -> Self {
        let tls = dir.join(TLS_DIR);
        TlsFiles {
            ca: tls.join(CA_CERT_FILE),
            cert: tls.join(format!("{name}.crt")),
            key: tls.join(format!("{name}.key")),
        }
    }
}

/// `transport.link.tls` of a client: trust the site CA, verify that the
/// router's certificate names the host connected to, show its own (Zenoh
/// sends a client certificate only with `enable_mtls` on the client too).
fn client_tls(tls: &TlsFiles) -> Value {
    json!({
        "enable_mtls": true,
        "root_ca_certificate": tls.ca.display().to_string(),
        "connect_certificate": tls.cert.display().to_string(),
        "connect_private_key": tls.key.display().to_string(),
        "verify_name_on_connect": true,
        "close_link_on_expiration": true,
    })
}

/// `transport.link.tls` of a router: the same as a client's for the links
/// it opens, and for the links it accepts its certificate and a client
/// certificate of the site CA required (mutual TLS).
fn router_tls(tls: &TlsFiles) -> Value {
    let mut value = client_tls(tls);
    value["listen_certificate"] = json!(tls.cert.display().to_string());
    value["listen_private_key"] = json!(tls.key.display().to_string());
    value
}

/// A link lease of 3 s, as `deploy/zenoh/*.json5`: a hung host is noticed
/// within a few cycles.
fn link_settings() -> Value {
    json!({ "tx": { "lease": 3000, "keep_alive": 4 } })
}

/// A password nobody can guess: 192 bits from the operating system's random
/// source (`getrandom`), hex-encoded so that it never holds a `:` (the
/// dictionary's separator) or a quote.
pub fn new_password() -> Result<String, SecureError> {
    let mut bytes = [0u8; 24];
    rand::rngs::OsRng
        .try_fill_bytes(&mut bytes)
        .map_err(|e| SecureError::Random(e.to_string()))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// The configuration of a client that authenticates as `user`, connecting
/// to `connect`; with `tls`, over mutual TLS with these files.
pub fn client_config(
    user: &str,
    password: &str,
    connect: &[String],
    tls: Option<&TlsFiles>,
) -> Value {
    let mut link = link_settings();
    if let Some(tls) = tls {
        link["tls"] = client_tls(tls);
    }
    json!({
        "mode": "client",
        "connect": { "endpoints": connect, "timeout_ms": -1 },
        "scouting": { "multicast": { "enabled": false } },
        "transport": {
            "link": link,
            "auth": { "usrpwd": { "user": user, "password": password } },
        },
    })
}

/// The router's configuration: its pinned id `zid` (without TLS, the only
/// way the routers it links to know it), listening on `listen`, clients
/// checked against the dictionary at `users` and, with `tls`, by their
/// certificates; the ACL `access_control`, the message sizes
/// `low_pass_filter` ([`super::limits`]); `link`: the routers it connects
/// to and the credential it authenticates there with (user `router`).
pub fn router_config(
    zid: Option<&str>,
    listen: &[String],
    users: &Path,
    (access_control, low_pass_filter): (Value, Value),
    link: Option<(&[String], &str)>,
    tls: Option<&TlsFiles>,
) -> Value {
    let mut usrpwd = json!({ "dictionary_file": users.display().to_string() });
    let mut connect = json!({ "endpoints": [] });
    if let Some((endpoints, password)) = link {
        usrpwd["user"] = json!("router");
        usrpwd["password"] = json!(password);
        connect = json!({ "endpoints": endpoints, "timeout_ms": -1 });
    }
    let mut link = link_settings();
    if let Some(tls) = tls {
        link["tls"] = router_tls(tls);
    }
    let mut config = json!({
        "mode": "router",
        "listen": { "endpoints": listen },
        "connect": connect,
        "scouting": { "multicast": { "enabled": false } },
        "transport": {
            "link": link,
            "auth": { "usrpwd": usrpwd },
        },
        "access_control": access_control,
        "low_pass_filter": low_pass_filter,
    });
    if let Some(zid) = zid {
        config["id"] = json!(zid);
    }
    config
}

/// A Zenoh id for a router (32 lowercase hex digits, the first not 0), from
/// the operating system's random source: pinned in its configuration so
/// that the other routers' ACL can name it.
pub fn new_zid() -> Result<String, SecureError> {
    let mut bytes = [0u8; 16];
    rand::rngs::OsRng
        .try_fill_bytes(&mut bytes)
        .map_err(|e| SecureError::Random(e.to_string()))?;
    bytes[0] |= 0x10;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// Creates `dir` (and its parents) with mode 0700; an existing directory
/// must be empty, so that no credential is ever overwritten or mixed.
pub fn create_private_dir(dir: &Path) -> Result<(), SecureError> {
    if dir.exists() {
        let mut entries = std::fs::read_dir(dir).map_err(|e| SecureError::io(dir, e))?;
        if entries.next().is_some() {
            return Err(SecureError::NotEmpty(dir.to_path_buf()));
        }
    }
    std::fs::DirBuilder::new()
        .recursive(true)
        .mode(0o700)
        .create(dir)
        .map_err(|e| SecureError::io(dir, e))
}

/// Writes `text` to a new file `path`, mode 0600.
pub fn write_private(path: &Path, text: &str) -> Result<(), SecureError> {
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
        .map_err(|e| SecureError::io(path, e))?;
    file.write_all(text.as_bytes())
        .and_then(|_| file.sync_all())
        .map_err(|e| SecureError::io(path, e))
}

/// A JSON document as a JSON5 file with a comment on top.
pub fn with_header(header: &str, value: &Value) -> String {
    let body = serde_json::to_string_pretty(value).unwrap_or_else(|_| "{}".into());
    let comment: String = header.lines().map(|l| format!("// {l}\n")).collect();
    format!("{comment}{body}\n")
}

/// The client configuration of `identity` in the secured directory `dir`.
pub fn client_path(dir: &Path, identity: &Identity) -> PathBuf {
    dir.join(CLIENTS_DIR).join(identity.file_name())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passwords_are_long_hex_and_differ() {
        let a = new_password().unwrap();
        let b = new_password().unwrap();
        assert_eq!(a.len(), 48);
        assert!(a.bytes().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
    }

    #[test]
    fn files_are_private_and_never_overwritten() {
        use std::os::unix::fs::PermissionsExt;
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("s");
        create_private_dir(&dir).unwrap();
        let mode = std::fs::metadata(&dir).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o700);
        let f = dir.join("x");
        write_private(&f, "secret").unwrap();
        assert_eq!(
            std::fs::metadata(&f).unwrap().permissions().mode() & 0o777,
            0o600
        );
        assert!(write_private(&f, "other").is_err());
        assert_eq!(std::fs::read_to_string(&f).unwrap(), "secret");
        assert!(matches!(
            create_private_dir(&dir),
            Err(SecureError::NotEmpty(_))
        ));
    }

    #[test]
    fn generated_configs_are_accepted_by_zenoh() {
        let tls = TlsFiles::of(Path::new("/site"), "robot-r1");
        let client = client_config("robot-r1", "pw", &["tls/127.0.0.1:7447".into()], Some(&tls));
        let text = with_header("a client", &client);
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("c.json5");
        std::fs::write(&path, text).unwrap();
        let config = zenoh::Config::from_file(&path).unwrap();
        assert_eq!(
            config
                .get_json("transport/link/tls/connect_certificate")
                .unwrap(),
            "\"/site/tls/robot-r1.crt\""
        );
    }
}
