//! `ickon convert util --to tdoa DIR`: a UTIL flight written in the log
//! format, so that `ickon replay tdoa` on it can be held against
//! `ickon replay util` on the original.
//!
//! Each UTIL range difference becomes one `tdoa_m` row (`anchor` = its
//! anchor B, `reference` = its anchor A, the UTIL sigma), grouped into
//! epochs of [`EPOCH_S`]; the truth is the antenna's position (the lever
//! arm applied as the UTIL replay applies it), on the same clock; with
//! `--imu`, the IMU samples the UTIL replay keeps (screened as it screens
//! them), in SI units.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use ickon_runtime::CommandError;

use super::format::{FORMAT, imu_columns};
use crate::util::dataset::{UtilReader, read_anchors};
use crate::util::estimators::{MEASUREMENT_SIGMA_M, WINDOW_S};
use crate::util::imu_input::Screen;

/// Length of an epoch of a converted UTIL flight, seconds: the window of
/// `window-gn`, several measurements per anchor pair.
pub const EPOCH_S: f64 = WINDOW_S;

/// The formats `ickon convert` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Target {
    /// The arrival-time log format (`docs/log-format.md`).
    Tdoa,
}

/// Arguments of `ickon convert util`.
#[derive(Debug, Args)]
pub struct ConvertUtilArgs {
    /// The UTIL measurement CSV (as for `ickon replay util`).
    #[arg(long)]
    pub data: PathBuf,
    /// The UTIL anchor CSV.
    #[arg(long)]
    pub anchors: PathBuf,
    /// Which anchor constellation the flight used.
    #[arg(long)]
    pub constellation: Option<u32>,
    /// Also write `imu.csv` (the file must have the IMU columns): replay
    /// it with `--imu` and the antenna's lever arm
    /// `--imu-lever-arm-m -0.01245,0.00127,0.0908`.
    #[arg(long)]
    pub imu: bool,
    /// The format to write.
    #[arg(long, value_enum)]
    pub to: Target,
    /// The directory to write `anchors.csv`, `measurements.csv` and
    /// `truth.csv` into (created; existing files are refused).
    pub dir: PathBuf,
}

