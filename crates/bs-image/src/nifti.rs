//! NIfTI-1 images (`.nii`, `.nii.gz`) read and written with the `nifti` crate.
//!
//! World coordinates are the NIfTI world frame, RAS, in mm: the sform when `sform_code > 0`,
//! else the qform when `qform_code > 0`. A file with neither has no defined world frame and
//! is refused (the fix is named), rather than guessed.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Matrix4};
use ndarray::{Array, IxDyn, ShapeBuilder};
use nifti::{IntoNdArray, NiftiHeader, NiftiObject, NiftiType, ReaderOptions};

use crate::{Grid, ImageError, Volume};

/// Voxel data larger than this are refused before anything is allocated (a corrupt header
/// must not abort the process); 4 GiB is 32 times the MNI152 template at 0.5 mm in float32.
pub const MAX_DATA_BYTES: u64 = 4 << 30;

/// NIFTI_INTENT_DISPVECT: a displacement vector per voxel (ITK and 3D Slicer read it as a
/// displacement-field transform).
pub const INTENT_DISPVECT: i16 = 1006;

/// The header of a NIfTI file read, kept so outputs on the same grid carry the same header
/// (orientation codes, units, description).
#[derive(Debug, Clone)]
pub struct Header {
    raw: NiftiHeader,
}

impl Header {
    /// The NIfTI datatype code of the file (e.g. 2 = uint8, 16 = float32).
    pub fn datatype(&self) -> i16 {
        self.raw.datatype
    }

    /// The sform code (0: no sform) and qform code.
    pub fn xform_codes(&self) -> (i16, i16) {
        (self.raw.sform_code, self.raw.qform_code)
    }
}

/// A 3-D scalar image read from a NIfTI file: values (after the file's scaling) and header.
#[derive(Debug, Clone)]
pub struct NiftiImage {
    /// Voxel values in float32 (slope and intercept applied).
    pub volume: Volume<f32>,
    /// The file's header.
    pub header: Header,
    /// The file read, for messages.
    pub path: PathBuf,
}

fn invalid(file: &Path, message: impl Into<String>) -> ImageError {
    ImageError::Invalid { file: file.to_path_buf(), message: message.into() }
}

fn io(file: &Path, message: impl Into<String>) -> ImageError {
    ImageError::Io { file: file.to_path_buf(), message: message.into() }
}

