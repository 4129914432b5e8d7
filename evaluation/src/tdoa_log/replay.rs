//! `ickon replay tdoa`: a log of the format through the estimators, epoch
//! by epoch, scored against the truth as `ickon replay util` scores.

use std::time::{Duration, Instant};

use ickon_fusion::estimator::flight::CvFilter;
use ickon_fusion::estimator::guard::FlightVolume;
use ickon_fusion::estimator::tdoa_ekf::TdoaEkf3dParams;
use nalgebra::Matrix3;

use super::TdoaArgs;
use super::cv_fix::CvFix;
use super::epoch::{EpochSolver, Units, Unsolved};
use super::epochs::Epochs;
use super::format::{Anchors, Arrival, Role};
use super::offset::{self, Offset};
use super::read::LogError;
use super::rows::{MeasurementReader, TruthReader, read_anchors};
use crate::util::dataset::TruthRow as ScoredTruth;
use crate::util::estimators::{self, CvRunner, EkfRunner, Overrides, Rejections, WindowRunner};
use crate::util::run::{Replayed, report};
use crate::util::score::{Track, Truth};

/// Margin of the volume around the anchors' box, metres (as for UTIL:
/// a mobile inside the anchors' box, half a metre of slack).
const VOLUME_MARGIN_M: f64 = 0.5;

/// Truth read ahead of the newest estimate, seconds: estimates wait for
/// the truth after them before they are scored.
const TRUTH_LEAD_S: f64 = 0.5;

/// Estimators `ickon replay tdoa` runs in 3D, in the order printed; the
/// per-epoch least-squares baseline `ls` last.
pub const NAMES_3D: [&str; 5] = ["tdoa-ekf", "cv-ekf", "window-gn", "cv-fix", "ls"];
/// The same in 2D: the guarded filter's placement and the window solver
/// are 3D only, and the plain filter fed the differences of an epoch one
/// at a time, in the plane, lost the emitter of the generated microphone
/// network for good.
pub const NAMES_2D: [&str; 2] = ["cv-fix", "ls"];

/// Everything a replay produced.
pub struct TdoaReplayed {
    /// The tables' content, as `ickon replay util` prints it.
    pub replayed: Replayed,
    /// The anchors' dimension and role.
    pub dim: usize,
    /// Fixed transmitters or fixed receivers.
    pub role: Role,
    /// Rows of the measurements file.
    pub rows: u64,
    /// Epochs.
    pub epochs: u64,
    /// Epochs the least-squares solver fixed.
    pub solved: u64,
    /// Epochs it did not, by reason.
    pub unsolved: Unsolved,
    /// The truth clock's offset, when it was estimated.
    pub truth_offset: Option<Offset>,
    /// Whether a truth file was given.
    pub has_truth: bool,
}

enum Runner {
    TdoaEkf(Box<CvRunner>),
    CvEkf(EkfRunner),
    Window(WindowRunner),
    CvFix(CvFix),
    Ls,
}

struct Slot {
    name: &'static str,
    runner: Runner,
    track: Track,
    wall: Duration,
}

