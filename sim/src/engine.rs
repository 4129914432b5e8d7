//! The virtual-time engine: the central unit's and the cells' own cores on
//! their drifting clocks ([`crate::control`]: triggers, synchronisation,
//! bursts), the world and one MSU core per estimator, all in one process on
//! a discrete event queue ordered by (time, sequence).
//! No sleeping, no network: ten tours of a route take seconds, and the same
//! seed gives the same numbers on any machine.

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};

use ickon_central::survey_calibration::CalibrationConfig;
use ickon_fusion::estimator::{self, EstimatorConfig, WheelGeometry};
use ickon_msu::{Event as MsuEvent, MsuConfig, MsuCore, MsuDriver};
use ickon_proto::msg::control::Schedule;
use ickon_proto::msg::robot::Fix;
use ickon_proto::site::Site;

use crate::air_sensor::CellAirSensors;
use crate::control::{CellSyncReport, ControlPlane};
use crate::profile::NoiseProfile;
use crate::world::{TruthSample, World};

/// Physics step, seconds.
pub const PHYSICS_DT_S: f64 = 0.005;
/// Wheel encoder / odometry rate, Hz.
pub const ENCODER_HZ: f64 = 50.0;
/// Obstacle sensor rate, Hz.
pub const RANGES_HZ: f64 = 10.0;
/// Seconds the robot stands still at the start (gyro calibration of the CDA paper).
pub const REST_S: f64 = 2.0;
/// Seconds between two samples of the plotted traces.
const TRACE_DT_S: f64 = 0.25;

/// What to run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunConfig {
    /// Route name.
    pub route: String,
    /// Tours to drive.
    pub tours: u32,
    /// Noise profile.
    pub profile: NoiseProfile,
    /// Run seed.
    pub seed: u64,
    /// Estimator names, all hosted by one MSU core (one solve per cycle).
    pub estimators: Vec<String>,
    /// The central unit's tuning (which schedule; every transmitter fires
    /// unless it says otherwise).
    pub central: ickon_central::core::CentralConfig,
    /// Filter options a user sets in the MSU configuration.
    pub filter: FilterOptions,
    /// Transmitters that fail during the run.
    pub transmitter_faults: Vec<crate::tx_faults::TransmitterFault>,
    /// Rows (arrivals, truth samples, odometry samples) to record for
    /// export ([`RunOutput::recording`]); 0 records nothing.
    pub record_rows: usize,
}

/// Options of the MSU's filter that a user turns on in its configuration
/// file, for the runs of `ickon eval`, `ickon sim` and `ickon bench scale`.
/// Default: the estimators' own defaults.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FilterOptions {
    /// `tdoa-ekf` learns each cell's sync error as a state
    /// (`[filter.params] learn_cell_sync = true`).
    pub learn_cell_sync: bool,
    /// `tdoa-ekf` (ground) carries the wind where the robot is as a state,
    /// with spread [`LOCAL_WIND_SIGMA_M_S`]
    /// (`[filter.params] sensors.local_wind_sigma_m_s`).
    pub local_wind: bool,
}

/// The spread of the local wind state that `--local-wind` sets, m/s: the
/// low end of real air handlers' drafts, chosen in decision 0151 on the
/// filter's corridor tests with a gyro bias step (wider spreads let the
/// wind hide part of a heading error).
pub const LOCAL_WIND_SIGMA_M_S: f64 = 0.5;

impl FilterOptions {
    /// Why these options cannot go with estimator `name`, if they cannot.
    pub fn check_for(&self, name: &str) -> Result<(), String> {
        for (on, flag) in [
            (self.learn_cell_sync, "--learn-cell-sync"),
            (self.local_wind, "--local-wind"),
        ] {
            if on && name != "tdoa-ekf" {
                return Err(format!(
                    "{flag} is an option of `tdoa-ekf`, not of `{name}`"
                ));
            }
        }
        Ok(())
    }
}

