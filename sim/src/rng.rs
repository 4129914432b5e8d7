//! Independent random streams derived from the run seed.
//!
//! Each sensor of each robot draws from its own `ChaCha8Rng`, seeded from the
//! run seed and a stream label, so adding a draw to one sensor never shifts
//! the numbers of another, and the same seed gives the same numbers on any
//! machine (ChaCha is specified bit for bit).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The stream for `label` under `seed` (FNV-1a of the label mixed with the seed).
pub fn stream(seed: u64, label: &str) -> ChaCha8Rng {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in label.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    ChaCha8Rng::seed_from_u64(seed ^ h.rotate_left(17))
}

/// A normal draw with standard deviation `sigma` (0 or less gives exactly 0,
/// without consuming a draw, so that `ideal` stays noise-free).
pub fn normal(rng: &mut ChaCha8Rng, sigma: f64) -> f64 {
    if sigma > 0.0 && sigma.is_finite() {
        Normal::new(0.0, sigma).map_or(0.0, |n| n.sample(rng))
    } else {
        0.0
    }
}

/// True with probability `p` (never for `p <= 0`, without consuming a draw).
pub fn chance(rng: &mut ChaCha8Rng, p: f64) -> bool {
    p > 0.0 && rand::Rng::random::<f64>(rng) < p
}

/// A uniform draw in `[lo, hi]`.
pub fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rand::Rng::random::<f64>(rng)
}
