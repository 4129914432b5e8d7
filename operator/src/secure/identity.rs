//! Who may connect to a secured router: one identity per node of the site.

use ickon_proto::site::Site;

/// One authenticated identity: a user name on the router, one credential.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Identity {
    /// The central unit (`central`).
    Central,
    /// `ickon admin` (`admin`).
    Admin,
    /// `ickon record` (`recorder`).
    Recorder,
    /// The simulated world (`world`, simulation only: it publishes every
    /// robot's arrivals and odometry, which no real device may).
    World,
    /// The `ickon sim` launcher's own session (`observer`, simulation only):
    /// reads everything, publishes latency probes.
    Observer,
    /// A cell controller (`cell-<id>`).
    Cell(String),
    /// A robot: its MSU agent and its drivers (`robot-<id>`).
    Robot(String),
    /// Simulation only: one process hosting several robots' agents
    /// (`ickon sim --robots-per-process`), allowed exactly what each of
    /// its robots is (`fleet-<first robot>`; a process's robots are
    /// hosted by no other, so the first names it).
    Fleet(Vec<String>),
    /// Another floor's router linking to this one (`router`): it carries
    /// every node's traffic of its floor, already filtered by its own ACL.
    Router,
}

impl Identity {
    /// The user name it authenticates with: the ACL's subject.
    pub fn user(&self) -> String {
        match self {
            Identity::Central => "central".into(),
            Identity::Admin => "admin".into(),
            Identity::Recorder => "recorder".into(),
            Identity::World => "world".into(),
            Identity::Observer => "observer".into(),
            Identity::Cell(id) => format!("cell-{id}"),
            Identity::Robot(id) => format!("robot-{id}"),
            Identity::Fleet(robots) => {
                format!("fleet-{}", robots.first().map_or("", String::as_str))
            }
            Identity::Router => "router".into(),
        }
    }

    /// The file name of its client configuration.
    pub fn file_name(&self) -> String {
        format!("{}.json5", self.user())
    }

    /// Every identity of `site`: the central unit, admin, recorder, each
    /// cell and robot, and with `sim` the world and the launcher.
    pub fn all_of(site: &Site, sim: bool) -> Vec<Identity> {
        let mut out = vec![Identity::Central, Identity::Admin, Identity::Recorder];
        if sim {
            out.extend([Identity::World, Identity::Observer]);
        }
        out.extend(site.cells.iter().map(|c| Identity::Cell(c.id.clone())));
        out.extend(site.robots.iter().map(|r| Identity::Robot(r.id.clone())));
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn user_names_never_collide() {
        let site = Site::load_or_default(Some("warehouse".as_ref())).unwrap().0;
        let ids = Identity::all_of(&site, true);
        let mut users: Vec<String> = ids.iter().map(Identity::user).collect();
        let n = users.len();
        users.sort();
        users.dedup();
        assert_eq!(users.len(), n);
        assert_eq!(n, 5 + site.cells.len() + site.robots.len());
        assert!(!Identity::all_of(&site, false).contains(&Identity::World));
    }
}
