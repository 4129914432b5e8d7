//! `ickon site secure SITE --out DIR`: a site's routers with access control,
//! default deny, and one credential per node.
//!
//! Writes into a new private directory:
//! - `router.json5`: the router's configuration (`ickon router --zenoh-config`,
//!   or `zenohd -c`), with the user/password check and the ACL
//!   ([`acl::access_control`]): a robot publishes only `robot/<id>/...`, a
//!   cell only `cell/<id>/...`, only the central unit `central/**`, and only
//!   the admin identity (and the central unit) queries `central/admin/**`;
//!   and the largest message it lets through per key ([`limits`]);
//! - `users.txt`: the dictionary of user names and passwords the router
//!   checks (`<user>:<password>` per line);
//! - `clients/<user>.json5`: each identity's client configuration
//!   (`--zenoh-config` of `ickon-central`, `ickon-cell`, `ickon-msu`,
//!   `ickon admin`, `ickon record`), with its user and password.
//!
//! Passwords are 192 bits from the operating system's random source, not
//! from a seed: a seed would make them guessable. Every file is 0600.

pub mod acl;
pub mod check;
pub mod files;
mod identity;
pub mod limits;

pub use identity::Identity;

use std::path::{Path, PathBuf};

use clap::Args;
use ickon_proto::site::Site;

use files::{CLIENTS_DIR, ROUTER_FILE, USERS_FILE};
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
            SecureError::Random(_) => CommandError::failure(self.to_string()),
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
    /// Where the router listens (repeatable).
    #[arg(long, default_value = "tcp/0.0.0.0:7447")]
    pub listen: Vec<String>,
    /// Where the clients reach the router (repeatable).
    #[arg(long, default_value = "tcp/127.0.0.1:7447")]
    pub connect: Vec<String>,
    /// Also write the simulation's identities (`world`, `observer`): never
    /// on a real site, where the world's rights would let one device forge
    /// every robot's arrivals.
    #[arg(long)]
    pub sim: bool,
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
    /// The robots' ROS 2 keys.
    pub ros2: acl::Ros2Scope,
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
    files::create_private_dir(dir)?;
    files::create_private_dir(&dir.join(CLIENTS_DIR))?;
    // The router reads the dictionary from wherever it is started: give it
    // the absolute path.
    let dir = std::fs::canonicalize(dir).map_err(|e| SecureError::io(dir, e))?;
    let mut identities = Identity::all_of(site, layout.sim);
    let mut dictionary = String::new();
    for identity in &identities {
        let user = identity.user();
        let password = files::new_password()?;
        dictionary.push_str(&format!("{user}:{password}\n"));
        let config = files::client_config(&user, &password, &layout.connect);
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
    let zids = (0..routers)
        .map(|_| files::new_zid())
        .collect::<Result<Vec<_>, _>>()?;
    let router_password = files::new_password()?;
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
        // The first router knows the others by the user they connect as;
        // they know the first, which they connected to, only by its id.
        let trusted_ids = if k > 1 { &zids[..1] } else { &[] };
        let acl = acl::access_control(site, &identities, layout.ros2, trusted_ids);
        let keys = ickon_proto::keys::Keys::new(&site.name).map_err(|e| SecureError::Field {
            file: dir.join(files::router_file(k)),
            field: "site name".into(),
            problem: e.to_string(),
        })?;
        let limits = limits::low_pass_filter(&keys);
        let config = files::router_config(zid, &layout.listen, &users, (acl, limits), to_first);
        files::write_private(
            &dir.join(files::router_file(k)),
            &files::with_header(&header, &config),
        )?;
    }
    Ok(SecuredDir { dir })
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
        ros2: acl::Ros2Scope {
            domain: args.ros2_domain,
        },
    };
    match write_dir(&site, &args.out, &layout) {
        Ok(dir) => {
            let n = Identity::all_of(&site, args.sim).len();
            let routers: Vec<String> = (1..=layout.routers)
                .map(|k| dir.router_k(k).display().to_string())
                .collect();
            println!(
                "site {:?} from {name}: router configuration {}, {n} credentials in {}",
                site.name,
                routers.join(", "),
                dir.dir.join(CLIENTS_DIR).display()
            );
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
            listen: vec!["tcp/127.0.0.1:0".into()],
            connect: vec!["tcp/127.0.0.1:7447".into()],
            link: vec![],
            routers: 2,
            sim: true,
            ros2: acl::Ros2Scope { domain: 0 },
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
        // A second run into the same directory is refused, nothing changed.
        let again = write_dir(&site, &dir, &layout);
        assert!(matches!(again, Err(SecureError::NotEmpty(_))));
    }
}
