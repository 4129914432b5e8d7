//! The site's certificate authority and one TLS key and certificate per
//! identity, for Zenoh's mutual TLS: every link to a router is encrypted,
//! and both ends prove who they are with a certificate the site CA signed.
//!
//! A certificate's common name is its identity's user name ([`Identity::user`]):
//! the routers' ACL matches it (`cert_common_names`). Nodes' certificates
//! are for client authentication only, so that a stolen robot key cannot
//! pose as a router; routers' certificates serve both ends (they accept
//! clients and link to each other) and name the hosts clients reach them
//! at, which clients verify.
//!
//! Keys are ECDSA P-256 (rcgen's default: small, fast handshakes, accepted
//! by rustls), made from the operating system's random source.

use std::net::IpAddr;

use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use time::{Duration, OffsetDateTime};

use super::SecureError;

/// Default validity of an identity's certificate, days: a year, so that
/// renewal is a yearly routine an operator plans for (nodes warn a month
/// ahead), while a key copied off a robot stops opening the site within a
/// year at most even if nobody notices the theft.
pub const DEFAULT_VALID_DAYS: u32 = 365;

/// Validity of the site CA, days: ten years, longer than any identity's, so
/// that identities are renewed with the same CA (`--ca`) without touching
/// the CA certificate every node trusts.
pub const CA_VALID_DAYS: u32 = 3650;

/// How far back a new certificate's validity starts: a machine whose clock
/// is behind the issuing one by up to an hour still accepts it at once.
const BACKDATE: Duration = Duration::hours(1);

/// When a certificate is valid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Validity {
    /// Start of validity.
    pub not_before: OffsetDateTime,
    /// End of validity.
    pub not_after: OffsetDateTime,
}

impl Validity {
    /// From `not_before_s` to `not_after_s`, seconds since the Unix epoch
    /// (`None` outside the dates a certificate can hold).
    pub fn from_unix(not_before_s: i64, not_after_s: i64) -> Option<Self> {
        Some(Validity {
            not_before: OffsetDateTime::from_unix_timestamp(not_before_s).ok()?,
            not_after: OffsetDateTime::from_unix_timestamp(not_after_s).ok()?,
        })
    }

    /// From an hour ago (clock skew) until `days` days from now.
    pub fn days_from_now(days: u32) -> Self {
        let now = OffsetDateTime::now_utc();
        Validity {
            not_before: now - BACKDATE,
            not_after: now + Duration::days(i64::from(days)),
        }
    }
}

/// What a certificate lets its holder do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role {
    /// A node: authenticates to a router.
    Client,
    /// A router: accepts TLS links (a server certificate naming its hosts)
    /// and links to other routers (a client certificate).
    Router,
}

/// A certificate and its private key, both PEM.
#[derive(Debug, Clone)]
pub struct Issued {
    /// The certificate.
    pub cert_pem: String,
    /// The private key (PKCS#8).
    pub key_pem: String,
}

/// The site's certificate authority: it signs every identity's certificate.
pub struct SiteCa {
    issuer: Issuer<'static, KeyPair>,
    cert_pem: String,
    key_pem: String,
}

fn cert_error(what: &str, e: rcgen::Error) -> SecureError {
    SecureError::Certificate(format!("{what}: {e}"))
}

/// The parameters of a site CA named `common_name`.
fn ca_params(common_name: &str) -> CertificateParams {
    let mut params = CertificateParams::default();
    params
        .distinguished_name
        .push(DnType::CommonName, common_name);
    // Signs identities directly: no intermediate CA below it.
    params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
    params.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::CrlSign,
        KeyUsagePurpose::DigitalSignature,
    ];
    params
}