/// Words a `nifti` crate error for a user, with the fix where one is known.
fn reader_error(file: &Path, e: nifti::NiftiError) -> ImageError {
    match e {
        nifti::NiftiError::Io(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => invalid(
            file,
            "the file ends before its voxel data do (a truncated download or an interrupted \
             gzip); copy the image again",
        ),
        nifti::NiftiError::Io(e) if e.kind() == std::io::ErrorKind::NotFound => {
            io(file, "no such file")
        }
        nifti::NiftiError::Io(e) => io(file, format!("could not read: {e}")),
        nifti::NiftiError::InvalidFormat => invalid(
            file,
            "not a NIfTI-1 file (bad magic or header size); convert it to .nii or .nii.gz \
             (e.g. with 3D Slicer, dcm2niix or nibabel)",
        ),
        other => invalid(file, format!("not a readable NIfTI-1 image: {other}")),
    }
}

/// Reads and checks the header alone: a 3-D image (trailing dimensions of size 1 allowed),
/// a supported datatype, a size below [`MAX_DATA_BYTES`] and a world frame.
fn read_header(file: &Path) -> Result<(NiftiHeader, Grid), ImageError> {
    let header = NiftiHeader::from_file(file).map_err(|e| reader_error(file, e))?;
    let grid = grid_of(file, &header)?;
    let datatype = header.data_type().ok();
    let bytes_per_voxel: u64 = match datatype {
        Some(NiftiType::Uint8 | NiftiType::Int8) => 1,
        Some(NiftiType::Uint16 | NiftiType::Int16) => 2,
        Some(NiftiType::Uint32 | NiftiType::Int32 | NiftiType::Float32) => 4,
        Some(NiftiType::Uint64 | NiftiType::Int64 | NiftiType::Float64) => 8,
        _ => {
            return Err(invalid(
                file,
                format!(
                    "unsupported NIfTI datatype code {} (supported: integers of 8 to 64 bits, \
                     float32, float64); convert the image to one of them",
                    header.datatype
                ),
            ));
        }
    };
    let bytes = grid.len() as u64 * bytes_per_voxel;
    if bytes > MAX_DATA_BYTES {
        return Err(invalid(
            file,
            format!(
                "the header declares {:?} voxels ({bytes} bytes), more than the {} bytes \
                 brainshift reads; the header is corrupt or the image must be resampled",
                grid.dims(),
                MAX_DATA_BYTES
            ),
        ));
    }
    Ok((header, grid))
}

/// The grid of a header: dimensions (3-D only) and the world map, scaled to mm.
fn grid_of(file: &Path, h: &NiftiHeader) -> Result<Grid, ImageError> {
    let rank = h.dim[0] as usize;
    if !(1..=7).contains(&rank) {
        return Err(invalid(file, format!("dim[0] = {} is not a NIfTI rank (1 to 7)", h.dim[0])));
    }
    let dims: Vec<usize> = h.dim[1..=rank].iter().map(|&d| d as usize).collect();
    if dims.contains(&0) {
        return Err(invalid(file, format!("a dimension is zero: {dims:?}")));
    }
    if rank < 3 || dims[2] == 1 {
        return Err(invalid(
            file,
            format!(
                "a 2-D image ({dims:?}); brainshift needs a 3-D volume (a labelmap or an MRI \
                 of the whole head), not a slice"
            ),
        ));
    }
    if dims[3..].iter().any(|&d| d != 1) {
        return Err(invalid(
            file,
            format!(
                "a {rank}-D image ({dims:?}); pass a single 3-D volume (extract one, e.g. \
                 with fslroi or nibabel)"
            ),
        ));
    }
    let scale = match h.xyzt_units & 0x07 {
        1 => 1000.0, // metres
        3 => 1e-3,   // micrometres
        _ => 1.0,    // mm, or unknown (NIfTI's default for spatial units is mm)
    };
    let mut m = world_affine(file, h)?;
    for r in 0..3 {
        for c in 0..4 {
            m[(r, c)] *= scale;
        }
    }
    Grid::new([dims[0], dims[1], dims[2]], m).map_err(|e| invalid(file, e.to_string()))
}

/// The voxel-to-world affine of the header (before unit scaling): sform, else qform.
fn world_affine(file: &Path, h: &NiftiHeader) -> Result<Matrix4<f64>, ImageError> {
    if h.sform_code > 0 {
        let r = [h.srow_x, h.srow_y, h.srow_z];
        let mut m = Matrix4::identity();
        for (row, srow) in r.iter().enumerate() {
            for c in 0..4 {
                m[(row, c)] = srow[c] as f64;
            }
        }
        return Ok(m);
    }
    if h.qform_code > 0 {
        let [_, dx, dy, dz] = [h.pixdim[0], h.pixdim[1], h.pixdim[2], h.pixdim[3]].map(f64::from);
        if !(dx > 0.0 && dy > 0.0 && dz > 0.0) {
            return Err(invalid(
                file,
                format!(
                    "the qform needs positive voxel sizes, pixdim[1..4] = ({dx}, {dy}, {dz}); \
                     fix the header's pixdim"
                ),
            ));
        }
        let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
        let (b, c, d) = (h.quatern_b as f64, h.quatern_c as f64, h.quatern_d as f64);
        let s = 1.0 - (b * b + c * c + d * d);
        let (a, b, c, d) = if s > 1e-7 {
            (s.sqrt(), b, c, d)
        } else {
            // a 180° rotation: normalise (b, c, d), a = 0, as the NIfTI reference does
            let n = (b * b + c * c + d * d).sqrt();
            if n == 0.0 {
                return Err(invalid(file, "the qform quaternion is zero"));
            }
            (0.0, b / n, c / n, d / n)
        };
        let r = Matrix3::new(
            a * a + b * b - c * c - d * d,
            2.0 * (b * c - a * d),
            2.0 * (b * d + a * c),
            2.0 * (b * c + a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d - a * b),
            2.0 * (b * d - a * c),
            2.0 * (c * d + a * b),
            a * a + d * d - c * c - b * b,
        );
        let lin = r * Matrix3::from_diagonal(&nalgebra::Vector3::new(dx, dy, qfac * dz));
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&lin);
        m[(0, 3)] = h.quatern_x as f64;
        m[(1, 3)] = h.quatern_y as f64;
        m[(2, 3)] = h.quatern_z as f64;
        return Ok(m);
    }
    Err(invalid(
        file,
        "neither sform_code nor qform_code is set, so the image has no world frame and a mesh \
         made from it could not be placed on the patient; set one (e.g. in nibabel: \
         img.set_sform(img.affine, code=1)) or re-export the image from its source",
    ))
}

