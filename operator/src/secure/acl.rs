//! The routers' access control list, default deny: who may publish, read,
//! ask and answer which keys. Pure: a site and its identities in, Zenoh's
//! `access_control` block (JSON) out.
//!
//! Zenoh checks every message a client sends (ingress) and every message
//! the router forwards to it (egress) against the rules of the subjects the
//! client authenticated as; with `default_permission: "deny"` a message no
//! rule allows is dropped. So each role below is written as verbs on keys,
//! and each verb is the messages and directions it takes (docs/architecture.md,
//! "Zenoh facts the code relies on"): a reader needs its subscription declared (ingress) and the
//! data forwarded to it (egress); a writer only its `put` (ingress).

use ickon_proto::keys::Keys;
use ickon_proto::site::Site;
use serde_json::{Value, json};

use super::Identity;

/// What a role may do on a set of keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verb {
    /// Put samples.
    Publish,
    /// Declare a subscriber and receive the samples.
    Subscribe,
    /// Send queries and receive the replies.
    Query,
    /// Declare a queryable, receive queries, reply.
    Serve,
    /// Declare a liveliness token (presence).
    Token,
    /// Watch liveliness tokens (subscribe and ask).
    Watch,
    /// See which subscribers and queryables exist (not their data): lets a
    /// client's publisher and querier know where to send.
    SeeDeclarations,
    /// Everything, both ways: a linked router's traffic.
    Everything,
}

/// Every message kind of Zenoh's ACL.
const ALL_MESSAGES: &[&str] = &[
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "reply",
    "declare_queryable",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
];

impl Verb {
    /// The (flow, messages) pairs the verb allows, in Zenoh's names.
    fn grants(self) -> &'static [(&'static str, &'static [&'static str])] {
        match self {
            Verb::Publish => &[("ingress", &["put"])],
            Verb::Subscribe => &[("ingress", &["declare_subscriber"]), ("egress", &["put"])],
            Verb::Query => &[("ingress", &["query"]), ("egress", &["reply"])],
            Verb::Serve => &[
                ("ingress", &["declare_queryable", "reply"]),
                ("egress", &["query"]),
            ],
            Verb::Token => &[("ingress", &["liveliness_token"])],
            Verb::Watch => &[
                (
                    "ingress",
                    &["declare_liveliness_subscriber", "liveliness_query"],
                ),
                ("egress", &["liveliness_token"]),
            ],
            Verb::SeeDeclarations => &[("egress", &["declare_subscriber", "declare_queryable"])],
            Verb::Everything => &[("ingress", ALL_MESSAGES), ("egress", ALL_MESSAGES)],
        }
    }
}

/// Where the ROS 2 keys of `ickon-msu --ros2` (rmw_zenoh) live.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ros2Scope {
    /// The ROS domain id: the first chunk of every rmw_zenoh key.
    pub domain: u32,
}

/// What the central unit subscribes to: every node's reports (its own
/// keys it may publish and so hear).
fn central_hears(keys: &Keys) -> Vec<String> {
    vec![
        keys.cell_status_all(),
        keys.cell_burst_all(),
        keys.robot_summary_all(),
        keys.robot_status_all(),
        keys.cell_link_all(),
        keys.robot_link_all(),
        keys.sim_truth_all(),
    ]
}