/// Replays the log of `args`.
pub fn replay(args: &TdoaArgs) -> Result<TdoaReplayed, LogError> {
    let anchors = read_anchors(&args.anchors)?;
    if let Some(dim) = args.dim
        && usize::from(dim) != anchors.dim
    {
        return Err(LogError::Usage(format!(
            "--dim {dim}, but {} is {}D (it {} a `z_m` column): 2D and 3D do not mix",
            args.anchors.display(),
            anchors.dim,
            if anchors.dim == 3 { "has" } else { "has no" }
        )));
    }
    let names = selected(args, anchors.dim)?;
    let reader = MeasurementReader::open(&args.measurements)?;
    let units = Units {
        speed_m_s: args.speed_m_s.or(reader.meta().propagation_speed_m_s),
        default_sigma_m: args.sigma_m,
    };
    let positions = anchors.positions();
    let volume = FlightVolume::around(&positions, VOLUME_MARGIN_M)
        .map_err(|e| LogError::Usage(format!("{}: {e}", args.anchors.display())))?;
    let truth_offset = match &args.truth {
        Some(path) => {
            let truth = TruthReader::open(path, anchors.dim)?;
            let same_clock = match (&reader.meta().clock, &truth.meta().clock) {
                (Some(a), Some(b)) => a == b,
                _ => true,
            };
            if same_clock {
                None
            } else {
                Some(estimate_offset(args, &anchors, units, volume, truth)?)
            }
        }
        None => None,
    };
    let mut slots: Vec<Slot> = names
        .iter()
        .map(|&name| Slot {
            name,
            runner: runner(name, args, &anchors, volume),
            track: Track::new(args.plot.is_some()),
            wall: Duration::ZERO,
        })
        .collect();
    let mut solver = EpochSolver::new(
        anchors.dim,
        (volume.min_m, volume.max_m),
        anchors.centroid(),
        anchors.role == Role::Receiver,
    );
    let mut truth = match &args.truth {
        Some(path) => Some(TruthStream::open(
            path,
            anchors.dim,
            truth_offset.map_or(0.0, |o| o.offset_s),
        )?),
        None => None,
    };
    let mut epochs = Epochs::new(reader, &anchors, units);
    let mut rows: Vec<Arrival> = Vec::new();
    let (mut n_epochs, mut differences) = (0_u64, 0_u64);
    while epochs.next_epoch(&mut rows)? {
        n_epochs += 1;
        let samples = super::epoch::samples(&rows, &anchors, epochs.units());
        differences += samples.len() as u64;
        let t0 = Instant::now();
        let fix = solver.solve(&rows, &anchors, epochs.units());
        let solve_wall = t0.elapsed();
        for slot in &mut slots {
            let t0 = Instant::now();
            let track = &mut slot.track;
            let mut push = |out: Option<(f64, [f64; 3])>, cov: Option<Matrix3<f64>>| {
                if let Some((t, p)) = out {
                    track.push_with(t, p, cov);
                }
            };
            match &mut slot.runner {
                Runner::TdoaEkf(r) => samples.iter().for_each(|s| {
                    let out = r.step(s);
                    push(out, Some(r.covariance_m2()));
                }),
                Runner::CvEkf(r) => samples.iter().for_each(|s| {
                    let out = r.step(s);
                    push(out, r.covariance_m2());
                }),
                Runner::Window(r) => samples.iter().for_each(|s| push(r.step(s), None)),
                Runner::CvFix(f) => {
                    if let Some((t, p, cov)) = &fix {
                        push(f.step(*t, *p, cov), None);
                    }
                }
                Runner::Ls => push(fix.map(|(t, p, _)| (t, p)), fix.map(|(_, _, c)| c)),
            }
            slot.wall += t0.elapsed();
            if matches!(slot.runner, Runner::Ls | Runner::CvFix(_)) {
                slot.wall += solve_wall;
            }
        }
        if let (Some(t), Some(last)) = (&mut truth, rows.last()) {
            t.advance(last.t_s + TRUTH_LEAD_S, &mut slots)?;
        }
    }
    for slot in &mut slots {
        if let Runner::Window(r) = &mut slot.runner
            && let Some((t, p)) = r.finish()
        {
            slot.track.push(t, p);
        }
    }
    let span = epochs.span_s;
    let n_rows = epochs.rows;
    if let Some(t) = &mut truth {
        t.advance(f64::INFINITY, &mut slots)?;
        t.finish(&mut slots, span)?;
    }
    let (first_s, duration_s) = span.map_or((None, 0.0), |(a, b)| (Some(a), b - a));
    let began = |t: Option<f64>| t.zip(first_s).map(|(t, f)| t - f);
    let reports = slots
        .iter()
        .map(|s| {
            let (measurements, rejected, first) = match &s.runner {
                Runner::TdoaEkf(r) => (differences, r.rejections, r.first_published_s),
                Runner::CvEkf(r) => (differences, r.rejections, s.track.first_s()),
                Runner::Window(r) => (differences, r.rejections, s.track.first_s()),
                Runner::CvFix(f) => (
                    n_epochs,
                    Rejections {
                        gate: f.gated,
                        other: solver.unsolved.total(),
                        ..Rejections::default()
                    },
                    s.track.first_s(),
                ),
                Runner::Ls => (
                    n_epochs,
                    Rejections {
                        other: solver.unsolved.total(),
                        ..Rejections::default()
                    },
                    s.track.first_s(),
                ),
            };
            let mut r = report(s.name, &s.track, measurements, duration_s, rejected, s.wall);
            r.output_began_s = began(first);
            if let Runner::TdoaEkf(f) = &s.runner {
                r.guard = Some(f.counts());
            }
            if let Runner::CvEkf(f) = &s.runner {
                r.recoveries = f.recoveries();
            }
            if let Runner::CvFix(f) = &s.runner {
                r.recoveries = f.restarts;
            }
            r
        })
        .collect();
    Ok(TdoaReplayed {
        replayed: Replayed {
            measurements: differences,
            duration_s,
            volume,
            reports,
            tracks: slots.into_iter().map(|s| s.track).collect(),
        },
        dim: anchors.dim,
        role: anchors.role,
        rows: n_rows,
        epochs: n_epochs,
        solved: solver.solved,
        unsolved: solver.unsolved,
        truth_offset,
        has_truth: args.truth.is_some(),
    })
}

