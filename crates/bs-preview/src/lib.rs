//! Pictures for brainshift: a PNG a user looks at instead of reading numbers. [`render`]
//! draws three orthogonal slices (rows) through the point of largest displacement, each as
//! the pre-operative image, the warped image and the displacement magnitude in mm with the
//! deformed brain's outline (columns), and a colour bar in mm; with σ on the slices (a
//! fitted answer's uncertainty) a fourth column shows it, with its own bar.
//!
//! The input is plain data ([`Slice`]: a grid of numbers with its pixel size in mm and an
//! inside mask): this crate knows no meshes, images or files other than the PNG it writes.
//! Text is drawn with the embedded DejaVu Sans (assets/, Bitstream Vera licence), so no
//! system font is needed.
//!
//! Files: `lib.rs` only (`render`, the `viridis` colour map, `PreviewError`); the font is
//! in `assets/`.
//!
//! *Architecture invariant:* bs-preview knows bs-image's [`Slice`] (plain data) and
//! bs-atomic's writer, nothing else of brainshift; bs-register cuts the slices
//! (`planes.rs`), bs-cli calls [`render`].

use std::path::Path;
use std::sync::Once;

pub use bs_image::Slice;
use plotters::prelude::*;

/// What went wrong drawing or writing the picture.
#[derive(Debug)]
pub struct PreviewError(pub String);

impl std::fmt::Display for PreviewError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for PreviewError {}