/// Everything `identity` may do, as (verb, key expressions).
///
/// One piece on purpose: it is the access table of the whole mesh, one
/// arm per identity, and reviewing who may do what means reading every
/// identity's rules side by side.
fn permissions(identity: &Identity, keys: &Keys, ros2: Ros2Scope) -> Vec<(Verb, Vec<String>)> {
    use Verb::*;
    let p = keys.prefix();
    let d = ros2.domain;
    let mut out = vec![(SeeDeclarations, vec![format!("{p}/**")])];
    match identity {
        Identity::Central => out.extend([
            (Publish, vec![format!("{p}/central/**")]),
            (Serve, vec![format!("{p}/central/**")]),
            (Query, vec![format!("{p}/central/**")]),
            (Token, vec![keys.alive_central()]),
            (Watch, vec![keys.alive_all()]),
            (Subscribe, central_hears(keys)),
        ]),
        Identity::Cell(id) => out.extend([
            (Publish, vec![format!("{p}/cell/{id}/**")]),
            (
                Subscribe,
                vec![keys.central_cycle(), keys.central_schedule()],
            ),
            (
                Query,
                vec![
                    keys.central_site(),
                    keys.central_schedule(),
                    keys.central_clock(),
                ],
            ),
            (Token, vec![format!("{p}/alive/cell/{id}")]),
            (Watch, vec![keys.alive_central()]),
        ]),
        Identity::Robot(id) => out.extend([
            (
                Publish,
                vec![
                    format!("{p}/robot/{id}/**"),
                    format!("{d}/{id}/**"),
                    format!("{d}/tf/**"),
                ],
            ),
            (
                Subscribe,
                vec![
                    format!("{p}/robot/{id}/**"),
                    keys.central_schedule(),
                    // Which transmitters fire each cycle (occupancy firing).
                    keys.central_cycle(),
                    // Each cell's sync sigma (the prior of its clock bias).
                    keys.cell_status_all(),
                    // The transmitters' positions as the fleet calibrated them.
                    keys.central_survey(),
                    format!("{d}/{id}/**"),
                ],
            ),
            (Query, vec![keys.central_site(), keys.central_schedule()]),
            (
                Token,
                vec![
                    format!("{p}/alive/robot/{id}"),
                    // rmw_zenoh's tokens: domain, zid, node id, entity id,
                    // kind, enclave, then the namespace `/<id>` mangled.
                    format!("@ros2_lv/{d}/*/*/*/*/*/%{id}/**"),
                ],
            ),
            (Watch, vec![keys.alive_central()]),
            (SeeDeclarations, vec![format!("{d}/**")]),
        ]),
        Identity::World => out.extend([
            (
                Publish,
                vec![
                    format!("{p}/robot/*/ultrasound"),
                    format!("{p}/robot/*/odom"),
                    format!("{p}/robot/*/imu"),
                    format!("{p}/robot/*/range"),
                    format!("{p}/sim/**"),
                    format!("{d}/*/odom/**"),
                    format!("{d}/*/imu/**"),
                ],
            ),
            (
                Subscribe,
                vec![
                    keys.central_schedule(),
                    keys.cell_burst_all(),
                    // Which transmitters fire each cycle: when it is over.
                    keys.central_cycle(),
                ],
            ),
            (Query, vec![keys.central_site(), keys.central_schedule()]),
            (Token, vec![keys.alive_world(), format!("@ros2_lv/{d}/**")]),
            (Watch, vec![keys.alive_central()]),
            (SeeDeclarations, vec![format!("{d}/**")]),
        ]),
        Identity::Admin => out.extend([
            (Query, vec![format!("{p}/central/**")]),
            (Watch, vec![keys.alive_all()]),
        ]),
        Identity::Recorder => out.extend([
            (Subscribe, vec![keys.everything()]),
            (Query, vec![keys.central_site(), keys.central_schedule()]),
            (Watch, vec![keys.alive_all()]),
        ]),
        Identity::Observer => out.extend([
            (Subscribe, vec![keys.everything()]),
            (Publish, vec![keys.sim_probe()]),
            (Watch, vec![keys.alive_all()]),
        ]),
        Identity::Fleet(robots) => {
            for robot in robots {
                // Each robot's own rules, without the shared first one again.
                let own = permissions(&Identity::Robot(robot.clone()), keys, ros2);
                out.extend(own.into_iter().skip(1));
            }
        }
        // `**` does not match a chunk starting with `@`: name rmw_zenoh's.
        Identity::Router => out.push((Everything, vec!["**".into(), "@ros2_lv/**".into()])),
    }
    out
}

/// How a router knows who is at the other end of a link.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Trust {
    /// Links are mutual TLS: a client must show a certificate of the site
    /// CA whose common name is its user name, and give that user's password.
    pub certificates: bool,
    /// With certificates: the common names of the routers that link to
    /// this one (they also authenticate as the user `router`).
    pub linking_routers: Vec<String>,
    /// The routers this one connected to. A link between two routers
    /// authenticates the connecting one by its user name `router` (and its
    /// certificate); the accepting one is known to the other by its
    /// certificate's common name (with certificates) or else only by its
    /// pinned Zenoh id, which is what this lists.
    pub connected_routers: Vec<String>,
}

