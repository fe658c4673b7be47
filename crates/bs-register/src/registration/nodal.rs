//! A nodal quantity of a result (σ of a fit, per node) as an image of the intra-operative
//! configuration: on the grid of an image (the pre-operative one, whose warp shares it) or,
//! without one, on a 1 mm grid around the deformed brain; RAS, mm; zero outside the brain.

use std::path::Path;

use bs_image::{Grid, Volume};
use bs_mesh::Point3;

use super::files::image_error;
use super::inverse::{IMAGE_SPACE, InverseMap};
use super::result::RunResult;
use bs_scene::SceneError;

/// The default grid's spacing and its margin around the deformed brain (mm).
pub const NODAL_SPACING_MM: f64 = 1.0;
pub const NODAL_MARGIN_MM: f64 = 3.0;

/// A nodal quantity on an image grid, ready to write.
#[derive(Debug, Clone)]
pub struct NodalImage {
    volume: Volume<f32>,
    header: Option<bs_image::nifti::Header>,
    /// Voxels of the grid, and inside the deformed brain.
    pub voxels: usize,
    pub inside: usize,
}

impl NodalImage {
    /// `values` (one per node of `result`) on the grid of `like` (an image file, read for
    /// its grid and header), or on the default grid without one.
    pub fn new(
        result: &RunResult,
        values: &[f64],
        like: Option<&Path>,
    ) -> Result<NodalImage, SceneError> {
        let (grid, header, source) = match like {
            Some(path) => {
                let (v, header) = bs_image::formats::read_image(path).map_err(image_error)?;
                (v.grid, header, path.to_path_buf())
            }
            None => (default_grid(result)?, None, Path::new("(the default grid)").to_path_buf()),
        };
        let map = InverseMap::new(result, &grid, &source)?;
        let data = map.nodal(values);
        let (voxels, inside) = (grid.len(), map.inside_count());
        Ok(NodalImage { volume: Volume { grid, data }, header, voxels, inside })
    }

    /// Writes it (NIfTI `.nii`/`.nii.gz` or NRRD, float32; atomically).
    pub fn write(&self, path: &Path) -> Result<(), SceneError> {
        bs_image::formats::write_image(path, &self.volume, self.header.as_ref())
            .map_err(|e| SceneError::Write { path: path.to_path_buf(), message: e.to_string() })
    }

    /// The largest value on the grid.
    pub fn max(&self) -> f32 {
        self.volume.data.iter().copied().fold(0.0, f32::max)
    }
}

/// A 1 mm axis-aligned RAS grid over the deformed brain with a margin.
fn default_grid(result: &RunResult) -> Result<Grid, SceneError> {
    let scale = result.units.metres() / 1e-3;
    let (lo, hi) = result.mesh.nodes.iter().zip(&result.displacements).fold(
        (Point3::from([f64::INFINITY; 3]), Point3::from([f64::NEG_INFINITY; 3])),
        |(lo, hi), (x, u)| {
            let p = result.space.convert_point(IMAGE_SPACE, (x + u) * scale);
            (lo.inf(&p), hi.sup(&p))
        },
    );
    let origin = lo.map(|c| (c - NODAL_MARGIN_MM).floor());
    let dims = [0, 1, 2].map(|a| {
        (((hi[a] + NODAL_MARGIN_MM - origin[a]) / NODAL_SPACING_MM).ceil() as usize + 1).max(1)
    });
    Grid::axis_aligned(dims, [NODAL_SPACING_MM; 3], [origin.x, origin.y, origin.z])
        .map_err(image_error)
}
