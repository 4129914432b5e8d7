//! A node's own TLS files, checked at start: the certificates and private
//! keys its Zenoh configuration names (`transport.link.tls`) are read and
//! parsed before Zenoh opens a link, so that a broken, expired or
//! soon-expiring file is a message naming the file, not a handshake that
//! fails with the peer's words on another machine.
//!
//! An expired certificate (or one not valid yet: a clock far off) is
//! refused: no peer would accept it. One expiring within
//! [`EXPIRY_WARNING_DAYS`] is a warning at every start.

use std::path::{Path, PathBuf};

use x509_parser::pem::Pem;
use x509_parser::prelude::*;

/// Days before its expiry from which a node warns at start that its
/// certificate must be renewed: a month leaves time to notice the warning
/// in a weekly log review and to reissue with `ickon site secure`.
pub const EXPIRY_WARNING_DAYS: i64 = 30;

/// A certificate or key file is larger than any real one (a chain of a few
/// certificates is a few kB): a path to anything endless is refused, not read.
const MAX_PEM_BYTES: u64 = 1 << 20;

const SECONDS_PER_DAY: i64 = 86_400;

/// Why a node's TLS files cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum CertificateError {
    /// The file cannot be read.
    #[error("{}: cannot read: {reason}", path.display())]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// What the system said.
        reason: String,
    },
    /// The file holds no certificate, or a broken one.
    #[error("{}: not a PEM X.509 certificate: {reason}", path.display())]
    MalformedCertificate {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The file holds no private key, or a broken one.
    #[error("{}: not a PEM private key: {reason}", path.display())]
    MalformedKey {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The certificate's validity is over.
    #[error(
        "{}: the certificate of {subject:?} expired on {not_after}: no peer accepts it; issue a new one (`ickon site secure`, docs/security.md)",
        path.display()
    )]
    Expired {
        /// The file.
        path: PathBuf,
        /// Its common name.
        subject: String,
        /// When it expired.
        not_after: String,
    },
    /// The certificate's validity has not begun (or this clock is far off).
    #[error(
        "{}: the certificate of {subject:?} is not valid before {not_before}: is this machine's clock right?",
        path.display()
    )]
    NotYetValid {
        /// The file.
        path: PathBuf,
        /// Its common name.
        subject: String,
        /// When it becomes valid.
        not_before: String,
    },
    /// The private key is not the one of the certificate beside it.
    #[error("{}: the private key does not belong to the certificate {}", key.display(), certificate.display())]
    KeyMismatch {
        /// The key file.
        key: PathBuf,
        /// The certificate file.
        certificate: PathBuf,
    },
}

/// What a valid certificate file holds that a node reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CertificateFacts {
    /// The file.
    pub path: PathBuf,
    /// The first certificate's common name (the identity the ACL knows).
    pub subject: String,
    /// Whole days until it expires.
    pub days_left: i64,
}

impl CertificateFacts {
    /// The warning to give at start, if it expires within [`EXPIRY_WARNING_DAYS`].
    pub fn expiry_warning(&self) -> Option<String> {
        (self.days_left < EXPIRY_WARNING_DAYS).then(|| {
            format!(
                "{}: the certificate of {:?} expires in {} day(s): renew it before then (docs/security.md, \"Certificates\"), or every link it authenticates is refused",
                self.path.display(),
                self.subject,
                self.days_left
            )
        })
    }
}

fn read(path: &Path) -> Result<Vec<u8>, CertificateError> {
    ickon_proto::text_file::read_bounded(path, MAX_PEM_BYTES)
        .map(String::into_bytes)
        .map_err(|reason| CertificateError::Unreadable {
            path: path.to_path_buf(),
            reason,
        })
}

/// The PEM blocks of `bytes`, at least one.
fn pem_blocks(bytes: &[u8]) -> Result<Vec<Pem>, String> {
    let blocks: Vec<Pem> = Pem::iter_from_buffer(bytes)
        .collect::<Result<_, _>>()
        .map_err(|e| e.to_string())?;
    if blocks.is_empty() {
        return Err("no PEM block".into());
    }
    Ok(blocks)
}

/// Reads the certificate (chain) at `path` and checks its first
/// certificate's validity at `now_unix_s`; every certificate of the file
/// must parse.
pub fn check_certificate(
    path: &Path,
    now_unix_s: i64,
) -> Result<CertificateFacts, CertificateError> {
    let malformed = |reason: String| CertificateError::MalformedCertificate {
        path: path.to_path_buf(),
        reason,
    };
    let blocks = pem_blocks(&read(path)?).map_err(malformed)?;
    let mut first = None;
    for block in &blocks {
        if block.label != "CERTIFICATE" {
            return Err(malformed(format!(
                "a {:?} block where a CERTIFICATE was expected",
                block.label
            )));
        }
        let (_, cert) =
            X509Certificate::from_der(&block.contents).map_err(|e| malformed(e.to_string()))?;
        if first.is_none() {
            first = Some((
                common_name(&cert),
                cert.validity().not_before,
                cert.validity().not_after,
            ));
        }
    }
    let Some((subject, not_before, not_after)) = first else {
        return Err(malformed("no certificate".into()));
    };
    if now_unix_s < not_before.timestamp() {
        return Err(CertificateError::NotYetValid {
            path: path.to_path_buf(),
            subject,
            not_before: not_before.to_string(),
        });
    }
    if now_unix_s >= not_after.timestamp() {
        return Err(CertificateError::Expired {
            path: path.to_path_buf(),
            subject,
            not_after: not_after.to_string(),
        });
    }
    Ok(CertificateFacts {
        path: path.to_path_buf(),
        subject,
        days_left: (not_after.timestamp() - now_unix_s) / SECONDS_PER_DAY,
    })
}

