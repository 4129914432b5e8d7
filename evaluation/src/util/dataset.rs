//! Reading the UTIL files (described by the READMEs of the data's `util/`
//! and `util-imu/` folders): the anchor file whole (it is
//! small), the measurement file as a stream of rows.
//!
//! A measurement row carries independent streams that only share the row
//! index: a TDOA (`idA,idB,tdoa_meas,t_tdoa`), a truth pose
//! (`pose_x,pose_y,pose_z,t_pose`, with `pose_qx..pose_qw` in the 27-column
//! layout) and, in the 27-column layout, the accelerometer (`t_acc,acc_*`,
//! in g) and the gyro (`t_gyro,gyro_*`, in deg/s); a stream that has ended
//! leaves its columns blank. Columns are found by name in the header. Every
//! problem is reported with the file and the line (1 = the header).

use std::collections::HashMap;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

/// What is wrong with an input file; the text names the file and the line.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The file cannot be opened or read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A column the format needs is not in the header.
    #[error("{}:1: column `{column}` is missing from the header", path.display())]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The missing column.
        column: &'static str,
    },
    /// A line cannot be read as the format says.
    #[error("{}:{line}: {message}", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// Line number, 1-based (the header is line 1).
        line: u64,
        /// What is wrong.
        message: String,
    },
}

/// One TDOA measurement: `|p - anchor_b| - |p - anchor_a| = d_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TdoaRow {
    /// Anchor A.
    pub id_a: u32,
    /// Anchor B.
    pub id_b: u32,
    /// Range difference B minus A, metres.
    pub d_m: f64,
    /// Time on the tag's clock, seconds.
    pub t_s: f64,
}

/// One motion-capture pose of the body centre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthRow {
    /// Time on the tag's clock, seconds.
    pub t_s: f64,
    /// Body centre, metres.
    pub position_m: [f64; 3],
    /// Orientation body to world `[x, y, z, w]`, when the file has it.
    pub attitude_xyzw: Option<[f64; 4]>,
}

/// One IMU sample (accelerometer and gyro rows of the same line), SI units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuRow {
    /// Time of the accelerometer sample, seconds.
    pub t_s: f64,
    /// Specific force, m/s^2.
    pub accel_m_s2: [f64; 3],
    /// Angular rate, rad/s.
    pub gyro_rad_s: [f64; 3],
}

/// Standard gravity: the file's accelerometer is in g.
const G_M_S2: f64 = 9.80665;

/// One line of the measurement file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// Line number in the file.
    pub line: u64,
    /// The TDOA of this line, unless that stream has ended.
    pub tdoa: Option<TdoaRow>,
    /// The truth of this line, unless that stream has ended.
    pub truth: Option<TruthRow>,
    /// The IMU sample of this line (27-column layout only).
    pub imu: Option<ImuRow>,
}

/// Largest anchor coordinate accepted, metres: UWB anchors reach a few
/// hundred metres; a larger value is a unit or typing error, and squared
/// it would overflow every distance computed from it.
const MAX_ANCHOR_COORDINATE_M: f64 = 10_000.0;

/// The anchors of one constellation, by id, metres. Two layouts: the
/// extracts' `constellation,anchor_id,x,y,z` (then `constellation` is
/// needed) and the raw logs' `anchor_id,x_m,y_m,z_m,...` (one layout per
/// file, `constellation` must be `None`).
pub fn read_anchors(
    path: &Path,
    constellation: Option<u32>,
) -> Result<HashMap<u32, [f64; 3]>, InputError> {
    let with_constellation = ["constellation", "anchor_id", "x", "y", "z"];
    let single = ["anchor_id", "x_m", "y_m", "z_m"];
    let (mut reader, wanted) = match (Table::open(path, &with_constellation, false), constellation)
    {
        (Ok(t), Some(c)) => (t, Some(c)),
        (Ok(_), None) => {
            return Err(InputError::Malformed {
                path: path.to_owned(),
                line: 1,
                message: "the file has several constellations: give --constellation".into(),
            });
        }
        (Err(InputError::MissingColumn { .. }), None) => (Table::open(path, &single, false)?, None),
        (Err(e), _) => return Err(e),
    };
    let offset = usize::from(wanted.is_some());
    let mut anchors = HashMap::new();
    while let Some(fields) = reader.next_record()? {
        let line = reader.line();
        let c: Option<u32> = match wanted {
            Some(_) => Some(reader.parse(&fields, 0, line)?),
            None => None,
        };
        let id: u32 = reader.parse(&fields, offset, line)?;
        let p = [
            reader.number(&fields, offset + 1, line)?,
            reader.number(&fields, offset + 2, line)?,
            reader.number(&fields, offset + 3, line)?,
        ];
        if let Some(v) = p.iter().find(|v| v.abs() > MAX_ANCHOR_COORDINATE_M) {
            return Err(reader.malformed(
                line,
                format!(
                    "anchor {id}: coordinate {v:e} m is beyond {MAX_ANCHOR_COORDINATE_M} m: not an anchor of a flight volume"
                ),
            ));
        }
        if c == wanted && anchors.insert(id, p).is_some() {
            return Err(reader.malformed(line, format!("anchor {id} appears twice")));
        }
    }
    if anchors.is_empty() {
        return Err(InputError::Malformed {
            path: path.to_owned(),
            line: reader.line(),
            message: match wanted {
                Some(c) => format!("no anchor of constellation {c}"),
                None => "no anchor".into(),
            },
        });
    }
    Ok(anchors)
}

