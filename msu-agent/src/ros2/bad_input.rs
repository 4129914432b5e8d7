//! The kinds of bad input on the ROS 2 topics. Each is counted and logged
//! through the runtime's `LogLimiter` (the first time, then at most once
//! per 10 s per kind with the count held back), so that a robot flooding
//! garbage can neither crash the agent nor drown its log.

/// What was wrong with a ROS 2 sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum BadInputKind {
    /// The CDR did not decode (truncated, trailing bytes, bad header).
    Undecodable,
    /// The key names another type or type hash.
    WrongType,
    /// rmw_zenoh sample without the attachment (rmw_zenoh drops these too).
    NoAttachment,
    /// An attachment that is not the 33-byte layout.
    BadAttachment,
    /// NaN or infinity in a value or a covariance.
    NonFinite,
    /// A stamp with nanoseconds of one second or more.
    BadStamp,
    /// A stamp older than the previous sample of the same topic.
    Backwards,
    /// The odometry moved further between two samples than a robot can.
    Jump,
}

impl BadInputKind {
    /// What the log says.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Undecodable => "undecodable CDR",
            Self::WrongType => "wrong message type on the topic",
            Self::NoAttachment => "sample without the rmw_zenoh attachment",
            Self::BadAttachment => "malformed rmw_zenoh attachment",
            Self::NonFinite => "NaN or infinite value",
            Self::BadStamp => "malformed stamp",
            Self::Backwards => "stamp going backwards",
            Self::Jump => "odometry jump (re-anchored)",
        }
    }
}
