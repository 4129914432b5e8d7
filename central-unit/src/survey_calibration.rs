//! The fleet's calibration of the transmitters' surveyed positions, the
//! cells' lateness and the speed of sound (docs/architecture.md, "The
//! fleet's survey calibration").
//!
//! A robot hears most transmitters steeply from below, so an error in a
//! transmitter's surveyed height goes almost whole into its range, while
//! the range says little about the robot's horizontal position: on
//! `warehouse` the survey's error (1 cm per axis) made most of the mean
//! error left over, the heights most of it. One robot cannot tell its own
//! position from the transmitters it passes under (tried as filter states,
//! it made things worse); the fleet can, because many robots hear each
//! transmitter from many places.
//!
//! Each good fix of every robot carries the residuals of its used signals
//! (`e_i = rho_i - |s_i - p| - b`, the common offset `b` fitted). A survey
//! error `d_k` of transmitter `k` adds `u_k . d_k` to its pseudo-range
//! (`u_k` the unit vector from the receiver to the transmitter), a cell's
//! sync error adds the same `c_j` to the pseudo-range of every transmitter
//! of cell `j`, and a speed of sound off by the fraction `k` takes `k r_i`
//! from each. The fix absorbs what its own unknowns (position and offset,
//! Jacobian `A`) can explain, so the residuals are `e = P (J x + n)` with
//! `P = I - A (A'A)^-1 A'` and `x = (d, c, k)`. Every fix adds
//! `(PJ)'(PJ) / sigma^2` to the information of `x`; with the survey's, the
//! sync's and the air's own sigmas as the prior, the estimate is the
//! least-squares solution over every fix taken (a batch over the whole
//! history: the transmitters do not move; the cells' lateness, which
//! changes with their network paths, is forgotten over
//! [`CalibrationConfig::cell_sync_memory_s`], see `forgetting`). The speed
//! of sound changes with the air: it is forgotten over
//! [`CalibrationConfig::sound_memory_s`] and published as a speed, which
//! every MSU turns its arrival times into ranges with from the next cycle
//! (the fixes solved with it are read with it put back, as the offsets
//! are). The cells' sync errors are published, as each
//! transmitter's lateness (`late_m`), which the MSUs take from its
//! pseudo-ranges: what a cell's sync is off by is mostly the asymmetry of
//! its network path, which no clock exchange can see and which stays
//! while the path does; only differences between cells are observable
//! (what every cell shares, every range difference cancels), and the prior
//! keeps the rest at zero.
//!
//! A signal heard by a reflection has a path longer than its range, and a
//! few centimetres of it pass a fix's gate: it would bend a position. A fix
//! is taken only if every transmitter it used is in sight (by the site's
//! walls and columns) from everywhere the receiver may be.
//!
//! The residuals of a fix are taken against the table the MSU solved with
//! (the calibration it last applied): the offset it used is put back
//! (`e + P J_d a`), so the estimate is always of the whole error, never of
//! an increment.

use std::collections::BTreeMap;

use ickon_proto::msg::control::{
    MAX_LATE_M, MAX_RESURVEYED_OFFSET_M, MAX_SOUND_SPEED_CHANGE, MAX_SURVEY_OFFSET_M,
    SurveyCalibration as SurveyMessage, TransmitterOffset,
};
use ickon_proto::msg::robot::{Fix, FixQuality};
use ickon_proto::site::{Column, Site, Wall, line_of_sight};
use ickon_proto::time::{Duration, Time};
use nalgebra::{DMatrix, DVector, Vector3};

use consensus::{Consensus, RobotCheck};

use crate::air_temperature::SpeedEvidence;
pub use crate::learnt_speed::LearntSpeed;
use crate::transmitter_health::{HealthConfig, TransmitterHealth, TransmitterReport};

/// What the calibration assumes of the site's sensors (data-sheet values)
/// and how often it is published.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationConfig {
    /// One-sigma error of each surveyed coordinate, metres (the survey's
    /// accuracy: the prior of every position).
    pub survey_sigma_m: f64,
    /// One-sigma range error a cell's sync adds to its transmitters, metres:
    /// the prior of each cell's published lateness (0: every cell on time).
    pub cell_sync_sigma_m: f64,
    /// One-sigma error of one arrival's pseudo-range, metres (timing noise
    /// times the speed of sound; never less than 1 cm is used, see
    /// `MIN_RANGE_SIGMA_M`).
    pub range_sigma_m: f64,
    /// One-sigma relative error of the site's speed of sound in the hall's
    /// air at any one time (0.0018 per degree Celsius): the stationary
    /// sigma of the learnt speed of sound. 0: the site's speed is held.
    pub sound_scale_sigma: f64,
    /// The correlation time of the air's speed of sound, seconds: the
    /// learnt speed follows a change of the air within a fraction of this
    /// (with the fixes of a few robots, seconds; `forgetting`). 0: the
    /// speed is learnt once for good.
    pub sound_memory_s: f64,
    /// Whether the learnt speed of sound is published for the MSUs to
    /// solve with (`false`: it is still estimated, within a degree's worth
    /// and for good, so that the air does not leak into the transmitters'
    /// positions, but the site's is used).
    pub learn_speed_of_sound: bool,
    /// How long a cell's lateness is remembered, seconds: its correlation
    /// time (`survey_calibration::forgetting`); a re-routed cell's new
    /// lateness is followed within about this long. 0: for good.
    pub cell_sync_memory_s: f64,
    /// How often the calibration is published.
    pub publish_every: Duration,
}

/// The speed of sound's relative sigma when it is not learnt: the site
/// file's temperature within a degree.
const UNLEARNT_SOUND_SCALE_SIGMA: f64 = 0.0018;