fn selected(args: &TdoaArgs, dim: usize) -> Result<Vec<&'static str>, LogError> {
    let names: &[&'static str] = if dim == 2 { &NAMES_2D } else { &NAMES_3D };
    if args.estimator == "all" {
        return Ok(names.to_vec());
    }
    let mut out = Vec::new();
    for want in args.estimator.split(',').map(str::trim) {
        match names.iter().find(|n| **n == want) {
            Some(n) => out.push(*n),
            None => {
                return Err(LogError::Usage(format!(
                    "--estimator `{want}`: in {dim}D the estimators are {} (or `all`)",
                    names.join(", ")
                )));
            }
        }
    }
    Ok(out)
}

fn runner(name: &str, args: &TdoaArgs, anchors: &Anchors, volume: FlightVolume) -> Runner {
    let start_m = anchors.centroid();
    match name {
        "tdoa-ekf" => {
            let params = estimators::util_cv_params(Overrides {
                shadow_m: Some(args.shadow_m),
                accel_psd_m2_s3: Some(args.accel_psd_m2_s3),
                ..Overrides::default()
            });
            match CvFilter::new(params) {
                Ok(f) => Runner::TdoaEkf(Box::new(CvRunner::new(
                    f,
                    volume,
                    estimators::util_guard_params(),
                ))),
                // The defaults with a checked shadow are valid.
                Err(_) => Runner::Ls,
            }
        }
        "cv-ekf" => Runner::CvEkf(EkfRunner::new(
            TdoaEkf3dParams {
                accel_psd_m2_s3: args.accel_psd_m2_s3,
                ..estimators::baseline_params()
            },
            start_m,
        )),
        "window-gn" => Runner::Window(WindowRunner::with_sigma(start_m, args.sigma_m)),
        "cv-fix" => Runner::CvFix(CvFix::new(args.accel_psd_m2_s3)),
        _ => Runner::Ls,
    }
}

