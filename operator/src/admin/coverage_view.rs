//! What `ickon admin coverage` prints: a summary of the grid and a text map
//! of the HDOP, or the whole grid as JSON.

use std::fmt::Write;

use ickon_central::admin_json::CoverageJson;
use ickon_central::admin_json::coverage_summary;
use ickon_proto::msg::admin::CoverageReport;

use super::format::{FormatError, to_json};

/// The map character of one grid point: blank off the floor, `x` without a
/// fix, else the HDOP class `1` (< 1.5) to `5` (>= 8).
fn map_char(on_floor: bool, hdop: f64) -> char {
    match (on_floor, hdop) {
        (false, _) => ' ',
        (true, h) if h <= 0.0 => 'x',
        (true, h) if h < 1.5 => '1',
        (true, h) if h < 2.5 => '2',
        (true, h) if h < 4.0 => '3',
        (true, h) if h < 8.0 => '4',
        _ => '5',
    }
}

/// Widest text map, characters; finer grids are shown every k-th point.
const MAP_WIDTH: usize = 100;

/// `coverage`.
pub fn coverage(r: &CoverageReport, json: bool) -> Result<String, FormatError> {
    let summary = coverage_summary(r);
    if json {
        return to_json(&CoverageJson::from(r));
    }
    let opt = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.2}"));
    let mut out = String::new();
    let _ = writeln!(
        out,
        "coverage for schedule v{}: {} x {} grid, {:.2} m spacing, at {:.2} m height",
        r.schedule_version, r.columns, r.rows, r.resolution_m, r.height_m
    );
    let _ = writeln!(
        out,
        "floor points {}, with a 2D fix {} ({:.1} %), fewest transmitters heard {}",
        summary.floor_points,
        summary.fix_points,
        summary.fix_share * 100.0,
        summary.visible_min.map_or("-".into(), |v| v.to_string())
    );
    let _ = writeln!(
        out,
        "HDOP median {}, p95 {}, max {}",
        opt(summary.hdop_median),
        opt(summary.hdop_p95),
        opt(summary.hdop_max)
    );
    let (columns, rows) = (r.columns as usize, r.rows as usize);
    let step = columns.div_ceil(MAP_WIDTH).max(1);
    let _ = writeln!(
        out,
        "map (north up, one character per {:.2} m; HDOP 1: < 1.5, 2: < 2.5, 3: < 4, 4: < 8, 5: >= 8, x: no fix):",
        r.resolution_m * step as f64
    );
    for row in (0..rows).rev().step_by(step) {
        let line: String = (0..columns)
            .step_by(step)
            .map(|col| {
                let i = row * columns + col;
                map_char(
                    r.on_floor.get(i).copied().unwrap_or(false),
                    r.hdop.get(i).copied().unwrap_or(0.0),
                )
            })
            .collect();
        let _ = writeln!(out, "  |{}", line.trim_end());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_summary_counts_only_floor_points() {
        let r = CoverageReport {
            schedule_version: 1,
            origin_x_m: 0.125,
            origin_y_m: 0.125,
            resolution_m: 0.25,
            height_m: 0.5,
            columns: 3,
            rows: 2,
            on_floor: vec![true, true, true, false, true, true],
            visible: vec![4, 2, 5, 0, 6, 3],
            hdop: vec![1.2, 0.0, 1.0, 0.0, 3.0, 9.0],
        };
        let s = coverage_summary(&r);
        assert_eq!(
            (s.floor_points, s.fix_points, s.visible_min),
            (5, 4, Some(2))
        );
        assert_eq!(s.hdop_max, Some(9.0));
        assert_eq!(s.hdop_median, Some(1.2));
        let text = coverage(&r, false).unwrap();
        // North up: the second row (y = 0.375) first.
        assert!(text.contains("  | 35\n  |1x1\n"), "{text}");
    }
}