impl CalibrationConfig {
    /// The prior (and stationary) sigma of the speed of sound's relative
    /// error: the air's when the speed is learnt, else a degree's (the
    /// site's speed is then held, as the MSUs use it).
    pub fn sound_prior_sigma(&self) -> f64 {
        if self.learn_speed_of_sound {
            self.sound_scale_sigma
        } else {
            UNLEARNT_SOUND_SCALE_SIGMA
        }
    }

    /// The speed of sound's memory, seconds (0: held; see
    /// [`Self::sound_memory_s`]).
    pub fn sound_memory(&self) -> f64 {
        if self.learn_speed_of_sound {
            self.sound_memory_s
        } else {
            0.0
        }
    }
}

impl Default for CalibrationConfig {
    /// The values a site states before it has measured anything: a survey
    /// to 1 cm per axis (a tape and a laser meter), the cells' sync within
    /// about 60 us, the ICKON paper's receivers' 50 us timing noise at 343 m/s, a cell's
    /// lateness remembered for a day (a network path is re-routed rarely; a
    /// day keeps what was learnt through a night the fleet stands idle),
    /// published every second, the speed of sound learnt. The air: a heated
    /// hall stays within about 5 degrees of its nominal temperature (one sigma, 0.009 of the speed of
    /// sound) and wanders over tens of minutes (a memory of 600 s): its
    /// daily swing of 5 to 15 degrees takes hours, a door opened changes it
    /// by a few degrees within a minute. That random walk (0.0018 per
    /// degree, 2 sigma^2 / memory = 2.7e-7 per second) lets the speed move
    /// by a degree's worth in about 45 s of no fixes; with a few robots'
    /// fixes the estimate settles within seconds.
    fn default() -> Self {
        Self {
            survey_sigma_m: 0.01,
            cell_sync_sigma_m: 0.02,
            range_sigma_m: 50e-6 * 343.0,
            sound_scale_sigma: 0.009,
            sound_memory_s: 600.0,
            learn_speed_of_sound: true,
            cell_sync_memory_s: 86_400.0,
            publish_every: Duration::from_millis(1_000),
        }
    }
}

/// A moved transmitter is surveyed again only when the fleet's fixes place
/// it this far from where it is taken, metres (three range sigmas of the
/// calibration's floor): every re-survey restarts the check that takes it
/// back, and the estimate wanders by a centimetre or two as fixes come.
const RESURVEY_STEP_M: f64 = 0.03;

/// A residual larger than this many range sigmas is down-weighted (Huber):
/// a reflection that passed the fix's gate must not bend a height.
const HUBER_SIGMAS: f64 = 2.0;

/// A good fix's residuals are centimetres (the MSU's gate); beyond this,
/// metres, the fix is malformed.
const MAX_RESIDUAL_M: f64 = 1.0;

/// No transmitter is heard from further than this, metres (a fix that
/// says so is malformed).
const MAX_RANGE_M: f64 = 100.0;

/// No site is larger: a fix further out is malformed, metres.
const MAX_COORDINATE_M: f64 = 100_000.0;

/// A residual is never trusted beyond this, metres, whatever the timing
/// noise: under a centimetre what is left in a residual is the solver's
/// own model (the receivers' spread on the robot, the motion within a
/// cycle), not the survey. With microsecond stamps and nothing else (the
/// `ideal` profile) the calibration otherwise bent the table to fit them
/// and the ground filter ran 78 mm off on `lab`'s `eight`.
const MIN_RANGE_SIGMA_M: f64 = 0.01;

/// A fix needs this many used signals to say anything of the heights: its
/// own position and offset take three.
const MIN_USED: usize = 4;

/// A transmitter must be in sight from the fix and from points this many
/// of its sigmas away, or at least [`LOS_MIN_REACH_M`] (the receivers'
/// spread on the robot and the motion during the cycle).
const LOS_SIGMAS: f64 = 3.0;
/// See [`LOS_SIGMAS`], metres.
const LOS_MIN_REACH_M: f64 = 0.15;

/// The estimate of one transmitter's survey error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TransmitterCorrection {
    /// Transmitter id.
    pub tx_id: u32,
    /// What to add to its surveyed position (x, y, z), metres.
    pub offset_m: [f64; 3],
    /// One-sigma uncertainty of each corrected coordinate, metres.
    pub sigma_m: [f64; 3],
    /// How late its cell's bursts arrive, metres of path (its cell's sync
    /// error; see [`TransmitterOffset::late_m`]).
    pub late_m: f64,
    /// One-sigma uncertainty of `late_m`, metres.
    pub late_sigma_m: f64,
}

/// Position corrections by transmitter id, as an MSU applies them (absent:
/// the surveyed position).
pub type Applied = BTreeMap<u32, [f64; 3]>;

/// Lateness corrections by transmitter id, metres, as an MSU applies them
/// (absent: none).
pub type AppliedLate = BTreeMap<u32, f64>;

/// Calibrations kept to read the fixes solved with them: a fix comes back
/// within a second or two of the calibration it used, and one is published
/// a second.
const HISTORY_KEPT: usize = 16;