/// The first common name of a certificate's subject (empty when none).
fn common_name(cert: &X509Certificate<'_>) -> String {
    cert.subject()
        .iter_common_name()
        .next()
        .and_then(|cn| cn.as_str().ok())
        .unwrap_or_default()
        .to_string()
}

/// Reads the private key at `path`; with `certificate`, checks that the key
/// is the one whose public half the certificate carries.
pub fn check_private_key(path: &Path, certificate: Option<&Path>) -> Result<(), CertificateError> {
    let malformed = |reason: String| CertificateError::MalformedKey {
        path: path.to_path_buf(),
        reason,
    };
    let blocks = pem_blocks(&read(path)?).map_err(malformed)?;
    let block = &blocks[0];
    match block.label.as_str() {
        // PKCS#8, what `ickon site secure` writes: parsed and matched.
        "PRIVATE KEY" => {}
        // PKCS#1 and SEC1 keys, which Zenoh also takes: only their framing is checked.
        "RSA PRIVATE KEY" | "EC PRIVATE KEY" if !block.contents.is_empty() => return Ok(()),
        other => return Err(malformed(format!("a {other:?} block, no private key"))),
    }
    let key = rcgen::KeyPair::try_from(block.contents.as_slice())
        .map_err(|e| malformed(format!("{e}")))?;
    let Some(cert_path) = certificate else {
        return Ok(());
    };
    let cert_blocks =
        pem_blocks(&read(cert_path)?).map_err(|reason| CertificateError::MalformedCertificate {
            path: cert_path.to_path_buf(),
            reason,
        })?;
    let (_, cert) = X509Certificate::from_der(&cert_blocks[0].contents).map_err(|e| {
        CertificateError::MalformedCertificate {
            path: cert_path.to_path_buf(),
            reason: e.to_string(),
        }
    })?;
    if cert.public_key().subject_public_key.data.as_ref() != key.public_key_raw() {
        return Err(CertificateError::KeyMismatch {
            key: path.to_path_buf(),
            certificate: cert_path.to_path_buf(),
        });
    }
    Ok(())
}

/// One TLS setting of a Zenoh configuration: a file name, if set.
fn tls_file(config: &zenoh::Config, name: &str) -> Option<PathBuf> {
    let text = config
        .get_json(&format!("transport/link/tls/{name}"))
        .ok()?;
    let value: Option<String> = serde_json::from_str(&text).ok()?;
    value.filter(|v| !v.is_empty()).map(PathBuf::from)
}

/// Checks every TLS file `config` names (the root CA, the listening and
/// connecting certificates and their keys) at `now_unix_s`; returns the
/// facts of each certificate, for the expiry warnings.
pub fn check_config_files(
    config: &zenoh::Config,
    now_unix_s: i64,
) -> Result<Vec<CertificateFacts>, CertificateError> {
    let mut facts = Vec::new();
    if let Some(ca) = tls_file(config, "root_ca_certificate") {
        facts.push(check_certificate(&ca, now_unix_s)?);
    }
    for side in ["listen", "connect"] {
        let certificate = tls_file(config, &format!("{side}_certificate"));
        if let Some(cert) = &certificate {
            facts.push(check_certificate(cert, now_unix_s)?);
        }
        if let Some(key) = tls_file(config, &format!("{side}_private_key")) {
            check_private_key(&key, certificate.as_deref())?;
        }
    }
    Ok(facts)
}

/// Now, in seconds since the Unix epoch (the certificates' time scale).
pub fn unix_now_s() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_secs()).unwrap_or(i64::MAX))
}

#[cfg(test)]
mod tests {
    use super::*;

    const DAY: i64 = SECONDS_PER_DAY;

    /// A self-signed certificate of `cn` valid from `from` to `to` (Unix s), and its key.
    fn certificate(cn: &str, from: i64, to: i64) -> (String, String) {
        let key = rcgen::KeyPair::generate().unwrap();
        let mut params = rcgen::CertificateParams::new(vec!["localhost".to_string()]).unwrap();
        params
            .distinguished_name
            .push(rcgen::DnType::CommonName, cn);
        params.not_before = ::time::OffsetDateTime::from_unix_timestamp(from).unwrap();
        params.not_after = ::time::OffsetDateTime::from_unix_timestamp(to).unwrap();
        let cert = params.self_signed(&key).unwrap();
        (cert.pem(), key.serialize_pem())
    }

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    const NOW: i64 = 1_800_000_000;

