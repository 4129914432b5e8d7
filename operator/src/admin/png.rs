//! The coverage heat map as a PNG: one square per grid point coloured by
//! its HDOP, titled with the colour key and with labelled axes (the font is
//! compiled in, see [`ickon_evaluation::chart`]); grid lines are 1 m apart.

use std::path::Path;

use ickon_proto::msg::admin::CoverageReport;
use plotters::prelude::*;

type Error = Box<dyn std::error::Error>;

/// What the colours mean, for the command to print.
pub const LEGEND: &str =
    "green HDOP <= 1 through yellow to red >= 5, grey: no fix, white: off the floor; grid 1 m";

/// Colour of one grid point: off the floor white, no fix grey, else HDOP
/// from green (<= 1) through yellow (3) to red (>= 5).
fn colour(on_floor: bool, hdop: f64) -> RGBColor {
    if !on_floor {
        return WHITE;
    }
    if hdop <= 0.0 || !hdop.is_finite() {
        return RGBColor(160, 160, 160);
    }
    let t = ((hdop - 1.0) / 4.0).clamp(0.0, 1.0);
    let (r, g) = if t < 0.5 {
        (2.0 * t, 1.0)
    } else {
        (1.0, 2.0 * (1.0 - t))
    };
    RGBColor((40.0 + 200.0 * r) as u8, (40.0 + 160.0 * g) as u8, 40)
}

/// Writes the heat map of `r` to `file`.
pub fn heat_map(file: &Path, r: &CoverageReport) -> Result<(), Error> {
    let (columns, rows) = (r.columns as usize, r.rows as usize);
    let sane = columns > 0
        && rows > 0
        && r.hdop.len() == columns * rows
        && r.on_floor.len() == r.hdop.len()
        && r.resolution_m.is_finite()
        && r.resolution_m > 0.0
        && r.origin_x_m.is_finite()
        && r.origin_y_m.is_finite();
    if !sane {
        return Err("the coverage grid is empty or inconsistent".into());
    }
    let res = r.resolution_m;
    let x0 = r.origin_x_m - res / 2.0;
    let y0 = r.origin_y_m - res / 2.0;
    let (x1, y1) = (x0 + columns as f64 * res, y0 + rows as f64 * res);
    // About 40 pixels per metre, at most 2000 pixels wide, aspect kept.
    let px_per_m = (2000.0 / (x1 - x0)).clamp(1.0, 40.0);
    // Room around the map for the title and the axis labels.
    let size = (
        ((x1 - x0) * px_per_m).ceil() as u32 + 80,
        ((y1 - y0) * px_per_m).ceil() as u32 + 90,
    );
    ickon_evaluation::chart::register();
    let root = BitMapBackend::new(file, size).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .margin(10)
        .caption(
            format!("coverage: {LEGEND}"),
            (ickon_evaluation::chart::FAMILY, 14),
        )
        .x_label_area_size(35)
        .y_label_area_size(45)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    ickon_evaluation::chart::axes(&mut chart, "x (m)", "y (m)")?;
    chart.draw_series((0..rows).flat_map(|row| {
        (0..columns).map(move |col| {
            let i = row * columns + col;
            let (x, y) = (x0 + col as f64 * res, y0 + row as f64 * res);
            Rectangle::new(
                [(x, y), (x + res, y + res)],
                colour(r.on_floor[i], r.hdop[i]).filled(),
            )
        })
    }))?;
    let line = RGBColor(90, 90, 90).mix(0.3);
    let mut v = x0.ceil();
    while v <= x1 {
        chart.draw_series(LineSeries::new([(v, y0), (v, y1)], line))?;
        v += 1.0;
    }
    let mut h = y0.ceil();
    while h <= y1 {
        chart.draw_series(LineSeries::new([(x0, h), (x1, h)], line))?;
        h += 1.0;
    }
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colours_run_from_green_to_red_with_grey_for_no_fix() {
        assert_eq!(colour(false, 1.0), WHITE);
        assert_eq!(colour(true, 0.0), RGBColor(160, 160, 160));
        let good = colour(true, 1.0);
        let bad = colour(true, 6.0);
        assert!(good.1 > good.0, "green dominates: {good:?}");
        assert!(bad.0 > bad.1, "red dominates: {bad:?}");
    }

    #[test]
    fn a_heat_map_is_written_and_a_broken_grid_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let mut r = CoverageReport {
            schedule_version: 1,
            origin_x_m: 0.25,
            origin_y_m: 0.25,
            resolution_m: 0.5,
            height_m: 0.5,
            columns: 4,
            rows: 2,
            on_floor: vec![true; 8],
            visible: vec![4; 8],
            hdop: vec![1.0, 2.0, 3.0, 6.0, 0.0, 1.1, 1.2, 1.3],
        };
        let file = dir.path().join("cov.png");
        heat_map(&file, &r).unwrap();
        let bytes = std::fs::read(&file).unwrap();
        assert_eq!(&bytes[..4], b"\x89PNG");
        r.hdop.pop();
        assert!(heat_map(&dir.path().join("bad.png"), &r).is_err());
    }
}