/// Why a fix was not taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FixSkipped {
    /// Only fixes whose every residual was checked say something.
    #[error("fix is not of good quality")]
    NotGood,
    /// Fewer than four used signals leave no residual to learn from.
    #[error("fix has too few used signals")]
    TooFewSignals,
    /// The residuals do not match the used transmitters, or are not numbers.
    #[error("fix is malformed")]
    Malformed,
    /// A used transmitter is not one of the site's.
    #[error("fix names a transmitter the site does not have")]
    UnknownTransmitter,
    /// A used transmitter is hidden from somewhere the receiver may be: its
    /// signal may be a reflection, whose extra path would bend a height.
    #[error("fix uses a transmitter the site's walls or columns may hide")]
    MaybeReflected,
    /// The fix was solved with a calibration this central unit did not
    /// publish or no longer remembers.
    #[error("fix was solved with an unknown survey calibration")]
    UnknownCalibration,
    /// The geometry of the fix leaves its own unknowns undetermined.
    #[error("fix geometry is degenerate")]
    Degenerate,
    /// The robot gave more fixes than one a cycle ([`fix_rate`]).
    #[error("robot gives more fixes than one a cycle")]
    OverRate,
}

impl FixSkipped {
    /// A short name of the reason, for counts.
    pub fn label(self) -> &'static str {
        match self {
            Self::NotGood => "not good",
            Self::TooFewSignals => "too few signals",
            Self::Malformed => "malformed",
            Self::UnknownTransmitter => "unknown transmitter",
            Self::MaybeReflected => "maybe reflected",
            Self::UnknownCalibration => "unknown calibration",
            Self::Degenerate => "degenerate",
            Self::OverRate => "over its rate",
        }
    }
}

/// What a central unit keeps of its calibration across restarts: the
/// information gathered, and the table it was gathered for.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SavedCalibration {
    /// Site name.
    pub site: String,
    /// The surveyed table it is of: `(id, [x, y, z])` in the site's order.
    pub transmitters: Vec<(u32, [f64; 3])>,
    /// The site's cells, in order.
    pub cells: Vec<String>,
    /// Fixes behind it.
    pub fixes_taken: u64,
    /// The information matrix, row-major.
    pub information: Vec<f64>,
    /// The information-weighted estimate.
    pub weighted: Vec<f64>,
    /// When it was last published, seconds of the master clock: the cells'
    /// lateness drifts from there across the restart. Absent from files
    /// written before the lateness was forgotten (read as "just now").
    #[serde(default)]
    pub saved_at_s: Option<f64>,
    /// The transmitters the fleet's fixes surveyed again, `(id, [dx, dy,
    /// dz])` from their surveyed positions, metres: what the learnt
    /// offsets of those are relative to (absent from older files: none).
    #[serde(default)]
    pub rebased: Vec<(u32, [f64; 3])>,
}

/// Why a saved calibration cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SavedMismatch {
    /// It is of another site, or of another table or cells of this one
    /// (a transmitter moved, added or removed): what it learnt is not of
    /// these transmitters.
    #[error("it is of another site or transmitter table than this site's")]
    OtherSite,
    /// Its numbers cannot be a calibration (sizes, not numbers, not
    /// positive definite).
    #[error("its numbers are not a calibration: {0}")]
    Broken(&'static str),
}

/// The fleet's survey calibration: the information gathered so far.
#[derive(Debug, Clone)]
pub struct SurveyCalibration {
    config: CalibrationConfig,
    /// Transmitter id -> (its index, the index of its cell's sync
    /// parameter). Transmitter `i`'s offset is parameters `3i..3i+3`.
    index: BTreeMap<u32, (usize, usize)>,
    ids: Vec<u32>,
    surveyed_m: Vec<Vector3<f64>>,
    /// Where each transmitter was surveyed again from its surveyed
    /// position (zero: it was not), metres: its learnt offset is taken
    /// from there (`rebase`).
    rebased_m: Vec<Vector3<f64>>,
    walls: Vec<Wall>,
    columns: Vec<Column>,
    information: DMatrix<f64>,
    weighted: DVector<f64>,
    fixes_taken: u64,
    /// The site's speed of sound, m/s: the learnt relative error scales it.
    site_speed_m_s: f64,
}

impl SurveyCalibration {
    /// A calibration of `site`'s transmitters with nothing learnt yet.
    pub fn new(site: &Site, config: CalibrationConfig) -> Self {
        let n_tx = site.transmitters.len();
        let cells: BTreeMap<&str, usize> = site
            .cells
            .iter()
            .enumerate()
            .map(|(i, c)| (c.id.as_str(), 3 * n_tx + i))
            .collect();
        let mut index = BTreeMap::new();
        let mut ids = Vec::with_capacity(n_tx);
        let mut surveyed_m = Vec::with_capacity(n_tx);
        for (i, t) in site.transmitters.iter().enumerate() {
            // A validated site names only its own cells.
            let cell = cells.get(t.cell.as_str()).copied().unwrap_or(usize::MAX);
            index.insert(t.id, (i, cell));
            ids.push(t.id);
            surveyed_m.push(Vector3::from(t.position_m));
        }
        // The last parameter: the speed of sound's relative error.
        let n = 3 * n_tx + site.cells.len() + 1;
        let mut information = DMatrix::zeros(n, n);
        let prior = |sigma: f64| 1.0 / sigma.max(1e-6).powi(2);
        for i in 0..n {
            information[(i, i)] = if i < 3 * n_tx {
                prior(config.survey_sigma_m)
            } else if i == n - 1 {
                prior(config.sound_prior_sigma())
            } else {
                prior(config.cell_sync_sigma_m)
            };
        }
        Self {
            config,
            index,
            ids,
            surveyed_m,
            rebased_m: vec![Vector3::zeros(); n_tx],
            walls: site.walls.clone(),
            columns: site.columns.clone(),
            information,
            weighted: DVector::zeros(n),
            fixes_taken: 0,
            site_speed_m_s: site.speed_of_sound_m_s,
        }
    }

