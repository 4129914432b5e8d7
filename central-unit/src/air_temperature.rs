//! The cell boards' air temperature sensors: each reading screened, the
//! accepted ones turned into evidence for the speed of sound
//! ([`SpeedEvidence`], fused with the fleet's by
//! [`crate::survey_calibration::SurveyPublisher::observe_air_temperature`]).
//!
//! A reading is refused (counted per board, logged at a bounded rate,
//! never used) when it is not a number, outside the range of the sensors
//! a board carries ([`MIN_C`]..[`MAX_C`]), identical to the board's last
//! [`STUCK_READINGS`] readings (a sensor that stopped converting repeats
//! its last value, while a working one's noise moves the last digit), or
//! more than [`MAX_JUMP_C_PER_S`] from the board's last accepted reading
//! per second since it (air does not warm by 20 degrees in a second; a
//! loose contact does). A stuck board's readings stay unused until it
//! reports a different value.
//!
//! A sensor measures the air at the board, under the ceiling, not along
//! the robots' paths: with a degree per metre of stratification, a board at
//! 4 m reads about 2 degrees warmer than the paths' average, and a board by
//! a heater warmer still. The evidence is therefore the median of the
//! boards' fresh readings with a sigma that is honest about it:
//! [`PLACEMENT_SIGMA_C`] shared by every board (they all hang at the
//! ceiling) and [`BOARD_SIGMA_C`] each (bias, a spot), averaged over the
//! boards. That is wide against what the fleet's fixes learn within
//! minutes, narrow against the air's own spread (five degrees): it helps
//! while few fixes have come (after a start, a step of the air), and the
//! fleet's fixes outweigh it once they have.

use std::collections::BTreeMap;

use ickon_proto::msg::admin::BoardAirStatus;
use ickon_proto::time::{Duration, Time};

use crate::learnt_speed::LearntSpeed;

/// The coldest reading accepted, degrees Celsius (the industrial range of
/// the sensors a board carries).
pub const MIN_C: f64 = -40.0;
/// The warmest reading accepted, degrees Celsius.
pub const MAX_C: f64 = 85.0;
/// Identical readings in a row after which a board's sensor is taken to be
/// stuck.
pub const STUCK_READINGS: u32 = 10;
/// The fastest change of a board's reading accepted, degrees Celsius per
/// second since its last accepted reading (at least a second is counted).
pub const MAX_JUMP_C_PER_S: f64 = 20.0;
/// A board's last accepted reading is used this long, seconds.
pub const FRESH_S: f64 = 10.0;
/// One-sigma difference between the air at the ceiling, shared by every
/// board, and the robots' paths' average, degrees Celsius.
pub const PLACEMENT_SIGMA_C: f64 = 2.0;
/// One-sigma error of one board's reading beyond the shared one (its
/// sensor's bias, a spot near it), degrees Celsius.
pub const BOARD_SIGMA_C: f64 = 1.0;
/// A refusal of one kind is logged at most this often per board.
const LOG_EVERY: Duration = Duration::from_millis(10_000);

/// The speed of sound in dry air at `t_c` degrees Celsius, m/s (the
/// site file's formula).
pub fn speed_of_sound_at_c(t_c: f64) -> f64 {
    ickon_proto::site::speed_of_sound_at(t_c)
}

/// Why a reading was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, thiserror::Error)]
pub enum AirRefused {
    /// Not a number (the board's sensor had no valid reading).
    #[error("not a number")]
    NotANumber,
    /// Outside [`MIN_C`]..[`MAX_C`].
    #[error("outside {MIN_C}..{MAX_C} C")]
    OutOfRange,
    /// The same value as the last [`STUCK_READINGS`] readings.
    #[error("stuck at one value")]
    Stuck,
    /// Too far from the last accepted reading for the time since.
    #[error("jumped more than {MAX_JUMP_C_PER_S} C in a second")]
    Jump,
    /// From a cell the site does not have.
    #[error("from a cell the site does not have")]
    UnknownCell,
}

/// The evidence of the boards' sensors for the speed of sound, as a
/// relative change from the site's speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedEvidence {
    /// The relative change from the site's speed.
    pub scale: f64,
    /// Its variance.
    pub variance: f64,
}