/// Which streams of the measurement file a reader parses: a replay reads
/// each stream with a reader of its own, so that each goes at its own
/// pace through the file (the streams share the row index, not the time).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Parts {
    /// The TDOA columns.
    pub tdoa: bool,
    /// The truth columns (and the orientation, when the file has it).
    pub truth: bool,
    /// The IMU columns, when the file has them.
    pub imu: bool,
}

impl Parts {
    /// Every stream.
    pub const ALL: Self = Self {
        tdoa: true,
        truth: true,
        imu: true,
    };
}

/// The measurement file, read one line at a time.
pub struct UtilReader {
    parts: Parts,
    table: Table,
    /// The optional columns, when the header has all of them.
    imu: Option<Table>,
    attitude: Option<Table>,
    last_tdoa_s: f64,
    /// TDOA rows since `t_tdoa` last advanced.
    tdoa_rows_at_last_s: u32,
    last_truth_s: f64,
}

/// Most TDOA rows stamped with one time: the flights never repeat a time
/// (at 450 rows/s with microsecond stamps), and a clock stuck for this
/// long would fill every estimator's window, a span of time, without end.
pub const MAX_ROWS_AT_ONE_TIME: u32 = 1000;

const DATA_COLUMNS: [&str; 8] = [
    "idA",
    "idB",
    "tdoa_meas",
    "t_tdoa",
    "pose_x",
    "pose_y",
    "pose_z",
    "t_pose",
];

const IMU_COLUMNS: [&str; 8] = [
    "t_acc", "acc_x", "acc_y", "acc_z", "t_gyro", "gyro_x", "gyro_y", "gyro_z",
];

const ATTITUDE_COLUMNS: [&str; 4] = ["pose_qx", "pose_qy", "pose_qz", "pose_qw"];

impl UtilReader {
    /// Opens `path` and checks its header.
    pub fn open(path: &Path) -> Result<Self, InputError> {
        Self::open_parts(path, Parts::ALL, false)
    }

    /// Opens `path` to read the streams `parts` (the others' fields are
    /// not looked at), with a progress bar when `progress` is set and
    /// the file is large.
    pub fn open_parts(path: &Path, parts: Parts, progress: bool) -> Result<Self, InputError> {
        let optional = |wanted: bool, columns: &[&'static str]| {
            if !wanted {
                return Ok(None);
            }
            match Table::open(path, columns, false) {
                Ok(t) => Ok(Some(t)),
                Err(InputError::MissingColumn { .. }) => Ok(None),
                Err(e) => Err(e),
            }
        };
        Ok(Self {
            parts,
            table: Table::open(path, &DATA_COLUMNS, progress)?,
            imu: optional(parts.imu, &IMU_COLUMNS)?,
            attitude: optional(parts.truth, &ATTITUDE_COLUMNS)?,
            last_tdoa_s: f64::NEG_INFINITY,
            tdoa_rows_at_last_s: 0,
            last_truth_s: f64::NEG_INFINITY,
        })
    }

    /// Whether the file has the IMU columns.
    pub fn has_imu(&self) -> bool {
        self.imu.is_some()
    }

    /// The file being read.
    pub fn path(&self) -> &Path {
        &self.table.path
    }

