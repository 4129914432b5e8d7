//! The message sizes a router lets through, per key (Zenoh's
//! `low_pass_filter`): a message over its key's limit is dropped by the
//! router, in both directions, before it reaches any node. Zenoh applies
//! these limits by key (and by network interface or link protocol), not by
//! authenticated identity: which identity may put on a key at all is the
//! ACL's ([`super::acl`]); how large is this module's. Rates are not
//! limited by the router: Zenoh's downsampling keeps one message per
//! period of a key expression for all its publishers together, which would
//! throttle a fleet as one robot; each node bounds the rate of what it
//! takes instead (the central unit's share of survey fixes per robot, the
//! MSU's and the cells' input queues).

use ickon_proto::codec::MAX_MESSAGE_BYTES;
use ickon_proto::keys::{Keys, ROOT};
use serde_json::{Value, json};

/// The largest message a robot or a cell puts, bytes. A robot's largest is
/// its arrivals of one cycle, 16 bytes per transmitter heard (CDR): 64 KiB
/// holds 4,000 of them, 60 times the `warehouse` site's 64 transmitters.
/// A cell's status and bursts are a few hundred bytes.
pub const NODE_MESSAGE_BYTES: usize = 64 * 1024;

/// The largest message of anyone else on the site's keys: the nodes refuse
/// to decode more than [`MAX_MESSAGE_BYTES`] (the site file a `reload`
/// carries and `central/site` answers is at most 4 MiB); the rest is room
/// for the encoding's header and the file's name.
pub const SITE_MESSAGE_BYTES: usize = MAX_MESSAGE_BYTES + 64 * 1024;

/// The `low_pass_filter` block of a router of the site of `keys`. Zenoh
/// takes the smallest limit of the rules that include a key, so the
/// site-wide rule bounds every key of the site and the node rules bound
/// the robots' and cells' keys further. Keys outside the site (ROS 2's)
/// are left alone: their sizes are the robots' applications' business.
pub fn low_pass_filter(keys: &Keys) -> Value {
    limits_under(keys.prefix())
}

/// The same limits for every site's keys (`ickon/*`): what a router
/// started without a configuration of its own enforces, which serves
/// whatever site connects to it. An outside client's messages of
/// megabytes on a node's keys, passed on to every subscriber, filled a
/// link's queue until the router closed a node's transport; dropped at
/// the router they cost no link anything.
pub fn low_pass_filter_any_site() -> Value {
    limits_under(&format!("{ROOT}/*"))
}

fn limits_under(prefix: &str) -> Value {
    json!([
        {
            "id": "site-messages",
            "messages": ["put", "delete", "query", "reply"],
            "key_exprs": [format!("{prefix}/**")],
            "size_limit": SITE_MESSAGE_BYTES,
        },
        {
            "id": "robot-and-cell-messages",
            "messages": ["put", "delete"],
            "key_exprs": [format!("{prefix}/robot/**"), format!("{prefix}/cell/**")],
            "size_limit": NODE_MESSAGE_BYTES,
        },
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::msg::robot::{Arrival, UltrasoundArrivals};
    use ickon_proto::time::Time;

    #[test]
    fn zenoh_takes_the_limits_as_written() {
        let keys = Keys::new("lab").unwrap();
        let mut config = zenoh::Config::default();
        config
            .insert_json5("low_pass_filter", &low_pass_filter(&keys).to_string())
            .expect("a valid low_pass_filter block");
        config
            .insert_json5("low_pass_filter", &low_pass_filter_any_site().to_string())
            .expect("a valid low_pass_filter block for any site");
    }

    /// The arrivals of one cycle from a site far larger than any shipped
    /// pass the robots' limit.
    #[test]
    fn a_robots_largest_message_fits_its_limit() {
        let arrivals = UltrasoundArrivals {
            seq: 1,
            arrivals: (0..4_000)
                .map(|k| Arrival {
                    tx_id: k,
                    receiver_id: 0,
                    t_arrival: Time(1),
                })
                .collect(),
        };
        let bytes = ickon_proto::encode(&arrivals).unwrap();
        assert!(bytes.len() <= NODE_MESSAGE_BYTES, "{}", bytes.len());
    }
}
