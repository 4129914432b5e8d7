//! The arrivals of the cycle being fused, rebuilt from its range
//! differences.
//!
//! The MSU hands a cycle over as differences of consecutive arrivals
//! (`d = rho_b - rho_a`, stamped at the later arrival). Summing them along
//! the chain gives each arrival's pseudo-range relative to the first one,
//! and its arrival time (the stamp of the pair it ended). So the filter can
//! fuse every arrival on its own, related to the robot's position at its own
//! arrival time, and blame a reflection on the one arrival that was late
//! (a sum along the chain is unaffected by a late arrival inside it: the
//! extra path enters one difference with `+` and the next with `-`).
//!
//! A chain ends when a difference does not start at its last arrival, or
//! names a transmitter already in it (each transmitter fires once per
//! cycle, so the same one again is the next cycle).

use crate::estimator::TransmitterClock;

/// One arrival of the chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Arrival {
    /// Transmitter position, metres.
    pub tx_m: [f64; 3],
    /// Pseudo-range relative to the chain's first arrival, metres.
    pub rho_m: f64,
    /// Arrival time, seconds.
    pub t_s: f64,
    /// The clock the transmitter fires by, when known.
    pub clock: Option<TransmitterClock>,
}

/// Most arrivals kept per chain (more than any cycle hears).
const MAX_ARRIVALS: usize = 32;

/// The current chain and the usual time between two arrivals.
#[derive(Debug, Clone, Default)]
pub(super) struct Chain {
    arrivals: Vec<Arrival>,
    /// Last time between two chained arrivals, seconds: the arrival time
    /// of a chain's first signal, when the difference does not carry it, is
    /// its successor's minus this.
    slot_s: f64,
}

/// What adding a difference did to the chain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Link {
    /// The difference continued the chain: only `b` is new.
    Continued(Arrival),
    /// A new chain started with `a` and `b`.
    Started(Arrival, Arrival),
}

impl Chain {
    /// Adds the difference `rho_b - rho_a = d_m` stamped `t_s` (B's arrival),
    /// with A's arrival time `a_t_s` when known (ignored when after `t_s`).
    pub fn add(
        &mut self,
        a_m: [f64; 3],
        b_m: [f64; 3],
        d_m: f64,
        t_s: f64,
        a_t_s: Option<f64>,
        clocks: Option<[TransmitterClock; 2]>,
    ) -> Link {
        let continues = self.arrivals.last().is_some_and(|last| {
            last.tx_m == a_m
                && t_s >= last.t_s
                && self.arrivals.len() < MAX_ARRIVALS
                && !self.arrivals.iter().any(|x| x.tx_m == b_m)
        });
        if let (true, Some(last)) = (continues, self.arrivals.last().copied()) {
            self.slot_s = t_s - last.t_s;
            let b = Arrival {
                tx_m: b_m,
                rho_m: last.rho_m + d_m,
                t_s,
                clock: clocks.map(|c| c[1]),
            };
            self.arrivals.push(b);
            return Link::Continued(b);
        }
        // The first arrival's own time, exact when the difference carries
        // it: guessed from the last spacing, it was off by up to the
        // difference between two slots (milliseconds, millimetres of
        // driving: far beyond the arrival noise of an exact world).
        let a = Arrival {
            tx_m: a_m,
            rho_m: 0.0,
            t_s: a_t_s
                .filter(|ta| ta.is_finite() && *ta <= t_s)
                .unwrap_or(t_s - self.slot_s),
            clock: clocks.map(|c| c[0]),
        };
        let b = Arrival {
            tx_m: b_m,
            rho_m: d_m,
            t_s,
            clock: clocks.map(|c| c[1]),
        };
        self.arrivals.clear();
        self.arrivals.push(a);
        self.arrivals.push(b);
        Link::Started(a, b)
    }

    /// The chain's arrivals, oldest first.
    pub fn arrivals(&self) -> &[Arrival] {
        &self.arrivals
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: [f64; 3] = [0.0, 0.0, 2.5];
    const B: [f64; 3] = [4.0, 0.0, 2.5];
    const C: [f64; 3] = [4.0, 4.0, 2.5];

    #[test]
    fn consecutive_differences_sum_to_pseudo_ranges_and_a_repeat_starts_anew() {
        let mut c = Chain::default();
        assert!(matches!(
            c.add(A, B, 1.0, 0.10, None, None),
            Link::Started(..)
        ));
        let Link::Continued(cc) = c.add(B, C, -0.5, 0.15, None, None) else {
            panic!("not continued");
        };
        assert!((cc.rho_m - 0.5).abs() < 1e-12);
        // The next cycle starts with C again, then A: A is already in.
        assert!(matches!(
            c.add(C, A, 0.2, 0.55, None, None),
            Link::Started(..)
        ));
        let first = c.arrivals()[0];
        // Its time comes from the last slot seen.
        assert!((first.t_s - 0.50).abs() < 1e-12);
        assert_eq!(c.arrivals().len(), 2);
        // A difference that carries A's time gives it exactly; one whose A
        // came after B is not believed.
        assert!(matches!(
            c.add(B, C, 0.1, 1.0, Some(0.93), None),
            Link::Started(..)
        ));
        assert!((c.arrivals()[0].t_s - 0.93).abs() < 1e-12);
        assert!(matches!(
            c.add(A, C, 0.1, 2.0, Some(2.5), None),
            Link::Started(..)
        ));
        // (the last spacing seen, 0.05 s between B and C, stands in)
        assert!((c.arrivals()[0].t_s - 1.95).abs() < 1e-12);
    }
}
