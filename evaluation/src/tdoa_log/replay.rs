//! `ickon replay tdoa`: a log of the format through the estimators, epoch
//! by epoch, scored against the truth as `ickon replay util` scores.

use std::time::{Duration, Instant};

use ickon_fusion::estimator::InitialPose;
use ickon_fusion::estimator::RangeDifferenceSample;
use ickon_fusion::estimator::flight::{CvFilter, ImuFilter};
use ickon_fusion::estimator::guard::FlightVolume;
use ickon_fusion::estimator::tdoa_ekf::TdoaEkf3dParams;
use nalgebra::Matrix3;

use super::TdoaArgs;
use super::cv_fix::CvFix;
use super::epoch::{EpochSolver, Units, Unsolved};
use super::epochs::Epochs;
use super::format::{Anchors, Arrival, Kind, Role};
use super::motion::{DeadReckoning, GroundRunner, ImuSlot};
use super::offset::{self, Offset};
use super::read::LogError;
use super::rows::{MeasurementReader, TruthReader, read_anchors};
use crate::util::dataset::TruthRow as ScoredTruth;
use crate::util::estimators::{
    self, CvRunner, EkfRunner, ImuRunner, Overrides, Rejections, WindowRunner,
};
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
/// Estimators added in 2D by an odometry file: the ground robot's filter
/// and dead reckoning.
pub const NAMES_ODOMETRY: [&str; 2] = ["tdoa-ekf", "odometry"];
/// Estimator added in 3D by an IMU file.
pub const NAMES_IMU: [&str; 1] = ["imu-eskf"];

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
    /// Whether the odometry filters started at the truth's first pose.
    pub start_from_truth: bool,
    /// Whether a truth file was given.
    pub has_truth: bool,
    /// Estimators `all` left out, each with the reason.
    pub left_out: Vec<(&'static str, &'static str)>,
}

/// Why `all` leaves dead reckoning out without a start pose.
const NO_START: &str = "it starts at the truth's first pose: give a truth with `heading_rad`";

