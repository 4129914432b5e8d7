//! `robot/<id>/fix` and `robot/<id>/summary` as MSUs published them before
//! a fix carried the residuals of the transmitters it heard and did not
//! use (`unused`, `unused_residuals_m`): MSUs of that time send them, and
//! recordings made then hold them. Read as fixes that measured no unused
//! arrival, so that such a robot still feeds the fleet's calibration and
//! such a recording replays.

use serde::{Deserialize, Serialize};

use super::{Fix, FixQuality, PoseStatus, RobotSummary};
use crate::time::Time;

/// A fix without the unused arrivals' residuals (the fields mean what
/// [`Fix`]'s of the same name do).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FixWithoutUnused {
    /// Time of the measurement on the MSU clock.
    pub stamp: Time,
    /// `seq` of the arrivals the fix was solved from.
    pub arrivals_seq: u64,
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Height, metres.
    pub z_m: f64,
    /// Position covariance, 3x3 row-major, m^2.
    pub covariance: [f64; 9],
    /// Heading, radians.
    pub heading_rad: f64,
    /// Whether `heading_rad` holds a value.
    pub heading_valid: bool,
    /// Transmitters used.
    pub used: Vec<u32>,
    /// Transmitters heard but rejected.
    pub rejected: Vec<u32>,
    /// Residuals of the used transmitters, metres.
    pub residuals_m: Vec<f64>,
    /// Quality flag.
    pub quality: FixQuality,
    /// The survey calibration's version the fix was solved with.
    pub survey_version: u32,
}

impl From<FixWithoutUnused> for Fix {
    fn from(old: FixWithoutUnused) -> Self {
        Fix {
            stamp: old.stamp,
            arrivals_seq: old.arrivals_seq,
            x_m: old.x_m,
            y_m: old.y_m,
            z_m: old.z_m,
            covariance: old.covariance,
            heading_rad: old.heading_rad,
            heading_valid: old.heading_valid,
            used: old.used,
            rejected: old.rejected,
            residuals_m: old.residuals_m,
            quality: old.quality,
            survey_version: old.survey_version,
            unused: Vec::new(),
            unused_residuals_m: Vec::new(),
        }
    }
}

/// A summary whose fixes carry no unused arrivals (the fields mean what
/// [`RobotSummary`]'s of the same name do).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SummaryWithoutUnused {
    /// Increases by one per summary.
    pub seq: u64,
    /// Time of the newest pose.
    pub stamp: Time,
    /// Position, metres.
    pub x_m: f64,
    /// Position, metres.
    pub y_m: f64,
    /// Heading, radians.
    pub theta_rad: f64,
    /// Covariance of (x, y, theta).
    pub covariance: [f64; 9],
    /// Name of the estimator.
    #[serde(deserialize_with = "crate::wire_string::deserialize")]
    pub estimator: String,
    /// `arrivals_seq` of the newest fix absorbed.
    pub fix_seq: u64,
    /// Whether the pose's inputs are coming.
    pub status: PoseStatus,
    /// Mean velocity, m/s.
    pub vx_m_s: f64,
    /// Mean velocity, m/s.
    pub vy_m_s: f64,
    /// The span the velocity is the mean over, seconds.
    pub velocity_span_s: f64,
    /// Fixes solved since the previous summary.
    pub fixes_solved: u32,
    /// The newest fixes.
    pub fixes: Vec<FixWithoutUnused>,
}

