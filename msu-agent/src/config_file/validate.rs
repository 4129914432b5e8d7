//! From TOML text to a validated [`MsuTuning`], collecting every problem
//! with its line and column.

use std::ops::Range;

use ickon_fusion::estimator::tdoa_ekf::GroundNoise;
use ickon_fusion::estimator::{EstimatorConfig, WheelGeometry, names};

use super::apply::{self, Touched};
use super::raw::{Num, RawFilter, RawMsuFile};
use super::{ConfigIssue, MsuConfigError, MsuTuning, SolverTuning, pioneer_wheels};
use crate::hedgehog::MarvelmindSettings;

/// Where a value must lie, and in what unit it is named in messages.
struct Bounds {
    lo: f64,
    hi: f64,
    /// Whether `lo` itself is refused (a noise of zero, a rate of zero).
    lo_open: bool,
    unit: &'static str,
}

const fn positive(hi: f64, unit: &'static str) -> Bounds {
    Bounds {
        lo: 0.0,
        hi,
        lo_open: true,
        unit,
    }
}

const fn non_negative(hi: f64, unit: &'static str) -> Bounds {
    Bounds {
        lo: 0.0,
        hi,
        lo_open: false,
        unit,
    }
}

struct Ctx<'a> {
    text: &'a str,
    issues: Vec<ConfigIssue>,
    warnings: Vec<ConfigIssue>,
}

impl Ctx<'_> {
    fn issue(&mut self, span: Range<usize>, field: &str, message: impl Into<String>) {
        self.issues
            .push(ConfigIssue::at(self.text, span, field, message));
    }

    fn warn(&mut self, span: Range<usize>, field: &str, message: impl Into<String>) {
        self.warnings
            .push(ConfigIssue::at(self.text, span, field, message));
    }

    /// The value of an optional number if it is finite and within `b`.
    fn num(&mut self, v: &Option<Num>, field: &str, b: Bounds) -> Option<(f64, Range<usize>)> {
        let v = v.as_ref()?;
        let x = *v.get_ref();
        let below = if b.lo_open { x <= b.lo } else { x < b.lo };
        if !x.is_finite() {
            self.issue(v.span(), field, "must be a finite number (not nan or inf)");
            None
        } else if below || x > b.hi {
            let lo = if b.lo_open { "above" } else { "from" };
            self.issue(
                v.span(),
                field,
                format!(
                    "{x} {} is out of range: expected {lo} {} up to {} {}",
                    b.unit, b.lo, b.hi, b.unit
                ),
            );
            None
        } else {
            Some((x, v.span()))
        }
    }
}

/// Whether the dotted `path` is set in `table`.
fn in_table(table: &toml::Table, path: &str) -> bool {
    let mut node = table;
    let mut parts = path.split('.').peekable();
    while let Some(part) = parts.next() {
        match (node.get(part), parts.peek()) {
            (None, _) => return false,
            (Some(_), None) => return true,
            (Some(toml::Value::Table(t)), Some(_)) => node = t,
            (Some(_), Some(_)) => return false,
        }
    }
    false
}

/// The estimator named in `[filter]` with `[filter.params]` over its
/// defaults; `None` (with the issue recorded) when either is wrong.
fn estimator(ctx: &mut Ctx, raw: &RawMsuFile) -> Option<EstimatorConfig> {
    let filter = raw.filter.get_ref();
    let name = filter.estimator.get_ref();
    let defaults = match EstimatorConfig::default_for(name) {
        Ok(c) => c,
        Err(_) => {
            ctx.issue(
                filter.estimator.span(),
                "filter.estimator",
                format!("unknown estimator `{name}` (known: {})", names().join(", ")),
            );
            return None;
        }
    };
    let Some(params) = &filter.params else {
        return Some(defaults);
    };
    let mut table = params.get_ref().clone();
    if table.contains_key("name") {
        ctx.issue(
            params.span(),
            "filter.params.name",
            "the estimator is named by `filter.estimator`, not here",
        );
        return None;
    }
    table.insert("name".into(), toml::Value::String(name.clone()));
    match toml::Value::Table(table).try_into::<EstimatorConfig>() {
        Ok(c) => Some(c),
        Err(e) => {
            ctx.issue(
                params.span(),
                "filter.params",
                format!("{} (parameters of `{name}`)", e.message().trim()),
            );
            None
        }
    }
}

