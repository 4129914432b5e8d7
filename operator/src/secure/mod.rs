//! `ickon site secure SITE --out DIR`: a site's routers with access control,
//! default deny, and one credential per node.
//!
//! Writes into a new private directory:
//! - `router.json5`: the router's configuration (`ickon router --zenoh-config`,
//!   or `zenohd -c`), with mutual TLS ([`certs`]), the user/password check
//!   and the ACL
//!   ([`acl::access_control`]): a robot publishes only `robot/<id>/...`, a
//!   cell only `cell/<id>/...`, only the central unit `central/**`, and only
//!   the admin identity (and the central unit) queries `central/admin/**`;
//!   and the largest message it lets through per key ([`limits`]);
//! - `users.txt`: the dictionary of user names and passwords the router
//!   checks (`<user>:<password>` per line);
//! - `clients/<user>.json5`: each identity's client configuration
//!   (`--zenoh-config` of `ickon-central`, `ickon-cell`, `ickon-msu`,
//!   `ickon admin`, `ickon record`), with its user and password;
//! - `tls/`: the site CA's certificate (`ca.crt`) and each identity's key
//!   and certificate (`<user>.key`, `<user>.crt`; the routers' `router.*`,
//!   `router-<k>.*`): what nodes get;
//! - `ca/`: the site CA's private key and certificate, kept apart: it
//!   signs certificates and is never copied to a node.
//!
//! TLS is used when the endpoints are `tls/` ones (the default); with
//! `tcp/` endpoints the links are in clear and only the passwords
//! authenticate. Passwords and keys come from the operating system's random
//! source, not from a seed: a seed would make them guessable. Every file
//! is 0600.

pub mod acl;
pub mod certs;
pub mod check;
pub mod files;
mod identity;
pub mod limits;
pub mod robot_list;

pub use identity::Identity;

use std::path::{Path, PathBuf};

use clap::Args;
use ickon_proto::site::Site;

use files::{
    CA_CERT_FILE, CA_DIR, CA_KEY_FILE, CLIENTS_DIR, ROUTER_FILE, TLS_DIR, TlsFiles, USERS_FILE,
};
use ickon_runtime::CommandError;

