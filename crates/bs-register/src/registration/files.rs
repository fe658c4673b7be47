//! The entry points on files and volumes: `warp` and `field` of a run directory, in memory or
//! written.

use std::path::{Path, PathBuf};
use std::time::Instant;

use bs_image::{Grid, Volume};

use super::inverse::InverseMap;
use super::result::RunResult;
use crate::outside::OutsideReport;
use bs_scene::SceneError;

/// What a warp or field export did, for the front end to print.
#[derive(Debug, Clone)]
pub struct Summary {
    /// The file written.
    pub out: PathBuf,
    /// Voxels of the grid.
    pub voxels: usize,
    /// Voxels inside the deformed brain (mapped).
    pub inside: usize,
    /// Largest displacement in the brain (mm): of the result's nodes (`warp`), of the
    /// field's voxels inside the deformed brain (`field`).
    pub max_displacement: f64,
    /// Largest |d| over the field's gap voxels (mm; `field` only, None without a gap):
    /// beyond the skin a gap voxel points at the pre-operative gap
    /// ([`InverseMap::gap_points`]), on a coarse grid farther than the brain moved.
    pub gap_max_displacement: Option<f64>,
    /// Seconds reading the result and the image.
    pub read_seconds: f64,
    /// Seconds computing the inverse map and resampling.
    pub map_seconds: f64,
    /// Seconds writing.
    pub write_seconds: f64,
    /// The map outside the deformed brain (None: identity there).
    pub outside: Option<OutsideReport>,
    /// The planes through the largest displacement, when asked for (a preview).
    pub planes: Option<crate::planes::Planes>,
    /// Notes from reading the result.
    pub notes: Vec<String>,
}

/// The scene error of an image that cannot be read or used.
pub fn image_error(e: bs_image::ImageError) -> SceneError {
    match e {
        bs_image::ImageError::Io { file, message }
        | bs_image::ImageError::Invalid { file, message } => SceneError::Image { file, message },
        bs_image::ImageError::Grid(message) => {
            SceneError::Image { file: PathBuf::from("(image)"), message }
        }
    }
}

fn output_error(e: bs_image::ImageError, out: &Path) -> SceneError {
    SceneError::Write {
        path: out.to_path_buf(),
        message: e.to_string().replacen(&format!("{}: ", out.display()), "", 1),
    }
}

/// `brainshift warp`: resamples the pre-operative image `image` (NIfTI or NRRD) into the
/// intra-operative configuration of the result in `result_dir` and writes it to `out`
/// (`.nii`, `.nii.gz` or `.nrrd`) on the same grid (and, NIfTI to NIfTI, the same header);
/// a labelmap with nearest-voxel sampling when `labels` is `Some(cavity)`, a resection's
/// cavity taking the label `cavity` (0: background). Nothing is written when an input is
/// bad.
/// With `planes`, the summary carries the three planes through the largest displacement, or
/// through the world point (RAS mm) it names (for a preview picture).
pub fn warp_file(
    result_dir: &Path,
    image: &Path,
    out: &Path,
    labels: Option<u32>,
    planes: Option<Option<[f64; 3]>>,
) -> Result<Summary, SceneError> {
    let focus = planes.flatten();
    let planes = planes.is_some();
    bs_image::formats::require_image_output(out).map_err(|e| output_error(e, out))?;
    let started = Instant::now();
    let result = RunResult::load(result_dir)?;
    if let Some(cavity) = labels {
        let (volume, header) = bs_image::formats::read_labels(image).map_err(image_error)?;
        let read_seconds = started.elapsed().as_secs_f64();
        resample_and_write(
            &result,
            &volume,
            image,
            out,
            read_seconds,
            |map, v, keep| map.warp_labels(v, keep, cavity),
            |v| bs_image::formats::write_labels(out, v, header.as_ref()),
            planes.then_some((|v: &u32| *v as f32, focus)),
        )
    } else {
        let (volume, header) = bs_image::formats::read_image(image).map_err(image_error)?;
        let read_seconds = started.elapsed().as_secs_f64();
        resample_and_write(
            &result,
            &volume,
            image,
            out,
            read_seconds,
            InverseMap::warp,
            |v| bs_image::formats::write_image(out, v, header.as_ref()),
            planes.then_some((|v: &f32| *v, focus)),
        )
    }
}

