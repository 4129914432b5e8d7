//! `ickon eval --export-tdoa DIR`: each route's simulated run written in
//! the arrival-time log format (docs/log-format.md), so that
//! `ickon replay tdoa` can be held against `ickon eval` on the same
//! measurements; `ickon convert mcap` writes each robot of a recording
//! through [`write_run`] the same way.
//!
//! One directory per route, `DIR/ROUTE/`: the site's transmitters with
//! `# mobile_height_m:` (the MSU's height: a 2D log of a ground robot under
//! ceiling transmitters), every delivered cycle's arrivals as `toa_s` rows
//! (arrival minus the transmitter's emission offset in the cycle's
//! schedule: the flight time plus the cycle's unknown start, on the MSU
//! clock), the truth every 10 ms with the heading, and the wheel odometry
//! as body-frame increments, all on the MSU clock.

use std::path::Path;

use ickon_proto::site::Site;
use ickon_runtime::CommandError;
use ickon_sim::RunOutput;
use ickon_sim::recording::{RecordedArrival, RecordedCycle, Recording};

use super::convert::Writers;
use super::format::FORMAT;

/// The rows a route's recording may hold (arrivals, truth and odometry
/// samples): about 100 bytes each in memory. A ten-tour `lab` route needs
/// a tenth of it.
pub const MAX_ROWS: usize = 4_000_000;

/// The clock name every exported file carries.
const CLOCK: &str = "msu";

/// Writes every run of `outputs` under `dir`, one directory per route.
pub fn write_all(dir: &Path, site: &Site, outputs: &[RunOutput]) -> Result<(), CommandError> {
    for o in outputs {
        let Some(rec) = &o.recording else {
            continue;
        };
        if rec.truncated {
            return Err(CommandError::bad_input(format!(
                "--export-tdoa: route {} is longer than an export holds ({MAX_ROWS} rows): give fewer --tours",
                o.config.route
            )));
        }
        write_run(
            &dir.join(&o.config.route),
            &format!("ickon eval from site {}", site.name),
            site,
            o.timing_sigma_s,
            rec,
        )?;
    }
    Ok(())
}

/// Writes one run `rec` into `dir` (created; existing files are refused):
/// the anchors of `site` (`source`: who wrote them, said in a comment),
/// the arrivals with the timing sigma `sigma_s`, the truth and the
/// odometry.
pub fn write_run(
    dir: &Path,
    source: &str,
    site: &Site,
    sigma_s: f64,
    rec: &Recording,
) -> Result<(), CommandError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| CommandError::failure(format!("cannot create {}: {e}", dir.display())))?;
    let names = [
        "anchors.csv",
        "measurements.csv",
        "truth.csv",
        "odometry.csv",
    ];
    let mut out = Writers::create_named(dir, &names)?;
    write_anchors(&mut out, source, site)?;
    let rows = write_measurements(&mut out, site, sigma_s, rec)?;
    write_truth(&mut out, rec)?;
    write_odometry(&mut out, rec)?;
    out.flush()?;
    eprintln!(
        "{} cycles, {rows} arrivals written to {}",
        rec.cycles.len(),
        dir.display()
    );
    Ok(())
}

/// `anchors.csv` (file 0): the site's transmitters as surveyed.
fn write_anchors(out: &mut Writers, source: &str, site: &Site) -> Result<(), CommandError> {
    out.line(0, &format!("# written by {source}"))?;
    out.line(0, &format!("# mobile_height_m: {}", mobile_height_m(site)))?;
    out.line(0, "id,x_m,y_m,z_m,role")?;
    for t in &site.transmitters {
        let [x, y, z] = t.position_m;
        out.line(0, &format!("{},{x},{y},{z},transmitter", t.id))?;
    }
    Ok(())
}

/// `measurements.csv` (file 1): one `toa_s` row per arrival the MSU can
/// use (a transmitter heard twice in a cycle: its first arrival, as the
/// MSU takes it), in time order; returns the rows written.
fn write_measurements(
    out: &mut Writers,
    site: &Site,
    sigma_s: f64,
    rec: &Recording,
) -> Result<u64, CommandError> {
    out.line(1, &format!("# format: {FORMAT}"))?;
    out.line(1, &format!("# clock: {CLOCK}"))?;
    out.line(
        1,
        &format!("# propagation_speed_m_s: {}", site.speed_of_sound_m_s),
    )?;
    out.line(1, "epoch,time_s,anchor,reference,kind,value,sigma")?;
    let mut rows = 0;
    for (cycle, arrivals) in epochs(rec) {
        for a in arrivals {
            out.line(
                1,
                &format!(
                    "{},{:.9},{},,toa_s,{:.9},{sigma_s:e}",
                    cycle,
                    a.t_s,
                    a.tx_id,
                    a.t_s - a.offset_s
                ),
            )?;
            rows += 1;
        }
    }
    Ok(rows)
}

