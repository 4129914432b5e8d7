//! Per-cycle assembly: the arrivals of one cycle, matched to the schedule,
//! become pseudo-ranges with one unknown common offset.
//!
//! Transmitter `i` fires at `T_k + offset_i` and is heard at `t_i` (MSU
//! clock), so `c (t_i - offset_i) = r_i + c T_k'` where `T_k'` (the cycle
//! start on the MSU clock) is unknown but common: range differences need no
//! clock shared with the robot (docs/architecture.md, "A cycle").

use ickon_proto::msg::control::{Schedule, TransmitterEntry};
use ickon_proto::msg::robot::UltrasoundArrivals;
use ickon_proto::time::Time;

/// One usable arrival.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Signal {
    /// Transmitter id.
    pub tx_id: u32,
    /// Transmitter position, metres.
    pub tx_m: [f64; 3],
    /// `c (t_i - offset_i)` relative to the first arrival of the cycle, metres.
    pub pseudo_range_m: f64,
    /// Receiver that heard it first.
    pub receiver_id: u8,
    /// Emission offset inside the cycle, seconds (orders the signals by emission).
    pub offset_s: f64,
    /// Arrival time on the MSU clock.
    pub t_arrival: Time,
    /// The clock the transmitter fires by: its cell, named by the index of
    /// the cell's first transmitter in the table (arrivals of one cell
    /// share its sync error).
    pub clock: u32,
}

/// The signals of one cycle.
#[derive(Debug, Clone, PartialEq)]
pub struct CycleSignals {
    /// Usable signals, in order of emission.
    pub signals: Vec<Signal>,
    /// Ids heard but unusable: not in the schedule, or heard twice (the later copy).
    pub rejected: Vec<u32>,
    /// Measurement time: the mean arrival time, MSU clock.
    pub stamp: Time,
}

/// Why a cycle could not be assembled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AssemblyError {
    /// The message has no arrival.
    #[error("the cycle has no arrival")]
    Empty,
    /// The speed of sound is not a positive number.
    #[error("speed of sound {0} m/s is not positive")]
    BadSpeedOfSound(f64),
}

/// Matches the arrivals of one cycle to the schedule and the lookup table.
pub fn assemble(
    msg: &UltrasoundArrivals,
    schedule: &Schedule,
    transmitters: &[TransmitterEntry],
    speed_of_sound_m_s: f64,
) -> Result<CycleSignals, AssemblyError> {
    if !(speed_of_sound_m_s > 0.0 && speed_of_sound_m_s.is_finite()) {
        return Err(AssemblyError::BadSpeedOfSound(speed_of_sound_m_s));
    }
    let first = msg
        .arrivals
        .iter()
        .map(|a| a.t_arrival)
        .min()
        .ok_or(AssemblyError::Empty)?;
    let mean_ns = msg
        .arrivals
        .iter()
        .map(|a| i128::from(a.t_arrival.as_nanos()))
        .sum::<i128>()
        / msg.arrivals.len() as i128;
    let mut signals: Vec<Signal> = Vec::with_capacity(msg.arrivals.len());
    let mut rejected = Vec::new();
    for a in &msg.arrivals {
        let emission = schedule.emissions.iter().find(|e| e.tx_id == a.tx_id);
        let entry = transmitters.iter().find(|t| t.tx_id == a.tx_id);
        let (Some(e), Some(t)) = (emission, entry) else {
            rejected.push(a.tx_id);
            continue;
        };
        if signals.iter().any(|s| s.tx_id == a.tx_id) {
            rejected.push(a.tx_id);
            continue;
        }
        let offset_s = e.offset.as_secs_f64();
        let since_first_s = a.t_arrival.since(first).as_secs_f64();
        signals.push(Signal {
            tx_id: a.tx_id,
            tx_m: [t.x_m, t.y_m, t.z_m],
            pseudo_range_m: speed_of_sound_m_s * (since_first_s - offset_s),
            receiver_id: a.receiver_id,
            offset_s,
            t_arrival: a.t_arrival,
            clock: clock_of_cell(transmitters, &t.cell_id).unwrap_or(0),
        });
    }
    signals.sort_by(|a, b| a.offset_s.total_cmp(&b.offset_s));
    Ok(CycleSignals {
        signals,
        rejected,
        stamp: Time::from_nanos(i64::try_from(mean_ns).unwrap_or(i64::MAX)),
    })
}

