//! Distances to beacons, as a ranging source reports them (a Marvelmind
//! hedgehog's raw distances): the MSU's input where a site's beacons are
//! ranged by time of flight instead of timed against a schedule.

use ickon_proto::time::Time;

/// Most distances one message may carry: a Marvelmind hedgehog reports up
/// to four per cycle; more than this is not a ranging source's message.
pub const MAX_DISTANCES: usize = 16;

/// One reading of distances to beacons, taken together.
#[derive(Debug, Clone, PartialEq)]
pub struct BeaconDistances {
    /// When the distances were measured, on the MSU clock.
    pub stamp: Time,
    /// The distances.
    pub distances: Vec<BeaconDistance>,
}

/// One distance to one beacon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeaconDistance {
    /// The beacon: a transmitter of the site.
    pub tx_id: u32,
    /// Distance from the beacon to the receiver, metres.
    pub distance_m: f64,
    /// Its standard deviation, metres (the source's stated accuracy).
    pub sigma_m: f64,
}

/// Where a ranging kit says the receiver is (a Marvelmind hedgehog's own
/// position), in the site's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KitPosition {
    /// When, on the MSU clock.
    pub stamp: Time,
    /// Position, metres.
    pub x_m: f64,
    /// See `x_m`.
    pub y_m: f64,
    /// One-sigma noise per axis, metres.
    pub sigma_m: f64,
}
