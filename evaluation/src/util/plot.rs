//! PNG pictures of a replay: the trajectory (top view; height over time),
//! truth in black and each estimator in its colour, and the 3D error over
//! time, titled, with labelled axes and a legend (the font is compiled in,
//! see [`crate::chart`]); grid lines are 1 m apart on the floor, 0.5 m on
//! the height axis, 10 s on the time axes and 0.1 m on the error axis.

use std::path::Path;

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::score::SeriesPoint;
use crate::chart::{axes, legend};

type Error = Box<dyn std::error::Error>;
type Chart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Estimator colours, in the order of the report.
const PALETTE: [RGBColor; 3] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
];
const GRID: RGBColor = RGBColor(220, 220, 220);

/// Writes `<stem>_trajectory.png` and `<stem>_error.png` into `dir`;
/// `names[k]` is the estimator of `series[k]`.
pub fn write_all(
    dir: &Path,
    stem: &str,
    names: &[&str],
    series: &[&[SeriesPoint]],
) -> Result<(), Error> {
    std::fs::create_dir_all(dir)?;
    crate::chart::register();
    trajectory(
        &dir.join(format!("{stem}_trajectory.png")),
        stem,
        names,
        series,
    )?;
    errors(&dir.join(format!("{stem}_error.png")), stem, names, series)
}

fn span(values: impl Iterator<Item = f64>, margin: f64) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if lo.is_finite() {
        (lo - margin, hi + margin)
    } else {
        (0.0, 1.0)
    }
}

fn grid(chart: &mut Chart, x: (f64, f64), y: (f64, f64), step: (f64, f64)) -> Result<(), Error> {
    let mut v = (x.0 / step.0).ceil() * step.0;
    while v <= x.1 {
        chart.draw_series(LineSeries::new([(v, y.0), (v, y.1)], GRID))?;
        v += step.0;
    }
    let mut h = (y.0 / step.1).ceil() * step.1;
    while h <= y.1 {
        chart.draw_series(LineSeries::new([(x.0, h), (x.1, h)], GRID))?;
        h += step.1;
    }
    Ok(())
}

fn all(series: &[&[SeriesPoint]]) -> impl Iterator<Item = SeriesPoint> {
    series.iter().flat_map(|s| s.iter().copied())
}

fn trajectory(
    file: &Path,
    stem: &str,
    names: &[&str],
    series: &[&[SeriesPoint]],
) -> Result<(), Error> {
    let root = BitMapBackend::new(file, (1400, 640)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.titled(
        &format!("{stem}: truth (black) and estimates"),
        (crate::chart::FAMILY, 22),
    )?;
    let (left, right) = root.split_horizontally(600);
    let pts = || all(series).flat_map(|p| [p.estimate_m, p.truth_m]);
    let x = span(pts().map(|p| p[0]), 0.3);
    let y = span(pts().map(|p| p[1]), 0.3);
    // Same scale on both floor axes.
    let half = (x.1 - x.0).max(y.1 - y.0) / 2.0;
    let (cx, cy) = ((x.0 + x.1) / 2.0, (y.0 + y.1) / 2.0);
    let (x, y) = ((cx - half, cx + half), (cy - half, cy + half));
    let mut top = ChartBuilder::on(&left)
        .margin(10)
        .caption("top view", (crate::chart::FAMILY, 16))
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    axes(&mut top, "x (m)", "y (m)")?;
    grid(&mut top, x, y, (1.0, 1.0))?;
    let t = span(all(series).map(|p| p.t_s), 0.0);
    let z = span(pts().map(|p| p[2]), 0.2);
    let mut side = ChartBuilder::on(&right)
        .margin(10)
        .caption("height over time", (crate::chart::FAMILY, 16))
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(t.0..t.1, z.0..z.1)?;
    axes(&mut side, "time (s)", "z (m)")?;
    grid(&mut side, t, z, (10.0, 0.5))?;
    for (k, s) in series.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        top.draw_series(LineSeries::new(
            s.iter().map(|p| (p.estimate_m[0], p.estimate_m[1])),
            colour,
        ))?;
        side.draw_series(LineSeries::new(
            s.iter().map(|p| (p.t_s, p.estimate_m[2])),
            colour,
        ))?
        .label(names.get(k).copied().unwrap_or("?"))
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], colour.stroke_width(3)));
    }
    // The truth last, on top: from the densest series.
    if let Some(s) = series.iter().max_by_key(|s| s.len()) {
        top.draw_series(LineSeries::new(
            s.iter().map(|p| (p.truth_m[0], p.truth_m[1])),
            BLACK,
        ))?;
        side.draw_series(LineSeries::new(
            s.iter().map(|p| (p.t_s, p.truth_m[2])),
            BLACK,
        ))?
        .label("truth")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 16, y)], BLACK.stroke_width(3)));
    }
    legend(&mut side)?;
    root.present()?;
    Ok(())
}

fn errors(file: &Path, stem: &str, names: &[&str], series: &[&[SeriesPoint]]) -> Result<(), Error> {
    let root = BitMapBackend::new(file, (1400, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let err = |p: &SeriesPoint| {
        let d: [f64; 3] = std::array::from_fn(|k| p.estimate_m[k] - p.truth_m[k]);
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    };
    let t = span(all(series).map(|p| p.t_s), 0.0);
    let top = span(all(series).map(|p| err(&p)), 0.0).1.clamp(0.1, 1.0);
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .caption(
            format!("{stem}: 3D error against the truth (clipped at {top:.1} m)"),
            (crate::chart::FAMILY, 20),
        )
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(t.0..t.1, 0.0..top)?;
    axes(&mut chart, "time (s)", "3D error (m)")?;
    grid(&mut chart, t, (0.0, top), (10.0, 0.1))?;
    for (k, s) in series.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        chart
            .draw_series(LineSeries::new(
                s.iter().map(|p| (p.t_s, err(p).min(top))),
                colour,
            ))?
            .label(names.get(k).copied().unwrap_or("?"))
            .legend(move |(x, y)| PathElement::new([(x, y), (x + 16, y)], colour.stroke_width(3)));
    }
    legend(&mut chart)?;
    root.present()?;
    Ok(())
}
