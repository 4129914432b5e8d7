//! `ickon sim --secure [DIR]`: the run's routers with access control and
//! every node, the launcher included, authenticated with its own credential
//! over mutual TLS, as `ickon site secure --sim` writes them (into a
//! temporary directory removed at exit, or DIR; a DIR written with `tcp/`
//! endpoints runs the links in clear).

use std::path::Path;
use std::process::Command;

use ickon_proto::site::Site;

use ickon_operator::secure::{
    Identity, Layout, SecureError, SecuredDir, acl::Ros2Scope, write_dir,
};
use ickon_runtime::CommandError;

use crate::args::Mesh;
use crate::args::SimArgs;
use crate::error::LaunchError;

/// The credentials of one secured run.
pub(crate) struct SimSecurity {
    dir: SecuredDir,
    /// Holds the generated directory until the run is over.
    _temp: Option<tempfile::TempDir>,
}

impl SimSecurity {
    /// With `--secure`: the directory given (checked: the router's files
    /// and a credential for every node of this run), or a new set in a
    /// temporary directory.
    pub(crate) fn prepare(
        args: &SimArgs,
        site: &Site,
        robots: &[String],
    ) -> Result<Option<Self>, CommandError> {
        let Some(wanted) = &args.secure else {
            return Ok(None);
        };
        if args.mesh != Mesh::Router {
            return Err(CommandError::bad_input(
                "--secure needs --mesh router: access control is enforced by the router, peers talking directly bypass it",
            ));
        }
        let result = if let Some(wanted) = wanted {
            let mut needed = vec![Identity::Central, Identity::World, Identity::Observer];
            needed.extend(site.cells.iter().map(|c| Identity::Cell(c.id.clone())));
            needed.extend(robots.iter().map(|r| Identity::Robot(r.clone())));
            if args.record.is_some() {
                needed.push(Identity::Recorder);
            }
            SecuredDir::open(wanted, &needed)
                .and_then(|dir| check_routers(dir, args.routers))
                .map(|dir| SimSecurity { dir, _temp: None })
        } else {
            generate(
                site,
                args.routers,
                &crate::zones::fleets(site, robots, args.robots_per_process(), args.routers),
            )
        };
        result
            .map(Some)
            .map_err(|e| e.into_command_error().context("--secure"))
    }

    /// The scheme of the run's endpoints: `tls` when the secured directory
    /// has certificates, else `tcp`.
    pub(crate) fn scheme(&self) -> &'static str {
        if self.dir.uses_tls() { "tls" } else { "tcp" }
    }

    /// Starts router `k` (from 1; the first is the hub the others link
    /// to) with the ACL and the user/password check.
    pub(crate) fn router(&self, cmd: &mut Command, k: usize) {
        cmd.arg("--zenoh-config").arg(self.dir.router_k(k));
    }

    /// Gives a node its credential (the flags on its command line still
    /// say where to connect).
    pub(crate) fn client(&self, cmd: &mut Command, identity: &Identity) {
        cmd.arg("--zenoh-config").arg(self.dir.client(identity));
    }

    /// The client configuration of `identity`, for the launcher's own sessions.
    pub(crate) fn client_file(&self, identity: &Identity) -> std::path::PathBuf {
        self.dir.client(identity)
    }

    /// Where the admin credential is, to tell the user.
    pub(crate) fn admin_hint(&self) -> String {
        format!(
            "access control on; `ickon admin` needs --zenoh-config {}",
            self.dir.client(&Identity::Admin).display()
        )
    }
}

/// Checks that a secured directory has the files of routers 2 to
/// `routers` (the first was checked when it was opened), each a router
/// configuration the router would accept.
fn check_routers(dir: SecuredDir, routers: usize) -> Result<SecuredDir, SecureError> {
    for k in 2..=routers {
        let file = dir.router_k(k);
        if !file.exists() {
            return Err(SecureError::Field {
                file,
                field: "(file)".into(),
                problem: format!(
                    "missing: --routers {routers} needs the files of {routers} linked routers (`ickon site secure --sim --routers {routers}`)"
                ),
            });
        }
        let config = zenoh::Config::from_file(&file).map_err(|e| SecureError::Field {
            file: file.clone(),
            field: "(file)".into(),
            problem: e.to_string(),
        })?;
        ickon_operator::secure::check::router(&file, &config)?;
    }
    Ok(dir)
}