    /// The next line, `None` at the end of the file. The TDOA and truth
    /// streams must be in time order (the IMU's is screened later); a
    /// stream's fields are all present or all blank.
    pub fn next_row(&mut self) -> Result<Option<Row>, InputError> {
        let Some(f) = self.table.next_record()? else {
            return Ok(None);
        };
        let line = self.table.line();
        let t = &self.table;
        let tdoa = if !self.parts.tdoa || t.all_blank(&f, 0..4) {
            None
        } else {
            let row = TdoaRow {
                id_a: t.parse(&f, 0, line)?,
                id_b: t.parse(&f, 1, line)?,
                d_m: t.number(&f, 2, line)?,
                t_s: t.number(&f, 3, line)?,
            };
            if row.t_s < self.last_tdoa_s {
                return Err(t.malformed(line, "t_tdoa goes back in time".into()));
            }
            if row.t_s == self.last_tdoa_s {
                self.tdoa_rows_at_last_s += 1;
                if self.tdoa_rows_at_last_s >= MAX_ROWS_AT_ONE_TIME {
                    return Err(t.malformed(
                        line,
                        format!(
                            "t_tdoa has stayed at {} s for more than {MAX_ROWS_AT_ONE_TIME} rows: the clock is stuck",
                            row.t_s
                        ),
                    ));
                }
            } else {
                self.tdoa_rows_at_last_s = 0;
            }
            self.last_tdoa_s = row.t_s;
            Some(row)
        };
        let attitude = match &mut self.attitude {
            Some(a) => a.next_record()?,
            None => None,
        };
        let imu = match &mut self.imu {
            Some(i) => i.next_record()?,
            None => None,
        };
        let t = &self.table;
        let truth = if !self.parts.truth || t.all_blank(&f, 4..8) {
            None
        } else {
            let attitude_xyzw = match (&self.attitude, attitude) {
                (Some(a), Some(q)) => Some([
                    a.number(&q, 0, line)?,
                    a.number(&q, 1, line)?,
                    a.number(&q, 2, line)?,
                    a.number(&q, 3, line)?,
                ]),
                _ => None,
            };
            let row = TruthRow {
                t_s: t.number(&f, 7, line)?,
                position_m: [
                    t.number(&f, 4, line)?,
                    t.number(&f, 5, line)?,
                    t.number(&f, 6, line)?,
                ],
                attitude_xyzw,
            };
            if row.t_s < self.last_truth_s {
                return Err(t.malformed(line, "t_pose goes back in time".into()));
            }
            self.last_truth_s = row.t_s;
            Some(row)
        };
        // The accelerometer and the gyro are separate streams of nearly
        // equal length: a line where either has ended carries no sample.
        let imu = match (&self.imu, imu) {
            (Some(i), Some(v)) if !i.all_blank(&v, 0..4) && !i.all_blank(&v, 4..8) => {
                // NaN, infinite and out-of-order samples are screened and
                // counted downstream (`imu_input`), not fatal here.
                let n = |k| i.any_number(&v, k, line);
                Some(ImuRow {
                    t_s: n(0)?,
                    accel_m_s2: [n(1)? * G_M_S2, n(2)? * G_M_S2, n(3)? * G_M_S2],
                    gyro_rad_s: [n(5)?.to_radians(), n(6)?.to_radians(), n(7)?.to_radians()],
                })
            }
            _ => None,
        };
        Ok(Some(Row {
            line,
            tdoa,
            truth,
            imu,
        }))
    }
}

/// A CSV file with named columns, streamed record by record.
struct Table {
    path: PathBuf,
    reader: csv::Reader<Box<dyn Read>>,
    /// Position in the record of each wanted column, in the wanted order.
    index: Vec<usize>,
    names: Vec<&'static str>,
    record: csv::StringRecord,
}