const PANEL: u32 = 300;
const TOP: u32 = 56;
const ROW_TITLE: u32 = 22;
const BAR: u32 = 110;

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// A perceptually ordered colour map (viridis, 9 stops, linearly interpolated).
pub fn viridis(t: f64) -> RGBColor {
    const STOPS: [(u8, u8, u8); 9] = [
        (68, 1, 84),
        (71, 44, 122),
        (59, 81, 139),
        (44, 113, 142),
        (33, 144, 141),
        (39, 173, 129),
        (92, 200, 99),
        (170, 220, 50),
        (253, 231, 37),
    ];
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 } * 8.0;
    let i = (t.floor() as usize).min(7);
    let f = t - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let mix = |x: u8, y: u8| (x as f64 + f * (y as f64 - x as f64)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Draws `slices` (normally three) into a PNG at `path`, written atomically (a temporary
/// file renamed into place). `window`: the grey-level range of the two images; `max_mm`:
/// the top of the colour bar. `title` heads the picture.
pub fn render(
    path: &Path,
    title: &str,
    slices: &[Slice],
    window: [f32; 2],
    max_mm: f64,
) -> Result<(), PreviewError> {
    register_font();
    let rows = slices.len() as u32;
    let size = (
        columns(slices) * PANEL + (columns(slices) - 2) * BAR,
        TOP + rows * (PANEL + ROW_TITLE) + 10,
    );
    // The temporary name keeps `.png`: the bitmap backend encodes by the extension.
    bs_atomic::write_via(path, ".png", |tmp| {
        draw(tmp, size, title, slices, window, max_mm).map_err(|e| std::io::Error::other(e.0))
    })
    .map_err(|e| PreviewError(format!("{}: could not write the preview: {e}", path.display())))
}

/// Three columns, or four with σ on every slice (the σ column sits after the first bar).
fn columns(slices: &[Slice]) -> u32 {
    if !slices.is_empty() && slices.iter().all(|s| s.sigma.is_some()) { 4 } else { 3 }
}

/// The largest σ on the slices (the top of the σ bar).
fn max_sigma(slices: &[Slice]) -> f64 {
    slices
        .iter()
        .flat_map(|s| s.sigma.iter().flatten())
        .fold(0.0f32, |m, &v| if v.is_finite() { m.max(v) } else { m }) as f64
}

fn err<E: std::fmt::Debug>(e: E) -> PreviewError {
    PreviewError(format!("{e:?}"))
}

fn draw(
    path: &Path,
    size: (u32, u32),
    title: &str,
    slices: &[Slice],
    window: [f32; 2],
    max_mm: f64,
) -> Result<(), PreviewError> {
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let text = |s: &str, x: i32, y: i32, px: u32| {
        root.draw_text(s, &("sans-serif", px).into_font().color(&BLACK), (x, y))
    };
    text(title, 8, 6, 18).map_err(err)?;
    let cols = columns(slices);
    let sigma_max = max_sigma(slices);
    // The σ column sits right of the |d| bar.
    let left = |c: u32| c * PANEL + if c == 3 { BAR } else { 0 };
    for (c, head) in [
        "pre-operative",
        "warped (intra-operative)",
        "|displacement| (mm), outline: deformed brain",
        "σ of the fit (mm)",
    ]
    .iter()
    .take(cols as usize)
    .enumerate()
    {
        text(head, left(c as u32) as i32 + 8, 34, 13).map_err(err)?;
    }
    let grey = |v: f32| {
        let t = ((v - window[0]) / (window[1] - window[0]).max(f32::MIN_POSITIVE)).clamp(0.0, 1.0);
        let g = (t * 255.0).round() as u8;
        RGBColor(g, g, g)
    };
    for (r, s) in slices.iter().enumerate() {
        let y0 = TOP + r as u32 * (PANEL + ROW_TITLE);
        text(&s.title, 8, y0 as i32 + 2, 13).map_err(err)?;
        // The panel's scale: mm to pixels, the whole slice in a PANEL square, aspect kept.
        let (wmm, hmm) = (s.width as f64 * s.spacing[0], s.height as f64 * s.spacing[1]);
        let scale = (PANEL as f64 - 8.0) / wmm.max(hmm);
        let (pw, ph) = ((wmm * scale) as u32, (hmm * scale) as u32);
        let oy = y0 + ROW_TITLE + (PANEL - ph) / 2;
        for c in 0..cols {
            let ox = left(c) + (PANEL - pw) / 2;
            for py in 0..ph {
                // Row 0 of the slice at the bottom of the panel.
                let j = (((ph - 1 - py) as f64 + 0.5) / scale / s.spacing[1]) as usize;
                for px in 0..pw {
                    let i = ((px as f64 + 0.5) / scale / s.spacing[0]) as usize;
                    let n = j.min(s.height - 1) * s.width + i.min(s.width - 1);
                    let colour = match c {
                        0 => grey(s.before[n]),
                        1 => grey(s.after[n]),
                        3 => match (s.inside[n], &s.sigma) {
                            (true, Some(sigma)) => viridis(sigma[n] as f64 / sigma_max.max(1e-9)),
                            _ => RGBColor(0, 0, 0),
                        },
                        _ => {
                            if edge(s, i.min(s.width - 1), j.min(s.height - 1)) {
                                RGBColor(255, 255, 255)
                            } else {
                                viridis(s.magnitude[n] as f64 / max_mm.max(1e-9))
                            }
                        }
                    };
                    root.draw_pixel(((ox + px) as i32, (oy + py) as i32), &colour).map_err(err)?;
                }
            }
            // The marker: a red cross at the largest displacement.
            let mx = ox as f64 + (s.marker[0] as f64 + 0.5) * s.spacing[0] * scale;
            let my = (oy + ph) as f64 - (s.marker[1] as f64 + 0.5) * s.spacing[1] * scale;
            let red = ShapeStyle::from(&RED).stroke_width(1);
            for (a, b) in
                [((-6, 0), (-2, 0)), ((2, 0), (6, 0)), ((0, -6), (0, -2)), ((0, 2), (0, 6))]
            {
                root.draw(&PathElement::new(
                    vec![(mx as i32 + a.0, my as i32 + a.1), (mx as i32 + b.0, my as i32 + b.1)],
                    red,
                ))
                .map_err(err)?;
            }
        }
    }
    colour_bar(&root, 3 * PANEL as i32 + 16, max_mm)?;
    if cols == 4 {
        colour_bar(&root, (4 * PANEL + BAR) as i32 + 16, sigma_max)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// A colour bar, 0 … `max` mm, its left edge at `bx`.
fn colour_bar<DB: DrawingBackend>(
    root: &DrawingArea<DB, plotters::coord::Shift>,
    bx: i32,
    max: f64,
) -> Result<(), PreviewError> {
    let (by, bh) = (TOP as i32 + ROW_TITLE as i32 + 10, 240i32);
    let font = ("sans-serif", 13).into_font().color(&BLACK);
    for y in 0..bh {
        let t = 1.0 - y as f64 / (bh - 1) as f64;
        root.draw(&Rectangle::new([(bx, by + y), (bx + 22, by + y + 1)], viridis(t).filled()))
            .map_err(err)?;
    }
    root.draw(&Rectangle::new([(bx, by), (bx + 22, by + bh)], BLACK.stroke_width(1)))
        .map_err(err)?;
    let digits = if max < 1.0 { 2 } else { 1 };
    for k in 0..=4 {
        let v = max * k as f64 / 4.0;
        let y = by + bh - 1 - (k * (bh - 1) / 4);
        root.draw_text(&format!("{v:.digits$}"), &font, (bx + 28, y - 7)).map_err(err)?;
    }
    root.draw_text("mm", &font, (bx + 28, by - 20)).map_err(err)?;
    Ok(())
}

/// Whether sample (i, j) is inside the brain with a neighbour outside (the outline).
fn edge(s: &Slice, i: usize, j: usize) -> bool {
    let at = |i: usize, j: usize| s.inside[j * s.width + i];
    if !at(i, j) {
        return false;
    }
    (i == 0 || !at(i - 1, j))
        || (i + 1 == s.width || !at(i + 1, j))
        || (j == 0 || !at(i, j - 1))
        || (j + 1 == s.height || !at(i, j + 1))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_preview_is_a_png_of_the_expected_size() {
        let (w, h) = (40, 30);
        let s = Slice {
            title: "axial".into(),
            width: w,
            height: h,
            spacing: [1.0, 1.5],
            before: (0..w * h).map(|n| (n % w) as f32).collect(),
            after: (0..w * h).map(|n| (n / w) as f32).collect(),
            magnitude: (0..w * h).map(|n| (n % 7) as f32).collect(),
            inside: (0..w * h).map(|n| (n % w) > 10 && (n % w) < 30).collect(),
            sigma: None,
            marker: [20, 15],
        };
        let dir = std::env::temp_dir().join(format!("bs-preview-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("p.png");
        render(&path, "test", &[s.clone(), s.clone(), s.clone()], [0.0, 40.0], 6.0).unwrap();
        let png = std::fs::read(&path).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        // IHDR: width and height, big-endian, at bytes 16..24.
        let width = u32::from_be_bytes([png[16], png[17], png[18], png[19]]);
        let height = u32::from_be_bytes([png[20], png[21], png[22], png[23]]);
        assert_eq!((width, height), (3 * PANEL + BAR, TOP + 3 * (PANEL + ROW_TITLE) + 10));
        // Nothing else was left in the folder (the temporary file was renamed).
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        // With σ on every slice: a fourth panel and a second bar.
        let with = Slice { sigma: Some((0..w * h).map(|n| (n % 5) as f32 * 0.1).collect()), ..s };
        assert!((max_sigma(std::slice::from_ref(&with)) - 0.4).abs() < 1e-6);
        render(&path, "test", &[with.clone(), with.clone(), with], [0.0, 40.0], 6.0).unwrap();
        let png = std::fs::read(&path).unwrap();
        let width = u32::from_be_bytes([png[16], png[17], png[18], png[19]]);
        assert_eq!(width, 4 * PANEL + 2 * BAR);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn viridis_runs_from_purple_to_yellow() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
    }
}
