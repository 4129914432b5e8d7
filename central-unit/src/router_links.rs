//! Each node's link to its Zenoh router as the node reports it
//! (`cell/<id>/link`, `robot/<id>/link`), kept for the admin's `links`
//! query: when the link last came back, and how often it was lost.

use std::collections::BTreeMap;

use ickon_proto::msg::admin::LinksReport;
use ickon_proto::msg::control::RouterLink;

/// The most nodes of each kind kept: far above any site's cells or fleet,
/// so that a flood of made-up ids on an open mesh cannot grow the map
/// without bound.
pub const MAX_NODES: usize = 4096;

/// Which kind of node a report is from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeKind {
    /// A cell controller.
    Cell,
    /// A robot's MSU agent.
    Robot,
}

/// The latest report of every node.
#[derive(Debug, Default)]
pub struct RouterLinks {
    cells: BTreeMap<String, RouterLink>,
    robots: BTreeMap<String, RouterLink>,
}

impl RouterLinks {
    /// Takes `link` from a node of `kind`; the id is the key's, not the
    /// payload's. Returns false, keeping nothing, for a report no honest
    /// node sends (back after a loss it does not count) and for a new id
    /// beyond [`MAX_NODES`].
    pub fn observe(&mut self, kind: NodeKind, id: String, link: RouterLink) -> bool {
        if link.back_unix_ms > 0 && link.losses == 0 {
            return false;
        }
        let map = match kind {
            NodeKind::Cell => &mut self.cells,
            NodeKind::Robot => &mut self.robots,
        };
        if map.len() >= MAX_NODES && !map.contains_key(&id) {
            return false;
        }
        let link = RouterLink {
            node_id: id.clone(),
            ..link
        };
        map.insert(id, link);
        true
    }

    /// The answer to `links`.
    pub fn report(&self) -> LinksReport {
        LinksReport {
            cells: self.cells.values().cloned().collect(),
            robots: self.robots.values().cloned().collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(id: &str, back: u64, losses: u64) -> RouterLink {
        RouterLink {
            node_id: id.into(),
            back_unix_ms: back,
            losses,
        }
    }

    #[test]
    fn the_latest_report_of_each_node_is_kept_under_the_keys_id() {
        let mut links = RouterLinks::default();
        links.observe(NodeKind::Cell, "c2".into(), link("c2", 0, 0));
        links.observe(NodeKind::Cell, "c1".into(), link("c1", 5, 1));
        links.observe(NodeKind::Cell, "c2".into(), link("c2", 9, 2));
        // A payload naming another node is taken for the key's.
        links.observe(NodeKind::Robot, "r1".into(), link("c1", 7, 1));
        let r = links.report();
        assert_eq!(r.cells, vec![link("c1", 5, 1), link("c2", 9, 2)]);
        assert_eq!(r.robots, vec![link("r1", 7, 1)]);
    }

    #[test]
    fn new_ids_beyond_the_bound_are_dropped_known_ones_still_update() {
        let mut links = RouterLinks::default();
        for k in 0..MAX_NODES {
            links.observe(NodeKind::Robot, format!("r{k}"), link("", 0, 0));
        }
        assert!(!links.observe(NodeKind::Robot, "extra".into(), link("", 1, 1)));
        assert!(links.observe(NodeKind::Robot, "r0".into(), link("", 3, 1)));
        let r = links.report();
        assert_eq!(r.robots.len(), MAX_NODES);
        assert!(r.robots.iter().all(|l| l.node_id != "extra"));
        assert!(r.robots.contains(&link("r0", 3, 1)));
    }

    #[test]
    fn a_report_of_coming_back_without_a_loss_is_refused_and_the_last_kept() {
        let mut links = RouterLinks::default();
        assert!(links.observe(NodeKind::Cell, "c1".into(), link("c1", 5, 1)));
        // Forged: back at the end of time, never lost.
        assert!(!links.observe(NodeKind::Cell, "c1".into(), link("c1", u64::MAX, 0)));
        assert!(!links.observe(NodeKind::Robot, "r9".into(), link("r9", 1, 0)));
        let r = links.report();
        assert_eq!(r.cells, vec![link("c1", 5, 1)]);
        assert!(r.robots.is_empty());
        // A restarted node (nothing lost since) is honest and replaces it.
        assert!(links.observe(NodeKind::Cell, "c1".into(), link("c1", 0, 0)));
        assert_eq!(links.report().cells, vec![link("c1", 0, 0)]);
    }
}
