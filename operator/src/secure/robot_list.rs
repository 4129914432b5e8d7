//! `ickon site secure --robots`: robots given on the command line besides
//! the site file's, to hold credentials before they are listed there
//! (spares, robots still to be delivered).
//!
//! A list is comma-separated; an item is a robot id or a range of ids
//! sharing a prefix, `r1..r50` (a zero-padded start, `r01..r50`, pads them
//! all to its width).

use ickon_proto::keys::validate_id;

/// The most robots one `--robots` may name: far above any site, low
/// enough that a typo (`r1..r1000000`) is refused rather than written.
pub const MAX_ROBOTS: usize = 10_000;

/// The robot ids of one `--robots` value, in the order given.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RobotIds(pub Vec<String>);

/// Parses a `--robots` value (clap's value parser).
pub fn parse(text: &str) -> Result<RobotIds, String> {
    let mut ids = Vec::new();
    for item in text.split(',').map(str::trim) {
        if item.is_empty() {
            return Err(format!("an empty robot id in {text:?}"));
        }
        match item.split_once("..") {
            Some((first, last)) => ids.extend(range(first, last)?),
            None => {
                validate_id(item).map_err(|e| format!("robot {item:?}: {e}"))?;
                ids.push(item.to_string());
            }
        }
        if ids.len() > MAX_ROBOTS {
            return Err(format!("more than {MAX_ROBOTS} robots in {text:?}"));
        }
    }
    let mut seen = std::collections::HashSet::new();
    if let Some(twice) = ids.iter().find(|id| !seen.insert(id.as_str())) {
        return Err(format!("robot {twice:?} is named twice in {text:?}"));
    }
    Ok(RobotIds(ids))
}

/// The ids from `first` to `last`: the same prefix, a number at the end.
fn range(first: &str, last: &str) -> Result<Vec<String>, String> {
    let (prefix, from) = split_number(first)
        .ok_or_else(|| format!("{first:?} does not end in a number (a range is r1..r50)"))?;
    let (last_prefix, to) = split_number(last)
        .ok_or_else(|| format!("{last:?} does not end in a number (a range is r1..r50)"))?;
    if prefix != last_prefix {
        return Err(format!(
            "{first}..{last}: both ends need the same prefix ({prefix:?}, {last_prefix:?})"
        ));
    }
    let start: u64 = from.parse().map_err(|_| format!("{from:?} is too large"))?;
    let end: u64 = to.parse().map_err(|_| format!("{to:?} is too large"))?;
    if end < start {
        return Err(format!("{first}..{last}: the range runs backwards"));
    }
    if end - start >= MAX_ROBOTS as u64 {
        return Err(format!("{first}..{last}: more than {MAX_ROBOTS} robots"));
    }
    let width = if from.len() > 1 && from.starts_with('0') {
        from.len()
    } else {
        0
    };
    (start..=end)
        .map(|n| {
            let id = format!("{prefix}{n:0width$}");
            validate_id(&id).map_err(|e| format!("robot {id:?}: {e}"))?;
            Ok(id)
        })
        .collect()
}

/// `r12` -> (`r`, `12`): the prefix and the digits it ends in, if any.
fn split_number(id: &str) -> Option<(&str, &str)> {
    let digits = id.bytes().rev().take_while(u8::is_ascii_digit).count();
    (digits > 0).then(|| id.split_at(id.len() - digits))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ids(text: &str) -> Vec<String> {
        parse(text).expect(text).0
    }

    #[test]
    fn ranges_and_lists_name_the_robots_in_order() {
        assert_eq!(ids("r1..r3"), ["r1", "r2", "r3"]);
        assert_eq!(ids("r1..r50").len(), 50);
        assert_eq!(
            ids("amr-7, r1..r2,forklift_a"),
            ["amr-7", "r1", "r2", "forklift_a"]
        );
        assert_eq!(ids("r08..r10"), ["r08", "r09", "r10"]);
        assert_eq!(ids("r9..r11"), ["r9", "r10", "r11"]);
    }

    #[test]
    fn what_names_no_robot_clearly_is_refused() {
        for bad in [
            "",
            "r1,,r2",
            "r1..x3",
            "a..b",
            "r5..r1",
            "r1..r20000",
            "r1, r1..r2",
            "bad/id",
            "r1..r99999999999999999999999",
        ] {
            assert!(parse(bad).is_err(), "{bad:?} accepted");
        }
    }

    #[test]
    fn robots_given_apart_from_the_site_file_get_credentials_and_rights() {
        use crate::secure::{Identity, Layout, SecuredDir, acl, write_dir};
        let tmp = tempfile::tempdir().unwrap();
        let site = ickon_proto::site::Site::load_or_default(None).unwrap().0;
        let listed = site.robots[0].id.clone();
        let layout = Layout {
            // Links in clear: no certificates to make, the same identities.
            listen: vec!["tcp/127.0.0.1:7447".into()],
            connect: vec!["tcp/127.0.0.1:7447".into()],
            link: vec![],
            routers: 1,
            sim: false,
            fleets: vec![],
            robots: vec!["amr-1".into(), "amr-2".into(), listed.clone()],
            ros2: acl::Ros2Scope { domain: 0 },
            valid_days: 1,
            ca: None,
        };
        let ids = layout.identities(&site);
        let robots = ids
            .iter()
            .filter(|i| matches!(i, Identity::Robot(_)))
            .count();
        // The site's own robots once each, and the two new ones.
        assert_eq!(robots, site.robots.len() + 2);
        let written = write_dir(&site, &tmp.path().join("secure"), &layout).unwrap();
        SecuredDir::open(&written.dir, &ids).unwrap();
        let router = std::fs::read_to_string(written.router()).unwrap();
        assert!(router.contains("robot/amr-2/"), "no rule for amr-2");
    }
}