impl SiteCa {
    /// A new CA for the site `site_name`, valid for `validity`.
    pub fn generate(site_name: &str, validity: Validity) -> Result<Self, SecureError> {
        let key = KeyPair::generate().map_err(|e| cert_error("the CA's key", e))?;
        let mut params = ca_params(&format!("ICKON site {site_name} certificate authority"));
        params.not_before = validity.not_before;
        params.not_after = validity.not_after;
        let cert = params
            .self_signed(&key)
            .map_err(|e| cert_error("the CA's certificate", e))?;
        let key_pem = key.serialize_pem();
        Ok(SiteCa {
            cert_pem: cert.pem(),
            key_pem,
            issuer: Issuer::new(params, key),
        })
    }

    /// The CA an earlier `ickon site secure` made, from its certificate and
    /// private key (PEM), to issue more certificates (renewal, a new
    /// robot) that every node already trusts. `Err` says what is wrong
    /// (a file that is not this CA's, an expired CA, a key of another).
    pub fn load(cert_pem: &str, key_pem: &str) -> Result<Self, String> {
        let (_, pem) = x509_parser::pem::parse_x509_pem(cert_pem.as_bytes())
            .map_err(|e| format!("the certificate: not PEM: {e}"))?;
        let cert = pem
            .parse_x509()
            .map_err(|e| format!("the certificate: {e}"))?;
        if !cert.is_ca() {
            return Err("the certificate is not a CA's".into());
        }
        if !cert.validity().is_valid() {
            return Err(format!(
                "the CA's certificate is not valid now (from {} to {})",
                cert.validity().not_before,
                cert.validity().not_after
            ));
        }
        let name = cert
            .subject()
            .iter_common_name()
            .next()
            .and_then(|cn| cn.as_str().ok())
            .ok_or("the certificate has no common name")?
            .to_string();
        let key = KeyPair::from_pem(key_pem).map_err(|e| format!("the private key: {e}"))?;
        if cert.public_key().subject_public_key.data.as_ref() != key.public_key_raw() {
            return Err("the private key is not the certificate's".into());
        }
        Ok(SiteCa {
            cert_pem: cert_pem.to_string(),
            key_pem: key_pem.to_string(),
            issuer: Issuer::new(ca_params(&name), key),
        })
    }

    /// The CA's certificate (PEM): every node and router trusts it.
    pub fn cert_pem(&self) -> &str {
        &self.cert_pem
    }

    /// The CA's private key (PEM): it signs certificates; never copied to a node.
    pub fn key_pem(&self) -> &str {
        &self.key_pem
    }

    /// A new key and a certificate for `common_name` in `role`, naming
    /// `hosts` (host names or IP addresses; a router's) as subject
    /// alternative names.
    pub fn issue(
        &self,
        common_name: &str,
        role: Role,
        hosts: &[String],
        validity: Validity,
    ) -> Result<Issued, SecureError> {
        let what = format!("the certificate of {common_name}");
        let key = KeyPair::generate().map_err(|e| cert_error(&what, e))?;
        let mut params =
            CertificateParams::new(hosts.to_vec()).map_err(|e| cert_error(&what, e))?;
        params
            .distinguished_name
            .push(DnType::CommonName, common_name);
        params.is_ca = IsCa::ExplicitNoCa;
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        params.extended_key_usages = match role {
            Role::Client => vec![ExtendedKeyUsagePurpose::ClientAuth],
            Role::Router => vec![
                ExtendedKeyUsagePurpose::ServerAuth,
                ExtendedKeyUsagePurpose::ClientAuth,
            ],
        };
        params.use_authority_key_identifier_extension = true;
        params.not_before = validity.not_before;
        params.not_after = validity.not_after;
        let cert = params
            .signed_by(&key, &self.issuer)
            .map_err(|e| cert_error(&what, e))?;
        Ok(Issued {
            cert_pem: cert.pem(),
            key_pem: key.serialize_pem(),
        })
    }
}

