//! What a run records, when asked, for writing it out as a log of
//! measurements (`ickon eval --export-tdoa`): each delivered cycle's
//! arrivals as the MSU heard them, the truth and the wheel odometry, all on
//! the MSU's clock. Bounded: past its row limit it stops and says so.

use ickon_proto::msg::control::Schedule;
use ickon_proto::msg::robot::{Odometry, UltrasoundArrivals};

use crate::world::TruthSample;

/// One arrival of a cycle, as the MSU heard it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecordedArrival {
    /// The transmitter heard.
    pub tx_id: u32,
    /// Arrival time on the MSU clock, seconds.
    pub t_s: f64,
    /// The transmitter's emission offset inside the cycle in the schedule
    /// the MSU solved the cycle with, seconds: `t_s - offset_s` is the
    /// flight time plus an offset common to the cycle.
    pub offset_s: f64,
}

/// The arrivals of one delivered cycle, in the order the MSU got them
/// (a transmitter heard twice keeps both: the MSU uses the first).
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedCycle {
    /// The cycle number.
    pub cycle: u64,
    /// Its arrivals.
    pub arrivals: Vec<RecordedArrival>,
}

impl RecordedCycle {
    /// Cycle `cycle`'s arrivals `msg`, each with its emission offset in
    /// `schedule` (arrivals of transmitters it does not list are left out:
    /// the MSU cannot use them either).
    pub fn of(cycle: u64, msg: &UltrasoundArrivals, schedule: &Schedule) -> Self {
        let arrivals = msg
            .arrivals
            .iter()
            .filter_map(|a| {
                let e = schedule.emissions.iter().find(|e| e.tx_id == a.tx_id)?;
                Some(RecordedArrival {
                    tx_id: a.tx_id,
                    t_s: a.t_arrival.as_secs_f64(),
                    offset_s: e.offset.as_secs_f64(),
                })
            })
            .collect();
        Self { cycle, arrivals }
    }
}

/// Everything recorded for export.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// Delivered cycles, in time order.
    pub cycles: Vec<RecordedCycle>,
    /// The robot's true pose every [`TRUTH_EVERY_STEPS`] physics steps,
    /// stamped on the MSU clock.
    pub truth: Vec<TruthSample>,
    /// The wheel odometry the MSU got, in order.
    pub odometry: Vec<Odometry>,
    /// The run went on past the row limit: the recording stops there.
    pub truncated: bool,
    /// Rows (arrivals, truth samples, odometry samples) still allowed.
    room: usize,
}

/// The truth is recorded every this many physics steps (every 10 ms: a
/// motion capture's rate).
pub const TRUTH_EVERY_STEPS: u64 = 2;

impl Recording {
    /// An empty recording that keeps at most `max_rows` rows.
    pub fn new(max_rows: usize) -> Self {
        Self {
            room: max_rows,
            ..Self::default()
        }
    }

    /// Takes `n` rows of room; false (and marked truncated) when there is none.
    fn take(&mut self, n: usize) -> bool {
        if self.truncated || n > self.room {
            self.truncated = true;
            return false;
        }
        self.room -= n;
        true
    }

    /// Records a delivered cycle.
    pub(crate) fn cycle(&mut self, cycle: RecordedCycle) {
        if self.take(cycle.arrivals.len()) {
            self.cycles.push(cycle);
        }
    }

    /// Records a true pose (its time on the MSU clock).
    pub(crate) fn truth(&mut self, sample: TruthSample) {
        if self.take(1) {
            self.truth.push(sample);
        }
    }

    /// Records an odometry sample.
    pub(crate) fn odometry(&mut self, odometry: Odometry) {
        if self.take(1) {
            self.odometry.push(odometry);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recording_stops_at_its_limit_and_says_so() {
        let mut r = Recording::new(3);
        let sample = TruthSample {
            t_s: 0.0,
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
        };
        r.truth(sample);
        let arrival = RecordedArrival {
            tx_id: 1,
            t_s: 0.0,
            offset_s: 0.0,
        };
        r.cycle(RecordedCycle {
            cycle: 0,
            arrivals: vec![arrival; 3],
        });
        assert!(r.truncated);
        assert!(r.cycles.is_empty());
        // Nothing more once truncated, though a row would fit.
        r.truth(sample);
        assert_eq!(r.truth.len(), 1);
        let mut fits = Recording::new(4);
        fits.truth(sample);
        fits.cycle(RecordedCycle {
            cycle: 0,
            arrivals: vec![arrival; 3],
        });
        assert!(!fits.truncated);
        assert_eq!(fits.cycles.len(), 1);
    }
}