/// The `access_control` block of the router's configuration: default deny,
/// one subject per identity (matched by the user name it authenticated
/// with and, with [`Trust::certificates`], by its certificate's common
/// name too: both must match), one rule per (identity, direction, message
/// kinds). Linked routers as [`Trust`] says.
pub fn access_control(
    site: &Site,
    identities: &[Identity],
    ros2: Ros2Scope,
    trust: &Trust,
) -> Value {
    // The site was validated when loaded, so its name is a valid key chunk;
    // were it not, no key could be built and every rule would be empty.
    let Ok(keys) = Keys::new(&site.name) else {
        return json!({ "enabled": true, "default_permission": "deny" });
    };
    let mut rules = Vec::new();
    let mut subjects = Vec::new();
    let mut policies = Vec::new();
    for identity in identities {
        let user = identity.user();
        let rule_ids = push_rules(identity, &keys, ros2, &mut rules);
        let mut subject = json!({ "id": user, "usernames": [user] });
        if trust.certificates {
            subject["cert_common_names"] = match identity {
                Identity::Router => json!(trust.linking_routers),
                _ => json!([user]),
            };
        }
        subjects.push(subject);
        let mut subject_ids = vec![user.clone()];
        if *identity == Identity::Router && !trust.connected_routers.is_empty() {
            let known_by = if trust.certificates {
                "cert_common_names"
            } else {
                "zids"
            };
            subjects.push(json!({ "id": "connected-routers", known_by: trust.connected_routers }));
            subject_ids.push("connected-routers".into());
        }
        policies.push(json!({ "id": user, "rules": rule_ids, "subjects": subject_ids }));
    }
    json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    })
}

