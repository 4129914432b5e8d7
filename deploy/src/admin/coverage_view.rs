//! What `ickon admin coverage` prints: a summary of the grid and a text map
//! of the HDOP, or the whole grid as JSON.

use std::fmt::Write;

use ickon_proto::msg::admin::CoverageReport;
use serde::Serialize;

use super::format::to_json;

/// Figures of a coverage grid over the points on the floor.
#[derive(Debug, Serialize, PartialEq)]
pub struct CoverageSummary {
    /// Grid points on the floor.
    pub floor_points: usize,
    /// Of those, points where a 2D fix is possible (HDOP > 0).
    pub fix_points: usize,
    /// `fix_points / floor_points`.
    pub fix_share: f64,
    /// Fewest transmitters heard at a floor point.
    pub visible_min: Option<u32>,
    /// Median HDOP where a fix is possible.
    pub hdop_median: Option<f64>,
    /// 95th percentile of the HDOP where a fix is possible.
    pub hdop_p95: Option<f64>,
    /// Largest HDOP where a fix is possible.
    pub hdop_max: Option<f64>,
}

/// Summarises a coverage grid.
pub fn coverage_summary(r: &CoverageReport) -> CoverageSummary {
    let floor: Vec<usize> = (0..r.on_floor.len()).filter(|&i| r.on_floor[i]).collect();
    let mut hdops: Vec<f64> = floor
        .iter()
        .filter_map(|&i| r.hdop.get(i).copied())
        .filter(|&h| h > 0.0)
        .collect();
    hdops.sort_by(f64::total_cmp);
    let rank = |p: f64| -> Option<f64> {
        let n = hdops.len();
        (n > 0).then(|| hdops[(((p / 100.0) * n as f64).ceil() as usize).clamp(1, n) - 1])
    };
    CoverageSummary {
        floor_points: floor.len(),
        fix_points: hdops.len(),
        fix_share: if floor.is_empty() {
            0.0
        } else {
            hdops.len() as f64 / floor.len() as f64
        },
        visible_min: floor
            .iter()
            .filter_map(|&i| r.visible.get(i).copied())
            .min(),
        hdop_median: rank(50.0),
        hdop_p95: rank(95.0),
        hdop_max: hdops.last().copied(),
    }
}

/// `coverage --json`.
#[derive(Debug, Serialize)]
struct CoverageJson<'a> {
    schedule_version: u32,
    resolution_m: f64,
    height_m: f64,
    origin_x_m: f64,
    origin_y_m: f64,
    columns: u32,
    rows: u32,
    summary: CoverageSummary,
    on_floor: &'a [bool],
    visible: &'a [u32],
    hdop: &'a [f64],
}

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
pub fn coverage(r: &CoverageReport, json: bool) -> anyhow::Result<String> {
    let summary = coverage_summary(r);
    if json {
        return to_json(&CoverageJson {
            schedule_version: r.schedule_version,
            resolution_m: r.resolution_m,
            height_m: r.height_m,
            origin_x_m: r.origin_x_m,
            origin_y_m: r.origin_y_m,
            columns: r.columns,
            rows: r.rows,
            summary,
            on_floor: &r.on_floor,
            visible: &r.visible,
            hdop: &r.hdop,
        });
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