impl SpeedEvidence {
    /// `fleet` (the fleet's estimate, on a site whose speed is
    /// `site_speed_m_s`) fused with this evidence, independent of it: the
    /// product of the two Gaussians. Nonsense on either side leaves the
    /// fleet's as it is.
    pub fn fused(self, fleet: LearntSpeed, site_speed_m_s: f64) -> LearntSpeed {
        let fleet_variance = (fleet.sigma_m_s / site_speed_m_s).powi(2);
        let usable = self.scale.is_finite()
            && self.variance > 0.0
            && self.variance.is_finite()
            && fleet_variance > 0.0
            && fleet_variance.is_finite();
        if !usable {
            return fleet;
        }
        let variance = 1.0 / (1.0 / fleet_variance + 1.0 / self.variance);
        let scale = variance * (fleet.scale / fleet_variance + self.scale / self.variance);
        LearntSpeed {
            speed_m_s: site_speed_m_s * (1.0 + scale),
            sigma_m_s: site_speed_m_s * variance.sqrt(),
            scale,
        }
    }
}

/// What one board's sensor said.
#[derive(Debug, Clone, Default)]
struct Board {
    /// The last reading received, degrees Celsius, and how many in a row
    /// had that value.
    last: Option<(f64, u32)>,
    /// The last accepted reading and when it came.
    accepted: Option<(f64, Time)>,
    /// Readings accepted.
    accepted_count: u64,
    /// Refusals by reason.
    refused: BTreeMap<AirRefused, u64>,
    /// When each reason was last logged.
    logged: BTreeMap<AirRefused, Time>,
}

impl Board {
    fn stuck(&self) -> bool {
        self.last.is_some_and(|(_, n)| n > STUCK_READINGS)
    }

    fn judge(&self, t_c: f64, now: Time) -> Result<(), AirRefused> {
        if t_c.is_nan() {
            return Err(AirRefused::NotANumber);
        }
        if !(MIN_C..=MAX_C).contains(&t_c) {
            return Err(AirRefused::OutOfRange);
        }
        if self.stuck() {
            return Err(AirRefused::Stuck);
        }
        if let Some((before_c, at)) = self.accepted {
            let dt_s = now.since(at).as_secs_f64().max(1.0);
            if (t_c - before_c).abs() > MAX_JUMP_C_PER_S * dt_s {
                return Err(AirRefused::Jump);
            }
        }
        Ok(())
    }
}

/// Every cell board's air temperature sensor.
#[derive(Debug, Clone)]
pub struct AirTemperatures {
    /// By cell id: only the site's cells.
    boards: BTreeMap<String, Board>,
    /// Readings from cells the site does not have.
    unknown_cell: u64,
}