impl From<SummaryWithoutUnused> for RobotSummary {
    fn from(old: SummaryWithoutUnused) -> Self {
        RobotSummary {
            seq: old.seq,
            stamp: old.stamp,
            x_m: old.x_m,
            y_m: old.y_m,
            theta_rad: old.theta_rad,
            covariance: old.covariance,
            estimator: old.estimator,
            fix_seq: old.fix_seq,
            status: old.status,
            vx_m_s: old.vx_m_s,
            vy_m_s: old.vy_m_s,
            velocity_span_s: old.velocity_span_s,
            fixes_solved: old.fixes_solved,
            fixes: old.fixes.into_iter().map(Fix::from).collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::{DecodeError, decode, encode};

    fn old_fix(k: u32) -> FixWithoutUnused {
        FixWithoutUnused {
            stamp: Time::from_nanos(1_000_000_000 + i64::from(k)),
            arrivals_seq: 40 + u64::from(k),
            x_m: 3.5,
            y_m: -1.25,
            z_m: 0.3,
            covariance: [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 0.0],
            heading_rad: 0.5,
            heading_valid: true,
            used: vec![1, 2, 3, 4],
            rejected: vec![5],
            residuals_m: vec![0.001, -0.002, 0.0, 0.001],
            quality: FixQuality::Good,
            survey_version: 7 + k,
        }
    }

    fn old_summary(fixes: u32) -> SummaryWithoutUnused {
        SummaryWithoutUnused {
            seq: 9,
            stamp: Time::from_nanos(2_000_000_000),
            x_m: 1.0,
            y_m: 2.0,
            theta_rad: 0.1,
            covariance: [0.0; 9],
            estimator: "tdoa-ekf".into(),
            fix_seq: 44,
            status: PoseStatus::Tracking,
            vx_m_s: 0.2,
            vy_m_s: 0.0,
            velocity_span_s: 0.5,
            fixes_solved: fixes,
            fixes: (0..fixes).map(old_fix).collect(),
        }
    }

    #[test]
    fn an_older_fix_is_read_with_no_unused_arrival() {
        let payload = encode(&old_fix(1)).unwrap();
        assert!(
            decode::<Fix>(&payload).is_err(),
            "the current layout alone must not read it (else the fallback is never taken)"
        );
        let read = Fix::decode(&payload).unwrap();
        assert_eq!(read, Fix::from(old_fix(1)));
        assert!(read.unused.is_empty() && read.unused_residuals_m.is_empty());
    }

    #[test]
    fn an_older_summary_is_read_with_its_fixes() {
        for n in [0, 1, 3] {
            let payload = encode(&old_summary(n)).unwrap();
            let read = RobotSummary::decode(&payload).unwrap();
            assert_eq!(read, RobotSummary::from(old_summary(n)), "{n} fixes");
        }
    }

    #[test]
    fn the_current_layout_is_read_as_it_is_and_never_as_the_older_one() {
        let mut fix = Fix::from(old_fix(2));
        fix.unused = vec![5];
        fix.unused_residuals_m = vec![0.21];
        let payload = encode(&fix).unwrap();
        assert_eq!(Fix::decode(&payload).unwrap(), fix);
        assert!(decode::<FixWithoutUnused>(&payload).is_err());
        let mut summary = RobotSummary::from(old_summary(2));
        summary.fixes[1] = fix;
        let payload = encode(&summary).unwrap();
        assert_eq!(RobotSummary::decode(&payload).unwrap(), summary);
        assert!(decode::<SummaryWithoutUnused>(&payload).is_err());
    }

    #[test]
    fn a_payload_of_neither_layout_fails_with_the_current_layouts_error() {
        let payload = encode(&old_fix(0)).unwrap();
        let mut longer = payload.clone();
        longer.extend_from_slice(&[0; 3]);
        assert_eq!(
            Fix::decode(&longer),
            Err(decode::<Fix>(&longer).unwrap_err())
        );
        for cut in [0, 3, 5, 20, payload.len() - 1] {
            assert!(Fix::decode(&payload[..cut]).is_err(), "cut at {cut}");
        }
        let summary = encode(&old_summary(2)).unwrap();
        for cut in [0, 5, 40, summary.len() - 1] {
            assert!(
                RobotSummary::decode(&summary[..cut]).is_err(),
                "cut at {cut}"
            );
        }
        assert!(matches!(
            Fix::decode(&[0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff]),
            Err(DecodeError::Truncated(_) | DecodeError::Malformed(_))
        ));
    }
}
