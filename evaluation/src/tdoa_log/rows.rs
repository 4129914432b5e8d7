//! The three files of the log read row by row: the anchors whole (they
//! are few), the measurements and the truth as streams, each row checked
//! against the format and named by file, line and column when it is not.

use std::collections::HashMap;
use std::path::Path;

use super::format::{
    Anchor, Anchors, Arrival, Kind, Meta, Role, TruthRow, anchor_columns as ac,
    measurement_columns as mc, truth_columns as tc,
};
use super::read::{LineFile, LogError};

/// Largest coordinate accepted, metres: beyond, a unit or typing error.
const MAX_COORDINATE_M: f64 = 100_000.0;

/// Reads the anchors file whole (it is small), checking that every anchor
/// has the same dimension as the file and the same role.
pub fn read_anchors(path: &Path) -> Result<Anchors, LogError> {
    let mut f = LineFile::open(path)?;
    let id = f.required(ac::ID)?;
    let x = f.required(ac::X)?;
    let y = f.required(ac::Y)?;
    let z = f.column(ac::Z);
    let role = f.required(ac::ROLE)?;
    // Anchors with heights around a mobile held in one horizontal plane
    // (ceiling transmitters over a ground robot) make a 2D log too.
    let plane_z_m = f.meta.mobile_height_m;
    let dim = if z.is_some() && plane_z_m.is_none() {
        3
    } else {
        2
    };
    let mut anchors = Anchors {
        list: Vec::new(),
        by_id: HashMap::new(),
        dim,
        role: Role::Transmitter,
        plane_z_m: plane_z_m.unwrap_or(0.0),
    };
    while let Some(r) = f.next_fields()? {
        let name = f.present(&r, id)?.to_owned();
        let mut p = [f.number(&r, x)?, f.number(&r, y)?, 0.0];
        if let Some(z) = z {
            if f.field(&r, z).is_empty() {
                return Err(f.bad(
                    Some(z),
                    "is blank in a 3D file: every anchor needs a height, or none (2D)".into(),
                ));
            }
            p[2] = f.number(&r, z)?;
        }
        if let Some(k) = p.iter().position(|v| v.abs() > MAX_COORDINATE_M) {
            let col = [x, y, z.unwrap_or(x)][k];
            return Err(f.bad(
                Some(col),
                format!("{} m is beyond {MAX_COORDINATE_M} m: a unit error?", p[k]),
            ));
        }
        let this_role = match f.present(&r, role)? {
            "transmitter" => Role::Transmitter,
            "receiver" => Role::Receiver,
            other => {
                return Err(f.bad(
                    Some(role),
                    format!("`{other}` is neither `transmitter` nor `receiver`"),
                ));
            }
        };
        if anchors.list.is_empty() {
            anchors.role = this_role;
        } else if this_role != anchors.role {
            return Err(f.bad(
                Some(role),
                format!(
                    "`{}` after `{}`: every anchor of a log has the same role",
                    this_role.as_str(),
                    anchors.role.as_str()
                ),
            ));
        }
        if anchors.by_id.contains_key(&name) {
            return Err(f.bad(Some(id), format!("anchor `{name}` appears twice")));
        }
        anchors.by_id.insert(name.clone(), anchors.list.len());
        anchors.list.push(Anchor {
            id: name,
            position_m: p,
        });
    }
    if anchors.list.len() < dim + 1 {
        return Err(f.bad(
            None,
            format!(
                "{} anchors: a {dim}D position needs at least {}",
                anchors.list.len(),
                dim + 1
            ),
        ));
    }
    Ok(anchors)
}

/// The measurements file, one row at a time, ids looked up and order
/// checked.
pub struct MeasurementReader {
    file: LineFile,
    cols: [usize; 5],
    reference: Option<usize>,
    sigma: Option<usize>,
    last: Option<(u64, f64)>,
}

impl MeasurementReader {
    /// Opens `path` and checks its header and format line.
    pub fn open(path: &Path) -> Result<Self, LogError> {
        let file = LineFile::open(path)?;
        match file.meta.format.as_deref() {
            Some(super::format::FORMAT) => {}
            Some(other) => {
                return Err(LogError::Bad {
                    path: path.to_owned(),
                    line: 1,
                    column: None,
                    message: format!(
                        "format `{other}` is not one this version reads ({})",
                        super::format::FORMAT
                    ),
                });
            }
            None => {
                return Err(LogError::Bad {
                    path: path.to_owned(),
                    line: 1,
                    column: None,
                    message: format!(
                        "no `# format: {}` line before the header",
                        super::format::FORMAT
                    ),
                });
            }
        }
        let cols = [
            file.required(mc::EPOCH)?,
            file.required(mc::TIME)?,
            file.required(mc::ANCHOR)?,
            file.required(mc::KIND)?,
            file.required(mc::VALUE)?,
        ];
        Ok(Self {
            reference: file.column(mc::REFERENCE),
            sigma: file.column(mc::SIGMA),
            file,
            cols,
            last: None,
        })
    }

    /// The file's `#` lines.
    pub fn meta(&self) -> &Meta {
        &self.file.meta
    }

    /// The file.
    pub fn path(&self) -> &Path {
        self.file.path()
    }

    /// An error at `line` in the column called `column`.
    pub fn error(&self, line: u64, column: &str, message: String) -> LogError {
        let k = self.file.column(column);
        LogError::Bad {
            path: self.file.path().to_owned(),
            line,
            column: k.map(|k| (k + 1, column.to_owned())),
            message,
        }
    }