/// The index of the voxel nearest to the world point `p` (RAS mm), if it lies in the grid.
fn voxel_of(g: &bs_image::Grid, p: [f64; 3]) -> Option<usize> {
    let v = g.voxel(&bs_mesh::Point3::from(p));
    let dims = g.dims();
    let ijk: Vec<usize> = (0..3)
        .map(|c| v[c].round())
        .zip(dims)
        .filter(|(x, d)| *x >= 0.0 && (*x as usize) < *d)
        .map(|(x, _)| x as usize)
        .collect();
    (ijk.len() == 3).then(|| g.index(ijk[0], ijk[1], ijk[2]))
}

/// The part of [`warp_file`] common to images and labelmaps: the inverse map on the image's
/// grid, `resample` through it, `write` the volume, the timings, and (with `grey`, the
/// values as grey levels, and the world point the planes go through, else the largest
/// displacement) the planes of a preview.
#[allow(clippy::too_many_arguments)]
fn resample_and_write<T: Copy>(
    result: &RunResult,
    volume: &Volume<T>,
    image: &Path,
    out: &Path,
    read_seconds: f64,
    resample: impl FnOnce(&InverseMap, &Volume<T>, &[T]) -> Vec<T>,
    write: impl FnOnce(&Volume<T>) -> Result<(), bs_image::ImageError>,
    grey: Option<(impl Fn(&T) -> f32, Option<[f64; 3]>)>,
) -> Result<Summary, SceneError> {
    if let Some((_, Some(p))) = &grey
        && voxel_of(&volume.grid, *p).is_none()
    {
        return Err(SceneError::Image {
            file: image.to_path_buf(),
            message: format!(
                "the preview's point ({}, {}, {}) mm lies outside this image's grid: give a \
                 point in the image (RAS mm)",
                p[0], p[1], p[2]
            ),
        });
    }
    let t = Instant::now();
    let map = InverseMap::new(result, &volume.grid, image)?;
    let data = resample(&map, volume, &volume.data);
    let map_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let warped = Volume { grid: volume.grid.clone(), data };
    write(&warped).map_err(image_error)?;
    let write_seconds = t.elapsed().as_secs_f64();
    let planes = grey.map(|(grey, focus)| {
        let f = |v: &Volume<T>| Volume {
            grid: v.grid.clone(),
            data: v.data.iter().map(&grey).collect(),
        };
        let in_brain = |n: usize| map.reference_point(n).is_some();
        let mm = result.units.metres() / 1e-3;
        let sigma = result
            .sigma
            .as_ref()
            .map(|s| map.nodal(&s.iter().map(|v| v * mm).collect::<Vec<f64>>()));
        crate::planes::planes(
            map.grid(),
            &in_brain,
            (&f(volume), &f(&warped).data),
            &map.harmonic_field(),
            sigma.as_deref(),
            focus.and_then(|p| voxel_of(map.grid(), p)),
        )
    });
    Ok(Summary {
        out: out.to_path_buf(),
        voxels: volume.grid.len(),
        inside: map.inside_count(),
        max_displacement: result.max_displacement_mm(),
        gap_max_displacement: None,
        read_seconds,
        map_seconds,
        write_seconds,
        outside: map.outside_report(),
        planes,
        notes: result.notes.clone(),
    })
}

/// What [`warp_file`] computes, in memory: the pre-operative image `image` (NIfTI or NRRD)
/// resampled into the configuration of `result`, on the image's grid (world frame RAS, mm).
pub fn warp_volume(result: &RunResult, image: &Path) -> Result<Volume<f32>, SceneError> {
    let (volume, _) = bs_image::formats::read_image(image).map_err(image_error)?;
    warp_loaded(result, &volume, image)
}