/// Converts a UTIL flight.
pub fn run(args: &ConvertUtilArgs) -> Result<(), CommandError> {
    let Target::Tdoa = args.to;
    let anchors = read_anchors(&args.anchors, args.constellation)
        .map_err(|e| CommandError::bad_input(e.to_string()))?;
    let mut reader =
        UtilReader::open(&args.data).map_err(|e| CommandError::bad_input(e.to_string()))?;
    if args.imu && !reader.has_imu() {
        return Err(CommandError::bad_input(format!(
            "{}: --imu needs the IMU columns (t_acc, acc_*, t_gyro, gyro_*)",
            args.data.display()
        )));
    }
    std::fs::create_dir_all(&args.dir)
        .map_err(|e| CommandError::failure(format!("cannot create {}: {e}", args.dir.display())))?;
    let mut names = vec!["anchors.csv", "measurements.csv", "truth.csv"];
    let mut screen = args.imu.then(Screen::default);
    if args.imu {
        names.push("imu.csv");
    }
    let mut out = Writers::create_named(&args.dir, &names)?;
    let mut ids: Vec<_> = anchors.iter().collect();
    ids.sort_by_key(|(id, _)| **id);
    out.line(0, "# written by ickon convert util from UTIL anchors")?;
    out.line(0, "id,x_m,y_m,z_m,role")?;
    for (id, p) in ids {
        out.line(0, &format!("{id},{},{},{},transmitter", p[0], p[1], p[2]))?;
    }
    out.line(1, &format!("# format: {FORMAT}"))?;
    out.line(1, "# clock: tag")?;
    out.line(1, "# propagation_speed_m_s: 299792458")?;
    out.line(1, "epoch,time_s,anchor,reference,kind,value,sigma")?;
    out.line(2, "# clock: tag")?;
    out.line(2, "time_s,x_m,y_m,z_m")?;
    if screen.is_some() {
        out.line(3, "# clock: tag")?;
        let c = imu_columns::ACCEL.iter().chain(&imu_columns::GYRO);
        let names: Vec<&str> = std::iter::once(imu_columns::TIME)
            .chain(c.copied())
            .collect();
        out.line(3, &names.join(","))?;
    }
    let mut first_s = None;
    let mut rows = 0_u64;
    while let Some(row) = reader
        .next_row()
        .map_err(|e| CommandError::bad_input(e.to_string()))?
    {
        if let Some(m) = row.tdoa {
            let t0 = *first_s.get_or_insert(m.t_s);
            let epoch = ((m.t_s - t0) / EPOCH_S).floor() as u64;
            out.line(
                1,
                &format!(
                    "{epoch},{},{},{},tdoa_m,{},{MEASUREMENT_SIGMA_M}",
                    m.t_s, m.id_b, m.id_a, m.d_m
                ),
            )?;
            rows += 1;
        }
        if let Some(t) = row.truth {
            let p = crate::util::run::antenna(&t).position_m;
            out.line(2, &format!("{},{},{},{}", t.t_s, p[0], p[1], p[2]))?;
        }
        if let (Some(s), Some(imu)) = (&mut screen, row.imu)
            && let Some(kept) = s.push(imu)
        {
            imu_line(&mut out, &kept)?;
        }
    }
    if let Some(kept) = screen.as_mut().and_then(Screen::finish) {
        imu_line(&mut out, &kept)?;
    }
    out.flush()?;
    eprintln!(
        "{}: {rows} range differences written to {}",
        args.data.display(),
        args.dir.display()
    );
    if let Some(s) = &screen {
        eprintln!(
            "imu.csv: {} of {} IMU samples written ({} dropped as the UTIL replay drops them: {:?})",
            s.kept,
            s.read,
            s.dropped.total(),
            s.dropped
        );
    }
    Ok(())
}

/// Writes one IMU sample into `imu.csv` (file 3).
fn imu_line(out: &mut Writers, s: &crate::util::dataset::ImuRow) -> Result<(), CommandError> {
    let [ax, ay, az] = s.accel_m_s2;
    let [gx, gy, gz] = s.gyro_rad_s;
    out.line(3, &format!("{},{ax},{ay},{az},{gx},{gy},{gz}", s.t_s))
}

/// The files of the log, written in step.
pub struct Writers {
    files: Vec<(PathBuf, BufWriter<File>)>,
}

impl Writers {
    /// Creates `anchors.csv`, `measurements.csv`, `truth.csv` in `dir`,
    /// refusing to overwrite.
    pub fn create(dir: &Path) -> Result<Self, CommandError> {
        Self::create_named(dir, &["anchors.csv", "measurements.csv", "truth.csv"])
    }

    /// Creates the files `names` in `dir` (numbered in that order),
    /// refusing to overwrite.
    pub fn create_named(dir: &Path, names: &[&str]) -> Result<Self, CommandError> {
        let mut files = Vec::new();
        for name in names {
            let path = dir.join(name);
            let f = File::options()
                .write(true)
                .create_new(true)
                .open(&path)
                .map_err(|e| {
                    CommandError::failure(format!("cannot create {}: {e}", path.display()))
                })?;
            files.push((path, BufWriter::new(f)));
        }
        Ok(Self { files })
    }

    /// Writes one line into file `k` (with [`Self::create`]: 0 anchors, 1
    /// measurements, 2 truth).
    pub fn line(&mut self, k: usize, text: &str) -> Result<(), CommandError> {
        let (path, w) = &mut self.files[k];
        writeln!(w, "{text}")
            .map_err(|e| CommandError::failure(format!("cannot write {}: {e}", path.display())))
    }

    /// Flushes every file.
    pub fn flush(&mut self) -> Result<(), CommandError> {
        for (path, w) in &mut self.files {
            w.flush().map_err(|e| {
                CommandError::failure(format!("cannot write {}: {e}", path.display()))
            })?;
        }
        Ok(())
    }
}