impl AirTemperatures {
    /// The sensors of the cells `cells` (of the site), none heard yet.
    pub fn new<'a>(cells: impl IntoIterator<Item = &'a str>) -> Self {
        Self {
            boards: cells
                .into_iter()
                .map(|c| (c.to_string(), Board::default()))
                .collect(),
            unknown_cell: 0,
        }
    }

    /// Follows the site's cells `cells` (after a reload): a new cell's
    /// board is added unheard, a removed cell's forgotten.
    pub fn follow_cells<'a>(&mut self, cells: impl IntoIterator<Item = &'a str>) {
        let cells: Vec<&str> = cells.into_iter().collect();
        self.boards.retain(|id, _| cells.contains(&id.as_str()));
        for c in cells {
            self.boards.entry(c.to_string()).or_default();
        }
    }

    /// Takes a reading of `cell`'s board, `t_c` degrees Celsius, arrived
    /// at `now`: accepted, or refused and counted.
    pub fn observe(&mut self, cell: &str, t_c: f64, now: Time) -> Result<(), AirRefused> {
        let Some(board) = self.boards.get_mut(cell) else {
            self.unknown_cell += 1;
            return Err(AirRefused::UnknownCell);
        };
        // Counted before judging: a stuck sensor is recognised by its run.
        board.last = match board.last {
            Some((c, n)) if c == t_c => Some((c, n.saturating_add(1))),
            _ if t_c.is_nan() => None,
            _ => Some((t_c, 1)),
        };
        match board.judge(t_c, now) {
            Ok(()) => {
                board.accepted = Some((t_c, now));
                board.accepted_count += 1;
                Ok(())
            }
            Err(why) => {
                *board.refused.entry(why).or_default() += 1;
                let due = board
                    .logged
                    .get(&why)
                    .is_none_or(|&at| now.since(at) >= LOG_EVERY);
                if due {
                    board.logged.insert(why, now);
                    tracing::warn!(
                        "cell {cell}: air temperature {t_c} C refused: {why} ({} refused so far)",
                        board.refused[&why]
                    );
                }
                Err(why)
            }
        }
    }

    /// Readings from cells the site does not have.
    pub fn unknown_cell(&self) -> u64 {
        self.unknown_cell
    }

    /// The fresh accepted readings at `now`, degrees Celsius, by cell.
    fn fresh(&self, now: Time) -> impl Iterator<Item = (&str, f64)> {
        self.boards.iter().filter_map(move |(cell, b)| {
            let (t_c, at) = b.accepted?;
            (!b.stuck() && now.since(at).as_secs_f64() <= FRESH_S).then_some((cell.as_str(), t_c))
        })
    }

    /// The median of the fresh readings and how many there are.
    fn median_c(&self, now: Time) -> Option<(f64, usize)> {
        let mut t: Vec<f64> = self.fresh(now).map(|(_, t)| t).collect();
        if t.is_empty() {
            return None;
        }
        t.sort_by(f64::total_cmp);
        let n = t.len();
        let median = if n % 2 == 1 {
            t[n / 2]
        } else {
            0.5 * (t[n / 2 - 1] + t[n / 2])
        };
        Some((median, n))
    }

    /// What the fresh readings at `now` say of the speed of sound,
    /// relative to the site's `site_speed_m_s` (`None`: no fresh reading).
    pub fn evidence(&self, now: Time, site_speed_m_s: f64) -> Option<SpeedEvidence> {
        let (t_c, n) = self.median_c(now)?;
        if site_speed_m_s.is_nan() || site_speed_m_s <= 0.0 {
            return None;
        }
        let variance_c = PLACEMENT_SIGMA_C.powi(2) + BOARD_SIGMA_C.powi(2) / n as f64;
        // dc/dT of `speed_of_sound_at_c`, relative to the site's speed.
        let slope = 331.3 * 0.5 / (273.15 * (1.0 + t_c / 273.15).max(1e-3).sqrt());
        Some(SpeedEvidence {
            scale: speed_of_sound_at_c(t_c) / site_speed_m_s - 1.0,
            variance: variance_c * (slope / site_speed_m_s).powi(2),
        })
    }

    /// Every board's sensor at `now`, in the site's order of cells.
    pub fn report(&self, now: Time, cells: &[String]) -> Vec<BoardAirStatus> {
        cells
            .iter()
            .filter_map(|cell| {
                let b = self.boards.get(cell)?;
                let count = |why| b.refused.get(&why).copied().unwrap_or(0);
                let heard = b.accepted.is_some() || b.last.is_some() || !b.refused.is_empty();
                let state = if !heard {
                    "no sensor"
                } else if b.stuck() {
                    "stuck"
                } else if b
                    .accepted
                    .is_some_and(|(_, at)| now.since(at).as_secs_f64() <= FRESH_S)
                {
                    "used"
                } else {
                    "not used"
                };
                Some(BoardAirStatus {
                    cell_id: cell.clone(),
                    state: state.to_string(),
                    temperature_c: b.accepted.map_or(f64::NAN, |(t, _)| t),
                    accepted_s_ago: b
                        .accepted
                        .map_or(-1.0, |(_, at)| now.since(at).as_secs_f64().max(0.0)),
                    accepted: b.accepted_count,
                    refused_not_a_number: count(AirRefused::NotANumber),
                    refused_out_of_range: count(AirRefused::OutOfRange),
                    refused_stuck: count(AirRefused::Stuck),
                    refused_jump: count(AirRefused::Jump),
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
