//! Scoring replayed poses against a recording's truth with `ickon eval`'s
//! metrics ([`ickon_sim::score::row`]): every pose after the warm-up, its
//! position against the truth interpolated at its stamp on the robot's
//! clock (the truth carries both clocks), its heading against the truth's.

use ickon_proto::Time;
use ickon_proto::msg::robot::Truth;
use ickon_sim::Row;

use super::feed::Published;

/// Seconds after the first pose that are not scored (as `ickon sim`: the
/// estimators start at the configured pose and need a few fixes).
pub const WARM_UP_S: f64 = 3.0;
/// Truth samples further apart than this are not interpolated between.
const MAX_TRUTH_GAP_NS: i64 = 1_000_000_000;

/// The score of one track.
#[derive(Debug, Clone, Copy)]
pub struct Scored {
    /// The row.
    pub row: Row,
    /// Poses scored.
    pub points: usize,
    /// Share of them whose truth lies inside the 95 % ellipse of the
    /// covariance published with them, percent.
    pub inside_95_pct: Option<f64>,
    /// Their average NEES and its 95 % bounds.
    pub nees: Option<ickon_sim::score::Nees>,
}

/// Truth position and heading at `stamp` on the robot's clock, interpolated
/// between the two samples around it; `None` outside the truth.
pub fn truth_at(truth: &[Truth], stamp: Time) -> Option<[f64; 3]> {
    let idx = truth.partition_point(|t| t.robot_clock <= stamp);
    let a = truth.get(idx.checked_sub(1)?)?;
    if a.robot_clock == stamp {
        return Some([a.x_m, a.y_m, a.theta_rad]);
    }
    let b = truth.get(idx)?;
    let span = b.robot_clock.since(a.robot_clock).as_nanos();
    if span <= 0 || span > MAX_TRUTH_GAP_NS {
        return None;
    }
    let w = stamp.since(a.robot_clock).as_nanos() as f64 / span as f64;
    let dtheta = ickon_fusion::angle::diff(b.theta_rad, a.theta_rad);
    Some([
        a.x_m + w * (b.x_m - a.x_m),
        a.y_m + w * (b.y_m - a.y_m),
        a.theta_rad + w * dtheta,
    ])
}

/// Scores `poses` against `truth` (recorded order; sorted here by the
/// robot's clock). `None` without truth or without a pose after the warm-up.
pub fn score(poses: &[Published], truth: &[Truth]) -> Option<Scored> {
    let mut truth = truth.to_vec();
    truth.sort_by_key(|t| t.robot_clock);
    let first = poses.first()?.pose.stamp;
    let mut pos = Vec::new();
    let mut head = Vec::new();
    let mut nees = Vec::new();
    for p in poses {
        if p.pose.stamp.since(first).as_secs_f64() < WARM_UP_S {
            continue;
        }
        if let Some([x, y, theta]) = truth_at(&truth, p.pose.stamp) {
            pos.push((p.pose.x_m - x).hypot(p.pose.y_m - y));
            head.push(ickon_fusion::angle::diff(p.pose.theta_rad, theta));
            let c = p.pose.covariance;
            nees.push(ickon_sim::score::nees_2d(
                [p.pose.x_m - x, p.pose.y_m - y],
                [c[0], c[1], c[4]],
            ));
        }
    }
    let (inside_95_pct, nees) = ickon_sim::score::consistency(&nees);
    (!pos.is_empty()).then(|| Scored {
        row: ickon_sim::score::row(None, &pos, &head),
        points: pos.len(),
        inside_95_pct,
        nees,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth(t_ns: i64, x: f64) -> Truth {
        Truth {
            stamp: Time::from_nanos(t_ns),
            robot_clock: Time::from_nanos(t_ns + 7),
            x_m: x,
            y_m: 0.0,
            theta_rad: 0.0,
            v_m_s: 0.0,
            omega_rad_s: 0.0,
        }
    }

    #[test]
    fn the_truth_is_interpolated_on_the_robot_clock_and_not_across_gaps() {
        let t = [truth(0, 0.0), truth(100, 1.0), truth(5_000_000_000, 9.0)];
        let mid = truth_at(&t, Time::from_nanos(57)).unwrap();
        assert!((mid[0] - 0.5).abs() < 1e-12, "{mid:?}");
        assert!(truth_at(&t, Time::from_nanos(2_000_000_000)).is_none());
        assert!(truth_at(&t, Time::from_nanos(0)).is_none());
    }
}