    /// The speed of sound learnt so far (`estimate` of every parameter,
    /// [`Self::estimate`]; its variance from `variance`): the site's speed
    /// scaled by the learnt relative error.
    fn learnt_speed(&self, scale: f64, variance: f64) -> LearntSpeed {
        LearntSpeed {
            speed_m_s: self.site_speed_m_s * (1.0 + scale),
            sigma_m_s: self.site_speed_m_s * variance.max(0.0).sqrt(),
            scale,
        }
    }

    /// Fixes that have added to the calibration.
    pub fn fixes_taken(&self) -> u64 {
        self.fixes_taken
    }

    /// What to keep across a restart (`site` is the site it serves).
    pub fn saved(&self, site: &Site) -> SavedCalibration {
        SavedCalibration {
            site: site.name.clone(),
            transmitters: table_of(site),
            cells: site.cells.iter().map(|c| c.id.clone()).collect(),
            fixes_taken: self.fixes_taken,
            information: self.information.transpose().as_slice().to_vec(),
            weighted: self.weighted.as_slice().to_vec(),
            saved_at_s: None,
            rebased: self.rebased(),
        }
    }

    /// The calibration of `site` that `saved` kept, to go on learning.
    pub fn restored(
        site: &Site,
        config: CalibrationConfig,
        saved: &SavedCalibration,
    ) -> Result<Self, SavedMismatch> {
        let cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
        if saved.site != site.name || saved.transmitters != table_of(site) || saved.cells != cells {
            return Err(SavedMismatch::OtherSite);
        }
        let mut c = Self::new(site, config);
        let n = c.weighted.len();
        if saved.information.len() != n * n || saved.weighted.len() != n {
            return Err(SavedMismatch::Broken("sizes do not match the site"));
        }
        if !saved
            .information
            .iter()
            .chain(&saved.weighted)
            .chain(&saved.saved_at_s)
            .all(|v| v.is_finite())
        {
            return Err(SavedMismatch::Broken("a value is not a number"));
        }
        let information = DMatrix::from_row_slice(n, n, &saved.information);
        let asymmetric = (0..n).any(|i| {
            (0..i).any(|k| {
                let (a, b) = (information[(i, k)], information[(k, i)]);
                (a - b).abs() > 1e-9 * (a.abs() + b.abs() + 1.0)
            })
        });
        if asymmetric || information.clone().cholesky().is_none() {
            return Err(SavedMismatch::Broken(
                "the information is not positive definite",
            ));
        }
        for &(id, d) in &saved.rebased {
            let &(tx, _) = c.index.get(&id).ok_or(SavedMismatch::OtherSite)?;
            if !d
                .iter()
                .all(|v| v.is_finite() && v.abs() <= MAX_RESURVEYED_OFFSET_M)
            {
                return Err(SavedMismatch::Broken(
                    "a re-surveyed position is out of bounds",
                ));
            }
            c.rebased_m[tx] = Vector3::from(d);
        }
        c.information = information;
        c.weighted = DVector::from_column_slice(&saved.weighted);
        c.fixes_taken = saved.fixes_taken;
        Ok(c)
    }

    /// Takes one robot's fix, solved with the positions corrected by
    /// `applied` and the pseudo-ranges by `late`.
    pub fn take_fix(
        &mut self,
        fix: &Fix,
        applied: &Applied,
        late: &AppliedLate,
    ) -> Result<(), FixSkipped> {
        let read = self.read_fix(fix, applied, late)?;
        self.add(&read);
        Ok(())
    }

    /// One row per signal of `fix` (received at `receiver`): its
    /// transmitter, the direction to it with the correction `applied`, and
    /// the lateness `late` the MSU solved with. Refuses a fix any of whose
    /// signals may have been reflected (no line of sight from around the
    /// receiver), or that is degenerate.
    fn rows(
        &self,
        fix: &Fix,
        receiver: Vector3<f64>,
        applied: &Applied,
        late: &AppliedLate,
    ) -> Result<Vec<Row>, FixSkipped> {
        let n = fix.used.len();
        let sigma_xy_m = (fix.covariance[0] + fix.covariance[4]).max(0.0).sqrt();
        let reach_m = (LOS_SIGMAS * sigma_xy_m).max(LOS_MIN_REACH_M);
        let places = [[0.0, 0.0], [1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]]
            .map(|[dx, dy]| [fix.x_m + reach_m * dx, fix.y_m + reach_m * dy, fix.z_m]);
        let mut rows = Vec::with_capacity(n);
        for &id in &fix.used {
            let &(tx, cell) = self.index.get(&id).ok_or(FixSkipped::UnknownTransmitter)?;
            // Where the transmitter is known to be: surveyed, or surveyed
            // again by the fleet; the offset learnt is from there.
            let base = self.surveyed_m[tx] + self.rebased_m[tx];
            if places
                .iter()
                .any(|&p| !line_of_sight(&self.walls, &self.columns, p, base.into()))
            {
                return Err(FixSkipped::MaybeReflected);
            }
            let offset =
                Vector3::from(applied.get(&id).copied().unwrap_or([0.0; 3])) - self.rebased_m[tx];
            let to_tx = base + offset - receiver;
            let range = to_tx.norm();
            if range < 1e-3 {
                return Err(FixSkipped::Degenerate);
            }
            if !range.is_finite() || range > MAX_RANGE_M {
                return Err(FixSkipped::Malformed);
            }
            rows.push(Row {
                tx,
                cell,
                toward: to_tx / range,
                offset,
                late: late.get(&id).copied().unwrap_or(0.0),
                range,
            });
        }
        Ok(rows)
    }