pub(super) fn parse_and_validate(text: &str, file: &str) -> Result<MsuTuning, MsuConfigError> {
    let mut ctx = Ctx {
        text,
        issues: Vec::new(),
        warnings: Vec::new(),
    };
    let invalid = |mut issues: Vec<ConfigIssue>| {
        issues.sort_by_key(|i| (i.line, i.column));
        MsuConfigError::Invalid {
            file: file.to_string(),
            issues,
        }
    };
    let raw: RawMsuFile = match toml::from_str(text) {
        Ok(raw) => raw,
        Err(e) => {
            ctx.issue(e.span().unwrap_or(0..0), "(syntax)", e.message().trim());
            return Err(invalid(ctx.issues));
        }
    };
    let tuning = build(&mut ctx, &raw);
    match tuning {
        Some(mut t) if ctx.issues.is_empty() => {
            ctx.warnings.sort_by_key(|i| (i.line, i.column));
            t.warnings = ctx.warnings;
            Ok(t)
        }
        _ => Err(invalid(ctx.issues)),
    }
}

/// Every value of the file, checked, and applied where the estimator uses it.
fn build(ctx: &mut Ctx, raw: &RawMsuFile) -> Option<MsuTuning> {
    let estimator = estimator(ctx, raw);
    // Every value is range-checked even when the estimator is unknown, so
    // that one run lists every problem.
    let values = Values::check(ctx, raw);
    let mut c = estimator?;
    apply_to_estimator(ctx, &mut c, raw, &values);
    let filter = raw.filter.get_ref();
    if let Err(e) = c.validate() {
        let span = filter
            .params
            .as_ref()
            .map_or(raw.filter.span(), |p| p.span());
        ctx.issue(span, "filter.params", e.to_string());
    }

    let sheet = pioneer_wheels();
    let wheels = WheelGeometry {
        wheel_base_m: values.wheel_base.map_or(sheet.wheel_base_m, |v| v.0),
        left_m_per_tick: values
            .m_per_tick
            .as_ref()
            .map_or(sheet.left_m_per_tick, |v| v.0),
        right_m_per_tick: values
            .m_per_tick
            .as_ref()
            .map_or(sheet.right_m_per_tick, |v| v.0),
    };
    let defaults = SolverTuning::default();
    let marvelmind = marvelmind(ctx, raw);
    let fix = values.fix;
    Some(MsuTuning {
        estimator: c,
        start: values.start,
        solver: SolverTuning {
            timing_sigma_s: fix.timing.map_or(defaults.timing_sigma_s, |v| v.0 * 1e-6),
            residual_gate_m: fix.residual_gate.map(|v| v.0),
            max_fix_sigma_m: fix.max_sigma.map_or(defaults.max_fix_sigma_m, |v| v.0),
        },
        wheels,
        marvelmind,
        warnings: Vec::new(),
        #[cfg(feature = "zenoh")]
        ros2: raw.ros2.clone(),
    })
}

/// The `[marvelmind]` section over the defaults.
fn marvelmind(ctx: &mut Ctx, raw: &RawMsuFile) -> MarvelmindSettings {
    let mut m = MarvelmindSettings::default();
    let Some(block) = raw.marvelmind.as_ref().map(|b| b.get_ref()) else {
        return m;
    };
    // Air from -40 to +60 °C: 306 to 366 m/s.
    let speed = Bounds {
        lo: 300.0,
        hi: 370.0,
        lo_open: false,
        unit: "m/s",
    };
    if let Some((v, _)) = ctx.num(
        &block.speed_of_sound_m_s,
        "marvelmind.speed_of_sound_m_s",
        speed,
    ) {
        m.speed_of_sound_m_s = v;
    }
    if let Some((v, _)) = ctx.num(
        &block.range_sigma_m,
        "marvelmind.range_sigma_m",
        positive(10.0, "m"),
    ) {
        m.range_sigma_m = v;
    }
    if let Some((v, _)) = ctx.num(
        &block.kit_position_sigma_m,
        "marvelmind.kit_position_sigma_m",
        positive(10.0, "m"),
    ) {
        m.kit_position_sigma_m = v;
    }
    if let Some(v) = &block.use_kit_positions {
        m.use_kit_positions = *v.get_ref();
    }
    // A count is at most a degree per second (16-bit gyros at their widest
    // range are 0.07 deg/s per count): more is a unit mistake.
    if let Some((v, _)) = ctx.num(
        &block.gyro_rad_s_per_count,
        "marvelmind.gyro_rad_s_per_count",
        positive(1f64.to_radians(), "rad/s"),
    ) {
        m.gyro_rad_s_per_count = Some(v);
    }
    m
}

