//! `ickon replay mcap --plot DIR`: per robot, the top view (truth in black,
//! each replayed estimator in colour, grid every metre) and the position
//! error over time (grid every 10 s and 50 mm), with labelled axes and a
//! legend (`<robot>_trajectory.png`, `<robot>_error.png`).

use std::path::Path;

use ickon_proto::msg::robot::Truth;
use plotters::prelude::*;

use super::feed::Published;
use super::score::truth_at;
use ickon_evaluation::chart::{DrawError, FAMILY, PALETTE, axes, legend};
use ickon_evaluation::chart::{gridlines, span};

const GRID: RGBColor = RGBColor(220, 220, 220);
/// Errors above this are drawn at it (a lost estimator would flatten the rest).
const ERROR_TOP_M: f64 = 0.5;

/// Writes both pictures of one robot into `dir`.
pub fn write(
    dir: &Path,
    robot: &str,
    truth: &[Truth],
    tracks: &[(&str, &[Published])],
) -> Result<(), DrawError> {
    std::fs::create_dir_all(dir)?;
    ickon_evaluation::chart::register();
    let mut truth = truth.to_vec();
    truth.sort_by_key(|t| t.robot_clock);
    trajectory(
        &dir.join(format!("{robot}_trajectory.png")),
        robot,
        &truth,
        tracks,
    )?;
    errors(
        &dir.join(format!("{robot}_error.png")),
        robot,
        &truth,
        tracks,
    )
}

fn trajectory(
    file: &Path,
    robot: &str,
    truth: &[Truth],
    tracks: &[(&str, &[Published])],
) -> Result<(), DrawError> {
    let root = BitMapBackend::new(file, (900, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    let xs = truth.iter().map(|t| t.x_m).chain(
        tracks
            .iter()
            .flat_map(|(_, p)| p.iter().map(|p| p.pose.x_m)),
    );
    let ys = truth.iter().map(|t| t.y_m).chain(
        tracks
            .iter()
            .flat_map(|(_, p)| p.iter().map(|p| p.pose.y_m)),
    );
    let (x, y) = (span(xs), span(ys));
    let half = (x.1 - x.0).max(y.1 - y.0) / 2.0 + 0.5;
    let (cx, cy) = ((x.0 + x.1) / 2.0, (y.0 + y.1) / 2.0);
    let (x, y) = ((cx - half, cx + half), (cy - half, cy + half));
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .caption(
            format!("{robot}: truth (black) and the replayed estimators"),
            (FAMILY, 20),
        )
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    axes(&mut chart, "x (m)", "y (m)")?;
    for line in gridlines(x, y, (1.0, 1.0)) {
        chart.draw_series(LineSeries::new(line, GRID))?;
    }
    for (k, (name, poses)) in tracks.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        chart
            .draw_series(LineSeries::new(
                poses.iter().map(|p| (p.pose.x_m, p.pose.y_m)),
                colour,
            ))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], colour.stroke_width(3)));
    }
    chart
        .draw_series(LineSeries::new(truth.iter().map(|t| (t.x_m, t.y_m)), BLACK))?
        .label("truth")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK.stroke_width(3)));
    legend(&mut chart)?;
    root.present()?;
    Ok(())
}

fn errors(
    file: &Path,
    robot: &str,
    truth: &[Truth],
    tracks: &[(&str, &[Published])],
) -> Result<(), DrawError> {
    let root = BitMapBackend::new(file, (1400, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let t0 = tracks
        .iter()
        .filter_map(|(_, p)| p.first())
        .map(|p| p.pose.stamp)
        .min();
    let Some(t0) = t0 else {
        root.present()?;
        return Ok(());
    };
    let series: Vec<Vec<(f64, f64)>> = tracks
        .iter()
        .map(|(_, poses)| {
            poses
                .iter()
                .filter_map(|p| {
                    let [x, y, _] = truth_at(truth, p.pose.stamp)?;
                    let e = (p.pose.x_m - x).hypot(p.pose.y_m - y);
                    Some((p.pose.stamp.since(t0).as_secs_f64(), e.min(ERROR_TOP_M)))
                })
                .collect()
        })
        .collect();
    let t = span(series.iter().flatten().map(|(t, _)| *t));
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .caption(
            format!(
                "{robot}: position error against the truth (clipped at {:.0} mm)",
                ERROR_TOP_M * 1e3
            ),
            (FAMILY, 20),
        )
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(t.0..t.1, 0.0..ERROR_TOP_M)?;
    axes(&mut chart, "time (s)", "error (m)")?;
    for line in gridlines(t, (0.0, ERROR_TOP_M), (10.0, 0.05)) {
        chart.draw_series(LineSeries::new(line, GRID))?;
    }
    for (k, ((name, _), points)) in tracks.iter().zip(&series).enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        chart
            .draw_series(LineSeries::new(points.iter().copied(), colour))?
            .label(*name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], colour.stroke_width(3)));
    }
    legend(&mut chart)?;
    root.present()?;
    Ok(())
}