    /// The next row, `None` at the end.
    pub fn next(&mut self, anchors: &Anchors) -> Result<Option<Arrival>, LogError> {
        let [epoch_k, time_k, anchor_k, kind_k, value_k] = self.cols;
        let Some(r) = self.file.next_fields()? else {
            return Ok(None);
        };
        let f2 = &self.file;
        let epoch_text = f2.present(&r, epoch_k)?;
        let epoch: u64 = epoch_text.parse().map_err(|_| {
            f2.bad(
                Some(epoch_k),
                format!("`{epoch_text}` is not a non-negative integer"),
            )
        })?;
        let t_s = f2.number(&r, time_k)?;
        let lookup =
            |k: usize| -> Result<usize, LogError> {
                let id = f2.present(&r, k)?;
                anchors.by_id.get(id).copied().ok_or_else(|| {
                    f2.bad(Some(k), format!("anchor `{id}` is not in the anchors file"))
                })
            };
        let anchor = lookup(anchor_k)?;
        let kind_text = f2.present(&r, kind_k)?;
        let kind = Kind::parse(kind_text).ok_or_else(|| {
            f2.bad(
                Some(kind_k),
                format!("`{kind_text}` is not a kind (toa_s, tdoa_s, tdoa_m, range_m)"),
            )
        })?;
        let reference = match (kind.is_difference(), self.reference) {
            (true, Some(k)) => Some(lookup(k)?),
            (true, None) => {
                return Err(f2.bad(
                    Some(kind_k),
                    format!("`{kind_text}` needs the column `{}`", mc::REFERENCE),
                ));
            }
            (false, Some(k)) if !f2.field(&r, k).is_empty() => {
                return Err(f2.bad(Some(k), format!("must be blank for `{kind_text}`")));
            }
            (false, _) => None,
        };
        if reference == Some(anchor) {
            return Err(f2.bad(Some(anchor_k), "is its own reference".into()));
        }
        let value = f2.number(&r, value_k)?;
        let sigma = f2.optional_number(&r, self.sigma)?;
        if let (Some(s), Some(k)) = (sigma, self.sigma)
            && s <= 0.0
        {
            return Err(f2.bad(Some(k), format!("{s} is not positive")));
        }
        if let Some((last_epoch, last_t)) = self.last {
            if epoch < last_epoch {
                return Err(f2.bad(
                    Some(epoch_k),
                    format!("epoch {epoch} after epoch {last_epoch}: epochs must not decrease"),
                ));
            }
            if t_s < last_t {
                return Err(f2.bad(
                    Some(time_k),
                    format!("{t_s} s after {last_t} s: times go backwards"),
                ));
            }
        }
        self.last = Some((epoch, t_s));
        Ok(Some(Arrival {
            line: f2.line(),
            epoch,
            t_s,
            anchor,
            reference,
            kind,
            value,
            sigma,
        }))
    }
}

/// The truth file, one row at a time, in time order.
pub struct TruthReader {
    file: LineFile,
    cols: [usize; 3],
    z: Option<usize>,
    heading: Option<usize>,
    last_s: f64,
    first_line: u64,
}

impl TruthReader {
    /// Opens `path`; its dimension must be `dim`.
    pub fn open(path: &Path, dim: usize) -> Result<Self, LogError> {
        let file = LineFile::open(path)?;
        let cols = [
            file.required(tc::TIME)?,
            file.required(tc::X)?,
            file.required(tc::Y)?,
        ];
        let z = file.column(tc::Z);
        if z.is_some() != (dim == 3) {
            return Err(file.bad(
                z,
                format!(
                    "a {}D truth with {dim}D anchors: 2D and 3D do not mix",
                    if z.is_some() { 3 } else { 2 }
                ),
            ));
        }
        Ok(Self {
            heading: file.column(tc::HEADING),
            file,
            cols,
            z,
            last_s: f64::NEG_INFINITY,
            first_line: 0,
        })
    }

    /// The file's `#` lines.
    pub fn meta(&self) -> &Meta {
        &self.file.meta
    }

    /// The file.
    pub fn path(&self) -> &Path {
        self.file.path()
    }

    /// An error about the file's times as a whole, at its first data line.
    pub fn time_error(&self, message: String) -> LogError {
        LogError::Bad {
            path: self.file.path().to_owned(),
            line: self.first_line,
            column: Some((self.cols[0] + 1, tc::TIME.to_owned())),
            message,
        }
    }

    /// The next row, `None` at the end.
    pub fn next_row(&mut self) -> Result<Option<TruthRow>, LogError> {
        let Some(r) = self.file.next_fields()? else {
            return Ok(None);
        };
        if self.first_line == 0 {
            self.first_line = self.file.line();
        }
        let f = &self.file;
        let [t, x, y] = self.cols;
        let t_s = f.number(&r, t)?;
        if t_s < self.last_s {
            return Err(f.bad(
                Some(t),
                format!("{t_s} s after {} s: times go backwards", self.last_s),
            ));
        }
        self.last_s = t_s;
        let z_m = match self.z {
            Some(k) => f.number(&r, k)?,
            None => 0.0,
        };
        Ok(Some(TruthRow {
            t_s,
            position_m: [f.number(&r, x)?, f.number(&r, y)?, z_m],
            heading_rad: f.optional_number(&r, self.heading)?,
        }))
    }
}