impl Table {
    fn open(path: &Path, columns: &[&'static str], progress: bool) -> Result<Self, InputError> {
        let io = |source| InputError::Io {
            path: path.to_owned(),
            source,
        };
        let file = File::open(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        let bar = crate::tdoa_log::read::progress_for(progress, len, path);
        let counted = crate::tdoa_log::read::Counting::new(file, bar);
        let counted = super::line_limit::LineLimit::new(counted);
        let boxed: Box<dyn Read> = Box::new(std::io::BufReader::new(counted));
        let mut reader = csv::ReaderBuilder::new().flexible(true).from_reader(boxed);
        let header = reader.headers().map_err(|e| csv_error(path, e))?.clone();
        let mut index = Vec::with_capacity(columns.len());
        for &column in columns {
            match header.iter().position(|h| h.trim() == column) {
                Some(i) => index.push(i),
                None => {
                    return Err(InputError::MissingColumn {
                        path: path.to_owned(),
                        column,
                    });
                }
            }
        }
        Ok(Self {
            path: path.to_owned(),
            reader,
            index,
            names: columns.to_vec(),
            record: csv::StringRecord::new(),
        })
    }

    /// Line of the last record read.
    fn line(&self) -> u64 {
        self.record.position().map_or(1, |p| p.line())
    }

    /// The wanted fields of the next record, trimmed.
    fn next_record(&mut self) -> Result<Option<Vec<String>>, InputError> {
        let more = self
            .reader
            .read_record(&mut self.record)
            .map_err(|e| csv_error(&self.path, e))?;
        if !more {
            return Ok(None);
        }
        let line = self.line();
        let mut fields = Vec::with_capacity(self.index.len());
        for (&i, name) in self.index.iter().zip(&self.names) {
            match self.record.get(i) {
                Some(v) => fields.push(v.trim().to_owned()),
                None => {
                    return Err(self.malformed(line, format!("column `{name}` is missing")));
                }
            }
        }
        Ok(Some(fields))
    }

    fn all_blank(&self, fields: &[String], range: std::ops::Range<usize>) -> bool {
        fields[range].iter().all(|f| f.is_empty())
    }

    fn parse<T: std::str::FromStr>(
        &self,
        f: &[String],
        k: usize,
        line: u64,
    ) -> Result<T, InputError> {
        f[k].parse().map_err(|_| {
            self.malformed(
                line,
                format!("`{}` = `{}` is not a valid id", self.names[k], f[k]),
            )
        })
    }

    /// A number, NaN and infinities included.
    fn any_number(&self, f: &[String], k: usize, line: u64) -> Result<f64, InputError> {
        f[k].parse::<f64>().map_err(|_| {
            self.malformed(
                line,
                format!("`{}` = `{}` is not a number", self.names[k], f[k]),
            )
        })
    }

    /// A finite number.
    fn number(&self, f: &[String], k: usize, line: u64) -> Result<f64, InputError> {
        match f[k].parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(self.malformed(
                line,
                format!("`{}` = `{}` is not finite", self.names[k], f[k]),
            )),
            Err(_) => Err(self.malformed(
                line,
                format!("`{}` = `{}` is not a number", self.names[k], f[k]),
            )),
        }
    }

    fn malformed(&self, line: u64, message: String) -> InputError {
        InputError::Malformed {
            path: self.path.clone(),
            line,
            message,
        }
    }
}

/// The reader's complaint in words (a binary file is not UTF-8 text; a
/// line has more fields than the header).
fn csv_error(path: &Path, e: csv::Error) -> InputError {
    let line = e.position().map_or(1, |p| p.line());
    let message = match e.kind() {
        csv::ErrorKind::Utf8 { err, .. } => format!(
            "field {} is not UTF-8 text (byte {} of the field): not a CSV file of this format",
            err.field() + 1,
            err.valid_up_to() + 1
        ),
        csv::ErrorKind::UnequalLengths {
            expected_len, len, ..
        } => format!("{len} fields where the header has {expected_len}"),
        _ => e.to_string(),
    };
    match e.into_kind() {
        csv::ErrorKind::Io(source) => InputError::Io {
            path: path.to_owned(),
            source,
        },
        _ => InputError::Malformed {
            path: path.to_owned(),
            line,
            message,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stuck_clock_is_refused_where_it_is_found() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("flight.csv");
        let mut text = DATA_COLUMNS.join(",");
        text.push('\n');
        for _ in 0..MAX_ROWS_AT_ONE_TIME + 5 {
            text.push_str("0,1,0.5,1.0,,,,\n");
        }
        std::fs::write(&path, text).unwrap();
        let mut reader = UtilReader::open(&path).unwrap();
        let mut rows = 0;
        let e = loop {
            match reader.next_row() {
                Ok(Some(_)) => rows += 1,
                Ok(None) => panic!("read to the end"),
                Err(e) => break e.to_string(),
            }
        };
        assert_eq!(rows, MAX_ROWS_AT_ONE_TIME);
        let line = MAX_ROWS_AT_ONE_TIME + 2;
        assert!(e.contains(&format!("flight.csv:{line}:")), "{e}");
        assert!(e.contains("the clock is stuck"), "{e}");
    }

    #[test]
    fn a_binary_file_is_refused_in_words() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("flight.csv");
        let mut bytes = DATA_COLUMNS.join(",").into_bytes();
        bytes.extend(b"\n1,2,0.5,");
        bytes.extend([0xff, 0xfe, 0x00, b'\n']);
        std::fs::write(&path, bytes).unwrap();
        let mut reader = UtilReader::open(&path).unwrap();
        let e = reader.next_row().err().unwrap().to_string();
        assert!(e.contains("flight.csv:2: field 4 is not UTF-8 text"), "{e}");
    }
}