/// The host of a Zenoh endpoint (`tls/host:port`, `tls/[::1]:port`, with
/// or without `?metadata` or `#config`), unless it is a wildcard address
/// (`0.0.0.0`, `[::]`), which no client connects to by that name.
pub fn endpoint_host(endpoint: &str) -> Option<String> {
    let address = endpoint.split(['?', '#']).next()?;
    let (_, address) = address.split_once('/')?;
    let host = match address.strip_prefix('[') {
        Some(v6) => v6.split_once(']')?.0,
        None => address.rsplit_once(':').map_or(address, |(h, _)| h),
    };
    if host.is_empty() {
        return None;
    }
    match host.parse::<IpAddr>() {
        Ok(ip) if ip.is_unspecified() => None,
        _ => Some(host.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoint_hosts_are_what_clients_verify() {
        assert_eq!(
            endpoint_host("tls/127.0.0.1:7447").as_deref(),
            Some("127.0.0.1")
        );
        assert_eq!(
            endpoint_host("tls/router.site.example:7447?x=1").as_deref(),
            Some("router.site.example")
        );
        assert_eq!(endpoint_host("tls/[::1]:7447").as_deref(), Some("::1"));
        assert_eq!(endpoint_host("tls/0.0.0.0:7447"), None);
        assert_eq!(endpoint_host("tls/[::]:7447"), None);
        assert_eq!(endpoint_host("garbage"), None);
    }

    #[test]
    fn identities_are_signed_by_the_ca_with_their_name_and_role() {
        let validity = Validity::days_from_now(DEFAULT_VALID_DAYS);
        let ca = SiteCa::generate("lab", Validity::days_from_now(CA_VALID_DAYS)).unwrap();
        let robot = ca.issue("robot-r1", Role::Client, &[], validity).unwrap();
        let router = ca
            .issue("router", Role::Router, &["127.0.0.1".into()], validity)
            .unwrap();
        let (_, ca_pem) = x509_parser::pem::parse_x509_pem(ca.cert_pem().as_bytes()).unwrap();
        let ca_cert = ca_pem.parse_x509().unwrap();
        assert!(ca_cert.is_ca());
        for (issued, cn, server) in [(&robot, "robot-r1", false), (&router, "router", true)] {
            let (_, pem) = x509_parser::pem::parse_x509_pem(issued.cert_pem.as_bytes()).unwrap();
            let cert = pem.parse_x509().unwrap();
            assert_eq!(
                cert.subject()
                    .iter_common_name()
                    .next()
                    .unwrap()
                    .as_str()
                    .unwrap(),
                cn
            );
            // The signature itself is checked by the TLS handshakes of
            // tests/mesh/secure_tls.rs; here, who signed.
            assert_eq!(cert.issuer(), ca_cert.subject());
            assert!(!cert.is_ca());
            let eku = cert.extended_key_usage().unwrap().unwrap().value;
            assert!(eku.client_auth);
            assert_eq!(eku.server_auth, server, "{cn}");
            let days = (cert.validity().not_after.timestamp()
                - cert.validity().not_before.timestamp())
                / 86_400;
            assert_eq!(days, i64::from(DEFAULT_VALID_DAYS));
        }
        assert_ne!(robot.key_pem, router.key_pem);

        // Loaded again from its files, the CA issues certificates with the
        // same issuer and key identifier; another CA's key is refused.
        let again = SiteCa::load(ca.cert_pem(), ca.key_pem()).unwrap();
        let renewed = again
            .issue("robot-r1", Role::Client, &[], validity)
            .unwrap();
        let (_, pem) = x509_parser::pem::parse_x509_pem(renewed.cert_pem.as_bytes()).unwrap();
        let cert = pem.parse_x509().unwrap();
        assert_eq!(cert.issuer(), ca_cert.subject());
        let other = SiteCa::generate("lab", validity).unwrap();
        let err = SiteCa::load(ca.cert_pem(), other.key_pem()).err().unwrap();
        assert!(err.contains("not the certificate's"), "{err}");
        assert!(SiteCa::load(&robot.cert_pem, &robot.key_pem).is_err());
        assert!(robot.key_pem.contains("BEGIN PRIVATE KEY"));
    }
}
