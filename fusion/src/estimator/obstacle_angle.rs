//! The CDA paper, section 3.3: the heading planned by obstacle avoidance,
//! `theta_oa`, from the left/right ultrasonic and infrared ranges
//! (eq. 12-15).
//!
//! - Case 1 (`d_lu > d_safe` and `d_ru > d_safe`): no obstacle, `theta_oa`
//!   unchanged and the manoeuvre is over.
//! - Case 2 (left obstacle): right turn, `theta_oa -= (pi/2)(k_u / d_lu)`
//!   (eq. 12). Case 3 (right obstacle): left turn, `+= (pi/2)(k_u / d_ru)`
//!   (eq. 13).
//! - Case 4 (both ultrasonic ranges below `d_safe`): the infrared ranges
//!   decide, `-+ n (pi/2)(k_i / d)` (eq. 14-15).
//!
//! Choices where the seed is ambiguous:
//! - A missing range means "nothing in reach", i.e. greater than `d_safe`.
//! - `theta_oa(t-1)` at the start of a manoeuvre is the robot's current
//!   heading estimate (the paper's recursion has no start value).
//! - Case 4: we turn away from the side whose infrared range is shorter and
//!   use that shorter range in eq. 14-15 ("the closer the robot is to the
//!   obstacle the wider it has to turn", as for eq. 12-13; the printed
//!   subscripts of eq. 14-15 pair the right turn with `d_ri`). A missing
//!   infrared range falls back to the ultrasonic one of that side.
//! - `d_n` (back up when too close) is a motion command, not an estimate;
//!   it is not modelled.
//! - If the planner publishes its heading (`planned_heading_rad`), that
//!   value is `theta_oa` and the equations are bypassed.
//! - The constants are not given by the seed: defaults `d_safe = 0.5 m`,
//!   `k_u = 0.0056 m` and `k_i = 0.001 m` (about 1 deg per sample at
//!   `d_safe`, resp. at 0.1 m with `n = 1`), `n = 1.5`.

use std::f64::consts::FRAC_PI_2;

use super::RangeSample;

/// Constants of eq. 12-15.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObstacleAngleParams {
    /// Flank safety distance `d_safe`, metres.
    pub d_safe_m: f64,
    /// Collision angle constant of the ultrasonic sensors `k_theta_u`, metres.
    pub k_ultrasonic_m: f64,
    /// Collision angle constant of the infrared sensors `k_theta_i`, metres.
    pub k_ir_m: f64,
    /// Gain `n` of the infrared cases.
    pub n_ir: f64,
}

impl Default for ObstacleAngleParams {
    fn default() -> Self {
        Self {
            d_safe_m: 0.5,
            k_ultrasonic_m: 0.0056,
            k_ir_m: 0.001,
            n_ir: 1.5,
        }
    }
}

/// Result of one range sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ObstacleAngle {
    /// Case 1: no manoeuvre in progress.
    Clear,
    /// A manoeuvre in progress with its planned heading, radians.
    Planned(f64),
}

/// `theta_oa` given the previous one (or the current heading when no
/// manoeuvre was in progress) and the ranges.
pub fn next_angle(
    params: &ObstacleAngleParams,
    previous_rad: f64,
    sample: &RangeSample,
) -> ObstacleAngle {
    if let Some(planned) = sample.planned_heading_rad {
        return ObstacleAngle::Planned(planned);
    }
    let far = f64::INFINITY;
    let lu = sample.left_ultrasonic_m.unwrap_or(far);
    let ru = sample.right_ultrasonic_m.unwrap_or(far);
    let safe = params.d_safe_m;
    let step = |k: f64, d: f64| FRAC_PI_2 * k / d;
    match (lu < safe, ru < safe) {
        (false, false) => ObstacleAngle::Clear,
        (true, false) => ObstacleAngle::Planned(previous_rad - step(params.k_ultrasonic_m, lu)),
        (false, true) => ObstacleAngle::Planned(previous_rad + step(params.k_ultrasonic_m, ru)),
        (true, true) => {
            let li = sample.left_ir_m.unwrap_or(lu);
            let ri = sample.right_ir_m.unwrap_or(ru);
            let turn = params.n_ir * step(params.k_ir_m, li.min(ri));
            if li <= ri {
                ObstacleAngle::Planned(previous_rad - turn)
            } else {
                ObstacleAngle::Planned(previous_rad + turn)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ranges(lu: Option<f64>, ru: Option<f64>) -> RangeSample {
        RangeSample {
            left_ultrasonic_m: lu,
            right_ultrasonic_m: ru,
            ..RangeSample::default()
        }
    }

    #[test]
    fn left_obstacle_turns_right_by_eq_12() {
        let p = ObstacleAngleParams::default();
        let out = next_angle(&p, 1.0, &ranges(Some(0.25), None));
        let expected = 1.0 - FRAC_PI_2 * 0.0056 / 0.25;
        assert_eq!(out, ObstacleAngle::Planned(expected));
    }

    #[test]
    fn right_obstacle_turns_left_by_eq_13() {
        let p = ObstacleAngleParams::default();
        let out = next_angle(&p, 0.0, &ranges(Some(3.0), Some(0.4)));
        assert_eq!(out, ObstacleAngle::Planned(FRAC_PI_2 * 0.0056 / 0.4));
    }

    #[test]
    fn clear_path_ends_the_manoeuvre() {
        let p = ObstacleAngleParams::default();
        assert_eq!(
            next_angle(&p, 0.3, &ranges(None, Some(2.0))),
            ObstacleAngle::Clear
        );
    }

    #[test]
    fn both_sides_blocked_uses_infrared_of_closer_side() {
        let p = ObstacleAngleParams::default();
        let s = RangeSample {
            left_ultrasonic_m: Some(0.3),
            right_ultrasonic_m: Some(0.3),
            left_ir_m: Some(0.1),
            right_ir_m: Some(0.2),
            ..RangeSample::default()
        };
        let expected = -1.5 * FRAC_PI_2 * 0.001 / 0.1;
        let ObstacleAngle::Planned(got) = next_angle(&p, 0.0, &s) else {
            panic!("expected a manoeuvre");
        };
        assert!((got - expected).abs() < 1e-12, "{got} vs {expected}");
    }

    #[test]
    fn planned_heading_bypasses_the_equations() {
        let p = ObstacleAngleParams::default();
        let s = RangeSample {
            planned_heading_rad: Some(2.0),
            ..RangeSample::default()
        };
        assert_eq!(next_angle(&p, 0.0, &s), ObstacleAngle::Planned(2.0));
    }
}