    /// No correction, each transmitter as surveyed with the survey's and
    /// the cells' prior uncertainty.
    fn prior_corrections(&self) -> Vec<TransmitterCorrection> {
        let sigma = self.config.survey_sigma_m;
        self.ids
            .iter()
            .zip(&self.rebased_m)
            .map(|(&tx_id, rebased)| TransmitterCorrection {
                tx_id,
                offset_m: (*rebased).into(),
                sigma_m: [sigma; 3],
                late_m: 0.0,
                late_sigma_m: self.config.cell_sync_sigma_m,
            })
            .collect()
    }

    /// The corrections from everything taken so far, one per transmitter
    /// of the site, in the site's order.
    pub fn corrections(&self) -> Vec<TransmitterCorrection> {
        self.corrections_and_estimate().0
    }

    /// The speed of sound learnt from everything taken so far (the site's,
    /// with its prior sigma, when numbers went wrong).
    pub fn speed_of_sound(&self) -> LearntSpeed {
        self.corrections_estimate_and_speed().2
    }

    /// The corrections ([`Self::corrections`]) and the estimate of every
    /// parameter ([`Self::estimate`]) from one factorisation: the work of a
    /// publication, a dense solve over every transmitter, done once.
    pub fn corrections_and_estimate(&self) -> (Vec<TransmitterCorrection>, Option<DVector<f64>>) {
        let (corrections, estimate, _) = self.corrections_estimate_and_speed();
        (corrections, estimate)
    }

    /// [`Self::corrections_and_estimate`] and the learnt speed of sound
    /// from the same factorisation.
    pub fn corrections_estimate_and_speed(
        &self,
    ) -> (
        Vec<TransmitterCorrection>,
        Option<DVector<f64>>,
        LearntSpeed,
    ) {
        let n_tx = self.ids.len();
        let prior_speed = self.learnt_speed(0.0, self.config.sound_prior_sigma().powi(2));
        // The prior alone is positive definite and every fix adds a
        // positive semi-definite term: only numbers gone wrong fail here.
        let Some(cholesky) = self.information.clone().cholesky() else {
            return (self.prior_corrections(), None, prior_speed);
        };
        let estimate = cholesky.solve(&self.weighted);
        // Only the covariance's diagonal is published: with the
        // information L L^T, the inverse is L^-T L^-1 and its i-th diagonal
        // entry the squared norm of column i of L^-1 (one triangular solve,
        // half the work of the whole inverse).
        let n = estimate.len();
        let Some(l_inverse) = cholesky
            .l()
            .solve_lower_triangular(&DMatrix::identity(n, n))
        else {
            return (self.prior_corrections(), None, prior_speed);
        };
        let variance: Vec<f64> = (0..n).map(|i| l_inverse.column(i).norm_squared()).collect();
        let scale = estimate.len() - 1;
        let cell_of = |tx_id: u32| {
            self.index
                .get(&tx_id)
                .map(|&(_, cell)| cell)
                .filter(|&cell| cell < scale)
        };
        let corrections = (0..n_tx)
            .map(|i| {
                let tx_id = self.ids[i];
                let (late_m, late_sigma_m) = cell_of(tx_id)
                    .map_or((0.0, self.config.cell_sync_sigma_m), |cell| {
                        (estimate[cell], variance[cell].max(0.0).sqrt())
                    });
                TransmitterCorrection {
                    tx_id,
                    offset_m: std::array::from_fn(|a| self.rebased_m[i][a] + estimate[3 * i + a]),
                    sigma_m: std::array::from_fn(|a| variance[3 * i + a].max(0.0).sqrt()),
                    late_m,
                    late_sigma_m,
                }
            })
            .collect();
        let speed = self.learnt_speed(estimate[scale], variance[scale]);
        (corrections, Some(estimate), speed)
    }
}

/// The receiver's position of a fix fit to learn from: good, with enough
/// signals and sane residuals, coordinates and covariance.
fn checked_receiver(fix: &Fix) -> Result<Vector3<f64>, FixSkipped> {
    if fix.quality != FixQuality::Good {
        return Err(FixSkipped::NotGood);
    }
    let n = fix.used.len();
    if n < MIN_USED {
        return Err(FixSkipped::TooFewSignals);
    }
    let receiver = Vector3::new(fix.x_m, fix.y_m, fix.z_m);
    if fix.residuals_m.len() != n
        || !fix
            .residuals_m
            .iter()
            .all(|e| e.is_finite() && e.abs() <= MAX_RESIDUAL_M)
        || !receiver.iter().all(|v| v.abs() <= MAX_COORDINATE_M)
    {
        return Err(FixSkipped::Malformed);
    }
    if !fix.covariance.iter().all(|v| v.is_finite()) {
        return Err(FixSkipped::Malformed);
    }
    Ok(receiver)
}