/// The clock of cell `cell_id`: the index of its first transmitter in
/// `transmitters` (`None`: no transmitter of the table is in that cell).
pub(crate) fn clock_of_cell(transmitters: &[TransmitterEntry], cell_id: &str) -> Option<u32> {
    let first = transmitters.iter().position(|x| x.cell_id == cell_id)?;
    Some(u32::try_from(first).unwrap_or(u32::MAX))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ickon_proto::msg::control::Emission;
    use ickon_proto::msg::robot::Arrival;
    use ickon_proto::time::Duration;

    fn schedule() -> Schedule {
        Schedule {
            version: 1,
            effective_cycle: 0,
            cycle_period: Duration::from_millis(100),
            slot_length: Duration::from_millis(50),
            emissions: vec![
                Emission {
                    tx_id: 1,
                    cell_id: "a".into(),
                    offset: Duration::ZERO,
                    slot: 0,
                },
                Emission {
                    tx_id: 2,
                    cell_id: "a".into(),
                    offset: Duration::from_millis(50),
                    slot: 1,
                },
            ],
            active_cells: vec!["a".into()],
            epoch: 1,
        }
    }

    fn entry(tx_id: u32) -> TransmitterEntry {
        TransmitterEntry {
            tx_id,
            cell_id: "a".into(),
            x_m: 0.0,
            y_m: 0.0,
            z_m: 3.0,
        }
    }

    #[test]
    fn pseudo_ranges_remove_the_emission_offsets_and_unknown_ids_are_rejected() {
        let msg = UltrasoundArrivals {
            seq: 1,
            arrivals: vec![
                Arrival {
                    tx_id: 1,
                    receiver_id: 0,
                    t_arrival: Time::from_nanos(1_010_000_000),
                },
                Arrival {
                    tx_id: 2,
                    receiver_id: 1,
                    t_arrival: Time::from_nanos(1_062_000_000),
                },
                Arrival {
                    tx_id: 9,
                    receiver_id: 1,
                    t_arrival: Time::from_nanos(1_070_000_000),
                },
                Arrival {
                    tx_id: 2,
                    receiver_id: 1,
                    t_arrival: Time::from_nanos(1_075_000_000),
                },
            ],
        };
        let c = assemble(&msg, &schedule(), &[entry(1), entry(2)], 340.0).unwrap();
        assert_eq!(c.signals.len(), 2);
        assert!((c.signals[1].pseudo_range_m - 340.0 * 0.002).abs() < 1e-9);
        assert_eq!(c.rejected, vec![9, 2]);
    }

    #[test]
    fn transmitters_of_one_cell_share_a_clock_and_other_cells_do_not() {
        let table = [
            entry(7),
            TransmitterEntry {
                cell_id: "b".into(),
                ..entry(1)
            },
            entry(2),
        ];
        assert_eq!(clock_of_cell(&table, "a"), Some(0));
        assert_eq!(clock_of_cell(&table, "b"), Some(1));
        assert_eq!(clock_of_cell(&table, "c"), None);
        let msg = UltrasoundArrivals {
            seq: 1,
            arrivals: [1, 2]
                .map(|tx_id| Arrival {
                    tx_id,
                    receiver_id: 0,
                    t_arrival: Time::from_nanos(1_000_000_000 + i64::from(tx_id) * 50_000_000),
                })
                .to_vec(),
        };
        let c = assemble(&msg, &schedule(), &table, 340.0).unwrap();
        let clocks: Vec<u32> = c.signals.iter().map(|s| s.clock).collect();
        assert_eq!(clocks, vec![1, 0]);
    }

    #[test]
    fn empty_cycle_is_an_error() {
        let msg = UltrasoundArrivals {
            seq: 1,
            arrivals: vec![],
        };
        assert_eq!(
            assemble(&msg, &schedule(), &[], 340.0),
            Err(AssemblyError::Empty)
        );
    }
}
