//! The one font of every picture: DejaVu Sans, compiled in (licence in
//! `evaluation/assets/DejaVuSans-LICENSE.txt`) and drawn by plotters' pure-Rust
//! `ab_glyph` backend, so that labelled PNGs need no system library and
//! look the same on every machine. Also the two pieces of chart styling
//! every picture shares: named axes and the legend, and the grid of a
//! picture's extent.

use std::sync::OnceLock;

use plotters::coord::CoordTranslate;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

/// Series colours, in the order of the series (estimators in a report):
/// one palette, so that an estimator has the same colour in every picture.
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// The family name pictures ask for.
pub const FAMILY: &str = "sans-serif";

static REGISTERED: OnceLock<bool> = OnceLock::new();

/// Registers the font once; `false` if plotters refused it (pictures are
/// then drawn without text rather than not at all).
pub fn register() -> bool {
    *REGISTERED.get_or_init(|| {
        plotters::style::register_font(
            FAMILY,
            plotters::style::FontStyle::Normal,
            include_bytes!("../assets/DejaVuSans.ttf"),
        )
        .is_ok()
    })
}

/// Errors of drawing a picture.
pub type DrawError = Box<dyn std::error::Error>;

/// Draws the axes of `chart` with their names and tick labels, without
/// mesh lines (each picture draws its own grid).
pub fn axes<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    x_desc: &str,
    y_desc: &str,
) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style((FAMILY, 13))
        .draw()?;
    Ok(())
}

/// Draws the legend of the series labelled so far, top right.
pub fn legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
) -> Result<(), DrawError>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font((FAMILY, 14))
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    Ok(())
}

/// The range of `values`, or 0..1 when they span nothing.
pub fn span(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if lo.is_finite() && hi > lo {
        (lo, hi)
    } else {
        (0.0, 1.0)
    }
}

/// Grid lines every `step` across the box `x` by `y`.
pub fn gridlines(x: (f64, f64), y: (f64, f64), step: (f64, f64)) -> Vec<[(f64, f64); 2]> {
    let mut out = Vec::new();
    let mut v = (x.0 / step.0).ceil() * step.0;
    while v <= x.1 {
        out.push([(v, y.0), (v, y.1)]);
        v += step.0;
    }
    let mut h = (y.0 / step.1).ceil() * step.1;
    while h <= y.1 {
        out.push([(x.0, h), (x.1, h)]);
        h += step.1;
    }
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_compiled_in_font_registers() {
        assert!(super::register());
    }
}
