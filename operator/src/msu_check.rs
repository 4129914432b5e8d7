//! `ickon msu check`: validate an MSU configuration file and print what it sets.

use std::path::Path;

use ickon_msu::MsuTuning;

use ickon_runtime::CommandError;

/// Validates an MSU configuration file and prints its summary on stdout,
/// and each value the estimator does not use as a warning on stderr; every
/// problem goes to stderr with exit code 2.
pub fn check(file: &Path) -> Result<(), CommandError> {
    let tuning = MsuTuning::load(file).map_err(|e| CommandError::bad_input(e.to_string()))?;
    let name = file.display();
    for w in &tuning.warnings {
        eprintln!("warning: {name}:{w}");
    }
    print!("{}", summary(&tuning, &name.to_string()));
    Ok(())
}

/// A human-readable summary of a valid configuration.
fn summary(t: &MsuTuning, file: &str) -> String {
    let gate = t
        .solver
        .residual_gate_m
        .map_or("4 sigma, at least 0.05 m".to_string(), |g| format!("{g} m"));
    let start = t.start.map_or("the site file's".to_string(), |s| {
        format!("[{}, {}] m, {:.1} deg", s[0], s[1], s[2].to_degrees())
    });
    format!(
        "MSU configuration {file}: valid, {} warning{}\n  estimator {}, start pose {start}\n  fix: arrival timing sigma {:.1} us, residual gate {gate}, largest sigma {} m\n  drive: wheel base {} m, {:.4e} m per tick\n",
        t.warnings.len(),
        if t.warnings.len() == 1 { "" } else { "s" },
        t.estimator_name(),
        t.solver.timing_sigma_s * 1e6,
        t.solver.max_fix_sigma_m,
        t.wheels.wheel_base_m,
        t.wheels.left_m_per_tick,
    )
}
