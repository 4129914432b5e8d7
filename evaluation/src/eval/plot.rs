//! PNG pictures like the ICKON paper's Figures 11-12 (truth as stars at the reference
//! points, the estimate as a line; the error per reference point) and a bar
//! chart comparing the estimators, titled and with labelled axes (the font
//! is compiled in, see [`crate::chart`]); grid lines are 1 m apart on the
//! floor plan and 50 mm apart on the error axis.

use std::path::Path;

use ickon_sim::{RunOutput, Score};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::chart::PALETTE;

type Error = Box<dyn std::error::Error>;

/// Writes every picture into `dir`.
pub fn write_all(
    dir: &Path,
    outputs: &[RunOutput],
    scores: &[Vec<Score>],
    flat: &[&Score],
) -> Result<(), Error> {
    std::fs::create_dir_all(dir)?;
    crate::chart::register();
    for (out, route_scores) in outputs.iter().zip(scores) {
        for (k, s) in route_scores.iter().enumerate() {
            for tour in 1..=out.config.tours {
                let file = dir.join(format!("{}_{}_tour{tour:02}.png", s.estimator, s.route));
                tour_picture(&file, out, k, tour, &s.estimator)?;
            }
        }
    }
    bars(&dir.join("comparison.png"), flat)
}

fn grid<DB: DrawingBackend>(
    chart: &mut ChartContext<
        '_,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    x: (f64, f64),
    y: (f64, f64),
    step_x: f64,
    step_y: f64,
) -> Result<(), Error>
where
    DB::ErrorType: 'static,
{
    let style = RGBColor(220, 220, 220);
    let mut v = (x.0 / step_x).ceil() * step_x;
    while v <= x.1 {
        chart.draw_series(LineSeries::new([(v, y.0), (v, y.1)], style))?;
        v += step_x;
    }
    let mut h = (y.0 / step_y).ceil() * step_y;
    while h <= y.1 {
        chart.draw_series(LineSeries::new([(x.0, h), (x.1, h)], style))?;
        h += step_y;
    }
    Ok(())
}

