//! Checking a start pose against the first fixes, for the filters that
//! are corrected with MSU fixes (`ickon-akf`, `cda-msu`).
//!
//! A start pose is what the site file says of where the robot starts; an
//! MSU restarted while the robot runs gets the same pose, and the robot is
//! wherever it drove to. With the start pose's centimetre of uncertainty
//! the filter would distrust every fix that disagrees (the adaptive `R`
//! grows with the residual), and stay lost. So the start is a guess until
//! a fix agrees with it (within three standard deviations of both); two
//! fixes that agree with each other but not with it replace it (position
//! at the later fix, heading unknown), and a single fix that disagrees
//! with both is held back as a possible outlier. Once confirmed or
//! replaced, the check is over: later disagreements are the filter's to
//! weigh.

use nalgebra::Matrix2;

use crate::tdoa::Fix;

/// What to do with a fix while the start is checked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum StartVerdict {
    /// Fuse it as usual (the start is confirmed, or there was none).
    Fuse,
    /// Hold it back: it disagrees with the start and no earlier fix
    /// agrees with it yet.
    Hold,
    /// The start was wrong: start again at this fix.
    Replace,
}

/// A fix held back, waiting for a second one to agree with it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Held {
    xy_m: [f64; 2],
    sigma_m: f64,
    /// The filter's position when it came (its motion until the next fix
    /// bounds how far apart two fixes of the same robot can be).
    own_m: [f64; 2],
}

/// The check of a start pose (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct StartCheck {
    done: bool,
    held: Option<Held>,
}

impl StartCheck {
    /// A check of a start pose; `given` false: there is nothing to check.
    pub(crate) fn new(given: bool) -> Self {
        Self {
            done: !given,
            held: None,
        }
    }

    /// Judges `fix` against the filter's position `own_m` (covariance
    /// `own_cov`), when it has one.
    pub(crate) fn judge(
        &mut self,
        fix: &Fix,
        own: Option<([f64; 2], Matrix2<f64>)>,
    ) -> StartVerdict {
        let Some((own_m, own_cov)) = own.filter(|_| !self.done) else {
            self.done = true;
            return StartVerdict::Fuse;
        };
        let xy_m = [fix.x_m(), fix.y_m()];
        let sigma_m = fix.covariance_xy_m2().trace().max(0.0).sqrt();
        if !(xy_m.iter().all(|v| v.is_finite()) && sigma_m.is_finite()) {
            return StartVerdict::Hold;
        }
        let own_sigma = own_cov.trace().max(0.0).sqrt();
        let apart = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
        if apart(xy_m, own_m) <= 3.0 * (sigma_m + own_sigma) {
            self.done = true;
            self.held = None;
            return StartVerdict::Fuse;
        }
        let this = Held {
            xy_m,
            sigma_m,
            own_m,
        };
        match self.held.replace(this) {
            Some(h)
                if apart(xy_m, h.xy_m) <= 3.0 * (sigma_m + h.sigma_m) + apart(own_m, h.own_m) =>
            {
                self.done = true;
                self.held = None;
                StartVerdict::Replace
            }
            _ => StartVerdict::Hold,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fix(x: f64, y: f64) -> Fix {
        Fix::from_position(1.0, x, y, Matrix2::from_diagonal_element(0.03f64.powi(2)))
    }

    fn own(x: f64, y: f64) -> Option<([f64; 2], Matrix2<f64>)> {
        Some(([x, y], Matrix2::from_diagonal_element(1e-4)))
    }

    #[test]
    fn a_fix_at_the_start_confirms_it_for_good() {
        let mut c = StartCheck::new(true);
        assert_eq!(c.judge(&fix(1.02, 1.0), own(1.0, 1.0)), StartVerdict::Fuse);
        // Later disagreements are the filter's business.
        assert_eq!(c.judge(&fix(5.0, 5.0), own(1.0, 1.0)), StartVerdict::Fuse);
    }

    #[test]
    fn two_agreeing_fixes_away_from_the_start_replace_it_and_one_outlier_does_not() {
        let mut c = StartCheck::new(true);
        assert_eq!(c.judge(&fix(4.0, 3.0), own(1.0, 1.0)), StartVerdict::Hold);
        // An outlier elsewhere: held instead of the first.
        assert_eq!(c.judge(&fix(0.0, 3.0), own(1.0, 1.0)), StartVerdict::Hold);
        assert_eq!(
            c.judge(&fix(0.05, 3.0), own(1.1, 1.0)),
            StartVerdict::Replace
        );
        assert_eq!(c.judge(&fix(9.0, 9.0), own(0.0, 3.0)), StartVerdict::Fuse);
    }

    #[test]
    fn without_a_start_pose_or_a_position_every_fix_is_fused() {
        let mut c = StartCheck::new(false);
        assert_eq!(c.judge(&fix(4.0, 3.0), own(1.0, 1.0)), StartVerdict::Fuse);
        let mut c = StartCheck::new(true);
        assert_eq!(c.judge(&fix(4.0, 3.0), None), StartVerdict::Fuse);
    }
}
