//! Time to plan one cycle for 128 robots (`ickon_central::occupancy::plan`
//! with what each robot needs, spaced by the room's reverberation), on
//! `hall` (open: every transmitter heard everywhere within range) and
//! `warehouse` (128 robots of its own). The central unit plans each cycle
//! when it triggers it, so a plan must take well under the cycle it plans
//! (the target: a tenth); each case prints the period it planned, to
//! compare with the time measured.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion};
use ickon_central::occupancy::{FiringConfig, RobotView, plan};
use ickon_central::selection::{FiringHistory, NeedsConfig};
use ickon_central::spacing::{Reverb, SpacingTable};
use ickon_proto::msg::robot::{PoseStatus, RobotPose};
use ickon_proto::site::Site;
use ickon_proto::time::{Duration, Time};

const ROBOTS: usize = 128;

/// `ROBOTS` poses spread over the site: its own robots' starts, and on a
/// site with fewer, points of a golden-ratio lattice over its cells.
fn poses(site: &Site) -> Vec<RobotPose> {
    let mut at: Vec<[f64; 2]> = site
        .robots
        .iter()
        .take(ROBOTS)
        .map(|r| [r.start[0], r.start[1]])
        .collect();
    let (lo, hi) = site.cells.iter().flat_map(|c| c.polygon.iter()).fold(
        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
        |(lo, hi), p| {
            (
                [lo[0].min(p[0]), lo[1].min(p[1])],
                [hi[0].max(p[0]), hi[1].max(p[1])],
            )
        },
    );
    let mut k = 0u32;
    while at.len() < ROBOTS {
        k += 1;
        let u = (f64::from(k) * 0.618_033_988_75).fract();
        let v = (f64::from(k) + 0.5) / (2.0 * ROBOTS as f64);
        let p = [
            lo[0] + u * (hi[0] - lo[0]),
            lo[1] + v.fract() * (hi[1] - lo[1]),
        ];
        if site.cell_at(p).is_some() {
            at.push(p);
        }
    }
    at.into_iter()
        .map(|[x_m, y_m]| RobotPose {
            stamp: Time(0),
            x_m,
            y_m,
            theta_rad: 0.0,
            covariance: [4e-4, 0.0, 0.0, 0.0, 4e-4, 0.0, 0.0, 0.0, 0.01],
            estimator: "tdoa-ekf".into(),
            fix_seq: 1,
            status: PoseStatus::Tracking,
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let config = FiringConfig {
        occupancy: true,
        needs: Some(NeedsConfig::default()),
        reverb: Some(Reverb::default()),
        ..FiringConfig::default()
    };
    let now = Time(10_000_000_000);
    let cycle = Duration::from_millis(200);
    let mut group = c.benchmark_group("firing_plan_128_robots");
    for name in ["hall", "warehouse"] {
        let (site, _) = Site::builtin(name).expect("built-in site");
        let cells: Vec<String> = site.cells.iter().map(|c| c.id.clone()).collect();
        let table = SpacingTable::new(&site, &cells);
        let poses = poses(&site);
        let views: Vec<RobotView> = poses
            .iter()
            .map(|p| RobotView::Seen(p, now, None))
            .collect();
        let history = FiringHistory::default();
        let planned = plan(&table, &views, &config, now, cycle, &history).expect("a plan");
        // On stderr: stdout is the benchmarks' list when the test runner
        // asks for it (`--list`), which runs this set-up too.
        eprintln!(
            "{name}: {} robots, {} transmitters fire, cycle period {:.1} ms",
            views.len(),
            planned.packing.offsets.len(),
            planned.packing.period.as_secs_f64() * 1e3
        );
        group.bench_with_input(BenchmarkId::new("plan", name), &views, |b, views| {
            b.iter(|| plan(&table, black_box(views), &config, now, cycle, &history))
        });
    }
    group.finish();
}

// A plain `main` instead of `criterion_group!`, whose generated function
// cannot carry the doc comment the workspace lints ask for.
fn main() {
    let mut c = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(3))
        .configure_from_args();
    bench(&mut c);
    c.final_summary();
}