/// Reads every voxel as f64 (after slope and intercept), first index fastest.
fn read_values(file: &Path) -> Result<(NiftiHeader, Grid, Vec<f64>), ImageError> {
    let (header, grid) = read_header(file)?;
    let obj = ReaderOptions::new().read_file(file).map_err(|e| reader_error(file, e))?;
    let array = obj.into_volume().into_ndarray::<f64>().map_err(|e| reader_error(file, e))?;
    if array.len() != grid.len() {
        return Err(invalid(
            file,
            format!("{} voxel values for a {:?} grid", array.len(), grid.dims()),
        ));
    }
    // The array is indexed [i, j, k, ...]; reversing its axes and iterating in logical
    // order walks i fastest, the NIfTI (and our) storage order.
    let values: Vec<f64> = array.t().iter().copied().collect();
    if let Some(n) = values.iter().position(|v| !v.is_finite()) {
        let [i, j, k] = unravel(&grid, n);
        return Err(invalid(
            file,
            format!("voxel ({i}, {j}, {k}) is {} (not a finite number)", values[n]),
        ));
    }
    Ok((header, grid, values))
}

fn unravel(grid: &Grid, n: usize) -> [usize; 3] {
    let [nx, ny, _] = grid.dims();
    [n % nx, (n / nx) % ny, n / (nx * ny)]
}

/// Reads a 3-D scalar image (an MRI): values in float32.
pub fn read_image(file: &Path) -> Result<NiftiImage, ImageError> {
    let (header, grid, values) = read_values(file)?;
    let data = values.into_iter().map(|v| v as f32).collect();
    Ok(NiftiImage {
        volume: Volume { grid, data },
        header: Header { raw: header },
        path: file.to_path_buf(),
    })
}

/// Reads a labelmap: every voxel a non-negative integer (integer or float datatype).
pub fn read_labels(file: &Path) -> Result<Volume<u32>, ImageError> {
    read_labels_with_header(file).map(|(volume, _)| volume)
}

/// [`read_labels`] with the file's header, so that a labelmap written on the same grid
/// (e.g. a warped segmentation) keeps it.
pub fn read_labels_with_header(file: &Path) -> Result<(Volume<u32>, Header), ImageError> {
    let (header, grid, values) = read_values(file)?;
    let mut data = Vec::with_capacity(values.len());
    for (n, &v) in values.iter().enumerate() {
        if v < 0.0 || v.fract() != 0.0 || v > u32::MAX as f64 {
            let [i, j, k] = unravel(&grid, n);
            return Err(invalid(
                file,
                format!(
                    "not a labelmap: voxel ({i}, {j}, {k}) has the value {v}, and labels are \
                     non-negative integers; pass the segmentation (e.g. Slicer's \
                     'Export to labelmap'), not an intensity image"
                ),
            ));
        }
        data.push(v as u32);
    }
    Ok((Volume { grid, data }, Header { raw: header }))
}

/// Writes through a temporary file in the same directory, renamed into place: a failed
/// write leaves no partial output. The temporary name keeps the extension so the `nifti`
/// writer compresses `.gz` names.
fn write_atomic(
    file: &Path,
    write: impl FnOnce(&Path) -> Result<(), nifti::NiftiError>,
) -> Result<(), ImageError> {
    let name = file
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| io(file, "the output path has no file name"))?;
    let ext = if name.ends_with(".nii.gz") {
        ".nii.gz"
    } else if name.ends_with(".nii") {
        ".nii"
    } else {
        return Err(io(file, "a NIfTI output must end in .nii or .nii.gz"));
    };
    // The temporary name keeps the extension (and no other dot): the writer derives the
    // compression from it.
    bs_atomic::write_via(file, ext, |tmp| write(tmp).map_err(std::io::Error::other))
        .map_err(|e| io(file, format!("could not write: {e}")))
}

/// A header for a volume on `grid`: the reference's fields when given (descriptions,
/// codes), the grid's affine as sform (code 1 = scanner anatomical unless the reference has
/// its own code) and qform, spatial units mm.
fn header_for(grid: &Grid, like: Option<&Header>) -> NiftiHeader {
    let mut h = like.map(|l| l.raw.clone()).unwrap_or_default();
    let m = grid.voxel_to_world();
    let code = if h.sform_code > 0 { h.sform_code } else { 1 };
    h.sform_code = code;
    for c in 0..4 {
        h.srow_x[c] = m[(0, c)] as f32;
        h.srow_y[c] = m[(1, c)] as f32;
        h.srow_z[c] = m[(2, c)] as f32;
    }
    let sp = grid.spacing();
    let qfac = if like.is_some() && h.pixdim[0] == -1.0 { -1.0 } else { 1.0 };
    h.pixdim = [qfac, sp[0] as f32, sp[1] as f32, sp[2] as f32, 1.0, 1.0, 1.0, 1.0];
    if like.is_none() {
        set_qform(&mut h, m);
    }
    h.xyzt_units = (h.xyzt_units & !0x07) | 2; // mm
    h.intent_code = 0;
    h
}