/// [`warp_volume`] of an image already in memory (`source` names it in messages): what a
/// live session does after each update.
pub fn warp_loaded(
    result: &RunResult,
    volume: &Volume<f32>,
    source: &Path,
) -> Result<Volume<f32>, SceneError> {
    let map = InverseMap::new(result, &volume.grid, source)?;
    let data = map.warp(volume, &volume.data);
    Ok(Volume { grid: volume.grid.clone(), data })
}

/// [`warp_volume`] for a labelmap (nearest voxel; a gap voxel never takes a brain label; a
/// resection's cavity takes `cavity`).
pub fn warp_labels_volume(
    result: &RunResult,
    image: &Path,
    cavity: u32,
) -> Result<Volume<u32>, SceneError> {
    let (volume, _) = bs_image::formats::read_labels(image).map_err(image_error)?;
    let map = InverseMap::new(result, &volume.grid, image)?;
    let data = map.warp_labels(&volume, &volume.data, cavity);
    Ok(Volume { grid: volume.grid, data })
}

/// What [`field_file`] computes, in memory: d(y) = X(y) − y on the grid of `reference`, RAS
/// vectors in mm (zero beyond the skull).
pub fn field_volume(result: &RunResult, reference: &Path) -> Result<Volume<[f32; 3]>, SceneError> {
    let (volume, _) = bs_image::formats::read_image(reference).map_err(image_error)?;
    field_on(result, &volume.grid, reference)
}

/// [`field_volume`] on a grid already in memory (`source` names it in messages).
pub fn field_on(
    result: &RunResult,
    grid: &Grid,
    source: &Path,
) -> Result<Volume<[f32; 3]>, SceneError> {
    let map = InverseMap::new(result, grid, source)?;
    Ok(Volume { grid: grid.clone(), data: map.field() })
}

/// `brainshift field`: the result's inverse map as a displacement field d(y) = X(y) − y on
/// the grid of `reference` (NIfTI or NRRD), written to `out`: `.nii`/`.nii.gz` (DISPVECT,
/// RAS vectors), `.mha` or `.nrrd` (LPS, ITK's frame).
pub fn field_file(result_dir: &Path, reference: &Path, out: &Path) -> Result<Summary, SceneError> {
    bs_image::formats::require_field_output(out).map_err(|e| output_error(e, out))?;
    let started = Instant::now();
    let result = RunResult::load(result_dir)?;
    let (volume, header) = bs_image::formats::read_image(reference).map_err(image_error)?;
    let read_seconds = started.elapsed().as_secs_f64();
    let t = Instant::now();
    let grid = &volume.grid;
    let map = InverseMap::new(&result, grid, reference)?;
    let field = map.field();
    let norm = |n: usize| field[n].iter().map(|&c| c as f64 * c as f64).sum::<f64>().sqrt();
    let inside = map.inside_mask();
    let max_displacement = (0..field.len()).filter(|&n| inside[n]).map(norm).fold(0.0, f64::max);
    let gaps = map.gap_voxels();
    let gap =
        (!gaps.is_empty()).then(|| gaps.iter().map(|&n| norm(n as usize)).fold(0.0, f64::max));
    let map_seconds = t.elapsed().as_secs_f64();
    let t = Instant::now();
    bs_image::formats::write_displacement(out, grid, &field, header.as_ref())
        .map_err(image_error)?;
    Ok(Summary {
        out: out.to_path_buf(),
        voxels: grid.len(),
        inside: map.inside_count(),
        max_displacement,
        gap_max_displacement: gap,
        read_seconds,
        map_seconds,
        write_seconds: t.elapsed().as_secs_f64(),
        outside: map.outside_report(),
        planes: None,
        notes: result.notes,
    })
}