/// A fresh set of credentials for every identity of the site, with the
/// files of `routers` linked routers, and one for each of `fleets` (the
/// robots of each process that hosts several).
fn generate(
    site: &Site,
    routers: usize,
    fleets: &[Vec<String>],
) -> Result<SimSecurity, SecureError> {
    let temp = tempfile::Builder::new()
        .prefix("ickon-secure-")
        .tempdir()
        .map_err(|e| SecureError::Io {
            path: std::env::temp_dir(),
            source: e,
        })?;
    let domain = ros2_domain();
    let layout = Layout {
        listen: vec!["tls/127.0.0.1:7447".into()],
        connect: vec!["tls/127.0.0.1:7447".into()],
        link: vec![],
        routers,
        sim: true,
        fleets: fleets.to_vec(),
        robots: vec![],
        ros2: Ros2Scope { domain },
        valid_days: ickon_operator::secure::certs::DEFAULT_VALID_DAYS,
        ca: None,
    };
    let dir = write_dir(site, &temp.path().join("site"), &layout)?;
    Ok(SimSecurity {
        dir,
        _temp: Some(temp),
    })
}

/// The ROS domain the agents use with `--ros2` (`ROS_DOMAIN_ID`, else 0),
/// so that the ACL names their keys.
fn ros2_domain() -> u32 {
    std::env::var("ROS_DOMAIN_ID")
        .ok()
        .and_then(|s| s.trim().parse().ok())
        .unwrap_or(0)
}

/// A Zenoh configuration starting from `file` (a credential, its TLS
/// files checked as every node checks its own), or the default.
pub(crate) fn base_config(file: Option<&Path>) -> Result<zenoh::Config, LaunchError> {
    match file {
        Some(f) => {
            let config = zenoh::Config::from_file(f).map_err(|e| LaunchError::ZenohConfigFile {
                file: f.to_path_buf(),
                message: e.to_string(),
            })?;
            ickon_runtime::args::check_tls_files(&config)?;
            Ok(config)
        }
        None => Ok(zenoh::Config::default()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn written(dir: &Path, routers: usize) -> SecuredDir {
        let site = Site::load_or_default(None).unwrap().0;
        let layout = Layout {
            // Links in clear: no certificates to make, the same files.
            listen: vec!["tcp/127.0.0.1:7447".into()],
            connect: vec!["tcp/127.0.0.1:7447".into()],
            link: vec![],
            routers,
            sim: true,
            fleets: vec![],
            robots: vec![],
            ros2: Ros2Scope { domain: 0 },
            valid_days: 1,
            ca: None,
        };
        write_dir(&site, dir, &layout).unwrap()
    }

    #[test]
    fn a_directory_needs_the_files_of_every_router_of_the_run() {
        let tmp = tempfile::tempdir().unwrap();
        let one = written(&tmp.path().join("one"), 1);
        assert!(check_routers(one.clone(), 1).is_ok());
        let err = check_routers(one, 3).unwrap_err().to_string();
        assert!(err.contains("router-2.json5"), "{err}");
        assert!(err.contains("--routers 3"), "{err}");
        let three = written(&tmp.path().join("three"), 3);
        assert!(check_routers(three.clone(), 3).is_ok());
        assert!(check_routers(three.clone(), 2).is_ok());
        // A router file that is not a router configuration is named.
        std::fs::write(three.router_k(3), "{ not json5").unwrap();
        let err = check_routers(three, 3).unwrap_err().to_string();
        assert!(err.contains("router-3.json5"), "{err}");
    }
}