/// Writes the qform of a rigid (+ scaling, possibly flipped) affine; an affine with shear has
/// no qform and gets qform_code 0 (the sform carries it).
fn set_qform(h: &mut NiftiHeader, m: &Matrix4<f64>) {
    let lin: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let sp =
        nalgebra::Vector3::new(lin.column(0).norm(), lin.column(1).norm(), lin.column(2).norm());
    let mut r = lin;
    for c in 0..3 {
        let n = sp[c];
        r.column_mut(c).scale_mut(1.0 / n);
    }
    let qfac = if r.determinant() < 0.0 { -1.0 } else { 1.0 };
    if qfac < 0.0 {
        r.column_mut(2).neg_mut();
    }
    if (r.transpose() * r - Matrix3::identity()).norm() > 1e-5 {
        h.qform_code = 0;
        return;
    }
    let rot = nalgebra::Rotation3::from_matrix_unchecked(r);
    let q = nalgebra::UnitQuaternion::from_rotation_matrix(&rot);
    let q = if q.w < 0.0 { -q.into_inner() } else { q.into_inner() };
    h.qform_code = 1;
    h.quatern_b = q.i as f32;
    h.quatern_c = q.j as f32;
    h.quatern_d = q.k as f32;
    h.quatern_x = m[(0, 3)] as f32;
    h.quatern_y = m[(1, 3)] as f32;
    h.quatern_z = m[(2, 3)] as f32;
    h.pixdim[0] = qfac as f32;
}

/// Writes a float32 scalar image on `volume.grid`, with `like`'s header fields (use the
/// input image's header so the output opens aligned with it).
pub fn write_image(
    file: &Path,
    volume: &Volume<f32>,
    like: Option<&Header>,
) -> Result<(), ImageError> {
    let header = header_for(&volume.grid, like);
    let [nx, ny, nz] = volume.grid.dims();
    let array = Array::from_shape_vec(IxDyn(&[nx, ny, nz]).f(), volume.data.clone())
        .map_err(|e| io(file, e.to_string()))?;
    write_atomic(file, |tmp| {
        nifti::writer::WriterOptions::new(tmp)
            .reference_header(&header)
            .write_nifti_with_type(&array, NiftiType::Float32)
    })
}

/// Writes a labelmap (int32) on `volume.grid`.
pub fn write_labels(
    file: &Path,
    volume: &Volume<u32>,
    like: Option<&Header>,
) -> Result<(), ImageError> {
    let header = header_for(&volume.grid, like);
    let [nx, ny, nz] = volume.grid.dims();
    let data: Vec<i32> = volume.data.iter().map(|&v| v.min(i32::MAX as u32) as i32).collect();
    let array = Array::from_shape_vec(IxDyn(&[nx, ny, nz]).f(), data)
        .map_err(|e| io(file, e.to_string()))?;
    write_atomic(file, |tmp| {
        nifti::writer::WriterOptions::new(tmp)
            .reference_header(&header)
            .write_nifti_with_type(&array, NiftiType::Int32)
    })
}

/// Writes a displacement field as ITK and 3D Slicer read it: 5-D (nx, ny, nz, 1, 3),
/// float32, intent NIFTI_INTENT_DISPVECT, vectors in the NIfTI world frame (RAS, mm).
/// `vectors[n]` belongs to voxel `n` (first index fastest).
pub fn write_displacement(
    file: &Path,
    grid: &Grid,
    vectors: &[[f32; 3]],
    like: Option<&Header>,
) -> Result<(), ImageError> {
    if vectors.len() != grid.len() {
        return Err(io(file, format!("{} vectors for {} voxels", vectors.len(), grid.len())));
    }
    let mut header = header_for(grid, like);
    header.intent_code = INTENT_DISPVECT;
    header.intent_name = [0; 16];
    header.intent_name[..8].copy_from_slice(b"DISPVECT");
    header.cal_min = 0.0;
    header.cal_max = 0.0;
    let [nx, ny, nz] = grid.dims();
    let n = grid.len();
    // component-major: all x components, then all y, then all z (the 5th dimension slowest)
    let mut data = vec![0f32; 3 * n];
    for (v, vec) in vectors.iter().enumerate() {
        for c in 0..3 {
            data[c * n + v] = vec[c];
        }
    }
    let array = Array::from_shape_vec(IxDyn(&[nx, ny, nz, 1, 3]).f(), data)
        .map_err(|e| io(file, e.to_string()))?;
    write_atomic(file, |tmp| {
        nifti::writer::WriterOptions::new(tmp)
            .reference_header(&header)
            .write_nifti_with_type(&array, NiftiType::Float32)
    })
}