fn tour_picture(
    file: &Path,
    out: &RunOutput,
    k: usize,
    tour: u32,
    estimator: &str,
) -> Result<(), Error> {
    let root = BitMapBackend::new(file, (1400, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let title = format!(
        "{estimator} on {}, tour {tour} (profile {}, seed {})",
        out.config.route, out.config.profile.name, out.config.seed
    );
    let root = root.titled(&title, (crate::chart::FAMILY, 22))?;
    let (left, right) = root.split_horizontally(840);
    floor(&left, out, k, tour)?;
    errors(&right, out, k, tour)?;
    root.present()?;
    Ok(())
}

fn floor(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    out: &RunOutput,
    k: usize,
    tour: u32,
) -> Result<(), Error> {
    let pts: Vec<[f64; 2]> = out.truth_trace.iter().map(|p| p.xy_m).collect();
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in &pts {
        for i in 0..2 {
            lo[i] = lo[i].min(p[i] - 0.5);
            hi[i] = hi[i].max(p[i] + 0.5);
        }
    }
    // Equal scales on both axes.
    let (w, h) = (hi[0] - lo[0], hi[1] - lo[1]);
    let span = w.max(h * 830.0 / 550.0);
    let (x0, x1) = (lo[0], lo[0] + span);
    let (y0, y1) = (lo[1], lo[1] + span * 550.0 / 830.0);
    let mut chart = ChartBuilder::on(area)
        .margin(5)
        .caption(
            "truth at the reference points (x), estimate (line)",
            (crate::chart::FAMILY, 16),
        )
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    crate::chart::axes(&mut chart, "x (m)", "y (m)")?;
    grid(&mut chart, (x0, x1), (y0, y1), 1.0, 1.0)?;
    let est: Vec<(f64, f64)> = out.estimate_traces[k]
        .iter()
        .filter(|p| p.tour == tour)
        .map(|p| (p.xy_m[0], p.xy_m[1]))
        .collect();
    chart.draw_series(LineSeries::new(est, PALETTE[0].stroke_width(2)))?;
    chart.draw_series(
        out.refs
            .iter()
            .filter(|r| r.tour == tour)
            .map(|r| Cross::new((r.truth.x_m, r.truth.y_m), 5, RED.stroke_width(2))),
    )?;
    Ok(())
}

fn errors(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    out: &RunOutput,
    k: usize,
    tour: u32,
) -> Result<(), Error> {
    let errs: Vec<(f64, f64)> = out
        .refs
        .iter()
        .filter(|r| r.tour == tour)
        .filter_map(|r| {
            let e = r.estimates[k]?;
            Some((
                r.index as f64,
                1e3 * (e[0] - r.truth.x_m).hypot(e[1] - r.truth.y_m),
            ))
        })
        .collect();
    let top = errs.iter().map(|e| e.1).fold(100.0f64, f64::max) * 1.05;
    let n = out.refs_per_tour as f64;
    let mut chart = ChartBuilder::on(area)
        .margin(10)
        .caption(
            "error at each reference point (grey: 100 mm)",
            (crate::chart::FAMILY, 16),
        )
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(-1.0..n, 0.0..top)?;
    crate::chart::axes(&mut chart, "reference point", "error (mm)")?;
    grid(
        &mut chart,
        (-1.0, n),
        (0.0, top),
        10.0,
        if top > 1000.0 { 500.0 } else { 50.0 },
    )?;
    chart.draw_series(LineSeries::new(
        [(-1.0, 100.0), (n, 100.0)],
        RGBColor(150, 150, 150).stroke_width(2),
    ))?;
    chart.draw_series(LineSeries::new(errs.clone(), PALETTE[0].stroke_width(2)))?;
    chart.draw_series(errs.iter().map(|&p| Circle::new(p, 3, PALETTE[0].filled())))?;
    Ok(())
}

/// Mean error per route (groups) and estimator (bars, in `PALETTE` order), log scale 1 mm to 100 m.
fn bars(file: &Path, flat: &[&Score]) -> Result<(), Error> {
    let mut routes: Vec<&str> = Vec::new();
    let mut names: Vec<&str> = Vec::new();
    for s in flat {
        if !routes.contains(&s.route.as_str()) {
            routes.push(&s.route);
        }
        if !names.contains(&s.estimator.as_str()) {
            names.push(&s.estimator);
        }
    }
    let root = BitMapBackend::new(file, (1200, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let groups = routes.len() as f64;
    let mut chart = ChartBuilder::on(&root)
        .margin(20)
        .caption(
            "mean error per route and estimator (log scale)",
            (crate::chart::FAMILY, 22),
        )
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..groups, (1.0f64..100_000.0f64).log_scale())?;
    let route_names: Vec<String> = routes.iter().map(|r| r.to_string()).collect();
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(routes.len() * 2 + 1)
        .x_label_formatter(&|x| {
            // Name each group at its centre, nothing elsewhere.
            let g = (x - 0.5).round();
            if (x - 0.5 - g).abs() < 1e-6 && g >= 0.0 {
                route_names.get(g as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_desc("mean error (mm)")
        .label_style((crate::chart::FAMILY, 14))
        .draw()?;
    // The decade above 10 m keeps the legend clear of the bars.
    for decade in [1.0, 10.0, 100.0, 1000.0, 10_000.0, 100_000.0] {
        chart.draw_series(LineSeries::new(
            [(0.0, decade), (groups, decade)],
            RGBColor(200, 200, 200),
        ))?;
    }
    let width = 0.8 / names.len().max(1) as f64;
    for (g, route) in routes.iter().enumerate() {
        for (i, name) in names.iter().enumerate() {
            if let Some(s) = flat
                .iter()
                .find(|s| s.route == *route && s.estimator == *name)
            {
                let x0 = g as f64 + 0.1 + i as f64 * width;
                let v = s.mean.mean_mm.clamp(1.0, 100_000.0);
                let colour = PALETTE[i % PALETTE.len()];
                let series = chart.draw_series([Rectangle::new(
                    [(x0, 1.0), (x0 + width * 0.9, v)],
                    colour.filled(),
                )])?;
                if g == 0 {
                    series.label(*name).legend(move |(x, y)| {
                        Rectangle::new([(x, y - 6), (x + 14, y + 6)], colour.filled())
                    });
                }
            }
        }
    }
    crate::chart::legend(&mut chart)?;
    root.present()?;
    Ok(())
}
