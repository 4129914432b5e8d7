//! One-sided handling of late arrivals. A blocked or reflected signal
//! (non-line-of-sight, NLOS) can only arrive late, never early, so a range
//! difference `d = r_b - r_a` that is too long blames B and one that is too
//! short blames A. An anchor blamed for most of its recent measurements is
//! behind an obstacle for a while (a person walking by, the airframe
//! turning): its measurements are set aside for a hold time instead of
//! being fought one gate decision at a time, where each one that slips
//! through pulls the state.

use crate::estimator::RangeDifferenceSample;

/// When an anchor is set aside, and for how long.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LateParams {
    /// Measurements of an anchor the blame share is averaged over
    /// (exponential forgetting); also the least number seen before it can
    /// be set aside.
    pub window: u32,
    /// Share of an anchor's recent measurements blamed on it above which
    /// it is set aside, in `(0, 1)`.
    pub blamed_share: f64,
    /// How long an anchor stays set aside, seconds.
    pub hold_s: f64,
    /// At most this many anchors aside at once: with more, the state is
    /// more likely wrong than the anchors (the lost-filter watch handles
    /// that).
    pub max_aside: usize,
}

impl Default for LateParams {
    /// 20 measurements (about a third of a second per anchor of a TDoA2
    /// round-robin at 450 Hz), over half blamed, 1 s aside, at most 2 of
    /// the anchors (a 3D fix needs 4 of the usual 8).
    fn default() -> Self {
        Self {
            window: 20,
            blamed_share: 0.5,
            hold_s: 1.0,
            max_aside: 2,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Anchor {
    at_m: [f64; 3],
    share: f64,
    seen: u32,
    aside_until_s: Option<f64>,
}

/// The blame record of every anchor heard.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LateArrivals {
    params: LateParams,
    anchors: Vec<Anchor>,
    set_aside: u64,
}

impl LateArrivals {
    /// An empty record.
    pub fn new(params: LateParams) -> Self {
        Self {
            params,
            anchors: Vec::new(),
            set_aside: 0,
        }
    }

    /// Whether `m` involves an anchor set aside at its time.
    pub fn is_aside(&mut self, m: &RangeDifferenceSample) -> bool {
        let t = m.t_s;
        [m.a_m, m.b_m].iter().any(|at| {
            let a = self.anchor(*at);
            match a.aside_until_s {
                Some(until) if t < until => true,
                Some(_) => {
                    // Hold over: heard afresh.
                    *a = Anchor {
                        at_m: a.at_m,
                        share: 0.0,
                        seen: 0,
                        aside_until_s: None,
                    };
                    false
                }
                None => false,
            }
        })
    }

    /// Notes the verdict on `m`: `late` is `None` when it fitted the state,
    /// else the sign of its innovation (measured minus predicted; positive
    /// blames B, negative blames A).
    pub fn note(&mut self, m: &RangeDifferenceSample, innovation_m: Option<f64>) {
        let blamed_b = innovation_m.map(|v| v > 0.0);
        let mut aside = self.aside_at(m.t_s);
        for (at, is_b) in [(m.a_m, false), (m.b_m, true)] {
            aside += self.blame(m.t_s, at, blamed_b == Some(is_b), aside);
        }
    }

    /// Whether the arrival from the anchor at `at_m` heard at `t_s` is set
    /// aside: for filters that judge each arrival on its own (the ground
    /// filter's chained pseudo-ranges) rather than a pair.
    pub fn is_arrival_aside(&mut self, t_s: f64, at_m: [f64; 3]) -> bool {
        self.is_aside(&RangeDifferenceSample {
            a_t_s: None,
            t_s,
            a_m: at_m,
            b_m: at_m,
            d_m: 0.0,
            sigma_m: 1.0,
            clocks: None,
            speed_rel_sigma: None,
        })
    }

    /// Notes the verdict on one arrival from `at_m` at `t_s`: `late` when
    /// it was later than the state predicts beyond the gate.
    pub fn note_arrival(&mut self, t_s: f64, at_m: [f64; 3], late: bool) {
        let aside = self.aside_at(t_s);
        self.blame(t_s, at_m, late, aside);
    }

    /// Anchors aside at `t_s`.
    fn aside_at(&self, t_s: f64) -> usize {
        self.anchors
            .iter()
            .filter(|a| a.aside_until_s.is_some_and(|u| t_s < u))
            .count()
    }

    /// One verdict on the anchor at `at_m`, `aside` anchors being aside
    /// already; returns 1 when it was set aside by it.
    fn blame(&mut self, t_s: f64, at_m: [f64; 3], blamed: bool, aside: usize) -> usize {
        let params = self.params;
        let alpha = 1.0 / f64::from(params.window.max(1));
        let a = self.anchor(at_m);
        a.share += alpha * (f64::from(u8::from(blamed)) - a.share);
        a.seen = a.seen.saturating_add(1);
        if a.aside_until_s.is_none()
            && a.seen >= params.window
            && a.share > params.blamed_share
            && aside < params.max_aside
        {
            a.aside_until_s = Some(t_s + params.hold_s);
            self.set_aside += 1;
            return 1;
        }
        0
    }

    /// Forgets every verdict (after a re-initialisation: the blame was
    /// measured against a state now known to be wrong).
    pub fn clear(&mut self) {
        self.anchors.clear();
    }

    /// How many times an anchor was set aside.
    pub fn times_set_aside(&self) -> u64 {
        self.set_aside
    }

    fn anchor(&mut self, at_m: [f64; 3]) -> &mut Anchor {
        let i = match self.anchors.iter().position(|a| a.at_m == at_m) {
            Some(i) => i,
            None => {
                self.anchors.push(Anchor {
                    at_m,
                    share: 0.0,
                    seen: 0,
                    aside_until_s: None,
                });
                self.anchors.len() - 1
            }
        };
        &mut self.anchors[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(t_s: f64, a: f64, b: f64) -> RangeDifferenceSample {
        RangeDifferenceSample {
            a_t_s: None,
            t_s,
            a_m: [a, 0.0, 0.0],
            b_m: [b, 0.0, 0.0],
            d_m: 0.0,
            sigma_m: 0.1,
            clocks: None,
            speed_rel_sigma: None,
        }
    }

    #[test]
    fn an_anchor_late_in_both_roles_is_set_aside_and_comes_back_after_the_hold() {
        let mut late = LateArrivals::new(LateParams::default());
        // Round robin 0-1-2-3; anchor 2 always late: (1,2) too long, (2,3) too short.
        let mut t = 0.0;
        // 15 rounds: anchor 2 is heard 30 times, blamed every time.
        for _ in 0..15 {
            for (a, b) in [(0.0, 1.0), (1.0, 2.0), (2.0, 3.0), (3.0, 0.0)] {
                t += 0.01;
                let s = m(t, a, b);
                if late.is_aside(&s) {
                    continue;
                }
                let v = if b == 2.0 {
                    Some(0.8)
                } else if a == 2.0 {
                    Some(-0.8)
                } else {
                    None
                };
                late.note(&s, v);
            }
        }
        assert_eq!(late.times_set_aside(), 1);
        assert!(late.is_aside(&m(t, 1.0, 2.0)));
        assert!(!late.is_aside(&m(t, 0.0, 1.0)));
        assert!(!late.is_aside(&m(t + 1.5, 1.0, 2.0)));
    }

    #[test]
    fn an_arrival_late_most_of_the_time_is_set_aside_on_its_own() {
        let params = LateParams {
            window: 10,
            hold_s: 3.0,
            ..LateParams::default()
        };
        let mut late = LateArrivals::new(params);
        let (blocked, clear) = ([1.0, 0.0, 2.5], [2.0, 0.0, 2.5]);
        let mut t = 0.0;
        for k in 0..12 {
            t = 0.4 * f64::from(k);
            assert!(!late.is_arrival_aside(t, clear));
            late.note_arrival(t, clear, false);
            if !late.is_arrival_aside(t, blocked) {
                late.note_arrival(t, blocked, k % 4 != 0);
            }
        }
        assert_eq!(late.times_set_aside(), 1);
        assert!(late.is_arrival_aside(t + 0.4, blocked));
        assert!(!late.is_arrival_aside(t + 0.4, clear));
        assert!(
            !late.is_arrival_aside(t + 3.5, blocked),
            "back after the hold"
        );
    }

    #[test]
    fn scattered_outliers_blame_nobody_for_long_enough() {
        let mut late = LateArrivals::new(LateParams::default());
        for k in 0..10_000 {
            let (a, b) = ((k % 8) as f64, ((k + 1) % 8) as f64);
            let s = m(k as f64 * 0.002, a, b);
            let v = (k % 7 == 0).then_some(if k % 2 == 0 { 1.0 } else { -1.0 });
            assert!(!late.is_aside(&s));
            late.note(&s, v);
        }
        assert_eq!(late.times_set_aside(), 0);
    }
}