/// Why a run could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RunError {
    /// No route of that name in the site.
    #[error("unknown route `{name}` (known: {known})")]
    UnknownRoute {
        /// The name asked for.
        name: String,
        /// The site's route names.
        known: String,
    },
    /// An estimator name is not in the registry.
    #[error(transparent)]
    UnknownEstimator(#[from] estimator::UnknownEstimator),
    /// An estimator configuration is invalid.
    #[error(transparent)]
    InvalidEstimator(#[from] estimator::InvalidParameter),
    /// Zero tours asked for.
    #[error("at least one tour is needed")]
    NoTours,
    /// The site cannot be scheduled.
    #[error(transparent)]
    Schedule(#[from] ickon_central::ScheduleError),
    /// The MSU refused the control plane's schedule.
    #[error(transparent)]
    Msu(#[from] ickon_msu::MsuError),
    /// The MSU refused the control plane's first schedule.
    #[error("the MSU refused the schedule: {0}")]
    Refused(String),
    /// More robots asked for than the site has (or none).
    #[error("{asked} robots asked for: the site has {site} (give 1 to {site})")]
    FleetSize {
        /// How many were asked for.
        asked: usize,
        /// How many the site has.
        site: usize,
    },
}

/// The truth and every estimate when the robot passed one reference point.
#[derive(Debug, Clone, PartialEq)]
pub struct RefSample {
    /// Tour, from 1.
    pub tour: u32,
    /// Reference point index on the route, from 0.
    pub index: usize,
    /// True pose.
    pub truth: TruthSample,
    /// Per estimator (in [`RunConfig::estimators`] order): `x, y, theta`, or `None` before initialisation.
    pub estimates: Vec<Option<[f64; 3]>>,
    /// Per estimator, the position covariance it published with that
    /// estimate: `xx, xy, yy`, m^2.
    pub covariances: Vec<Option<[f64; 3]>>,
}

/// A raw fix with the truth at its own measurement time.
#[derive(Debug, Clone, PartialEq)]
pub struct FixRecord {
    /// The fix.
    pub fix: Fix,
    /// True pose at the fix's measurement time.
    pub truth: TruthSample,
    /// Positions of the transmitters used, metres.
    pub used_tx_m: Vec<[f64; 3]>,
    /// True time the fix became available (the cycle's arrivals were complete), seconds.
    pub available_s: f64,
}

/// One point of a plotted trace.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracePoint {
    /// Tour, from 1.
    pub tour: u32,
    /// Position, metres.
    pub xy_m: [f64; 2],
}

/// The speed of sound at one moment of a run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct AirSample {
    /// True time, seconds.
    pub t_s: f64,
    /// What a system that knew the air would use for the robot's paths:
    /// the mean over the transmitters within [`AIR_PATHS_M`] of the
    /// receiver of each path's effective speed, m/s (`None`: none that near).
    pub true_m_s: Option<f64>,
    /// What the MSU solved with, m/s.
    pub used_m_s: f64,
}

/// The paths the true speed of sound is averaged over, metres: those a
/// fix is made of.
pub const AIR_PATHS_M: f64 = 8.0;

/// Seconds between two samples of the air.
const AIR_DT_S: f64 = 1.0;

/// Everything a run recorded.
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutput {
    /// The configuration.
    pub config: RunConfig,
    /// Reference point passages, in time order.
    pub refs: Vec<RefSample>,
    /// Raw fixes.
    pub fixes: Vec<FixRecord>,
    /// True path, sampled.
    pub truth_trace: Vec<TracePoint>,
    /// Per estimator, its path, sampled.
    pub estimate_traces: Vec<Vec<TracePoint>>,
    /// Reference points per tour.
    pub refs_per_tour: usize,
    /// The schedule that ran.
    pub schedule: Schedule,
    /// Virtual seconds simulated.
    pub virtual_s: f64,
    /// The MSU's assumed timing noise (sigma of an arrival), seconds.
    pub timing_sigma_s: f64,
    /// Each cell's synchronisation, from its own core's bursts.
    pub cells: Vec<CellSyncReport>,
    /// What collisions and reverberation did to the robot's detections.
    pub collisions: crate::collision::CollisionCounts,
    /// Inputs the MSU core refused, by kind, with the first reason (`None`:
    /// none was).
    pub refused_inputs: Option<String>,
    /// The speed of sound the MSU used against the air's, every second.
    pub air: Vec<AirSample>,
    /// The arrivals, truth and odometry, when [`RunConfig::record_rows`]
    /// asked for them.
    pub recording: Option<crate::recording::Recording>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Event {
    Physics,
    Gyro,
    Encoders,
    Ranges,
    Deliver(u64),
    Trace,
}

/// Event queue ordered by (time in ns, insertion sequence).
#[derive(Default)]
struct Queue {
    heap: BinaryHeap<Reverse<(i64, u64, Event)>>,
    seq: u64,
}

impl Queue {
    fn push(&mut self, t_s: f64, e: Event) {
        self.seq += 1;
        self.heap
            .push(Reverse(((t_s * 1e9).round() as i64, self.seq, e)));
    }
    fn pop(&mut self) -> Option<(f64, Event)> {
        self.heap
            .pop()
            .map(|Reverse((t, _, e))| (t as f64 * 1e-9, e))
    }
}

/// The estimator configuration used for `name` on a robot of `site` starting
/// at `start`: the MSU agent's own set-up ([`ickon_msu::estimator_for_site`]:
/// registry defaults, start pose, receiver height and floor for `tdoa-ekf`),
/// then the gyro noise of the profile's data sheet for `gyro-ckf` and
/// `tdoa-ekf` (as a user configures a filter to the sensor on the robot;
/// small floors keep `ideal` valid), and the CDA paper's curvature thresholds
/// rescaled from their 10 Hz steps to [`ENCODER_HZ`]; last, `options`
/// (those that do not apply to `name` are left out: check them with
/// [`FilterOptions::check_for`]).
pub fn estimator_config(
    name: &str,
    start: [f64; 3],
    site: &Site,
    profile: &NoiseProfile,
    options: FilterOptions,
) -> Result<EstimatorConfig, RunError> {
    let mut c = ickon_msu::estimator_for_site(name, site, start)?;
    let per_step = 10.0 / ENCODER_HZ;
    let g = &profile.gyro;
    match &mut c {
        EstimatorConfig::Odometry(_)
        | EstimatorConfig::MsuRaw(_)
        | EstimatorConfig::IckonAkf(_) => {}
        EstimatorConfig::GyroCkf(p) => {
            p.gyro_noise_deg_sqrt_s = (g.white_sigma_deg_s / g.rate_hz.max(1.0).sqrt()).max(0.002);
            p.bias_walk_deg_s_sqrt_s = g.bias_walk_deg_s_sqrt_s.max(0.001);
            p.initial_bias_sigma_deg_s = g.bias_sigma_deg_s.max(0.05);
        }
        EstimatorConfig::Cda(p) => {
            p.mu_start_deg *= per_step;
            p.mu_stop_deg *= per_step;
        }
        EstimatorConfig::CdaMsu(p) => {
            p.cda.mu_start_deg *= per_step;
            p.cda.mu_stop_deg *= per_step;
        }
        EstimatorConfig::TdoaEkf(p) => {
            let s = &mut p.sensors;
            s.gyro_white_deg_s = g.white_sigma_deg_s.max(0.01);
            s.gyro_rate_hz = g.rate_hz.max(1.0);
            s.gyro_bias_sigma_deg_s = g.bias_sigma_deg_s.max(0.05);
            s.gyro_bias_walk_deg_s_sqrt_s = g.bias_walk_deg_s_sqrt_s.max(0.001);
            s.gyro_scale_error = g.scale_error.max(0.001);
            p.learn_cell_sync = options.learn_cell_sync;
            if options.local_wind {
                s.local_wind_sigma_m_s = LOCAL_WIND_SIGMA_M_S;
            }
        }
    }
    Ok(c)
}

/// The MSU configuration for a site and profile.
pub fn msu_config(site: &Site, profile: &NoiseProfile, wheels: WheelGeometry) -> MsuConfig {
    MsuConfig::for_site(site, timing_sigma_s(profile), wheels)
}

/// The id a route run's one robot has towards the central unit (its
/// fixes feed the survey calibration).
const ROBOT_ID: &str = "robot";

/// The central unit's survey calibration on `site` under `profile`: the
/// defaults of [`CalibrationConfig`], with the arrivals' timing noise the
/// MSU's data sheet states ([`timing_sigma_s`]) and the cells' sync error
/// the network's states ([`cell_sync_sigma_s`]), at the site's speed of
/// sound.
pub fn survey_calibration(site: &Site, profile: &NoiseProfile) -> CalibrationConfig {
    CalibrationConfig {
        range_sigma_m: timing_sigma_s(profile) * site.speed_of_sound_m_s,
        cell_sync_sigma_m: cell_sync_sigma_s(profile) * site.speed_of_sound_m_s,
        ..CalibrationConfig::default()
    }
}

/// The one-sigma error of a cell's sync under `profile`, seconds, as the
/// site's network states it: half its paths' asymmetry (a clock exchange
/// splits the round trip evenly; the asymmetry is what it cannot see). The
/// cells' own fit of their offset averages the jitter away (a mean of
/// their best exchanges), so the asymmetry is the whole prior. The survey
/// calibration's prior on each cell's lateness: too wide a prior lets the
/// lateness take up what one robot's fixes cannot tell from its position
/// (with the default 60 us, `lab` seed 4 `rectangle` went from 8.5 to
/// 18.0 mm).
pub fn cell_sync_sigma_s(profile: &NoiseProfile) -> f64 {
    profile.clocks.net_asymmetry_sigma_us * 1e-6 / 2.0
}

/// The one-sigma timing noise of one arrival under `profile` (jitter and
/// quantisation), as the MSU's data sheet would state it; at least 1 us.
pub fn timing_sigma_s(profile: &NoiseProfile) -> f64 {
    let u = &profile.ultrasound;
    let q = u.quantisation_us;
    (u.timing_jitter_us * u.timing_jitter_us + q * q / 12.0)
        .sqrt()
        .max(1.0)
        * 1e-6
}

/// Runs one robot on `config.route` for `config.tours` tours; `progress` is
/// told the fraction done from time to time.
pub fn run(
    site: &Site,
    config: &RunConfig,
    progress: &mut dyn FnMut(f64),
) -> Result<RunOutput, RunError> {
    let mut run = RouteRun::start(site, config)?;
    while let Some((t, ev)) = run.q.pop() {
        run.forward_control_plane(t);
        match ev {
            Event::Physics => {
                if run.physics(t, progress) {
                    run.out.virtual_s = t;
                    break;
                }
            }
            Event::Gyro => {
                let imu = run.world.gyro(t, run.gyro_dt);
                // A rejected sample leaves the estimator as it was; the driver counts it.
                run.msu_driver.feed(MsuEvent::Imu(imu));
                run.q.push(t + run.gyro_dt, Event::Gyro);
            }
            Event::Encoders => {
                let odom = run.world.odometry(t);
                if let Some(r) = run.out.recording.as_mut() {
                    r.odometry(odom);
                }
                run.msu_driver.feed(MsuEvent::Odometry(odom));
                run.q.push(t + 1.0 / ENCODER_HZ, Event::Encoders);
            }
            Event::Ranges => {
                let r = run.world.ranges(t);
                run.msu_driver.feed(MsuEvent::Range(r));
                run.q.push(t + 1.0 / RANGES_HZ, Event::Ranges);
            }
            Event::Deliver(k) => run.deliver(t, k),
            Event::Trace => run.trace(t),
        }
    }
    Ok(run.finish(progress))
}

/// One route run in progress: the control plane, the world, the MSU driver
/// fed by both, the event queue and what has been recorded so far.
struct RouteRun<'a> {
    site: &'a Site,
    config: &'a RunConfig,
    control: ControlPlane,
    world: World,
    /// The cells' boards' air temperature sensors, when the profile gives
    /// them one.
    air_sensors: Option<CellAirSensors>,
    msu_driver: MsuDriver,
    out: RunOutput,
    /// The true emission times of each cycle's bursts, until it is delivered.
    emissions: BTreeMap<u64, Vec<(u32, f64)>>,
    q: Queue,
    /// Seconds between two gyro samples.
    gyro_dt: f64,
    /// Seconds after a cycle's last burst by which every burst has been heard.
    max_flight_s: f64,
    route_len: f64,
    /// Reference points per tour.
    n_refs: usize,
    /// Reference passages in the whole run.
    total_refs: usize,
    /// The next reference passage to sample, counted over all tours.
    next_ref: usize,
    /// The fraction done last told to `progress`.
    last_progress_report: f64,
    /// Physics steps taken.
    physics_steps: u64,
}

impl<'a> RouteRun<'a> {
    /// Checks the configuration, builds the control plane, the world and the
    /// MSU (which must accept the first schedule) and queues the first event
    /// of each kind.
    fn start(site: &'a Site, config: &'a RunConfig) -> Result<Self, RunError> {
        if config.tours == 0 {
            return Err(RunError::NoTours);
        }
        let route = site
            .route(&config.route)
            .ok_or_else(|| RunError::UnknownRoute {
                name: config.route.clone(),
                known: site
                    .routes
                    .iter()
                    .map(|r| r.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })?;
        let control =
            ControlPlane::with_config(site, &config.profile.clocks, config.seed, config.central)?;
        let schedule = control.central().latest_schedule().clone();
        let mut world = World::new(site, route, &config.profile, config.seed);
        world.set_transmitter_faults(&config.transmitter_faults);
        let s0 = world.robot.state;
        let start = [s0.x_m, s0.y_m, s0.theta_rad];
        let wheels = world.drive.geometry();
        let msu = msu_config(site, &config.profile, wheels);
        // One MSU: each cycle solved once, every estimator fed the same fix.
        let mut estimators = Vec::new();
        for name in &config.estimators {
            estimators.push(estimator::build(&estimator_config(
                name,
                start,
                site,
                &config.profile,
                config.filter,
            )?)?);
        }
        let n_est = estimators.len();
        let mut msu_driver = MsuDriver::new(MsuCore::with_estimators(msu.clone(), estimators));
        msu_driver.feed(MsuEvent::Schedule(schedule.clone()));
        if let Some(why) = msu_driver.first_refusal() {
            return Err(RunError::Refused(why.to_string()));
        }
        let route_len = world.robot.route_length_m();
        let n_refs = route.reference_points.len().max(1);
        let total_refs = n_refs * config.tours as usize;
        let max_flight_s = (config.profile.ultrasound.max_range_m
            + config.profile.ultrasound.reflection_extra_m[1])
            / site.speed_of_sound_m_s
            + 0.005;

        let out = RunOutput {
            config: config.clone(),
            refs: Vec::with_capacity(total_refs),
            fixes: Vec::new(),
            truth_trace: Vec::new(),
            estimate_traces: vec![Vec::new(); n_est],
            air: Vec::new(),
            refs_per_tour: n_refs,
            schedule: schedule.clone(),
            virtual_s: 0.0,
            timing_sigma_s: msu.timing_sigma_s,
            cells: Vec::new(),
            collisions: Default::default(),
            refused_inputs: None,
            recording: (config.record_rows > 0)
                .then(|| crate::recording::Recording::new(config.record_rows)),
        };
        let mut q = Queue::default();
        let gyro_dt = 1.0 / config.profile.gyro.rate_hz.max(1.0);
        q.push(PHYSICS_DT_S, Event::Physics);
        q.push(gyro_dt, Event::Gyro);
        q.push(1.0 / ENCODER_HZ, Event::Encoders);
        q.push(1.0 / RANGES_HZ, Event::Ranges);
        q.push(0.0, Event::Trace);
        let air_sensors =
            CellAirSensors::new(world.true_site(), &config.profile.air_sensors, config.seed);
        Ok(Self {
            site,
            config,
            control,
            air_sensors,
            world,
            msu_driver,
            out,
            emissions: BTreeMap::new(),
            q,
            gyro_dt,
            max_flight_s,
            route_len,
            n_refs,
            total_refs,
            next_ref: 0,
            last_progress_report: 0.0,
            physics_steps: 0,
        })
    }

    /// Advances the control plane to `t` and hands the MSU what it sent
    /// (cell statuses, surveys, triggers); queues each triggered cycle's
    /// delivery and keeps its bursts' true emission times.
    fn forward_control_plane(&mut self, t: f64) {
        let control = &mut self.control;
        control.advance_to(ickon_proto::time::Time::from_secs_f64(t));
        if let Some(sensors) = self.air_sensors.as_mut() {
            control.send_air_temperatures(sensors.due(self.world.air(), t));
        }
        for status in control.take_statuses() {
            self.msu_driver.feed(MsuEvent::CellStatus(status));
        }
        for survey in control.take_surveys() {
            self.msu_driver.feed(MsuEvent::Survey(survey));
        }
        for trigger in control.take_triggers() {
            // Every burst of the cycle has been heard by then.
            let period_s = trigger
                .period(control.schedule_for(trigger.cycle))
                .as_secs_f64();
            self.q.push(
                trigger.start.as_secs_f64() + period_s + self.max_flight_s,
                Event::Deliver(trigger.cycle),
            );
            // As on the mesh: the MSU hears every trigger and matches its
            // arrivals to one itself (`ickon_msu::cycle_match`).
            self.msu_driver.feed(MsuEvent::Trigger(trigger));
        }
        for b in control.take_fired() {
            self.emissions
                .entry(b.cycle)
                .or_default()
                .push((b.tx_id, b.actual.as_secs_f64()));
        }
    }

    /// One physics step at `t`: moves the world, samples the reference
    /// points passed, tells `progress`; true when the last tour is done
    /// (nothing more is queued then).
    fn physics(&mut self, t: f64, progress: &mut dyn FnMut(f64)) -> bool {
        let moving = t > REST_S;
        self.world.step(t, PHYSICS_DT_S, moving);
        self.physics_steps += 1;
        if let Some(r) = self.out.recording.as_mut()
            && self
                .physics_steps
                .is_multiple_of(crate::recording::TRUTH_EVERY_STEPS)
        {
            let mut sample = self.world.truth(t);
            sample.t_s = self.world.msu_clock.local_s(t);
            r.truth(sample);
        }
        if moving {
            self.sample_references(t);
        }
        let tours = f64::from(self.config.tours);
        let done = self.world.robot.progress_m / (self.route_len * tours);
        if done - self.last_progress_report > 0.01 {
            self.last_progress_report = done;
            progress(done.min(1.0));
        }
        if self.next_ref >= self.total_refs && self.world.robot.progress_m >= self.route_len * tours
        {
            return true;
        }
        self.q.push(t + PHYSICS_DT_S, Event::Physics);
        false
    }

    /// Records the truth and every estimate for each reference point the
    /// robot has passed by `t`.
    fn sample_references(&mut self, t: f64) {
        let n_refs = self.n_refs;
        let route_len = self.route_len;
        while self.next_ref < self.total_refs {
            let tour = self.next_ref / n_refs;
            let idx = self.next_ref % n_refs;
            let s_ref = tour as f64 * route_len + idx as f64 * route_len / n_refs as f64;
            if self.world.robot.progress_m < s_ref {
                break;
            }
            let n_est = self.out.estimate_traces.len();
            let poses: Vec<_> = (0..n_est)
                .map(|i| self.msu_driver.core().pose_of(i))
                .collect();
            self.out.refs.push(RefSample {
                tour: u32::try_from(tour + 1).unwrap_or(u32::MAX),
                index: idx,
                truth: self.world.truth(t),
                estimates: poses
                    .iter()
                    .map(|p| p.as_ref().map(|p| [p.x_m, p.y_m, p.theta_rad]))
                    .collect(),
                covariances: poses
                    .iter()
                    .map(|p| {
                        p.as_ref()
                            .map(|p| [p.covariance[0], p.covariance[1], p.covariance[4]])
                    })
                    .collect(),
            });
            self.next_ref += 1;
        }
    }

    /// Delivers cycle `k`'s arrivals to the MSU at `t` (with the schedule it
    /// ran on); a fix goes to the central unit and is recorded with the
    /// truth at its measurement time.
    fn deliver(&mut self, t: f64, k: u64) {
        // Cycles before `k` that never came to delivery are dropped with it.
        let later = self.emissions.split_off(&(k + 1));
        let fired = std::mem::replace(&mut self.emissions, later)
            .remove(&k)
            .unwrap_or_default();
        if fired.is_empty() {
            return;
        }
        let msg = self.world.arrivals_from_emissions(&fired);
        let schedule = self.control.schedule_for(k);
        if let Some(r) = self.out.recording.as_mut() {
            r.cycle(crate::recording::RecordedCycle::of(k, &msg, schedule));
        }
        self.msu_driver.feed(MsuEvent::Schedule(schedule.clone()));
        if let Some(fix) = self.msu_driver.feed(MsuEvent::Arrivals(msg)).fix {
            self.control
                .send_to_central(ickon_central::core::Event::Fix {
                    robot: ROBOT_ID.into(),
                    fix: Box::new(fix.clone()),
                });
            let t_true = self.world.msu_clock.true_s(fix.stamp.as_secs_f64());
            let used_tx_m = fix
                .used
                .iter()
                .filter_map(|id| self.site.transmitter(*id).map(|t| t.position_m))
                .collect();
            self.out.fixes.push(FixRecord {
                truth: self.world.truth_at(t_true),
                fix,
                used_tx_m,
                available_s: t,
            });
        }
    }

    /// Samples the true path and each estimator's path at `t`.
    fn trace(&mut self, t: f64) {
        let tour = u32::try_from((self.world.robot.progress_m / self.route_len) as u64 + 1)
            .unwrap_or(u32::MAX);
        let s = self.world.robot.state;
        self.out.truth_trace.push(TracePoint {
            tour,
            xy_m: [s.x_m, s.y_m],
        });
        for (i, trace) in self.out.estimate_traces.iter_mut().enumerate() {
            if let Some(p) = self.msu_driver.core().pose_of(i) {
                trace.push(TracePoint {
                    tour,
                    xy_m: [p.x_m, p.y_m],
                });
            }
        }
        if self
            .out
            .air
            .last()
            .is_none_or(|a| t - a.t_s >= AIR_DT_S - 1e-9)
        {
            self.out.air.push(AirSample {
                t_s: t,
                true_m_s: self.world.path_speed_m_s(t, AIR_PATHS_M),
                used_m_s: self.msu_driver.core().speed_of_sound_m_s(),
            });
        }
        self.q.push(t + TRACE_DT_S, Event::Trace);
    }

    /// The run's record, with the MSU's refusals, the cells' sync and the
    /// collisions; tells `progress` it is done.
    fn finish(self, progress: &mut dyn FnMut(f64)) -> RunOutput {
        let mut out = self.out;
        out.refused_inputs = self.msu_driver.refusal_summary();
        out.cells = self.control.sync_reports();
        out.collisions = self.world.collision_counts();
        progress(1.0);
        out
    }
}
