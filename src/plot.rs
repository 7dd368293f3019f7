//! Shared plotting support for reports and filmstrips (plotters with the bitmap and SVG
//! backends). Text is drawn with DejaVu Sans, embedded in the binary, so that plots render the
//! same on every machine without system font libraries (plotters' `ab_glyph` font backend).

use std::sync::Once;

/// DejaVu Sans (see assets/DejaVuSans.LICENSE: Bitstream Vera / public-domain changes).
static DEJAVU_SANS: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Registers the embedded font under the family name `"sans-serif"` (once per process); call
/// before drawing any text with plotters.
pub fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is a fixed, valid TrueType file; a failure here would be a packaging error
        // that the plot tests catch (text would be missing), so it is not worth an error type.
        let _ = plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, DEJAVU_SANS);
    });
}

#[cfg(test)]
mod tests {
    use plotters::prelude::*;

    #[test]
    fn draws_text_into_a_png() {
        super::register_fonts();
        let path = std::env::temp_dir().join(format!("gelenk_plot_{}.png", std::process::id()));
        {
            let root = BitMapBackend::new(&path, (200, 100)).into_drawing_area();
            root.fill(&WHITE).unwrap();
            root.draw(&Text::new("gelenk", (10, 40), ("sans-serif", 30).into_font())).unwrap();
            root.present().unwrap();
        }
        let bytes = std::fs::read(&path).unwrap();
        std::fs::remove_file(&path).ok();
        assert_eq!(&bytes[1..4], b"PNG");
    }
}
