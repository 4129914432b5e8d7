//! The one font of every picture: DejaVu Sans, compiled in (licence in
//! `deploy/assets/DejaVuSans-LICENSE.txt`) and drawn by plotters' pure-Rust
//! `ab_glyph` backend, so that labelled PNGs need no system library and
//! look the same on every machine.

use std::sync::OnceLock;

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

#[cfg(test)]
mod tests {
    #[test]
    fn the_compiled_in_font_registers() {
        assert!(super::register());
    }
}