/// Appends `identity`'s rules to `rules`, one per (flow, message kinds),
/// and returns their ids.
fn push_rules(
    identity: &Identity,
    keys: &Keys,
    ros2: Ros2Scope,
    rules: &mut Vec<Value>,
) -> Vec<String> {
    let user = identity.user();
    let mut rule_ids = Vec::new();
    // Merge the verbs' grants into one rule per (flow, message kinds).
    let mut merged: Vec<(&str, &[&str], Vec<String>)> = Vec::new();
    for (verb, key_exprs) in permissions(identity, keys, ros2) {
        for (flow, messages) in verb.grants() {
            match merged
                .iter_mut()
                .find(|(f, m, _)| f == flow && *m == *messages)
            {
                Some((_, _, k)) => k.extend(key_exprs.iter().cloned()),
                None => merged.push((flow, messages, key_exprs.clone())),
            }
        }
    }
    for (n, (flow, messages, mut key_exprs)) in merged.into_iter().enumerate() {
        key_exprs.sort();
        key_exprs.dedup();
        let id = format!("{user}-{n}");
        rules.push(json!({
            "id": id,
            "messages": messages,
            "flows": [flow],
            "permission": "allow",
            "key_exprs": key_exprs,
        }));
        rule_ids.push(id);
    }
    rule_ids
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lab() -> Site {
        Site::load_or_default(None).unwrap().0
    }

    fn allowed(acl: &Value, user: &str, flow: &str, message: &str) -> Vec<String> {
        let rules = acl["rules"].as_array().unwrap();
        let mut out = Vec::new();
        for rule in rules.iter().filter(|r| {
            r["id"].as_str().unwrap().starts_with(&format!("{user}-"))
                && r["flows"][0] == flow
                && r["messages"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .any(|m| m == message)
        }) {
            for k in rule["key_exprs"].as_array().unwrap() {
                out.push(k.as_str().unwrap().to_string());
            }
        }
        out
    }

    #[test]
    fn only_the_central_unit_publishes_central_keys() {
        let site = lab();
        let ids = Identity::all_of(&site, true);
        let acl = access_control(&site, &ids, Ros2Scope { domain: 0 }, &Trust::default());
        assert_eq!(acl["default_permission"], "deny");
        for id in &ids {
            let puts = allowed(&acl, &id.user(), "ingress", "put");
            let central = puts.iter().any(|k| k.contains("/central"));
            assert_eq!(central, *id == Identity::Central, "{}: {puts:?}", id.user());
        }
    }

    #[test]
    fn a_robot_publishes_only_its_own_keys_and_reads_only_what_its_msu_needs() {
        let site = lab();
        let acl = access_control(
            &site,
            &[Identity::Robot("r1".into())],
            Ros2Scope { domain: 7 },
            &Trust::default(),
        );
        let puts = allowed(&acl, "robot-r1", "ingress", "put");
        assert_eq!(puts, ["7/r1/**", "7/tf/**", "ickon/lab/robot/r1/**"]);
        let reads = allowed(&acl, "robot-r1", "egress", "put");
        assert_eq!(
            reads,
            [
                "7/r1/**",
                "ickon/lab/cell/*/status",
                "ickon/lab/central/cycle",
                "ickon/lab/central/schedule",
                "ickon/lab/central/survey",
                "ickon/lab/robot/r1/**"
            ]
        );
        let queries = allowed(&acl, "robot-r1", "ingress", "query");
        assert!(queries.iter().all(|k| !k.contains("admin")), "{queries:?}");
    }

    #[test]
    fn a_fleet_may_do_what_its_robots_may_and_nothing_for_the_others() {
        let site = lab();
        let fleet = Identity::Fleet(vec!["r1".into(), "r2".into()]);
        let acl = access_control(
            &site,
            std::slice::from_ref(&fleet),
            Ros2Scope { domain: 0 },
            &Trust::default(),
        );
        let user = fleet.user();
        assert_eq!(user, "fleet-r1");
        let mut puts = allowed(&acl, &user, "ingress", "put");
        puts.sort();
        puts.dedup();
        assert_eq!(
            puts,
            [
                "0/r1/**",
                "0/r2/**",
                "0/tf/**",
                "ickon/lab/robot/r1/**",
                "ickon/lab/robot/r2/**"
            ]
        );
        let tokens = allowed(&acl, &user, "ingress", "liveliness_token");
        assert!(
            tokens.contains(&"ickon/lab/alive/robot/r2".to_string()),
            "{tokens:?}"
        );
        let everything: Vec<String> = ["ingress", "egress"]
            .iter()
            .flat_map(|flow| {
                ALL_MESSAGES
                    .iter()
                    .flat_map(|m| allowed(&acl, &user, flow, m))
            })
            .collect();
        assert!(
            everything
                .iter()
                .all(|k| !k.contains("r3") && !k.contains("/central/admin")),
            "{everything:?}"
        );
    }

    #[test]
    fn a_cell_publishes_only_under_its_own_id() {
        let site = lab();
        let acl = access_control(
            &site,
            &[Identity::Cell("c2".into())],
            Ros2Scope { domain: 0 },
            &Trust::default(),
        );
        assert_eq!(
            allowed(&acl, "cell-c2", "ingress", "put"),
            ["ickon/lab/cell/c2/**"]
        );
        assert_eq!(
            allowed(&acl, "cell-c2", "ingress", "liveliness_token"),
            ["ickon/lab/alive/cell/c2"]
        );
    }

    #[test]
    fn only_admin_and_central_may_query_admin_keys() {
        let site = lab();
        let ids = Identity::all_of(&site, true);
        let acl = access_control(&site, &ids, Ros2Scope { domain: 0 }, &Trust::default());
        for id in &ids {
            let q = allowed(&acl, &id.user(), "ingress", "query");
            let admin = q.iter().any(|k| k.ends_with("central/**"));
            assert_eq!(
                admin,
                matches!(id, Identity::Admin | Identity::Central),
                "{}: {q:?}",
                id.user()
            );
        }
    }

    #[test]
    fn every_rule_is_named_in_a_policy_and_every_subject_has_one() {
        let site = lab();
        let acl = access_control(
            &site,
            &Identity::all_of(&site, true),
            Ros2Scope { domain: 0 },
            &Trust::default(),
        );
        let rule_ids: Vec<&str> = acl["rules"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["id"].as_str().unwrap())
            .collect();
        let in_policies: Vec<&str> = acl["policies"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|p| p["rules"].as_array().unwrap())
            .map(|r| r.as_str().unwrap())
            .collect();
        assert_eq!(rule_ids, in_policies);
        assert_eq!(
            acl["subjects"].as_array().unwrap().len(),
            acl["policies"].as_array().unwrap().len()
        );
    }

    #[test]
    fn with_certificates_both_the_name_and_the_user_must_match() {
        let site = lab();
        let ids = [Identity::Robot("r1".into()), Identity::Router];
        let trust = Trust {
            certificates: true,
            linking_routers: vec!["router-2".into()],
            connected_routers: vec!["router".into()],
        };
        let acl = access_control(&site, &ids, Ros2Scope { domain: 0 }, &trust);
        let subjects = acl["subjects"].as_array().unwrap();
        assert_eq!(
            subjects[0],
            json!({ "id": "robot-r1", "usernames": ["robot-r1"], "cert_common_names": ["robot-r1"] })
        );
        assert_eq!(
            subjects[1],
            json!({ "id": "router", "usernames": ["router"], "cert_common_names": ["router-2"] })
        );
        // The router this one linked to: by its certificate, not by an id.
        assert_eq!(
            subjects[2],
            json!({ "id": "connected-routers", "cert_common_names": ["router"] })
        );
        let plain = Trust {
            certificates: false,
            linking_routers: vec![],
            connected_routers: vec!["1234".into()],
        };
        let acl = access_control(&site, &ids, Ros2Scope { domain: 0 }, &plain);
        assert_eq!(acl["subjects"][0].get("cert_common_names"), None);
        assert_eq!(acl["subjects"][2]["zids"], json!(["1234"]));
    }
}