/// The arrivals written of each cycle, with the cycle's number: those the
/// MSU uses ([`usable`]), in time order. A late arrival of one cycle after
/// the first of the next would put the file's time backwards: left out,
/// as a receiver whose listening window had closed would leave it.
pub(super) fn epochs(rec: &Recording) -> Vec<(u64, Vec<RecordedArrival>)> {
    let mut last_s = f64::NEG_INFINITY;
    let mut out = Vec::with_capacity(rec.cycles.len());
    for c in &rec.cycles {
        let mut kept = usable(c);
        kept.retain(|a| {
            let in_order = a.t_s >= last_s;
            if in_order {
                last_s = a.t_s;
            }
            in_order
        });
        if !kept.is_empty() {
            out.push((c.cycle, kept));
        }
    }
    out
}

/// The height of the plane the MSU moves in, metres (the anchors file's
/// `# mobile_height_m:`).
pub(super) fn mobile_height_m(site: &Site) -> f64 {
    site.msu.height_m
}

/// The cycle's arrivals the MSU uses (the first of each transmitter), in
/// time order.
fn usable(c: &RecordedCycle) -> Vec<RecordedArrival> {
    let mut kept: Vec<RecordedArrival> = Vec::new();
    for a in &c.arrivals {
        if !kept.iter().any(|k| k.tx_id == a.tx_id) {
            kept.push(*a);
        }
    }
    kept.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    kept
}

/// `truth.csv` (file 2): the robot's pose every 10 ms on the MSU clock
/// (to the micrometre and microradian).
fn write_truth(out: &mut Writers, rec: &Recording) -> Result<(), CommandError> {
    out.line(2, &format!("# clock: {CLOCK}"))?;
    out.line(2, "time_s,x_m,y_m,heading_rad")?;
    for s in &rec.truth {
        out.line(
            2,
            &format!("{:.9},{:.6},{:.6},{:.6}", s.t_s, s.x_m, s.y_m, s.theta_rad),
        )?;
    }
    Ok(())
}

/// `odometry.csv` (file 3): each odometry sample as the increment since
/// the one before, in the body frame at its start (to the nanometre).
fn write_odometry(out: &mut Writers, rec: &Recording) -> Result<(), CommandError> {
    out.line(3, &format!("# clock: {CLOCK}"))?;
    out.line(3, "time_s,dx_m,dy_m,dtheta_rad")?;
    for w in rec.odometry.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        let [dx, dy] = body_increment([a.x_m, a.y_m, a.theta_rad], [b.x_m, b.y_m]);
        out.line(
            3,
            &format!(
                "{:.9},{dx:.9},{dy:.9},{:.9}",
                b.stamp.as_secs_f64(),
                b.theta_rad - a.theta_rad
            ),
        )?;
    }
    Ok(())
}

/// The move from pose `from` to position `to`, in the body frame of `from`.
fn body_increment(from: [f64; 3], to: [f64; 2]) -> [f64; 2] {
    let (s, c) = from[2].sin_cos();
    let (ex, ey) = (to[0] - from[0], to[1] - from[1]);
    [c * ex + s * ey, -s * ex + c * ey]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_move_is_turned_into_the_body_frame() {
        // Facing +y, a move of 1 m along +y is 1 m forward.
        let [dx, dy] = body_increment([2.0, 3.0, std::f64::consts::FRAC_PI_2], [2.0, 4.0]);
        assert!((dx - 1.0).abs() < 1e-12 && dy.abs() < 1e-12, "{dx} {dy}");
        // Facing +x, a move along +y is to the left.
        let [dx, dy] = body_increment([0.0, 0.0, 0.0], [0.0, 0.5]);
        assert!(dx.abs() < 1e-12 && (dy - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_transmitter_heard_twice_keeps_its_first_arrival_and_rows_sort_by_time() {
        let a = |tx_id, t_s| RecordedArrival {
            tx_id,
            t_s,
            offset_s: 0.0,
        };
        let c = RecordedCycle {
            cycle: 3,
            arrivals: vec![a(2, 1.2), a(1, 1.1), a(2, 1.05)],
        };
        let kept = usable(&c);
        assert_eq!(kept.len(), 2);
        assert_eq!((kept[0].tx_id, kept[0].t_s), (1, 1.1));
        assert_eq!((kept[1].tx_id, kept[1].t_s), (2, 1.2));
    }
}