    #[test]
    fn validity_is_checked_against_now() {
        let tmp = tempfile::tempdir().unwrap();
        let (good, _) = certificate("robot-r1", NOW - DAY, NOW + 400 * DAY);
        let f = write(tmp.path(), "good.crt", &good);
        let facts = check_certificate(&f, NOW).unwrap();
        assert_eq!(facts.subject, "robot-r1");
        assert_eq!(facts.days_left, 400);
        assert_eq!(facts.expiry_warning(), None);

        let (soon, _) = certificate("robot-r1", NOW - DAY, NOW + 10 * DAY + 5);
        let f = write(tmp.path(), "soon.crt", &soon);
        let warning = check_certificate(&f, NOW)
            .unwrap()
            .expiry_warning()
            .unwrap();
        assert!(
            warning.contains("soon.crt") && warning.contains("in 10 day"),
            "{warning}"
        );

        let (old, _) = certificate("robot-r1", NOW - 10 * DAY, NOW - 1);
        let f = write(tmp.path(), "old.crt", &old);
        let err = check_certificate(&f, NOW).unwrap_err().to_string();
        assert!(err.contains("old.crt") && err.contains("expired"), "{err}");

        let (future, _) = certificate("robot-r1", NOW + DAY, NOW + 10 * DAY);
        let f = write(tmp.path(), "future.crt", &future);
        let err = check_certificate(&f, NOW).unwrap_err();
        assert!(matches!(err, CertificateError::NotYetValid { .. }), "{err}");
    }

    #[test]
    fn malformed_files_are_named() {
        let tmp = tempfile::tempdir().unwrap();
        let (cert, key) = certificate("central", NOW - DAY, NOW + DAY * 100);
        let cut = &cert[..cert.len() / 2];
        let garbage = "-----BEGIN CERTIFICATE-----\nAAAA\n-----END CERTIFICATE-----\n";
        for (name, text) in [
            ("empty.crt", ""),
            ("cut.crt", cut),
            ("garbage.crt", garbage),
            ("key-as-cert.crt", key.as_str()),
        ] {
            let f = write(tmp.path(), name, text);
            let err = check_certificate(&f, NOW).unwrap_err();
            assert!(
                matches!(err, CertificateError::MalformedCertificate { .. })
                    && err.to_string().contains(name),
                "{name}: {err}"
            );
        }
        let missing = tmp.path().join("missing.crt");
        let err = check_certificate(&missing, NOW).unwrap_err().to_string();
        assert!(err.contains("missing.crt"), "{err}");

        let garbage_key = "-----BEGIN PRIVATE KEY-----\nAAAA\n-----END PRIVATE KEY-----\n";
        for (name, text) in [
            ("empty.key", ""),
            ("garbage.key", garbage_key),
            ("cert-as-key.key", cert.as_str()),
        ] {
            let f = write(tmp.path(), name, text);
            let err = check_private_key(&f, None).unwrap_err();
            assert!(
                matches!(err, CertificateError::MalformedKey { .. })
                    && err.to_string().contains(name),
                "{name}: {err}"
            );
        }
    }

    #[test]
    fn a_key_must_belong_to_its_certificate() {
        let tmp = tempfile::tempdir().unwrap();
        let (cert, key) = certificate("cell-c1", NOW - DAY, NOW + DAY * 100);
        let (_, other_key) = certificate("cell-c2", NOW - DAY, NOW + DAY * 100);
        let c = write(tmp.path(), "c1.crt", &cert);
        let k = write(tmp.path(), "c1.key", &key);
        let wrong = write(tmp.path(), "c2.key", &other_key);
        check_private_key(&k, Some(&c)).unwrap();
        let err = check_private_key(&wrong, Some(&c)).unwrap_err();
        assert!(matches!(err, CertificateError::KeyMismatch { .. }), "{err}");
    }

    #[test]
    fn a_zenoh_config_names_the_files_checked() {
        let tmp = tempfile::tempdir().unwrap();
        let (cert, key) = certificate("robot-r1", NOW - DAY, NOW + 5 * DAY);
        let c = write(tmp.path(), "r1.crt", &cert);
        let k = write(tmp.path(), "r1.key", &key);
        let mut config = zenoh::Config::default();
        for (name, path) in [
            ("root_ca_certificate", &c),
            ("connect_certificate", &c),
            ("connect_private_key", &k),
        ] {
            config
                .insert_json5(
                    &format!("transport/link/tls/{name}"),
                    &format!("{:?}", path.display().to_string()),
                )
                .unwrap();
        }
        let facts = check_config_files(&config, NOW).unwrap();
        assert_eq!(facts.len(), 2);
        assert!(facts.iter().all(|f| f.expiry_warning().is_some()));
        std::fs::write(&k, "not a key").unwrap();
        let err = check_config_files(&config, NOW).unwrap_err().to_string();
        assert!(err.contains("r1.key"), "{err}");
        assert!(
            check_config_files(&zenoh::Config::default(), NOW)
                .unwrap()
                .is_empty()
        );
    }
}