/// A number of the file that is within its bounds, with where it is;
/// `None` when absent or refused (the issue recorded).
type Checked = Option<(f64, Range<usize>)>;

/// Every number of the file, range-checked section by section.
struct Values {
    history: Checked,
    /// `x, y, heading` (radians).
    start: Option<[f64; 3]>,
    wheel_base: Checked,
    m_per_tick: Checked,
    fix: FixValues,
    range_differences: RangeDifferenceValues,
    odometry: OdometryValues,
    gyro: GyroValues,
    heading_sigma: Checked,
}

impl Values {
    /// Checks every number of `raw`, recording each problem in `ctx`.
    fn check(ctx: &mut Ctx, raw: &RawMsuFile) -> Self {
        let filter = raw.filter.get_ref();
        let history = ctx.num(
            &filter.history_s,
            "filter.history_s",
            non_negative(60.0, "s"),
        );
        let start = start_pose(ctx, filter);

        let robot = raw.robot.as_ref().map(|r| r.get_ref());
        let wheel_base =
            robot.and_then(|r| ctx.num(&r.wheel_base_m, "robot.wheel_base_m", positive(10.0, "m")));
        let m_per_tick =
            robot.and_then(|r| ctx.num(&r.m_per_tick, "robot.m_per_tick", positive(1.0, "m")));

        let fix = FixValues::check(ctx, raw);
        let range_differences = RangeDifferenceValues::check(ctx, raw);
        let odometry = OdometryValues::check(ctx, raw);
        let gyro = GyroValues::check(ctx, raw);
        let heading_sigma = raw.receiver_heading.as_ref().and_then(|h| {
            ctx.num(
                &h.get_ref().sigma_deg,
                "receiver_heading.sigma_deg",
                non_negative(360.0, "deg"),
            )
        });
        Self {
            history,
            start,
            wheel_base,
            m_per_tick,
            fix,
            range_differences,
            odometry,
            gyro,
            heading_sigma,
        }
    }
}

/// `filter.start` as `x, y, heading` in radians, if set and valid.
fn start_pose(ctx: &mut Ctx, filter: &RawFilter) -> Option<[f64; 3]> {
    filter.start.as_ref().and_then(|s| {
        let [x, y, heading_deg] = *s.get_ref();
        if [x, y, heading_deg].iter().all(|v| v.is_finite()) && heading_deg.abs() <= 360.0 {
            Some([x, y, heading_deg.to_radians()])
        } else {
            ctx.issue(
                s.span(),
                "filter.start",
                "expected [x_m, y_m, heading_deg]: finite numbers, heading within +-360 deg",
            );
            None
        }
    })
}

/// The `[fix]` section, checked.
struct FixValues {
    timing: Checked,
    residual_gate: Checked,
    max_sigma: Checked,
    sigma_floor: Checked,
}