enum Runner {
    TdoaEkf(Box<CvRunner>),
    Ground(Box<GroundRunner>),
    DeadReckoning(Box<DeadReckoning>),
    Imu(Box<ImuSlot>),
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

/// What the replay starts from: the anchors, the volume, the truth
/// offset and start pose, the runners.
struct Setup {
    anchors: Anchors,
    units: Units,
    volume: FlightVolume,
    truth_offset: Option<Offset>,
    start: Option<(InitialPose, f64)>,
}

/// Replays the log of `args`.
pub fn replay(args: &TdoaArgs) -> Result<TdoaReplayed, LogError> {
    let (setup, reader) = set_up(args)?;
    let Setup {
        anchors,
        units,
        volume,
        truth_offset,
        start,
    } = setup;
    let (names, left_out) = selected(args, anchors.dim, start.is_some())?;
    let mut slots = make_slots(names, args, &anchors, units, volume, start)?;
    let mut solver = solver_for(&anchors, volume);
    let mut truth = match &args.truth {
        Some(path) => Some(TruthStream::open(
            path,
            anchors.dim,
            truth_offset.map_or(0.0, |o| o.offset_s),
            args.truth_max_gap_s,
        )?),
        None => None,
    };
    let mut epochs = Epochs::new(reader, &anchors, units);
    let mut rows: Vec<Arrival> = Vec::new();
    let (mut n_epochs, mut differences, mut ranges) = (0_u64, 0_u64, 0_u64);
    while epochs.next_epoch(&mut rows)? {
        n_epochs += 1;
        let samples = super::epoch::samples(&rows, &anchors, epochs.units());
        differences += samples.len() as u64;
        // A range row is a measurement of its own, beside the differences
        // the other rows give.
        ranges += rows.iter().filter(|a| a.kind == Kind::RangeM).count() as u64;
        let t0 = Instant::now();
        let fix = solver.solve(&rows, &anchors, epochs.units());
        let solve_wall = t0.elapsed();
        let epoch = Epoch {
            rows: &rows,
            samples: &samples,
            fix,
            anchors: &anchors,
            units: epochs.units(),
        };
        for slot in &mut slots {
            let t0 = Instant::now();
            step(slot, &epoch)?;
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
        finish(slot)?;
    }
    let span = epochs.span_s;
    let n_rows = epochs.rows;
    if let Some(t) = &mut truth {
        t.advance(f64::INFINITY, &mut slots)?;
        t.finish(&mut slots, span)?;
    }
    let duration_s = span.map_or(0.0, |(a, b)| b - a);
    let count = Counts {
        differences,
        epochs: n_epochs,
        unsolved: solver.unsolved.total(),
        first_s: span.map(|s| s.0),
        duration_s,
    };
    let reports = slots.iter().map(|s| slot_report(s, &count)).collect();
    Ok(TdoaReplayed {
        replayed: Replayed {
            measurements: differences + ranges,
            duration_s,
            volume,
            reports,
            tracks: slots.into_iter().map(|s| s.track).collect(),
            // A log's truth is taken as given: it comes from any system,
            // at any rate, with no top speed known to screen it by.
            truth_dropped: 0,
        },
        dim: anchors.dim,
        role: anchors.role,
        rows: n_rows,
        epochs: n_epochs,
        solved: solver.solved,
        unsolved: solver.unsolved,
        truth_offset,
        start_from_truth: start.is_some(),
        has_truth: args.truth.is_some(),
        left_out,
    })
}

/// Reads the anchors, checks the command line against them, opens the
/// measurements and finds the truth's offset and start pose.
fn set_up(args: &TdoaArgs) -> Result<(Setup, MeasurementReader), LogError> {
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
    if args.odometry.is_some() && anchors.dim == 3 {
        return Err(LogError::Usage(format!(
            "--odometry: {} is 3D; wheel odometry is read for 2D logs (a ground robot), a 3D log takes --imu",
            args.anchors.display()
        )));
    }
    if args.imu.is_some() && anchors.dim == 2 {
        return Err(LogError::Usage(format!(
            "--imu: {} is 2D; the IMU filter is 3D (a 2D ground robot takes --odometry)",
            args.anchors.display()
        )));
    }
    let reader = MeasurementReader::open(&args.measurements)?;
    let units = Units {
        speed_m_s: args.speed_m_s.or(reader.meta().propagation_speed_m_s),
        default_sigma_m: args.sigma_m,
    };
    let volume = volume_of(&anchors)
        .map_err(|e| LogError::Usage(format!("{}: {e}", args.anchors.display())))?;
    let mut truth_offset = None;
    let mut start = None;
    if let Some(path) = &args.truth {
        let truth = TruthReader::open(path, anchors.dim)?;
        let same_clock = match (&reader.meta().clock, &truth.meta().clock) {
            (Some(a), Some(b)) => a == b,
            _ => true,
        };
        if !same_clock {
            truth_offset = Some(estimate_offset(args, &anchors, units, volume, truth)?);
        }
        if args.odometry.is_some() {
            let offset_s = truth_offset.map_or(0.0, |o| o.offset_s);
            start = start_pose(path, anchors.dim, offset_s)?;
        }
    }
    let setup = Setup {
        anchors,
        units,
        volume,
        truth_offset,
        start,
    };
    Ok((setup, reader))
}

/// The volume the mobile is kept in: the anchors' box with a margin (in
/// 2D, the plane's).
pub(super) fn volume_of(anchors: &Anchors) -> Result<FlightVolume, String> {
    let mut positions = anchors.positions();
    if anchors.dim == 2 {
        // In 2D the mobile stays in its plane: the volume is the plane's.
        positions.iter_mut().for_each(|p| p[2] = anchors.plane_z_m);
    }
    FlightVolume::around(&positions, VOLUME_MARGIN_M).map_err(|e| e.to_string())
}

/// The per-epoch least-squares solver of `anchors` in `volume`.
pub(super) fn solver_for(anchors: &Anchors, volume: FlightVolume) -> EpochSolver {
    EpochSolver::new(
        anchors.dim,
        anchors.plane_z_m,
        (volume.min_m, volume.max_m),
        anchors.centroid(),
        anchors.role == Role::Receiver,
    )
}

/// The truth's first pose, on the measurements' clock, when it has a
/// heading: where `ickon replay plaza` starts its filter (as a guess the
/// filter checks) and dead reckoning.
fn start_pose(
    path: &std::path::Path,
    dim: usize,
    offset_s: f64,
) -> Result<Option<(InitialPose, f64)>, LogError> {
    let mut reader = TruthReader::open(path, dim)?;
    let Some(first) = reader.next_row()? else {
        return Ok(None);
    };
    Ok(first.heading_rad.map(|theta_rad| {
        let pose = InitialPose {
            x_m: first.position_m[0],
            y_m: first.position_m[1],
            theta_rad,
            sigma_xy_m: crate::plaza::START_SIGMA_XY_M,
            sigma_theta_rad: crate::plaza::START_SIGMA_THETA_DEG.to_radians(),
        };
        (pose, first.t_s + offset_s)
    }))
}

/// One slot per estimator named, each with its runner and its track.
fn make_slots(
    names: Vec<&'static str>,
    args: &TdoaArgs,
    anchors: &Anchors,
    units: Units,
    volume: FlightVolume,
    start: Option<(InitialPose, f64)>,
) -> Result<Vec<Slot>, LogError> {
    names
        .into_iter()
        .map(|name| {
            Ok(Slot {
                name,
                runner: runner(name, args, anchors, units, volume, start)?,
                track: if anchors.dim == 2 {
                    Track::new(args.plot.is_some()).planar()
                } else {
                    Track::new(args.plot.is_some())
                },
                wall: Duration::ZERO,
            })
        })
        .collect()
}

/// One epoch as the runners take it.
struct Epoch<'a> {
    rows: &'a [Arrival],
    samples: &'a [RangeDifferenceSample],
    fix: Option<(f64, [f64; 3], Matrix3<f64>)>,
    anchors: &'a Anchors,
    units: &'a Units,
}

/// Feeds one epoch to one estimator, queuing what it publishes.
fn step(slot: &mut Slot, e: &Epoch) -> Result<(), LogError> {
    let track = &mut slot.track;
    let mut push = |out: Option<(f64, [f64; 3])>, cov: Option<Matrix3<f64>>| {
        if let Some((t, p)) = out {
            track.push_with(t, p, cov);
        }
    };
    match &mut slot.runner {
        Runner::TdoaEkf(r) => e.samples.iter().for_each(|s| {
            let out = r.step(s);
            push(out, Some(r.covariance_m2()));
        }),
        Runner::CvEkf(r) => e.samples.iter().for_each(|s| {
            let out = r.step(s);
            push(out, r.covariance_m2());
        }),
        Runner::Window(r) => e.samples.iter().for_each(|s| push(r.step(s), None)),
        Runner::Imu(r) => {
            for s in e.samples {
                let out = r.step(s)?;
                push(out, Some(r.runner.covariance_m2()));
            }
        }
        Runner::CvFix(f) => {
            if let Some((t, p, cov)) = &e.fix {
                push(f.step(*t, *p, cov), None);
            }
        }
        Runner::Ls => push(e.fix.map(|(t, p, _)| (t, p)), e.fix.map(|(_, _, c)| c)),
        Runner::Ground(g) => step_ground(g, &mut slot.track, e)?,
        Runner::DeadReckoning(d) => {
            if let Some(last) = e.rows.last() {
                d.drive_until(last.t_s, &mut slot.track)?;
            }
        }
    }
    Ok(())
}

/// The ground filter over one epoch: ranges as ranges (their bias and
/// scale estimated), anything else as the chain of range differences the
/// MSU hands it ([`super::epoch::chain_samples`]), each after the
/// increments before it.
fn step_ground(g: &mut GroundRunner, track: &mut Track, e: &Epoch) -> Result<(), LogError> {
    if e.rows.iter().all(|a| a.kind == Kind::RangeM) {
        for a in e.rows {
            g.drive_until(a.t_s, track)?;
            let position = e.anchors.list[a.anchor].position_m;
            g.range(a.t_s, position, a.value, e.units.sigma_m(a));
        }
    } else {
        for s in &super::epoch::chain_samples(e.rows, e.anchors, e.units) {
            g.drive_until(s.t_s, track)?;
            g.difference(s);
        }
    }
    Ok(())
}

/// What is left at the end of the measurements: the window's last, the
/// increments after the last measurement.
fn finish(slot: &mut Slot) -> Result<(), LogError> {
    match &mut slot.runner {
        Runner::Window(r) => {
            if let Some((t, p)) = r.finish() {
                slot.track.push(t, p);
            }
        }
        Runner::Ground(g) => g.drive_until(f64::INFINITY, &mut slot.track)?,
        Runner::DeadReckoning(d) => d.drive_until(f64::INFINITY, &mut slot.track)?,
        _ => {}
    }
    Ok(())
}

/// The counts every report is a share of.
struct Counts {
    differences: u64,
    epochs: u64,
    unsolved: u64,
    first_s: Option<f64>,
    duration_s: f64,
}

fn slot_report(s: &Slot, c: &Counts) -> crate::util::EstimatorReport {
    let per_epoch = |gate: u64| Rejections {
        gate,
        other: c.unsolved,
        ..Rejections::default()
    };
    let (measurements, rejected, first) = match &s.runner {
        Runner::TdoaEkf(r) => (c.differences, r.rejections, r.first_published_s),
        Runner::Imu(r) => (
            c.differences,
            r.runner.rejections,
            r.runner.first_published_s,
        ),
        Runner::CvEkf(r) => (c.differences, r.rejections, s.track.first_s()),
        Runner::Window(r) => (c.differences, r.rejections, s.track.first_s()),
        Runner::CvFix(f) => (c.epochs, per_epoch(f.gated), s.track.first_s()),
        Runner::Ls => (c.epochs, per_epoch(0), s.track.first_s()),
        Runner::Ground(g) => (
            g.used + g.rejected,
            Rejections {
                gate: g.rejected,
                ..Rejections::default()
            },
            s.track.first_s(),
        ),
        Runner::DeadReckoning(_) => (c.epochs, Rejections::default(), s.track.first_s()),
    };
    let mut r = report(
        s.name,
        &s.track,
        measurements,
        c.duration_s,
        rejected,
        s.wall,
    );
    r.output_began_s = first.zip(c.first_s).map(|(t, f)| t - f);
    match &s.runner {
        Runner::TdoaEkf(f) => r.guard = Some(f.counts()),
        Runner::Imu(f) => r.guard = Some(f.runner.counts()),
        Runner::CvEkf(f) => r.recoveries = f.recoveries(),
        Runner::CvFix(f) => r.recoveries = f.restarts,
        Runner::Ground(g) => r.recoveries = g.reinitialisations(),
        _ => {}
    }
    r
}

/// The estimators asked for, and those `all` leaves out for want of what
/// they need (dead reckoning without a start pose); asked for by name,
/// those fail in [`runner`] with the same reason.
type Selection = (Vec<&'static str>, Vec<(&'static str, &'static str)>);

fn selected(args: &TdoaArgs, dim: usize, has_start: bool) -> Result<Selection, LogError> {
    let mut names: Vec<&'static str> = Vec::new();
    if dim == 2 {
        if args.odometry.is_some() {
            names.extend(NAMES_ODOMETRY);
        }
        names.extend(NAMES_2D);
    } else {
        names.extend(&NAMES_3D[..1]);
        if args.imu.is_some() {
            names.extend(NAMES_IMU);
        }
        names.extend(&NAMES_3D[1..]);
    }
    if args.estimator == "all" {
        let mut left_out = Vec::new();
        if !has_start && names.contains(&"odometry") {
            names.retain(|n| *n != "odometry");
            left_out.push(("odometry", NO_START));
        }
        return Ok((names, left_out));
    }
    let mut out = Vec::new();
    for want in args.estimator.split(',').map(str::trim) {
        match names.iter().find(|n| **n == want) {
            Some(n) => out.push(*n),
            None => {
                return Err(LogError::Usage(format!(
                    "--estimator `{want}`: in {dim}D with these files the estimators are {} (or `all`)",
                    names.join(", ")
                )));
            }
        }
    }
    Ok((out, Vec::new()))
}

fn runner(
    name: &str,
    args: &TdoaArgs,
    anchors: &Anchors,
    units: Units,
    volume: FlightVolume,
    start: Option<(InitialPose, f64)>,
) -> Result<Runner, LogError> {
    let start_m = anchors.centroid();
    let usage = |e: String| LogError::Usage(format!("{name}: {e}"));
    Ok(match (name, anchors.dim) {
        ("tdoa-ekf", 2) => {
            let path = args
                .odometry
                .as_deref()
                .ok_or_else(|| usage("needs --odometry".into()))?;
            let mut params = crate::plaza::wheel_params(start.map(|s| s.0), args.odometry_fraction);
            params.receiver_height_m = anchors.plane_z_m;
            if !units.carried_by_air() {
                params.sensors = params.sensors.without_air();
            }
            Runner::Ground(Box::new(GroundRunner::new(
                path,
                &params,
                start.map(|s| s.1),
            )?))
        }
        ("odometry", _) => {
            let path = args
                .odometry
                .as_deref()
                .ok_or_else(|| usage("needs --odometry".into()))?;
            let (pose, t_s) = start.ok_or_else(|| usage(format!("dead reckoning: {NO_START}")))?;
            Runner::DeadReckoning(Box::new(DeadReckoning::new(path, pose, t_s)?))
        }
        ("imu-eskf", _) => {
            let path = args
                .imu
                .as_deref()
                .ok_or_else(|| usage("needs --imu".into()))?;
            let params = estimators::util_imu_params(
                args.imu_lever_arm_m.0,
                args.initial_yaw_deg.to_radians(),
                Overrides {
                    shadow_m: Some(args.shadow_m),
                    ..Overrides::default()
                },
            );
            let filter = ImuFilter::new(params).map_err(|e| usage(e.to_string()))?;
            let runner = ImuRunner::new(filter, volume, estimators::util_guard_params());
            Runner::Imu(Box::new(ImuSlot::new(runner, path)?))
        }
        ("tdoa-ekf", _) => {
            let params = estimators::util_cv_params(Overrides {
                shadow_m: Some(args.shadow_m),
                accel_psd_m2_s3: Some(args.accel_psd_m2_s3),
                ..Overrides::default()
            });
            let f = CvFilter::new(params).map_err(|e| usage(e.to_string()))?;
            Runner::TdoaEkf(Box::new(CvRunner::new(
                f,
                volume,
                estimators::util_guard_params(),
            )))
        }
        ("cv-ekf", _) => Runner::CvEkf(EkfRunner::new(
            TdoaEkf3dParams {
                accel_psd_m2_s3: args.accel_psd_m2_s3,
                ..estimators::baseline_params()
            },
            start_m,
        )),
        ("window-gn", _) => Runner::Window(WindowRunner::with_sigma(start_m, args.sigma_m)),
        ("cv-fix", _) => Runner::CvFix(CvFix::new(args.accel_psd_m2_s3)),
        _ => Runner::Ls,
    })
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
    let mut solver = solver_for(anchors, volume);
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
    fn open(
        path: &std::path::Path,
        dim: usize,
        offset_s: f64,
        max_gap_s: f64,
    ) -> Result<Self, LogError> {
        Ok(Self {
            reader: TruthReader::open(path, dim)?,
            truth: Truth::new([0.0; 3]).with_max_gap_s(max_gap_s),
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
