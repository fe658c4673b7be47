//! `brainshift.Image`: a pre-operative image read once and kept in memory (float32 on its
//! grid), so that a live session warps it after every update without reading the file
//! again. `Result.warp` and `Result.field` take one wherever they take a path.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use bs_image::{Grid, Volume};
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{affine, image_error, volume_array};

/// An image read into memory: its values (float32) on its grid, voxel index to RAS (mm).
#[pyclass(module = "brainshift", frozen)]
pub(crate) struct Image {
    pub(crate) volume: Volume<f32>,
    pub(crate) path: PathBuf,
    /// The pre-operative gap on this grid with the key of the maps it is for
    /// (`InverseMap::preop_key`): a live session's updates share it.
    gap: Mutex<Option<(u64, Gap)>>,
}

/// A pre-operative gap on an image's grid (None: the reference mesh could not be located
/// there), shared by the maps that use it.
type Gap = Arc<Option<Vec<bool>>>;

impl Image {
    /// This image warped by `result` (as `bs_register::registration::warp_loaded`), through
    /// the pre-operative gap this image keeps.
    pub(crate) fn warp(
        &self,
        result: &bs_register::registration::RunResult,
    ) -> Result<Volume<f32>, bs_scene::SceneError> {
        let (map, gap) = self.map_and_gap(result)?;
        let data = map.warp_with_gap(&self.volume, &self.volume.data, gap.as_deref());
        Ok(Volume { grid: self.volume.grid.clone(), data })
    }

    /// The displacement field of `result` on this image's grid (as
    /// `bs_register::registration::field_on`), through the pre-operative gap this image keeps.
    pub(crate) fn field(
        &self,
        result: &bs_register::registration::RunResult,
    ) -> Result<Volume<[f32; 3]>, bs_scene::SceneError> {
        let (map, gap) = self.map_and_gap(result)?;
        Ok(Volume { grid: self.volume.grid.clone(), data: map.field_with_gap(gap.as_deref()) })
    }

    /// The inverse map of `result` on this image's grid and the pre-operative gap it samples.
    fn map_and_gap(
        &self,
        result: &bs_register::registration::RunResult,
    ) -> Result<(bs_register::registration::InverseMap, Gap), bs_scene::SceneError> {
        let map =
            bs_register::registration::InverseMap::new(result, &self.volume.grid, &self.path)?;
        let gap = self.preop_gap(&map);
        Ok((map, gap))
    }

    /// The pre-operative gap of `map` on this image's grid, computed on the first ask for
    /// the map's reference mesh and skull and kept for the next.
    fn preop_gap(&self, map: &bs_register::registration::InverseMap) -> Gap {
        if map.gap_voxels().is_empty() {
            return Arc::new(None); // nothing between brain and skull samples it
        }
        let key = map.preop_key();
        let mut cache = self.gap.lock().unwrap_or_else(|e| e.into_inner());
        match &*cache {
            Some((k, gap)) if *k == key => gap.clone(),
            _ => {
                let gap = Arc::new(map.preop_gap(&self.volume.grid));
                *cache = Some((key, gap.clone()));
                gap
            }
        }
    }
}

#[pymethods]
impl Image {
    /// The grid's size (nx, ny, nz).
    #[getter]
    fn shape(&self) -> (usize, usize, usize) {
        let [nx, ny, nz] = self.volume.grid.dims();
        (nx, ny, nz)
    }

    /// The 4×4 voxel-index-to-RAS (mm) matrix.
    #[getter]
    fn affine<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        affine(py, self.volume.grid.voxel_to_world())
    }

    /// The file it was read from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// The values, float32 (nx, ny, nz).
    fn array<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        volume_array(py, self.volume.grid.dims(), self.volume.data.clone(), 1)
    }

    fn __repr__(&self) -> String {
        let [nx, ny, nz] = self.volume.grid.dims();
        format!("<brainshift.Image {}: {nx} x {ny} x {nz}>", self.path.display())
    }
}

/// A result's inverse map on an image grid (`Result.inverse_map`): the warped image and the
/// displacement field from it without building it again.
#[pyclass(module = "brainshift", frozen)]
pub(crate) struct InverseMap {
    pub(crate) map: bs_register::registration::InverseMap,
    pub(crate) grid: Grid,
    /// The pre-operative gap on the grid, from the image `warp` was given (an image keeps
    /// it for a session's maps) or computed by the first `field()`.
    pub(crate) gap: std::sync::OnceLock<Gap>,
}

