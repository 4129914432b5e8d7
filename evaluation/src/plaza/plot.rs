//! PNG pictures of a Plaza replay: the top view (truth in black, the
//! filter and dead reckoning in colour, grid every 10 m) and the 2D error
//! over time (grid every 60 s and 1 m), with labelled axes and a legend.

use std::path::Path;

use plotters::prelude::*;

use super::report::{RunReport, Sample};
use crate::chart::{DrawError, FAMILY, axes, gridlines, legend, span};

const FILTER: RGBColor = RGBColor(31, 119, 180);
const ODOMETRY: RGBColor = RGBColor(255, 127, 14);
const GRID: RGBColor = RGBColor(220, 220, 220);

/// Writes `<run>_trajectory.png` and `<run>_error.png` into `dir`.
pub fn write(dir: &Path, r: &RunReport) -> Result<(), DrawError> {
    std::fs::create_dir_all(dir)?;
    crate::chart::register();
    trajectory(&dir.join(format!("{}_trajectory.png", r.run)), r)?;
    errors(&dir.join(format!("{}_error.png", r.run)), r)
}

fn trajectory(file: &Path, r: &RunReport) -> Result<(), DrawError> {
    let root = BitMapBackend::new(file, (900, 900)).into_drawing_area();
    root.fill(&WHITE)?;
    // The view follows the truth (dead reckoning may wander far off).
    let x = span(r.filter_track.iter().map(|s| s.truth_m[0]));
    let y = span(r.filter_track.iter().map(|s| s.truth_m[1]));
    let half = (x.1 - x.0).max(y.1 - y.0) / 2.0 + 10.0;
    let (cx, cy) = ((x.0 + x.1) / 2.0, (y.0 + y.1) / 2.0);
    let (x, y) = ((cx - half, cx + half), (cy - half, cy + half));
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .caption(
            format!("{}: truth (black), tdoa-ekf and dead reckoning", r.run),
            (FAMILY, 20),
        )
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    axes(&mut chart, "x (m)", "y (m)")?;
    for line in gridlines(x, y, (10.0, 10.0)) {
        chart.draw_series(LineSeries::new(line, GRID))?;
    }
    let inside = |s: &Sample| {
        (x.0..=x.1).contains(&s.estimate_m[0]) && (y.0..=y.1).contains(&s.estimate_m[1])
    };
    for (track, colour, name) in [
        (&r.odometry_track, ODOMETRY, "dead reckoning"),
        (&r.filter_track, FILTER, "tdoa-ekf"),
    ] {
        chart
            .draw_series(LineSeries::new(
                track
                    .iter()
                    .filter(|s| inside(s))
                    .map(|s| (s.estimate_m[0], s.estimate_m[1])),
                colour,
            ))?
            .label(name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], colour.stroke_width(3)));
    }
    chart
        .draw_series(LineSeries::new(
            r.filter_track.iter().map(|s| (s.truth_m[0], s.truth_m[1])),
            BLACK,
        ))?
        .label("truth")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK.stroke_width(3)));
    legend(&mut chart)?;
    root.present()?;
    Ok(())
}

fn errors(file: &Path, r: &RunReport) -> Result<(), DrawError> {
    let root = BitMapBackend::new(file, (1400, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let err = |s: &Sample| (s.estimate_m[0] - s.truth_m[0]).hypot(s.estimate_m[1] - s.truth_m[1]);
    let t = span(r.filter_track.iter().map(|s| s.t_s));
    let top = 5.0;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .caption(
            format!(
                "{}: 2D error against the truth (clipped at {top:.0} m)",
                r.run
            ),
            (FAMILY, 20),
        )
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(t.0..t.1, 0.0..top)?;
    axes(&mut chart, "time (s)", "2D error (m)")?;
    for line in gridlines(t, (0.0, top), (60.0, 1.0)) {
        chart.draw_series(LineSeries::new(line, GRID))?;
    }
    for (track, colour, name) in [
        (&r.odometry_track, ODOMETRY, "dead reckoning"),
        (&r.filter_track, FILTER, "tdoa-ekf"),
    ] {
        chart
            .draw_series(LineSeries::new(
                track.iter().map(|s| (s.t_s, err(s).min(top))),
                colour,
            ))?
            .label(name)
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], colour.stroke_width(3)));
    }
    legend(&mut chart)?;
    root.present()?;
    Ok(())
}