/// What is published of `c`, and whether it is what was learnt: an offset
/// beyond [`MAX_SURVEY_OFFSET_M`] (or not a number) is not a survey's
/// error a calibration corrects, and the transmitter stays where it was
/// surveyed, with the survey's sigma; a lateness beyond [`MAX_LATE_M`] is a
/// cell failing its own synchronisation, and is published as 0 with the
/// sync's sigma. Everything else is published as learnt: the least-squares
/// estimate with the survey and the sync as its prior already shrinks what
/// the fleet has not shown towards zero.
///
/// Why small offsets are not held at 0:
/// [docs/decisions/0017-small-survey-offsets-published.md](../../docs/decisions/0017-small-survey-offsets-published.md).
fn publishable(
    c: TransmitterCorrection,
    rebased_m: [f64; 3],
    config: &CalibrationConfig,
) -> (TransmitterOffset, bool) {
    // What was learnt, from where the fleet surveyed it again if it did.
    let learnt_plausible =
        (0..3).all(|a| (c.offset_m[a] - rebased_m[a]).abs() <= MAX_SURVEY_OFFSET_M);
    let position_plausible = learnt_plausible
        && c.offset_m
            .iter()
            .all(|v| v.abs() <= MAX_RESURVEYED_OFFSET_M)
        && c.sigma_m.iter().all(|v| v.is_finite() && *v >= 0.0);
    let late_plausible =
        c.late_m.abs() <= MAX_LATE_M && c.late_sigma_m.is_finite() && c.late_sigma_m >= 0.0;
    let (offset_m, sigma_m) = if position_plausible {
        (c.offset_m, c.sigma_m)
    } else {
        (rebased_m, [config.survey_sigma_m; 3])
    };
    let (late_m, late_sigma_m) = if late_plausible {
        (c.late_m, c.late_sigma_m)
    } else {
        (0.0, config.cell_sync_sigma_m)
    };
    let offset = TransmitterOffset {
        tx_id: c.tx_id,
        offset_m,
        sigma_m,
        late_m,
        late_sigma_m,
        left_out: false,
    };
    (offset, position_plausible && late_plausible)
}

/// The surveyed table of `site`, as a saved calibration names it.
fn table_of(site: &Site) -> Vec<(u32, [f64; 3])> {
    site.transmitters
        .iter()
        .map(|t| (t.id, t.position_m))
        .collect()
}

/// One used signal of a fix.
struct Row {
    /// Index of its transmitter.
    tx: usize,
    /// Index of its cell's sync parameter (`usize::MAX`: none).
    cell: usize,
    /// Unit vector from the receiver to the transmitter.
    toward: Vector3<f64>,
    /// The correction the MSU solved with, metres.
    offset: Vector3<f64>,
    /// The lateness the MSU took from its pseudo-range, metres.
    late: f64,
    /// Distance from the receiver, metres.
    range: f64,
}

/// The central unit's side of the calibration: what it learnt, and the
/// versions it published (to read each fix against the one it used).
#[derive(Debug, Clone)]
pub struct SurveyPublisher {
    calibration: SurveyCalibration,
    publish_every: Duration,
    next_at: Option<Time>,
    /// When the last calibration was published: the cells' lateness
    /// drifts from there.
    last_at: Option<Time>,
    /// The versions published, oldest first: what each made the MSUs
    /// apply.
    history: std::collections::VecDeque<Published>,
    /// Transmitters already reported beyond a calibration's reach.
    warned: std::collections::BTreeSet<u32>,
    /// The fleet's check of each robot's fixes.
    consensus: Consensus,
    /// The estimate of every parameter at the last publication: what the
    /// robots' fixes are checked against.
    estimate: DVector<f64>,
    /// The speed of sound last published (`None`: the site's).
    published_speed: Option<LearntSpeed>,
    /// Each transmitter's health, from the trusted robots' fixes.
    health: TransmitterHealth,
    /// The transmitters left out at the last publication.
    left_out: std::collections::BTreeSet<u32>,
    /// Whether a speed beyond the bound was reported already.
    warned_speed: bool,
    /// What the cell boards' air temperature sensors say of the speed of
    /// sound now (`crate::air_temperature`), fused into the published one.
    air: Option<SpeedEvidence>,
}

/// What one published calibration made the MSUs apply.
#[derive(Debug, Clone)]
struct Published {
    version: u32,
    applied: Applied,
    late: AppliedLate,
    /// The relative change of the speed of sound from the site's.
    sound_scale: f64,
    /// The transmitters it left out of the fixes, by id.
    left_out: std::collections::BTreeSet<u32>,
}

impl SurveyPublisher {
    /// A publisher for `site` with nothing learnt; it publishes at the
    /// first [`Self::due`].
    pub fn new(site: &Site, config: CalibrationConfig) -> Self {
        let calibration = SurveyCalibration::new(site, config);
        let estimate = DVector::zeros(calibration.weighted.len());
        Self {
            calibration,
            publish_every: config.publish_every,
            next_at: None,
            last_at: None,
            history: std::collections::VecDeque::new(),
            warned: std::collections::BTreeSet::new(),
            consensus: Consensus::new(config.range_sigma_m.max(MIN_RANGE_SIGMA_M)),
            estimate,
            published_speed: None,
            warned_speed: false,
            health: TransmitterHealth::new(site, HealthConfig::default()),
            left_out: std::collections::BTreeSet::new(),
            air: None,
        }
    }

    /// The calibration learnt so far.
    pub fn calibration(&self) -> &SurveyCalibration {
        &self.calibration
    }

    /// What to keep across a restart (`site` is the site it serves), with
    /// the time it was last published.
    pub fn saved(&self, site: &Site) -> SavedCalibration {
        SavedCalibration {
            saved_at_s: self.last_at.map(Time::as_secs_f64),
            ..self.calibration.saved(site)
        }
    }

    /// Goes on from a calibration kept across a restart: the cells'
    /// lateness drifts over the time since it was saved at the next
    /// publication (not at all when it was saved "in the future", the
    /// master clock having been set back).
    pub fn restore(&mut self, site: &Site, saved: &SavedCalibration) -> Result<(), SavedMismatch> {
        self.calibration = SurveyCalibration::restored(site, self.calibration.config, saved)?;
        self.last_at = saved.saved_at_s.map(Time::from_secs_f64);
        if let Some(estimate) = self.calibration.estimate() {
            self.estimate = estimate;
        }
        Ok(())
    }

