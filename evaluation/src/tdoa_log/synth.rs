//! A microphone network hearing a mobile emitter, generated: fixed
//! receivers round a room, a robot's beeper driving a smooth loop, arrival
//! times with timing jitter, late reflections and missed arrivals, and a
//! motion-capture truth on its own clock. The example set under
//! `deploy/examples/` and the expectations of `docs/log-format.md` come
//! from here.

use std::path::Path;

use ickon_runtime::CommandError;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::convert::Writers;
use super::format::FORMAT;

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MicNetwork {
    /// Seed of every random draw.
    pub seed: u64,
    /// Length of the run, seconds.
    pub duration_s: f64,
    /// Beeps per second.
    pub beep_hz: f64,
    /// Truth samples per second.
    pub truth_hz: f64,
    /// Timing jitter of an arrival, seconds (one standard deviation).
    pub jitter_s: f64,
    /// Chance that an arrival is a reflection instead.
    pub reflection_p: f64,
    /// Chance that a microphone misses a beep.
    pub miss_p: f64,
    /// The truth clock runs behind the array's by this, seconds.
    pub truth_offset_s: f64,
}

impl Default for MicNetwork {
    /// 90 s of a beep every 0.2 s (5 Hz) heard by 8 microphones; 50 us of
    /// jitter (1.7 cm at 343 m/s, a cross-correlation's peak on a clean
    /// chirp); one arrival in ten a reflection, late by 0.3 to 3 ms (10 cm
    /// to 1 m more path); one in ten missed; motion capture at 100 Hz,
    /// 0.35 s behind the array's clock.
    fn default() -> Self {
        Self {
            seed: 1,
            duration_s: 90.0,
            beep_hz: 5.0,
            truth_hz: 100.0,
            jitter_s: 50e-6,
            reflection_p: 0.1,
            miss_p: 0.1,
            truth_offset_s: 0.35,
        }
    }
}

/// Speed of sound of the generated room (20 degC), m/s.
pub const SPEED_OF_SOUND_M_S: f64 = 343.0;

/// The microphones: a 12 m by 9 m room, four in the corners and four at
/// the middles of the walls, 0.2 m in from them.
pub const MICROPHONES_M: [[f64; 2]; 8] = [
    [0.2, 0.2],
    [6.0, 0.2],
    [11.8, 0.2],
    [11.8, 4.5],
    [11.8, 8.8],
    [6.0, 8.8],
    [0.2, 8.8],
    [0.2, 4.5],
];

/// The emitter's true position at `t_s`: a loop round the room's middle
/// (up to about 1.2 m/s).
pub fn emitter_m(t_s: f64) -> [f64; 2] {
    use std::f64::consts::TAU;
    [
        6.0 + 4.0 * (TAU * t_s / 30.0).sin(),
        4.5 + 3.0 * (TAU * t_s / 17.0).sin(),
    ]
}

/// Writes the run's `anchors.csv`, `measurements.csv` and `truth.csv`
/// into `dir` (refusing to overwrite).
pub fn write(dir: &Path, net: &MicNetwork) -> Result<(), CommandError> {
    let mut rng = ChaCha8Rng::seed_from_u64(net.seed);
    let jitter = Normal::new(0.0, net.jitter_s)
        .map_err(|e| CommandError::bad_input(format!("jitter: {e}")))?;
    let mut out = Writers::create(dir)?;
    out.line(
        0,
        "# a generated microphone network (ickon-evaluation synth)",
    )?;
    out.line(0, "id,x_m,y_m,role")?;
    for (k, m) in MICROPHONES_M.iter().enumerate() {
        out.line(0, &format!("mic{k},{},{},receiver", m[0], m[1]))?;
    }
    out.line(1, &format!("# format: {FORMAT}"))?;
    out.line(1, "# clock: array")?;
    out.line(1, &format!("# propagation_speed_m_s: {SPEED_OF_SOUND_M_S}"))?;
    out.line(1, "epoch,time_s,anchor,reference,kind,value,sigma")?;
    let beeps = (net.duration_s * net.beep_hz).floor() as u64;
    for epoch in 0..beeps {
        // The beeper fires on its own schedule, unknown to the array.
        let emitted_s = 0.5 + epoch as f64 / net.beep_hz + rng.random_range(0.0..0.01);
        let p = emitter_m(emitted_s);
        let mut arrivals: Vec<(f64, usize)> = Vec::new();
        for (k, m) in MICROPHONES_M.iter().enumerate() {
            let missed = rng.random_bool(net.miss_p);
            let reflected = rng.random_bool(net.reflection_p);
            let late_s = rng.random_range(0.3e-3..3e-3);
            let noise_s = jitter.sample(&mut rng);
            if missed {
                continue;
            }
            let range_m = (p[0] - m[0]).hypot(p[1] - m[1]);
            let mut t = emitted_s + range_m / SPEED_OF_SOUND_M_S + noise_s;
            if reflected {
                t += late_s;
            }
            arrivals.push((t, k));
        }
        arrivals.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (t, k) in arrivals {
            out.line(
                1,
                &format!("{epoch},{t:.7},mic{k},,toa_s,{t:.7},{}", net.jitter_s),
            )?;
        }
    }
    out.line(2, "# clock: motion-capture")?;
    out.line(2, "time_s,x_m,y_m")?;
    let samples = (net.duration_s * net.truth_hz).floor() as u64 + 1;
    for k in 0..samples {
        let t_array = 0.5 + k as f64 / net.truth_hz;
        let p = emitter_m(t_array);
        let t_truth = t_array - net.truth_offset_s;
        out.line(2, &format!("{t_truth:.3},{:.4},{:.4}", p[0], p[1]))?;
    }
    out.flush()
}
