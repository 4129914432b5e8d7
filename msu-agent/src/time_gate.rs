//! Time sanity for the MSU's inputs without a clock of its own: the newest
//! accepted stamp is the MSU's notion of now. A sample stamped far ahead of
//! it is held back until more samples agree that time really moved (a
//! robot clock that was stepped); a single one, forged or corrupt, is
//! refused, so that it cannot move every estimator's history past all real
//! inputs and silence the robot.

/// Largest step ahead of the newest accepted stamp taken without question, seconds.
pub const MAX_STEP_S: f64 = 5.0;
/// Samples that must agree on a new time before it is believed.
pub const AGREEING_SAMPLES: u32 = 3;

/// What the gate says of one stamp.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Within reach of the newest stamp: use it.
    Accept,
    /// Far ahead of the newest stamp and not (yet) confirmed: drop it.
    FromTheFuture {
        /// How far ahead, seconds.
        ahead_s: f64,
    },
}

/// The gate's state.
#[derive(Debug, Clone, Default)]
pub struct TimeGate {
    newest_s: Option<f64>,
    /// A far-ahead time some samples agree on, and how many.
    candidate: Option<(f64, u32)>,
    refused: u64,
}

impl TimeGate {
    /// Judges a sample stamped `t_s` (non-finite stamps are the estimators' to refuse).
    pub fn check(&mut self, t_s: f64) -> Verdict {
        let Some(newest) = self.newest_s.filter(|_| t_s.is_finite()) else {
            if t_s.is_finite() {
                self.newest_s = Some(t_s);
            }
            return Verdict::Accept;
        };
        let ahead_s = t_s - newest;
        if ahead_s <= MAX_STEP_S {
            self.newest_s = Some(newest.max(t_s));
            self.candidate = None;
            return Verdict::Accept;
        }
        let agreeing = match self.candidate {
            Some((c, n)) if (t_s - c).abs() <= MAX_STEP_S => n + 1,
            _ => 1,
        };
        if agreeing >= AGREEING_SAMPLES {
            self.newest_s = Some(t_s);
            self.candidate = None;
            return Verdict::Accept;
        }
        self.candidate = Some((t_s, agreeing));
        self.refused += 1;
        Verdict::FromTheFuture { ahead_s }
    }

    /// Samples refused so far.
    pub fn refused(&self) -> u64 {
        self.refused
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_sample_from_the_future_is_refused_and_time_goes_on() {
        let mut g = TimeGate::default();
        assert_eq!(g.check(10.0), Verdict::Accept);
        assert_eq!(g.check(10.02), Verdict::Accept);
        assert!(matches!(
            g.check(3_610.0),
            Verdict::FromTheFuture { ahead_s } if (ahead_s - 3_599.98).abs() < 1e-6
        ));
        assert_eq!(g.check(10.04), Verdict::Accept);
        assert_eq!(g.refused(), 1);
        // Late samples are the estimators' business, not the gate's.
        assert_eq!(g.check(9.0), Verdict::Accept);
    }

    #[test]
    fn a_real_clock_step_is_believed_once_samples_agree() {
        let mut g = TimeGate::default();
        g.check(10.0);
        assert_ne!(g.check(100.0), Verdict::Accept);
        assert_ne!(g.check(100.02), Verdict::Accept);
        assert_eq!(g.check(100.04), Verdict::Accept);
        assert_eq!(g.check(100.06), Verdict::Accept);
        // Scattered garbage never agrees.
        let mut h = TimeGate::default();
        h.check(0.0);
        for k in 1..100 {
            assert_ne!(h.check(1_000.0 * f64::from(k)), Verdict::Accept);
        }
        assert_eq!(h.refused(), 99);
    }

    #[test]
    fn non_finite_stamps_pass_to_the_estimators_and_move_nothing() {
        let mut g = TimeGate::default();
        assert_eq!(g.check(f64::NAN), Verdict::Accept);
        assert_eq!(g.check(5.0), Verdict::Accept);
        assert_eq!(g.check(f64::INFINITY), Verdict::Accept);
        assert!(matches!(g.check(100.0), Verdict::FromTheFuture { .. }));
    }
}
