//! The fuzzing kit (feature `fuzz`, and this crate's own tests): a case
//! count and deterministic seed for every fuzz target, values of any wire
//! type ([`values`]), mutations of valid encodings ([`mutate`]) and the
//! extreme numbers that break arithmetic ([`extreme`]).
//!
//! Fuzz targets are `proptest` properties named `fuzz_*`, run by the
//! ordinary test runner: `ICKON_FUZZ_CASES` cases each ([`DEFAULT_CASES`]
//! when unset), e.g. `ICKON_FUZZ_CASES=1000000 cargo nextest run
//! --cargo-profile fuzz -p ickon-msu fuzz_` (the `fuzz` profile: release
//! optimisation with overflow checks; the README's "Fuzzing" gives the
//! commands for every crate).

pub mod extreme;
pub mod mutate;
pub mod values;

use proptest::test_runner::{Config, RngAlgorithm, RngSeed};

/// Cases per target when `ICKON_FUZZ_CASES` is unset: the whole fuzz set
/// stays within seconds of a debug test run.
pub const DEFAULT_CASES: u32 = 256;

/// The seed of every target: a failure found once is found again.
pub const SEED: u64 = 0x1C0_F022;

/// The case count: `ICKON_FUZZ_CASES`, or [`DEFAULT_CASES`] when unset or
/// not a number.
pub fn cases() -> u32 {
    cases_or(DEFAULT_CASES)
}

fn cases_or(default: u32) -> u32 {
    std::env::var("ICKON_FUZZ_CASES")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(default)
}

/// The proptest configuration of a fuzz target: [`cases`] cases from the
/// fixed [`SEED`], no failure files (a failure prints its input and the
/// seed reproduces it), no forking.
pub fn config() -> Config {
    config_for(DEFAULT_CASES)
}

/// [`config`] for a slow target (a core fed event sequences): `default`
/// cases when `ICKON_FUZZ_CASES` is unset.
pub fn config_for(default: u32) -> Config {
    Config {
        cases: cases_or(default),
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(SEED),
        failure_persistence: None,
        max_shrink_iters: 2_000,
        ..Config::default()
    }
}

/// Entropy for [`values::draw`]: enough bytes for a message with a few
/// nested sequences.
pub fn entropy() -> proptest::collection::VecStrategy<proptest::num::u8::Any> {
    proptest::collection::vec(proptest::prelude::any::<u8>(), 0..384)
}

#[cfg(test)]
mod decode_tests;
#[cfg(test)]
mod file_tests;
