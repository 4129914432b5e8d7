//! A robot's velocity as its summary reports it (the mean over its agent's
//! last half second of poses): the central unit predicts where a robot
//! will be during the next cycle instead of allowing for its top speed in
//! every direction.

use ickon_proto::msg::robot::RobotSummary;

/// A robot's mean velocity over a span of its poses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Velocity {
    /// Velocity in the site frame, m/s.
    pub v_m_s: [f64; 2],
    /// The span of pose stamps it is the mean over, seconds.
    pub span_s: f64,
}

impl Velocity {
    /// Its speed, m/s.
    pub fn speed_m_s(&self) -> f64 {
        self.v_m_s[0].hypot(self.v_m_s[1])
    }

    /// The velocity a summary reports, when it reports one (a span above
    /// 0 and numbers throughout).
    pub fn of_summary(s: &RobotSummary) -> Option<Self> {
        let v = Self {
            v_m_s: [s.vx_m_s, s.vy_m_s],
            span_s: s.velocity_span_s,
        };
        (v.span_s > 0.0 && v.v_m_s.iter().chain([&v.span_s]).all(|x| x.is_finite())).then_some(v)
    }
}