    /// Takes a fix at once, read against the calibration it names, without
    /// the fleet's check: for a single source of fixes known to be honest.
    pub fn take_fix(&mut self, fix: &Fix) -> Result<(), FixSkipped> {
        let read = self.read(fix)?;
        self.calibration.add(&read);
        Ok(())
    }

    /// Offers a fix of robot `key` (see [`fix_rate::FixRate`] for the keys)
    /// arrived at `now`: read against the calibration it names, then held
    /// for the fleet's check ([`consensus`]); a fix of the robot's that the
    /// check lets through is learnt from.
    pub fn offer_fix(&mut self, key: &str, fix: &Fix, now: Time) -> Result<(), FixSkipped> {
        // What a robot the fleet distrusts says of the transmitters is not
        // taken either: a forger must not get a healthy one left out.
        if self.consensus.robot(key).check != consensus::Check::Quarantined {
            let published = self
                .history
                .iter()
                .find(|p| p.version == fix.survey_version);
            let none = std::collections::BTreeSet::new();
            let left_out = published.map_or(&none, |p| &p.left_out);
            self.health.observe_solved(fix, left_out, now);
            let solved_with = published.map(|p| &p.applied);
            if fix.survey_version == 0 || solved_with.is_some() {
                let none = Applied::new();
                self.health
                    .observe_unused(key, fix, solved_with.unwrap_or(&none), now);
            }
        }
        let read = self.read(fix)?;
        let misfit_m = read.misfit_m(&self.estimate);
        if let Some(agreed) = self.consensus.offer(key, read, misfit_m, now) {
            self.calibration.add(&agreed);
        }
        Ok(())
    }

    /// Robot `key` left: the fixes the fleet's check held of it are learnt
    /// from if its window agreed, and the check forgets it
    /// ([`Consensus::forget`]).
    pub fn forget_robot(&mut self, key: &str) {
        for read in self.consensus.forget(key) {
            self.calibration.add(&read);
        }
    }

    /// Robots the fleet's check holds a window or a standing of.
    pub fn robots_checked(&self) -> usize {
        self.consensus.len()
    }

    /// Fixes held for the fleet's check, not learnt from yet.
    pub fn fixes_held(&self) -> usize {
        self.consensus.held()
    }

    /// What the fleet's check says of robot `key`.
    pub fn robot_check(&self, key: &str) -> RobotCheck {
        self.consensus.robot(key)
    }

    /// A fix read against the calibration it names.
    fn read(&self, fix: &Fix) -> Result<ReadFix, FixSkipped> {
        if fix.survey_version == 0 {
            return self
                .calibration
                .read_fix(fix, &Applied::new(), &AppliedLate::new());
        }
        let published = self
            .history
            .iter()
            .find(|p| p.version == fix.survey_version)
            .ok_or(FixSkipped::UnknownCalibration)?;
        self.calibration.read_fix_solved_with(
            fix,
            &published.applied,
            &published.late,
            published.sound_scale,
        )
    }

    /// The offsets of the calibration published last, by transmitter id.
    pub fn published_offsets(&self) -> Option<&Applied> {
        self.history.back().map(|p| &p.applied)
    }

    /// The transmitters left out at the last publication, by id.
    pub fn left_out(&self) -> &std::collections::BTreeSet<u32> {
        &self.left_out
    }

    /// The site's speed of sound, m/s.
    pub fn site_speed_m_s(&self) -> f64 {
        self.calibration.site_speed_m_s
    }

    /// What the fleet saw of every transmitter at `now`, in the site's order.
    pub fn transmitters(&self, now: Time) -> Vec<TransmitterReport> {
        self.health.report(now)
    }

    /// Surveys again every moved transmitter the fleet's fixes now place
    /// away from where the calibration takes it (by more than three of its
    /// sigmas and [`RESURVEY_STEP_M`]), for the next publication, and
    /// checks one they place where it is taken there; one surveyed again
    /// already is not, until the fixes solved with its new position
    /// disagree with it or place it elsewhere.
    fn resurvey_moved(&mut self) {
        for tx_id in self.health.moved() {
            // Surveyed again already, and being checked: the check decides.
            if self.health.resurveyed_at(tx_id).is_some() {
                continue;
            }
            let (Some(r), Some(base)) = (
                self.health.resurveyed(tx_id),
                self.calibration.base_of(tx_id),
            ) else {
                continue;
            };
            let apart = (0..3)
                .map(|a| (r.position_m[a] - base[a]).powi(2))
                .sum::<f64>()
                .sqrt();
            let sigma = r.sigma_m.iter().fold(0.0_f64, |m, s| m.max(*s));
            if apart <= (3.0 * sigma).max(RESURVEY_STEP_M) {
                // The fixes place it where it is taken: checked there.
                self.health.mark_resurveyed(tx_id, base);
                continue;
            }
            match self.calibration.rebase(tx_id, r.position_m, r.sigma_m) {
                Ok(()) => {
                    tracing::warn!(
                        "transmitter {tx_id} surveyed again by {} fixes of {} robots at \
                         ({:.3}, {:.3}, {:.3}) m (sigma {:.0} mm), {:.0} mm from where it was \
                         taken; left out until fixes solved with it there agree",
                        r.fixes,
                        r.robots,
                        r.position_m[0],
                        r.position_m[1],
                        r.position_m[2],
                        sigma * 1e3,
                        apart * 1e3
                    );
                    self.health.mark_resurveyed(tx_id, r.position_m);
                }
                Err(e) => tracing::warn!("transmitter {tx_id} cannot be surveyed again: {e}"),
            }
        }
    }