/// The first [`offset::SEARCH_SPAN_S`] of fixes against the truth of the
/// same span (give or take the largest offset).
fn estimate_offset(
    args: &TdoaArgs,
    anchors: &Anchors,
    units: Units,
    volume: FlightVolume,
    mut truth: TruthReader,
) -> Result<Offset, LogError> {
    let reader = MeasurementReader::open(&args.measurements)?;
    let mut epochs = Epochs::new(reader, anchors, units);
    let mut solver = EpochSolver::new(
        anchors.dim,
        (volume.min_m, volume.max_m),
        anchors.centroid(),
        anchors.role == Role::Receiver,
    );
    let mut rows = Vec::new();
    let mut fixes = Vec::new();
    while epochs.next_epoch(&mut rows)? {
        let first = epochs.span_s.map_or(0.0, |s| s.0);
        if rows[0].t_s - first > offset::SEARCH_SPAN_S {
            break;
        }
        fixes.extend(
            solver
                .solve(&rows, anchors, epochs.units())
                .map(|(t, p, _)| (t, p)),
        );
    }
    let (Some(t0), Some(t1)) = (fixes.first().map(|f| f.0), fixes.last().map(|f| f.0)) else {
        return Err(truth.time_error(
            "its clock differs from the measurements' and no epoch gave a fix to align them".into(),
        ));
    };
    let margin = offset::MAX_OFFSET_S + 0.1;
    let mut samples = Vec::new();
    while let Some(r) = truth.next_row()? {
        if r.t_s > t1 + margin {
            break;
        }
        if r.t_s >= t0 - margin {
            samples.push((r.t_s, r.position_m));
        }
    }
    offset::estimate(&fixes, &samples).ok_or_else(|| {
        truth.time_error(format!(
            "its clock differs from the measurements' and no offset within {} s brings it over the measurements ({t0:.3} to {t1:.3} s)",
            offset::MAX_OFFSET_S
        ))
    })
}

/// The truth file streamed beside the measurements, on their clock.
struct TruthStream {
    reader: TruthReader,
    truth: Truth,
    offset_s: f64,
    next: Option<ScoredTruth>,
    span_s: Option<(f64, f64)>,
    ended: bool,
}

impl TruthStream {
    fn open(path: &std::path::Path, dim: usize, offset_s: f64) -> Result<Self, LogError> {
        Ok(Self {
            reader: TruthReader::open(path, dim)?,
            truth: Truth::new([0.0; 3]),
            offset_s,
            next: None,
            span_s: None,
            ended: false,
        })
    }

    /// Feeds the truth up to `until_s` (measurements' clock) to the tracks.
    fn advance(&mut self, until_s: f64, slots: &mut [Slot]) -> Result<(), LogError> {
        loop {
            if self.next.is_none() && !self.ended {
                match self.reader.next_row()? {
                    Some(r) => {
                        let t_s = r.t_s + self.offset_s;
                        self.span_s = Some(match self.span_s {
                            Some((a, _)) => (a, t_s),
                            None => (t_s, t_s),
                        });
                        self.next = Some(ScoredTruth {
                            t_s,
                            position_m: r.position_m,
                            attitude_xyzw: None,
                        });
                    }
                    None => self.ended = true,
                }
            }
            match self.next {
                Some(r) if r.t_s <= until_s => {
                    let mut tracks: Vec<&mut Track> =
                        slots.iter_mut().map(|s| &mut s.track).collect();
                    self.truth.push(r, &mut tracks);
                    self.next = None;
                }
                _ => return Ok(()),
            }
        }
    }

    /// Scores what is left, and refuses a truth that never overlaps the
    /// measurements' span.
    fn finish(&mut self, slots: &mut [Slot], measured: Option<(f64, f64)>) -> Result<(), LogError> {
        let mut tracks: Vec<&mut Track> = slots.iter_mut().map(|s| &mut s.track).collect();
        self.truth.finish(&mut tracks);
        match (self.span_s, measured) {
            (None, _) => Err(self.reader.time_error("the truth file has no row".into())),
            (Some((a, b)), Some((c, d))) if b < c || a > d => Err(self.reader.time_error(format!(
                "the truth ({a:.3} to {b:.3} s on the measurements' clock) never overlaps the measurements ({c:.3} to {d:.3} s)"
            ))),
            _ => Ok(()),
        }
    }
}