/// Why the secured files could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum SecureError {
    /// A file or directory could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
    /// The output directory holds files already.
    #[error("{}: the directory is not empty; credentials are never overwritten (choose a new directory)", .0.display())]
    NotEmpty(PathBuf),
    /// The operating system's random source failed.
    #[error("the operating system's random source failed: {0}")]
    Random(String),
    /// A key or certificate could not be made.
    #[error("cannot make {0}")]
    Certificate(String),
    /// The site CA given to reuse cannot be used.
    #[error("{}: {problem}", dir.display())]
    Ca {
        /// The directory given with `--ca`.
        dir: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// The endpoints mix TLS and links in clear.
    #[error("{0}")]
    Endpoints(String),
    /// A field of a configuration file is wrong.
    #[error("{}: {field}: {problem}", file.display())]
    Field {
        /// The file.
        file: PathBuf,
        /// The field, dotted (`access_control.policies[0].rules[1]`).
        field: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A line of the user/password dictionary is wrong.
    #[error("{}:{line}: {problem}", file.display())]
    Line {
        /// The dictionary file.
        file: PathBuf,
        /// Line number, from 1.
        line: usize,
        /// What is wrong with it.
        problem: String,
    },
}

impl SecureError {
    fn io(path: &Path, source: std::io::Error) -> Self {
        SecureError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// As a command's outcome: bad input for a bad file or directory
    /// given by the user, a failure when the system failed.
    pub fn into_command_error(self) -> CommandError {
        match self {
            SecureError::Random(_) | SecureError::Certificate(_) => {
                CommandError::failure(self.to_string())
            }
            _ => CommandError::bad_input(self.to_string()),
        }
    }
}

/// Arguments of `ickon site secure`.
#[derive(Debug, Args)]
pub struct SecureArgs {
    /// A built-in site (`lab`, `warehouse`, `hall`) or a site file (TOML); `lab` when omitted.
    pub site: Option<PathBuf>,
    /// A new (or empty) directory to write into.
    #[arg(long)]
    pub out: PathBuf,
    /// Where the router listens (repeatable). `tls/` endpoints (the
    /// default) give every link mutual TLS with the site CA's certificates;
    /// `tcp/` ones leave the links in clear (passwords only).
    #[arg(long, default_value = "tls/0.0.0.0:7447")]
    pub listen: Vec<String>,
    /// Where the clients reach the router (repeatable); with TLS, the
    /// router's certificate names these hosts and clients check it.
    #[arg(long, default_value = "tls/127.0.0.1:7447")]
    pub connect: Vec<String>,
    /// Also write the simulation's identities (`world`, `observer`): never
    /// on a real site, where the world's rights would let one device forge
    /// every robot's arrivals.
    #[arg(long)]
    pub sim: bool,
    /// Robots to write credentials for besides those in the site file
    /// (repeatable): ids and ranges, comma-separated (`r1..r50`,
    /// `amr-1,amr-2`): robots that have a credential but are not in the
    /// site file yet (spares, robots still to be delivered).
    #[arg(long, value_name = "IDS", value_parser = robot_list::parse)]
    pub robots: Vec<robot_list::RobotIds>,
    /// ROS domain id of the robots' rmw_zenoh keys (`ickon-msu --ros2`).
    #[arg(long, default_value_t = 0)]
    pub ros2_domain: u32,
    /// Linked routers, one per floor: `router.json5` and `router-2.json5`
    /// ... `router-N.json5`, the same ACL and users on each; routers 2 to N
    /// connect to the first (at `--link`) as the user `router`.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=64))]
    pub routers: u16,
    /// Where routers 2 to N reach the first (repeatable); `--connect` when not given.
    #[arg(long)]
    pub link: Vec<String>,
    /// Days each identity's TLS certificate is valid (the site CA's: ten
    /// years, or this if longer); nodes warn in their last 30 days and
    /// refuse to start after.
    #[arg(long, default_value_t = certs::DEFAULT_VALID_DAYS, value_parser = clap::value_parser!(u32).range(1..=i64::from(certs::CA_VALID_DAYS)))]
    pub valid_days: u32,
    /// Issue the certificates with the site CA of an earlier `ickon site
    /// secure` instead of a new CA: renewed or added identities that every
    /// node already trusts. Given its output directory, the identities also
    /// keep their passwords (nodes can be renewed one by one); given only
    /// its `ca/` directory, every password is new (locks out a stolen one).
    #[arg(long, value_name = "DIR")]
    pub ca: Option<PathBuf>,
}

/// How a secured site is laid out: its routers and where everyone connects.
#[derive(Debug, Clone)]
pub struct Layout {
    /// Where each router listens.
    pub listen: Vec<String>,
    /// Where the clients reach their router.
    pub connect: Vec<String>,
    /// Where routers 2 to N reach the first.
    pub link: Vec<String>,
    /// How many linked routers.
    pub routers: usize,
    /// Whether to add the simulation's identities.
    pub sim: bool,
    /// With `sim`: the robots of each process that hosts several
    /// (`ickon sim --robots-per-process`), one fleet identity each.
    pub fleets: Vec<Vec<String>>,
    /// Robots to give credentials besides the site file's.
    pub robots: Vec<String>,
    /// The robots' ROS 2 keys.
    pub ros2: acl::Ros2Scope,
    /// Days each identity's certificate is valid (with TLS).
    pub valid_days: u32,
    /// An earlier site CA to issue with (a new one when `None`).
    pub ca: Option<PathBuf>,
}

impl Layout {
    /// Whether the links are TLS: every endpoint `tls/`, or none (links in
    /// clear); a mix is refused, since a client connecting in clear would
    /// match none of the certificate-based ACL subjects.
    pub fn tls(&self) -> Result<bool, SecureError> {
        let all: Vec<&String> = self
            .listen
            .iter()
            .chain(&self.connect)
            .chain(&self.link)
            .collect();
        let tls = all.iter().filter(|e| e.starts_with("tls/")).count();
        if tls > 0 && tls < all.len() {
            return Err(SecureError::Endpoints(format!(
                "the endpoints mix tls/ and others ({}): give every --listen, --connect and --link as tls/ (mutual TLS) or none (links in clear)",
                all.iter()
                    .map(|e| e.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
        Ok(tls > 0)
    }

    /// The site's identities ([`Identity::all_of`]) and one per robot of
    /// [`Self::robots`] the site file does not list.
    pub fn identities(&self, site: &Site) -> Vec<Identity> {
        let mut out = Identity::all_of(site, self.sim);
        for robot in &self.robots {
            let identity = Identity::Robot(robot.clone());
            if !out.contains(&identity) {
                out.push(identity);
            }
        }
        out
    }

    /// The hosts the routers' certificates name: those clients and other
    /// routers connect to, and those routers listen on (but wildcards).
    fn router_hosts(&self) -> Vec<String> {
        let mut hosts: Vec<String> = self
            .connect
            .iter()
            .chain(&self.link)
            .chain(&self.listen)
            .filter_map(|e| certs::endpoint_host(e))
            .collect();
        hosts.sort();
        hosts.dedup();
        hosts
    }
}

/// What was written: where each file is.
#[derive(Debug, Clone)]
pub struct SecuredDir {
    /// The directory.
    pub dir: PathBuf,
}

impl SecuredDir {
    /// The (first) router's configuration.
    pub fn router(&self) -> PathBuf {
        self.dir.join(ROUTER_FILE)
    }

    /// Router `k`'s configuration (from 1).
    pub fn router_k(&self, k: usize) -> PathBuf {
        self.dir.join(files::router_file(k))
    }

    /// The client configuration of `identity`.
    pub fn client(&self, identity: &Identity) -> PathBuf {
        files::client_path(&self.dir, identity)
    }

    /// The TLS files of `identity` (they exist when the site uses TLS).
    pub fn tls_files(&self, identity: &Identity) -> TlsFiles {
        TlsFiles::of(&self.dir, &identity.user())
    }

    /// The site CA's certificate and key: they exist when the site uses TLS.
    pub fn ca(&self) -> (PathBuf, PathBuf) {
        let ca = self.dir.join(CA_DIR);
        (ca.join(CA_CERT_FILE), ca.join(CA_KEY_FILE))
    }

    /// Whether the routers listen on TLS: their configuration names a
    /// listening certificate.
    pub fn uses_tls(&self) -> bool {
        zenoh::Config::from_file(self.router())
            .ok()
            .and_then(|c| c.get_json("transport/link/tls/listen_certificate").ok())
            .is_some_and(|v| v != "null")
    }

    /// Checks a directory written earlier: the router's files, and a
    /// credential for each of `identities`.
    pub fn open(dir: &Path, identities: &[Identity]) -> Result<Self, SecureError> {
        let me = SecuredDir {
            dir: dir.to_path_buf(),
        };
        let router = me.router();
        let config = zenoh::Config::from_file(&router).map_err(|e| SecureError::Field {
            file: router.clone(),
            field: "(file)".into(),
            problem: e.to_string(),
        })?;
        check::router(&router, &config)?;
        for identity in identities {
            let path = me.client(identity);
            let user = check::client(&path)?;
            if user != identity.user() {
                return Err(SecureError::Field {
                    file: path,
                    field: "transport.auth.usrpwd.user".into(),
                    problem: format!("{user:?}, expected {:?}", identity.user()),
                });
            }
        }
        Ok(me)
    }
}

/// Writes the secured files of `site` into the new directory `dir`.
pub fn write_dir(site: &Site, dir: &Path, layout: &Layout) -> Result<SecuredDir, SecureError> {
    let tls = layout.tls()?;
    // Checked before anything is written.
    let reused_ca = match (&layout.ca, tls) {
        (Some(from), true) => Some(load_ca(from)?),
        _ => None,
    };
    let old_users = layout.ca.as_ref().map(|from| from.join(USERS_FILE));
    let old_passwords: std::collections::HashMap<String, String> = match old_users {
        Some(users) if users.exists() => check::dictionary(&users)?.into_iter().collect(),
        _ => Default::default(),
    };
    let password_of = |user: &str| match old_passwords.get(user) {
        Some(kept) => Ok(kept.clone()),
        None => files::new_password(),
    };
    files::create_private_dir(dir)?;
    files::create_private_dir(&dir.join(CLIENTS_DIR))?;
    // The router reads the dictionary from wherever it is started: give it
    // the absolute path.
    let dir = std::fs::canonicalize(dir).map_err(|e| SecureError::io(dir, e))?;
    let validity = certs::Validity::days_from_now(layout.valid_days);
    let ca = if tls {
        Some(write_ca(site, &dir, reused_ca, layout.valid_days)?)
    } else {
        None
    };
    let mut identities = layout.identities(site);
    if layout.sim {
        identities.extend(layout.fleets.iter().cloned().map(Identity::Fleet));
    }
    let mut dictionary = String::new();
    for identity in &identities {
        let user = identity.user();
        let password = password_of(&user)?;
        dictionary.push_str(&format!("{user}:{password}\n"));
        let tls_files = match &ca {
            Some(ca) => Some(write_identity(
                ca,
                &dir,
                &user,
                certs::Role::Client,
                &[],
                validity,
            )?),
            None => None,
        };
        let config = files::client_config(&user, &password, &layout.connect, tls_files.as_ref());
        let header = format!(
            "Zenoh client configuration of {user} on site {:?} (`--zenoh-config`).\n\
             Written by `ickon site secure`: keep it secret (0600).",
            site.name
        );
        files::write_private(
            &files::client_path(&dir, identity),
            &files::with_header(&header, &config),
        )?;
    }
    let routers = layout.routers.max(1);
    let router_names: Vec<String> = (1..=routers).map(router_name).collect();
    let zids = (0..routers)
        .map(|_| files::new_zid())
        .collect::<Result<Vec<_>, _>>()?;
    let router_password = password_of(&Identity::Router.user())?;
    if routers > 1 {
        identities.push(Identity::Router);
        dictionary.push_str(&format!("router:{router_password}\n"));
    }
    let users = dir.join(USERS_FILE);
    files::write_private(&users, &dictionary)?;
    let link = if layout.link.is_empty() {
        &layout.connect
    } else {
        &layout.link
    };
    let hosts = layout.router_hosts();
    for (k, zid) in (1..=routers).zip(&zids) {
        let header = format!(
            "Zenoh router {k} of {routers} of site {:?} with access control, default deny\n\
             (`ickon router --zenoh-config {}`, or `zenohd -c`).\n\
             Written by `ickon site secure`; the user/password dictionary is {}.",
            site.name,
            files::router_file(k),
            users.display()
        );
        let to_first = (k > 1).then_some((link.as_slice(), router_password.as_str()));
        let name = &router_names[k - 1];
        // The first router knows the others by the user they connect as
        // (and their certificates); they know the first, which they
        // connected to, by its certificate, or without TLS by its id.
        let trust = acl::Trust {
            certificates: tls,
            linking_routers: router_names[1..].to_vec(),
            connected_routers: match (k > 1, tls) {
                (false, _) => vec![],
                (true, true) => router_names[..1].to_vec(),
                (true, false) => zids[..1].to_vec(),
            },
        };
        let acl = acl::access_control(site, &identities, layout.ros2, &trust);
        let keys = ickon_proto::keys::Keys::new(&site.name).map_err(|e| SecureError::Field {
            file: dir.join(files::router_file(k)),
            field: "site name".into(),
            problem: e.to_string(),
        })?;
        let limits = limits::low_pass_filter(&keys);
        let tls_files = match &ca {
            Some(ca) => Some(write_identity(
                ca,
                &dir,
                name,
                certs::Role::Router,
                &hosts,
                validity,
            )?),
            None => None,
        };
        let pinned = (!tls).then_some(zid.as_str());
        let config = files::router_config(
            pinned,
            &layout.listen,
            &users,
            (acl, limits),
            to_first,
            tls_files.as_ref(),
        );
        files::write_private(
            &dir.join(files::router_file(k)),
            &files::with_header(&header, &config),
        )?;
    }
    Ok(SecuredDir { dir })
}

/// The name of router `k` (from 1): its certificate's common name, the stem
/// of its configuration file.
fn router_name(k: usize) -> String {
    files::router_file(k).trim_end_matches(".json5").to_string()
}

/// The site CA (`reused`, or a new one): its key and certificate in `ca/`,
/// its certificate also in `tls/` for the nodes.
fn write_ca(
    site: &Site,
    dir: &Path,
    reused: Option<certs::SiteCa>,
    valid_days: u32,
) -> Result<certs::SiteCa, SecureError> {
    let ca = match reused {
        Some(ca) => ca,
        None => {
            let days = valid_days.max(certs::CA_VALID_DAYS);
            certs::SiteCa::generate(&site.name, certs::Validity::days_from_now(days))?
        }
    };
    files::create_private_dir(&dir.join(CA_DIR))?;
    files::create_private_dir(&dir.join(TLS_DIR))?;
    files::write_private(&dir.join(CA_DIR).join(CA_KEY_FILE), ca.key_pem())?;
    files::write_private(&dir.join(CA_DIR).join(CA_CERT_FILE), ca.cert_pem())?;
    files::write_private(&dir.join(TLS_DIR).join(CA_CERT_FILE), ca.cert_pem())?;
    Ok(ca)
}

/// The CA in `from` (a secured directory, or its `ca/` directory).
fn load_ca(from: &Path) -> Result<certs::SiteCa, SecureError> {
    // A CA certificate or key is a few hundred bytes.
    const MAX_CA_FILE_BYTES: u64 = 1 << 20;
    let problem = |problem: String| SecureError::Ca {
        dir: from.to_path_buf(),
        problem,
    };
    let ca_dir = if from.join(CA_DIR).join(CA_KEY_FILE).exists() {
        from.join(CA_DIR)
    } else {
        from.to_path_buf()
    };
    let read = |name: &str| {
        let path = ca_dir.join(name);
        ickon_proto::text_file::read_bounded(&path, MAX_CA_FILE_BYTES)
            .map_err(|e| problem(format!("{}: {e}", path.display())))
    };
    let (cert, key) = (read(CA_CERT_FILE)?, read(CA_KEY_FILE)?);
    certs::SiteCa::load(&cert, &key).map_err(problem)
}

/// A new key and certificate for the identity named `name`, written to `tls/`.
fn write_identity(
    ca: &certs::SiteCa,
    dir: &Path,
    name: &str,
    role: certs::Role,
    hosts: &[String],
    validity: certs::Validity,
) -> Result<TlsFiles, SecureError> {
    let issued = ca.issue(name, role, hosts, validity)?;
    let tls = TlsFiles::of(dir, name);
    files::write_private(&tls.key, &issued.key_pem)?;
    files::write_private(&tls.cert, &issued.cert_pem)?;
    Ok(tls)
}

/// Runs `ickon site secure` and returns the exit code.
pub fn run(args: SecureArgs) -> Result<(), CommandError> {
    let (site, _, name) = Site::load_or_default(args.site.as_deref())
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    let layout = Layout {
        listen: args.listen,
        connect: args.connect,
        link: args.link,
        routers: usize::from(args.routers),
        sim: args.sim,
        fleets: vec![],
        robots: args.robots.into_iter().flat_map(|r| r.0).collect(),
        ros2: acl::Ros2Scope {
            domain: args.ros2_domain,
        },
        valid_days: args.valid_days,
        ca: args.ca,
    };
    match write_dir(&site, &args.out, &layout) {
        Ok(dir) => {
            let n = layout.identities(&site).len();
            let routers: Vec<String> = (1..=layout.routers)
                .map(|k| dir.router_k(k).display().to_string())
                .collect();
            println!(
                "site {:?} from {name}: router configuration {}, {n} credentials in {}",
                site.name,
                routers.join(", "),
                dir.dir.join(CLIENTS_DIR).display()
            );
            if dir.uses_tls() {
                let (_, ca_key) = dir.ca();
                println!(
                    "mutual TLS: the site CA's certificate and each identity's key and certificate ({} days) in {}\n\
                     the CA's private key is {}: keep it off every node (offline); it is needed only to issue certificates",
                    layout.valid_days,
                    dir.dir.join(TLS_DIR).display(),
                    ca_key.display()
                );
            } else {
                println!(
                    "links in clear (tcp/ endpoints): anyone on the network reads and can inject traffic; use tls/ endpoints"
                );
            }
            Ok(())
        }
        Err(e) => Err(e.into_command_error()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_directory_opens_and_zenoh_accepts_the_router() {
        let tmp = tempfile::tempdir().unwrap();
        let site = Site::load_or_default(None).unwrap().0;
        let dir = tmp.path().join("secure");
        let layout = Layout {
            listen: vec!["tls/127.0.0.1:0".into()],
            connect: vec!["tls/127.0.0.1:7447".into()],
            link: vec![],
            routers: 2,
            sim: true,
            fleets: vec![],
            robots: vec![],
            ros2: acl::Ros2Scope { domain: 0 },
            valid_days: certs::DEFAULT_VALID_DAYS,
            ca: None,
        };
        let written = write_dir(&site, &dir, &layout).unwrap();
        let ids = Identity::all_of(&site, true);
        SecuredDir::open(&written.dir, &ids).unwrap();
        for k in [1, 2] {
            let router = written.router_k(k);
            let config = zenoh::Config::from_file(&router).unwrap();
            check::router(&router, &config).unwrap();
        }
        let users = check::dictionary_users(&written.dir.join(USERS_FILE)).unwrap();
        assert_eq!(users.len(), ids.len() + 1, "and the linked routers' user");
        // Mutual TLS: a key and certificate per identity and router, the
        // CA key apart from what nodes get; every file checks.
        assert!(written.uses_tls());
        let now = ickon_runtime::certificate::unix_now_s();
        for id in &ids {
            let tls = written.tls_files(id);
            let facts = ickon_runtime::certificate::check_certificate(&tls.cert, now).unwrap();
            assert_eq!(facts.subject, id.user());
            ickon_runtime::certificate::check_private_key(&tls.key, Some(&tls.cert)).unwrap();
            let config = zenoh::Config::from_file(written.client(id)).unwrap();
            assert_eq!(
                ickon_runtime::certificate::check_config_files(&config, now)
                    .unwrap()
                    .len(),
                2
            );
        }
        for k in [1, 2] {
            let config = zenoh::Config::from_file(written.router_k(k)).unwrap();
            assert_eq!(
                ickon_runtime::certificate::check_config_files(&config, now)
                    .unwrap()
                    .len(),
                3
            );
            assert_eq!(
                config.get_json("transport/link/tls/enable_mtls").unwrap(),
                "true"
            );
        }
        let (_, ca_key) = written.ca();
        assert!(ca_key.exists());
        assert!(!written.dir.join(TLS_DIR).join(CA_KEY_FILE).exists());
        let in_tls: Vec<_> = std::fs::read_dir(written.dir.join(TLS_DIR))
            .unwrap()
            .collect();
        assert_eq!(
            in_tls.len(),
            1 + 2 * (ids.len() + 2),
            "the CA certificate, a pair per identity and router"
        );
        // A second run into the same directory is refused, nothing changed.
        let again = write_dir(&site, &dir, &layout);
        assert!(matches!(again, Err(SecureError::NotEmpty(_))));

        // Renewal: a new directory issued by the same CA.
        let renewed = write_dir(
            &site,
            &tmp.path().join("renewed"),
            &Layout {
                ca: Some(written.dir.clone()),
                ..layout.clone()
            },
        )
        .unwrap();
        let ca_cert = |d: &SecuredDir| std::fs::read_to_string(d.ca().0).unwrap();
        assert_eq!(ca_cert(&renewed), ca_cert(&written));
        let users = |d: &Path| std::fs::read_to_string(d.join(USERS_FILE)).unwrap();
        assert_eq!(users(&renewed.dir), users(&written.dir), "passwords kept");
        let cert = |d: &SecuredDir| std::fs::read_to_string(d.tls_files(&Identity::Central).cert);
        assert_ne!(cert(&renewed).unwrap(), cert(&written).unwrap());
        // Given only the CA, every password is new.
        let locked = write_dir(
            &site,
            &tmp.path().join("locked"),
            &Layout {
                ca: Some(written.dir.join(CA_DIR)),
                ..layout.clone()
            },
        )
        .unwrap();
        assert_eq!(ca_cert(&locked), ca_cert(&written));
        assert_ne!(users(&locked.dir), users(&written.dir));
        let bad = write_dir(
            &site,
            &tmp.path().join("bad"),
            &Layout {
                ca: Some(written.dir.join(TLS_DIR)),
                ..layout.clone()
            },
        );
        assert!(matches!(bad, Err(SecureError::Ca { .. })), "{bad:?}");
        assert!(!tmp.path().join("bad").exists(), "nothing written");
    }

    #[test]
    fn tls_and_clear_endpoints_do_not_mix() {
        let mut layout = Layout {
            listen: vec!["tls/0.0.0.0:7447".into()],
            connect: vec!["tcp/127.0.0.1:7447".into()],
            link: vec![],
            routers: 1,
            sim: false,
            fleets: vec![],
            robots: vec![],
            ros2: acl::Ros2Scope { domain: 0 },
            valid_days: 1,
            ca: None,
        };
        let err = layout.tls().unwrap_err().to_string();
        assert!(err.contains("mix"), "{err}");
        layout.connect = vec!["tls/router.example:7447".into(), "tls/10.0.0.1:7447".into()];
        assert!(layout.tls().unwrap());
        assert_eq!(layout.router_hosts(), ["10.0.0.1", "router.example"]);
        layout.listen = vec!["tcp/0.0.0.0:7447".into()];
        layout.connect = vec!["tcp/127.0.0.1:7447".into()];
        assert!(!layout.tls().unwrap());
    }
}