#[pymethods]
impl InverseMap {
    /// The 4×4 voxel-index-to-RAS (mm) matrix of the grid.
    #[getter]
    fn affine<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        affine(py, self.grid.voxel_to_world())
    }

    /// Voxels whose centre lies inside the deformed brain, where the map is the exact
    /// inverse of the finite-element map (elsewhere the extension to the skull, or zero):
    /// bool (nx, ny, nz).
    #[getter]
    fn inside<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mask = py.detach(|| self.map.inside_mask());
        volume_array(py, self.grid.dims(), mask, 1)
    }

    /// Conjugate-gradient iterations of the extension between brain and skull (0 without
    /// a skull or a gap).
    #[getter]
    fn extension_iterations(&self) -> usize {
        self.map.outside_report().map_or(0, |r| r.iterations)
    }

    /// What the map does between the deformed brain and the skull (None without a gap):
    /// a dict with `boundary` (`"skull"`, or the width in mm of the band it decays over
    /// without a skull), `gap_voxels`, `iterations` and `residual` of the harmonic
    /// extension, and whether the map folds there: `folding_voxels` (gap voxels where
    /// det(I + ∇d) ≤ 0), `min_det` and `min_det_at` (where it is smallest: RAS, mm; None
    /// when no voxel was measured). The numbers of `brainshift warp`'s "outside the brain"
    /// line.
    #[getter]
    fn outside<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(o) = self.map.outside_report() else { return Ok(None) };
        let d = PyDict::new(py);
        match o.boundary {
            bs_register::outside::Boundary::Skull => d.set_item("boundary", "skull")?,
            bs_register::outside::Boundary::Band(w) => d.set_item("boundary", w)?,
        }
        d.set_item("gap_voxels", o.gap_voxels)?;
        d.set_item("iterations", o.iterations)?;
        d.set_item("residual", o.residual)?;
        d.set_item("folding_voxels", o.folding.non_positive)?;
        d.set_item("min_det", o.folding.min)?;
        d.set_item("min_det_at", o.worst_at)?;
        Ok(Some(d))
    }

    /// The image (a `brainshift.Image`, on this grid) warped into the result's
    /// configuration: float32 (nx, ny, nz), as `Result.warp`.
    fn warp<'py>(&self, py: Python<'py>, image: &Bound<'py, Image>) -> PyResult<Bound<'py, PyAny>> {
        let i = image.get();
        if i.volume.grid != self.grid {
            return Err(pyo3::exceptions::PyValueError::new_err(format!(
                "{} is not on the grid of this map",
                i.path.display()
            )));
        }
        let data = py.detach(|| {
            let gap = self.gap.get_or_init(|| i.preop_gap(&self.map));
            self.map.warp_with_gap(&i.volume, &i.volume.data, gap.as_deref())
        });
        volume_array(py, self.grid.dims(), data, 1)
    }

    /// The displacement field d(y) = X(y) − y on the grid: float32 (nx, ny, nz, 3), RAS
    /// mm, as `Result.field`; resampling the image through it gives `warp`'s image.
    fn field<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let data: Vec<f32> = py.detach(|| {
            let gap = self.gap.get_or_init(|| {
                let none = self.map.gap_voxels().is_empty();
                Arc::new(if none { None } else { self.map.preop_gap(&self.grid) })
            });
            self.map.field_with_gap(gap.as_deref()).into_iter().flatten().collect()
        });
        volume_array(py, self.grid.dims(), data, 3)
    }
}

/// Reads an image (.nii, .nii.gz, .nrrd, .nhdr) into memory, as `brainshift warp` reads
/// its `--image`.
#[pyfunction]
pub(crate) fn read_image(py: Python<'_>, path: PathBuf) -> PyResult<Image> {
    let (volume, _) =
        py.detach(|| bs_image::formats::read_image(&path)).map_err(|e| image_error(py, e))?;
    Ok(Image { volume, path, gap: Mutex::new(None) })
}

/// An image argument: a loaded [`Image`] or a path to read.
pub(crate) enum ImageArg<'a> {
    Loaded(&'a Image),
    File(PathBuf),
}

impl<'a> ImageArg<'a> {
    pub(crate) fn of(v: &'a Bound<'_, PyAny>) -> PyResult<ImageArg<'a>> {
        if let Ok(i) = v.cast::<Image>() {
            return Ok(ImageArg::Loaded(i.get()));
        }
        v.extract::<PathBuf>().map(ImageArg::File).map_err(|_| {
            pyo3::exceptions::PyValueError::new_err(
                "image must be a path or a brainshift.Image (brainshift.read_image)",
            )
        })
    }

    /// The image's path (for messages).
    pub(crate) fn path(&self) -> &Path {
        match self {
            ImageArg::Loaded(i) => &i.path,
            ImageArg::File(p) => p,
        }
    }

    /// The grid, reading the file if need be.
    pub(crate) fn grid(&self, py: Python<'_>) -> PyResult<Grid> {
        match self {
            ImageArg::Loaded(i) => Ok(i.volume.grid.clone()),
            ImageArg::File(p) => Ok(read(py, p)?.grid),
        }
    }
}

/// Reads `p` with the GIL released.
pub(crate) fn read(py: Python<'_>, p: &Path) -> PyResult<Volume<f32>> {
    py.detach(|| bs_image::formats::read_image(p)).map(|(v, _)| v).map_err(|e| image_error(py, e))
}