    /// Where the fleet's fixes place moved transmitter `tx_id` now, if
    /// they pin it down
    /// ([`crate::transmitter_health::TransmitterHealth::resurveyed`]).
    pub fn resurveyed(
        &self,
        tx_id: u32,
    ) -> Option<crate::transmitter_health::resurvey::Resurveyed> {
        self.health.resurveyed(tx_id)
    }

    /// The speed of sound published last (the site's before the first).
    pub fn published_speed(&self) -> Option<LearntSpeed> {
        self.published_speed
    }

    /// What the cell boards' air temperature sensors say of the speed of
    /// sound now (`None`: nothing fresh), for the next publication: fused
    /// with the fleet's estimate as an independent measurement
    /// ([`SpeedEvidence::fused`]), so that the speed published starts from
    /// the air's before the fleet's fixes have told it. The fixes are still
    /// read with the published speed put back: what the fleet learns stays
    /// its own.
    pub fn observe_air_temperature(&mut self, evidence: Option<SpeedEvidence>) {
        self.air = evidence;
    }

    /// The calibration to publish at `now` in `epoch`, if one is due.
    ///
    /// Versions grow with the master clock's seconds (and by one at least),
    /// so that a restarted central unit never reuses a version its
    /// predecessor's fixes may still name: it publishes at most one a
    /// second, and the clock has moved on since.
    pub fn due(&mut self, now: Time, epoch: u64) -> Option<SurveyMessage> {
        if self.next_at.is_some_and(|at| now < at) {
            return None;
        }
        self.next_at = Some(now + self.publish_every);
        if let Some(last) = self.last_at.replace(now) {
            self.calibration
                .forget_cell_sync((now - last).as_secs_f64());
        }
        self.resurvey_moved();
        let (corrections, estimate, speed) = self.calibration.corrections_estimate_and_speed();
        let speed = match self.air {
            Some(air) if self.calibration.config.learn_speed_of_sound => {
                air.fused(speed, self.calibration.site_speed_m_s)
            }
            _ => speed,
        };
        if let Some(estimate) = estimate {
            self.estimate = estimate;
        }
        // Air further off than any hall's is no air's: the site's speed.
        let plausible = speed.scale.abs() <= MAX_SOUND_SPEED_CHANGE && speed.sigma_m_s.is_finite();
        let learn = self.calibration.config.learn_speed_of_sound;
        let speed = (learn && plausible).then_some(speed);
        if learn && !plausible && !self.warned_speed {
            self.warned_speed = true;
            tracing::warn!(
                "the fleet's fixes put the speed of sound more than {} % from the site's: \
                 the site's speed is published (check the site file's temperature)",
                MAX_SOUND_SPEED_CHANGE * 100.0
            );
        }
        self.published_speed = speed;
        let from_clock = u32::try_from(now.as_nanos().max(0) / 1_000_000_000).unwrap_or(u32::MAX);
        let last = self.history.back().map_or(0, |p| p.version);
        let version = from_clock.max(last.saturating_add(1)).max(1);
        let config = self.calibration.config;
        let left_out = self.health.left_out();
        if left_out != self.left_out {
            let reports = self.health.report(now);
            for r in reports
                .iter()
                .filter(|r| left_out.contains(&r.tx_id) != self.left_out.contains(&r.tx_id))
            {
                if left_out.contains(&r.tx_id) {
                    tracing::warn!(
                        "transmitter {} is {}: {}; left out of the robots' fixes until it is healthy",
                        r.tx_id,
                        r.condition.label(),
                        TransmitterHealth::evidence(r)
                    );
                } else {
                    tracing::info!(
                        "transmitter {} is healthy again ({}): back in the robots' fixes",
                        r.tx_id,
                        TransmitterHealth::evidence(r)
                    );
                }
            }
            self.left_out = left_out;
        }
        let offsets: Vec<TransmitterOffset> = corrections
            .into_iter()
            .map(|c| {
                let rebased = self.calibration.rebased_of(c.tx_id);
                let (mut offset, plausible) = publishable(c, rebased, &config);
                offset.left_out = self.left_out.contains(&c.tx_id);
                if !plausible && self.warned.insert(c.tx_id) {
                    tracing::warn!(
                        "transmitter {}: the fleet's fixes put it {:?} m from its surveyed \
                         position and its bursts {:.3} m late, beyond the {MAX_SURVEY_OFFSET_M} m \
                         and {MAX_LATE_M} m a calibration corrects: survey it again or check \
                         its cell's sync (left as surveyed and on time)",
                        c.tx_id,
                        c.offset_m,
                        c.late_m
                    );
                }
                offset
            })
            .collect();
        if self.history.len() == HISTORY_KEPT {
            self.history.pop_front();
        }
        self.history.push_back(Published {
            version,
            applied: offsets.iter().map(|o| (o.tx_id, o.offset_m)).collect(),
            late: offsets.iter().map(|o| (o.tx_id, o.late_m)).collect(),
            sound_scale: speed.map_or(0.0, |s| s.scale),
            left_out: self.left_out.clone(),
        });
        Some(SurveyMessage {
            epoch,
            version,
            fixes_taken: self.calibration.fixes_taken(),
            offsets,
            speed_of_sound_m_s: speed.map_or(0.0, |s| s.speed_m_s),
            speed_of_sound_sigma_m_s: speed.map_or(0.0, |s| s.sigma_m_s),
        })
    }
}

pub mod consensus;
pub mod fix_rate;
mod forgetting;
mod read_fix;
pub mod rebase;

pub use read_fix::ReadFix;

#[cfg(test)]
pub(crate) mod tests;
