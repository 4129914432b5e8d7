//! Behaviour tests of the TDOA solver; helpers shared by the files below.

use nalgebra::Vector3;

use super::Signal;

mod bad_input;
mod bounds;
mod moving;
mod recovery;
mod reflections;

/// Noise-free signals from `tx` at `p`, with ids `10 + i`.
pub(super) fn signals_at(tx: &[Vector3<f64>], p: Vector3<f64>, bias_m: f64) -> Vec<Signal> {
    tx.iter()
        .enumerate()
        .map(|(i, &s)| Signal {
            tx_id: 10 + i as u32,
            tx_m: s,
            pseudo_range_m: (p - s).norm() + bias_m,
            t_s: 0.0,
        })
        .collect()
}

/// Eight transmitters in a 6 x 5 x 3 m room at several heights.
pub(super) fn room() -> Vec<Vector3<f64>> {
    vec![
        Vector3::new(0.0, 0.0, 3.0),
        Vector3::new(6.0, 0.0, 2.2),
        Vector3::new(6.0, 5.0, 3.0),
        Vector3::new(0.0, 5.0, 2.0),
        Vector3::new(3.0, 0.0, 1.5),
        Vector3::new(3.1, 5.0, 2.6),
        Vector3::new(0.0, 2.4, 1.2),
        Vector3::new(6.0, 2.6, 2.8),
    ]
}

/// `n` transmitters on a 3 m ceiling over a 6 x 5 m cell.
pub(super) fn ceiling(n: usize) -> Vec<Vector3<f64>> {
    (0..n)
        .map(|i| {
            let a = i as f64 * std::f64::consts::TAU / n as f64 + 0.3;
            Vector3::new(3.0 + 2.8 * a.cos(), 2.5 + 2.3 * a.sin(), 3.0)
        })
        .collect()
}
