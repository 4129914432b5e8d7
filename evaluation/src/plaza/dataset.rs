//! Reading a CMU Plaza run (the README of the data's `plaza/` folder): four small
//! CSV files read whole and sorted by time. Columns are found by name in the header; every
//! problem is reported with the file and the line (1 = the header).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// What is wrong with a Plaza file; the text names the file and the line.
#[derive(Debug, thiserror::Error)]
pub enum PlazaError {
    /// The file cannot be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A line (or the header, line 1) is not what the format says.
    #[error("{}:{line}: {message}", path.display())]
    Malformed {
        /// The file.
        path: PathBuf,
        /// Line number, 1-based.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

/// One truth pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthRow {
    /// Time, seconds.
    pub t_s: f64,
    /// Position, metres.
    pub xy_m: [f64; 2],
    /// Heading, radians (Plaza2's points backwards, data README).
    pub heading_rad: f64,
}

/// One odometry increment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryRow {
    /// Time at the end of the increment, seconds.
    pub t_s: f64,
    /// Distance driven, metres.
    pub distance_m: f64,
    /// Heading change, radians.
    pub dtheta_rad: f64,
}

/// One radio range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeRow {
    /// Time, seconds.
    pub t_s: f64,
    /// Beacon id.
    pub beacon: u32,
    /// Measured range, metres.
    pub range_m: f64,
}

/// A whole run.
#[derive(Debug, Clone, PartialEq)]
pub struct PlazaRun {
    /// Truth, in time order.
    pub truth: Vec<TruthRow>,
    /// Odometry increments, in time order.
    pub odometry: Vec<OdometryRow>,
    /// Ranges, in time order.
    pub ranges: Vec<RangeRow>,
    /// Beacon positions by id, metres.
    pub beacons: HashMap<u32, [f64; 2]>,
}

/// Reads `gt.csv`, `odometry.csv`, `ranges.csv` and `beacons.csv` from `dir`.
pub fn read_run(dir: &Path) -> Result<PlazaRun, PlazaError> {
    let truth = rows(
        &dir.join("gt.csv"),
        &["t_s", "x_m", "y_m", "heading_rad"],
        |v| {
            Ok(TruthRow {
                t_s: v[0],
                xy_m: [v[1], v[2]],
                heading_rad: v[3],
            })
        },
    )?;
    let odometry = rows(
        &dir.join("odometry.csv"),
        &["t_s", "delta_distance_m", "delta_heading_rad"],
        |v| {
            Ok(OdometryRow {
                t_s: v[0],
                distance_m: v[1],
                dtheta_rad: v[2],
            })
        },
    )?;
    let ranges = rows(
        &dir.join("ranges.csv"),
        &["t_s", "beacon_id", "range_m"],
        |v| {
            if v[2] < 0.0 {
                return Err("a range cannot be negative".to_owned());
            }
            Ok(RangeRow {
                t_s: v[0],
                beacon: id(v[1])?,
                range_m: v[2],
            })
        },
    )?;
    let beacon_rows = rows(
        &dir.join("beacons.csv"),
        &["beacon_id", "x_m", "y_m"],
        |v| Ok((id(v[0])?, [v[1], v[2]])),
    )?;
    let beacons = beacon_rows.into_iter().collect();
    // The files hold a few stretches out of time order (Plaza1's ranges
    // jump back 64 s once): every stream is sorted, stably, on reading.
    let (mut truth, mut odometry, mut ranges) = (truth, odometry, ranges);
    truth.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    odometry.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    ranges.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    Ok(PlazaRun {
        truth,
        odometry,
        ranges,
        beacons,
    })
}

fn id(v: f64) -> Result<u32, String> {
    if v >= 0.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX) {
        Ok(v as u32)
    } else {
        Err(format!("`{v}` is not an id"))
    }
}

/// Parses the numeric `columns` (found by name) of every data line of
/// `path` and builds a row from them.
fn rows<T>(
    path: &Path,
    columns: &[&str],
    build: impl Fn(&[f64]) -> Result<T, String>,
) -> Result<Vec<T>, PlazaError> {
    let text = std::fs::read_to_string(path).map_err(|source| PlazaError::Io {
        path: path.to_owned(),
        source,
    })?;
    let bad = |line: usize, message: String| PlazaError::Malformed {
        path: path.to_owned(),
        line,
        message,
    };
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| bad(1, "the file is empty".to_owned()))?
        .split(',')
        .map(str::trim)
        .collect();
    let index: Vec<usize> = columns
        .iter()
        .map(|c| {
            header
                .iter()
                .position(|h| h == c)
                .ok_or_else(|| bad(1, format!("column `{c}` is missing from the header")))
        })
        .collect::<Result<_, _>>()?;
    let mut out = Vec::new();
    let mut values = vec![0.0; columns.len()];
    for (k, line) in lines.enumerate() {
        let n = k + 2;
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != header.len() {
            return Err(bad(
                n,
                format!("{} fields, the header has {}", fields.len(), header.len()),
            ));
        }
        for (slot, (&i, name)) in values.iter_mut().zip(index.iter().zip(columns)) {
            *slot = fields[i]
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(n, format!("`{}` is not a number ({name})", fields[i])))?;
        }
        out.push(build(&values).map_err(|m| bad(n, m))?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) {
        std::fs::write(dir.join(name), text).unwrap();
    }

    fn sample_dir(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("ickon-plaza-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        write(
            &dir,
            "gt.csv",
            "t_s,x_m,y_m,heading_rad\n0,0,0,0\n1,1,0,0\n",
        );
        write(
            &dir,
            "odometry.csv",
            "t_s,delta_distance_m,delta_heading_rad\n1,1,0\n",
        );
        write(
            &dir,
            "ranges.csv",
            "t_s,antenna_id,beacon_id,range_m\n0.5,2,5,3.0\n",
        );
        write(&dir, "beacons.csv", "beacon_id,x_m,y_m\n5,3,4\n");
        dir
    }

    #[test]
    fn a_small_run_reads_back() {
        let dir = sample_dir("ok");
        let run = read_run(&dir).unwrap();
        assert_eq!(run.truth.len(), 2);
        assert_eq!(run.ranges[0].beacon, 5);
        assert_eq!(run.beacons[&5], [3.0, 4.0]);
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_bad_number_names_the_file_and_line() {
        let dir = sample_dir("bad");
        write(
            &dir,
            "ranges.csv",
            "t_s,antenna_id,beacon_id,range_m\n0.5,2,5,3.0\n0.7,2,5,x\n",
        );
        let err = read_run(&dir).unwrap_err().to_string();
        assert!(
            err.ends_with("ranges.csv:3: `x` is not a number (range_m)"),
            "{err}"
        );
        write(&dir, "ranges.csv", "t_s,beacon_id\n");
        let err = read_run(&dir).unwrap_err().to_string();
        assert!(err.contains("ranges.csv:1: column `range_m`"), "{err}");
        std::fs::remove_dir_all(dir).unwrap();
    }
}
