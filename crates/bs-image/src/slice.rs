//! A plane cut from images on a grid: what a preview picture shows (bs-register cuts it,
//! bs-preview draws it).

/// One plane: the pre-operative and warped values, the displacement magnitude and where the
/// deformed brain is, on a `width × height` grid of samples (first index fastest, row 0 at
/// the bottom) with their spacing in mm.
#[derive(Debug, Clone, PartialEq)]
pub struct Slice {
    /// The row's title (e.g. "axial (k = 97)").
    pub title: String,
    /// Samples along the horizontal axis.
    pub width: usize,
    /// Samples along the vertical axis.
    pub height: usize,
    /// Sample spacing, horizontal and vertical (mm).
    pub spacing: [f64; 2],
    /// The pre-operative image.
    pub before: Vec<f32>,
    /// The warped image.
    pub after: Vec<f32>,
    /// |d| (mm).
    pub magnitude: Vec<f32>,
    /// Inside the deformed brain.
    pub inside: Vec<bool>,
    /// σ of a fitted answer (mm), when the result carries one (`run --uncertainty`).
    pub sigma: Option<Vec<f32>>,
    /// The point of largest displacement, in samples.
    pub marker: [usize; 2],
}
