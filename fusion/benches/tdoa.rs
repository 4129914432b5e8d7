//! Fixes per second of the TDOA solver: `closed_form` alone, `solve`
//! without refinement (checks, physical rejection, closed form, covariance,
//! output lists) and `solve` with Gauss-Newton, for 4, 8 and 16 signals, 2D
//! (known height) and 3D. The pseudo-ranges carry a
//! fixed 1 cm noise pattern so that the refinement has work to do.
//! `solve_consensus_2d`: cycles with a wrong id and reflections, which only
//! the consensus fallback cleans.

use std::f64::consts::TAU;
use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput};
use ickon_fusion::tdoa::{Mode, Signal, SolverConfig, closed_form, solve};
use nalgebra::Vector3;

/// `n` transmitters round a 6 x 5 m cell; in 3D at alternating heights so
/// that they are not coplanar.
fn transmitters(n: usize, three_d: bool) -> Vec<Vector3<f64>> {
    (0..n)
        .map(|i| {
            let a = i as f64 * TAU / n as f64 + 0.3;
            let z = if three_d {
                [3.0, 1.6, 2.4, 1.0][i % 4]
            } else {
                3.0
            };
            Vector3::new(3.0 + 2.8 * a.cos(), 2.5 + 2.3 * a.sin(), z)
        })
        .collect()
}

fn signals(n: usize, mode: Mode) -> Vec<Signal> {
    let p = Vector3::new(2.2, 1.9, mode.height_m().unwrap_or(0.8));
    transmitters(n, mode.height_m().is_none())
        .into_iter()
        .enumerate()
        .map(|(i, s)| Signal {
            tx_id: i as u32,
            tx_m: s,
            // A deterministic stand-in for 1 cm of noise.
            pseudo_range_m: (p - s).norm() + 4.0 + 0.01 * (i as f64 * 2.39).sin(),
            t_s: 0.0,
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let modes = [("2d", Mode::TwoD { height_m: 0.4 }), ("3d", Mode::ThreeD)];
    let mut group = c.benchmark_group("tdoa");
    group.throughput(Throughput::Elements(1));
    for (name, mode) in modes {
        for n in [4, 8, 16] {
            let s = signals(n, mode);
            let config = SolverConfig {
                mode,
                sigma_range_m: 0.01,
                ..SolverConfig::default()
            };
            assert!(solve(&s, &config).is_ok(), "{name} {n}");
            group.bench_with_input(
                BenchmarkId::new(format!("closed_form_{name}"), n),
                &s,
                |b, s| b.iter(|| closed_form(black_box(s), mode)),
            );
            let unrefined = SolverConfig {
                refine: false,
                ..config
            };
            group.bench_with_input(
                BenchmarkId::new(format!("solve_closed_{name}"), n),
                &s,
                |b, s| b.iter(|| solve(black_box(s), &unrefined)),
            );
            group.bench_with_input(
                BenchmarkId::new(format!("solve_refined_{name}"), n),
                &s,
                |b, s| b.iter(|| solve(black_box(s), &config)),
            );
        }
    }
    // The consensus fallback's worst case: leave-one-out cannot clean the
    // cycle (a wrong id heard far too early, and reflections).
    let mode = Mode::TwoD { height_m: 0.4 };
    for n in [8, 16] {
        let mut s = signals(n, mode);
        s[1].pseudo_range_m -= 40.0;
        for (k, extra_m) in [(3, 0.4), (5, 1.1)] {
            s[k].pseudo_range_m += extra_m;
        }
        if n == 16 {
            for (k, extra_m) in [(8, 0.7), (12, 0.9), (14, 0.3)] {
                s[k].pseudo_range_m += extra_m;
            }
        }
        let config = SolverConfig {
            mode,
            sigma_range_m: 0.01,
            ..SolverConfig::default()
        };
        let fix = solve(&s, &config).expect("the consensus finds the fix");
        assert!(fix.rejected.len() >= 3, "{n}: {fix:?}");
        group.bench_with_input(BenchmarkId::new("solve_consensus_2d", n), &s, |b, s| {
            b.iter(|| solve(black_box(s), &config))
        });
    }
    group.finish();
}

// A plain `main` instead of `criterion_group!`, whose generated function
// cannot carry the doc comment the workspace lints ask for.
fn main() {
    let mut c = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2))
        .configure_from_args();
    bench(&mut c);
    c.final_summary();
}