impl FixValues {
    fn check(ctx: &mut Ctx, raw: &RawMsuFile) -> Self {
        let fix = raw.fix.as_ref().map(|f| f.get_ref());
        let timing = fix.and_then(|f| {
            ctx.num(
                &f.timing_sigma_us,
                "fix.timing_sigma_us",
                positive(10_000.0, "us"),
            )
        });
        let residual_gate = fix.and_then(|f| {
            ctx.num(
                &f.residual_gate_m,
                "fix.residual_gate_m",
                positive(100.0, "m"),
            )
        });
        let max_sigma =
            fix.and_then(|f| ctx.num(&f.max_sigma_m, "fix.max_sigma_m", positive(100.0, "m")));
        let sigma_floor = fix.and_then(|f| {
            ctx.num(
                &f.sigma_floor_mm,
                "fix.sigma_floor_mm",
                positive(10_000.0, "mm"),
            )
        });
        Self {
            timing,
            residual_gate,
            max_sigma,
            sigma_floor,
        }
    }
}

/// The `[range_differences]` section, checked.
struct RangeDifferenceValues {
    gate_sigma: Checked,
    late_soft: Checked,
}

impl RangeDifferenceValues {
    fn check(ctx: &mut Ctx, raw: &RawMsuFile) -> Self {
        let rd = raw.range_differences.as_ref().map(|r| r.get_ref());
        let gate_sigma = rd.and_then(|r| {
            ctx.num(
                &r.gate_sigma,
                "range_differences.gate_sigma",
                positive(100.0, "sigma"),
            )
        });
        let late_soft = rd.and_then(|r| {
            ctx.num(
                &r.late_soft_sigma,
                "range_differences.late_soft_sigma",
                positive(100.0, "sigma"),
            )
        });
        Self {
            gate_sigma,
            late_soft,
        }
    }
}

/// The `[odometry]` section, checked.
struct OdometryValues {
    distance: Checked,
    heading_per_m: Checked,
    heading_per_turn: Checked,
}

impl OdometryValues {
    fn check(ctx: &mut Ctx, raw: &RawMsuFile) -> Self {
        let odo = raw.odometry.as_ref().map(|o| o.get_ref());
        let distance = odo.and_then(|o| {
            ctx.num(
                &o.distance_sigma_fraction,
                "odometry.distance_sigma_fraction",
                non_negative(1.0, ""),
            )
        });
        let heading_per_m = odo.and_then(|o| {
            ctx.num(
                &o.heading_sigma_deg_per_m,
                "odometry.heading_sigma_deg_per_m",
                non_negative(360.0, "deg/m"),
            )
        });
        let heading_per_turn = odo.and_then(|o| {
            ctx.num(
                &o.heading_sigma_per_turn,
                "odometry.heading_sigma_per_turn",
                non_negative(1.0, ""),
            )
        });
        Self {
            distance,
            heading_per_m,
            heading_per_turn,
        }
    }
}

/// The `[gyro]` section's numbers, checked.
struct GyroValues {
    white: Checked,
    rate: Checked,
    bias_sigma: Checked,
    bias_walk: Checked,
    scale: Checked,
    max_gap: Checked,
}

impl GyroValues {
    fn check(ctx: &mut Ctx, raw: &RawMsuFile) -> Self {
        let gyro = raw.gyro.as_ref().map(|g| g.get_ref());
        let white = gyro.and_then(|g| {
            ctx.num(
                &g.white_noise_deg_s,
                "gyro.white_noise_deg_s",
                positive(100.0, "deg/s"),
            )
        });
        let rate =
            gyro.and_then(|g| ctx.num(&g.rate_hz, "gyro.rate_hz", positive(100_000.0, "Hz")));
        let bias_sigma = gyro.and_then(|g| {
            ctx.num(
                &g.bias_sigma_deg_s,
                "gyro.bias_sigma_deg_s",
                positive(100.0, "deg/s"),
            )
        });
        let bias_walk = gyro.and_then(|g| {
            ctx.num(
                &g.bias_walk_deg_s_sqrt_s,
                "gyro.bias_walk_deg_s_sqrt_s",
                non_negative(10.0, "deg/s/sqrt(s)"),
            )
        });
        let scale =
            gyro.and_then(|g| ctx.num(&g.scale_error, "gyro.scale_error", non_negative(1.0, "")));
        let max_gap =
            gyro.and_then(|g| ctx.num(&g.max_gap_s, "gyro.max_gap_s", positive(60.0, "s")));
        Self {
            white,
            rate,
            bias_sigma,
            bias_walk,
            scale,
            max_gap,
        }
    }
}

