//! The measurements file as a stream of epochs, each checked whole: one
//! family of kinds, a propagation speed for times, a bounded size.

use super::epoch::{Units, same_family};
use super::format::{Anchors, Arrival, measurement_columns as mc};
use super::read::LogError;
use super::rows::MeasurementReader;

/// Most rows one epoch may hold: far more arrivals than any array has
/// receivers, small enough that an epoch id repeated down a huge file
/// cannot fill the memory.
pub const MAX_EPOCH_ROWS: usize = 4096;

/// Most epochs whose first rows share one time: the estimators' windows
/// are spans of time, and a clock stuck this long would fill them without
/// end (an array hears an emitter a few hundred times a second at most).
pub const MAX_EPOCHS_AT_ONE_TIME: u32 = 1000;

/// Epochs, one at a time.
pub struct Epochs<'a> {
    reader: MeasurementReader,
    anchors: &'a Anchors,
    units: Units,
    next: Option<Arrival>,
    /// Rows read so far.
    pub rows: u64,
    /// Time of the first and the last row, seconds.
    pub span_s: Option<(f64, f64)>,
    /// Time of the last epoch's first row, and the epochs since it changed.
    stuck: (f64, u32),
}

impl<'a> Epochs<'a> {
    /// Epochs of `reader`'s file.
    pub fn new(reader: MeasurementReader, anchors: &'a Anchors, units: Units) -> Self {
        Self {
            reader,
            anchors,
            units,
            next: None,
            rows: 0,
            span_s: None,
            stuck: (f64::NAN, 0),
        }
    }

    /// How values become metres.
    pub fn units(&self) -> &Units {
        &self.units
    }

    fn row(&mut self) -> Result<Option<Arrival>, LogError> {
        let Some(a) = self.reader.next(self.anchors)? else {
            return Ok(None);
        };
        if a.kind.is_time() && self.units.speed_m_s.is_none() {
            return Err(self.reader.error(
                a.line,
                mc::KIND,
                "a time needs the propagation speed: a `# propagation_speed_m_s: ...` line or --speed-m-s".into(),
            ));
        }
        self.rows += 1;
        self.span_s = Some(match self.span_s {
            Some((first, _)) => (first, a.t_s),
            None => (a.t_s, a.t_s),
        });
        Ok(Some(a))
    }

    /// Refuses a clock that stays on one time over more than
    /// [`MAX_EPOCHS_AT_ONE_TIME`] epochs.
    fn check_clock(&mut self, first: &Arrival) -> Result<(), LogError> {
        if first.t_s != self.stuck.0 {
            self.stuck = (first.t_s, 0);
            return Ok(());
        }
        self.stuck.1 += 1;
        if self.stuck.1 < MAX_EPOCHS_AT_ONE_TIME {
            return Ok(());
        }
        Err(self.reader.error(
            first.line,
            mc::TIME,
            format!(
                "{} s for more than {MAX_EPOCHS_AT_ONE_TIME} epochs: the clock is stuck",
                first.t_s
            ),
        ))
    }

    /// The next epoch's rows into `out` (cleared first); `false` at the
    /// end of the file.
    pub fn next_epoch(&mut self, out: &mut Vec<Arrival>) -> Result<bool, LogError> {
        out.clear();
        let first = match self.next.take() {
            Some(a) => a,
            None => match self.row()? {
                Some(a) => a,
                None => return Ok(false),
            },
        };
        self.check_clock(&first)?;
        out.push(first);
        while let Some(a) = self.row()? {
            if a.epoch != first.epoch {
                self.next = Some(a);
                break;
            }
            if !same_family(first.kind, a.kind) {
                return Err(self.reader.error(
                    a.line,
                    mc::KIND,
                    format!(
                        "epoch {} mixes differences (tdoa_s, tdoa_m) with arrival times or ranges (toa_s, range_m)",
                        a.epoch
                    ),
                ));
            }
            if out.len() == MAX_EPOCH_ROWS {
                return Err(self.reader.error(
                    a.line,
                    mc::EPOCH,
                    format!("epoch {} has more than {MAX_EPOCH_ROWS} rows", a.epoch),
                ));
            }
            out.push(a);
        }
        Ok(true)
    }
}
