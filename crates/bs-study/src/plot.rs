//! Figures for `cargo xtask chart` and `stability`: every figure is drawn once by code that is
//! generic over the plotters backend and saved as both SVG and PNG. The PNG text uses the
//! embedded DejaVu Sans (crates/bs-preview/assets, Bitstream Vera licence), so no system fonts are needed.

use std::path::Path;
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

/// A figure: draws itself on any plotters backend.
pub trait Figure {
    /// Draws the figure filling `root`.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String>;
}

/// Any plotters error as a message.
pub fn err<E: std::fmt::Debug>(e: E) -> String {
    format!("{e:?}")
}

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        static FONT: &[u8] = include_bytes!("../../bs-preview/assets/DejaVuSans.ttf");
        // Registration fails only for a malformed font file, which the assets test catches.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// Saves `figure` as `<stem>.svg` and `<stem>.png`, `size` pixels.
pub fn save(figure: &impl Figure, stem: &Path, size: (u32, u32)) -> Result<(), String> {
    register_font();
    if let Some(dir) = stem.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let svg = stem.with_extension("svg");
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        figure.draw(&root)?;
        root.present().map_err(|e| format!("{}: {e:?}", svg.display()))?;
    }
    let png = stem.with_extension("png");
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        figure.draw(&root)?;
        root.present().map_err(|e| format!("{}: {e:?}", png.display()))?;
    }
    Ok(())
}

/// A qualitative palette (Okabe–Ito, readable by colour-blind readers).
pub const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(240, 228, 66),
];

#[cfg(test)]
mod tests {
    use super::*;

    struct Diagonal;

    impl Figure for Diagonal {
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
            let mut chart = ChartBuilder::on(root)
                .caption("test", ("sans-serif", 20))
                .x_label_area_size(30)
                .y_label_area_size(30)
                .build_cartesian_2d(0.0..1.0, 0.0..1.0)
                .map_err(err)?;
            chart.configure_mesh().draw().map_err(err)?;
            chart
                .draw_series(LineSeries::new([(0.0, 0.0), (1.0, 1.0)], &PALETTE[0]))
                .map_err(err)?;
            Ok(())
        }
    }

    /// Both files are written. The bitmap backend draws text only with a registered font (it
    /// fails with a font error otherwise), so a successful PNG save shows the embedded font
    /// loads.
    #[test]
    fn saves_svg_and_png_with_text() {
        let dir = std::env::temp_dir().join(format!("bs-plot-{}", std::process::id()));
        let stem = dir.join("diag");
        save(&Diagonal, &stem, (320, 240)).unwrap();
        let svg = std::fs::read_to_string(stem.with_extension("svg")).unwrap();
        assert!(svg.contains("<svg") && svg.contains("\ntest\n</text>"), "{svg}");
        let png = std::fs::read(stem.with_extension("png")).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