/// Applies each checked value to the estimator configuration `c`; warns of
/// a value `c` does not use, and refuses one also set in `[filter.params]`.
fn apply_to_estimator(ctx: &mut Ctx, c: &mut EstimatorConfig, raw: &RawMsuFile, v: &Values) {
    let filter = raw.filter.get_ref();
    let name = filter.estimator.get_ref().clone();
    let empty = toml::Table::new();
    let params = filter.params.as_ref().map_or(&empty, |p| p.get_ref());
    let put = |ctx: &mut Ctx, span: Range<usize>, field: &str, touched: Touched| {
        if touched.is_empty() {
            ctx.warn(
                span,
                field,
                format!("not used by estimator `{name}`: ignored"),
            );
        } else if let Some(p) = touched.iter().find(|p| in_table(params, p)) {
            ctx.issue(
                span,
                field,
                format!("also set as `{p}` in [filter.params]: set it in one place"),
            );
        }
    };
    let mut each =
        |ctx: &mut Ctx, v: &Checked, field: &str, f: fn(&mut EstimatorConfig, f64) -> Touched| {
            if let Some((x, span)) = v.clone() {
                let touched = f(c, x);
                put(ctx, span, field, touched);
            }
        };
    let (fix, rd, odo, gyro) = (&v.fix, &v.range_differences, &v.odometry, &v.gyro);
    each(ctx, &v.history, "filter.history_s", apply::history_s);
    each(
        ctx,
        &fix.sigma_floor,
        "fix.sigma_floor_mm",
        apply::fix_sigma_floor_mm,
    );
    each(
        ctx,
        &rd.gate_sigma,
        "range_differences.gate_sigma",
        apply::range_gate_sigma,
    );
    each(
        ctx,
        &rd.late_soft,
        "range_differences.late_soft_sigma",
        apply::range_late_soft_sigma,
    );
    each(
        ctx,
        &odo.distance,
        "odometry.distance_sigma_fraction",
        apply::odometry_distance,
    );
    each(
        ctx,
        &odo.heading_per_m,
        "odometry.heading_sigma_deg_per_m",
        apply::odometry_heading_per_m,
    );
    each(
        ctx,
        &odo.heading_per_turn,
        "odometry.heading_sigma_per_turn",
        apply::odometry_heading_per_turn,
    );
    each(
        ctx,
        &gyro.bias_sigma,
        "gyro.bias_sigma_deg_s",
        apply::gyro_bias_sigma,
    );
    each(
        ctx,
        &gyro.bias_walk,
        "gyro.bias_walk_deg_s_sqrt_s",
        apply::gyro_bias_walk,
    );
    each(
        ctx,
        &gyro.scale,
        "gyro.scale_error",
        apply::gyro_scale_error,
    );
    each(ctx, &gyro.max_gap, "gyro.max_gap_s", apply::gyro_max_gap);
    each(
        ctx,
        &v.heading_sigma,
        "receiver_heading.sigma_deg",
        apply::receiver_heading_sigma,
    );
    let (white, rate) = (&gyro.white, &gyro.rate);
    if white.is_some() || rate.is_some() {
        // The two go together (the angle random walk is their ratio): one
        // without the other takes the data-sheet default of the other.
        let sheet = GroundNoise::default();
        let w = white.as_ref().map_or(sheet.gyro_white_deg_s, |v| v.0);
        let r = rate.as_ref().map_or(sheet.gyro_rate_hz, |v| v.0);
        let span = white.clone().or(rate.clone()).map(|v| v.1).unwrap_or(0..0);
        let touched = apply::gyro_white_noise(c, w, r);
        put(ctx, span, "gyro.white_noise_deg_s", touched);
    }
    let raw_gyro = raw.gyro.as_ref().map(|g| g.get_ref());
    if let Some(u) = raw_gyro.and_then(|g| g.use_gyro.as_ref()) {
        let touched = apply::gyro_use(c, *u.get_ref());
        put(ctx, u.span(), "gyro.use", touched);
    }
}
