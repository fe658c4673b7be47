//! MetaImage (`.mha`, header and data in one file) writing, as ITK reads it: origin,
//! direction and vectors in LPS.

use std::io::Write;
use std::path::Path;

use crate::{Grid, ImageError, Space};

/// Writes a 3-component displacement field given in RAS (as the rest of brainshift holds
/// it) as a MetaImage in ITK's frame, LPS: the grid's origin and direction cosines and every
/// vector have x and y negated. Data are float32, zlib-compressed. Atomic (temporary file
/// renamed into place).
pub fn write_displacement_mha(
    file: &Path,
    grid: &Grid,
    vectors_ras: &[[f32; 3]],
) -> Result<(), ImageError> {
    let err = |message: String| ImageError::Io { file: file.to_path_buf(), message };
    if vectors_ras.len() != grid.len() {
        return Err(err(format!("{} vectors for {} voxels", vectors_ras.len(), grid.len())));
    }
    let m = grid.voxel_to_world();
    let sp = grid.spacing();
    let flip = |r: usize| if r < 2 { -1.0 } else { 1.0 };
    // Direction: one unit column per voxel axis, in LPS. MetaImage lists TransformMatrix
    // axis by axis (the first three numbers are the direction of the i axis).
    let mut direction = Vec::with_capacity(9);
    for c in 0..3 {
        for r in 0..3 {
            direction.push(flip(r) * m[(r, c)] / sp[c]);
        }
    }
    let origin = [0, 1, 2].map(|r| flip(r) * m[(r, 3)]);
    let fmt = |v: &[f64]| v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(" ");
    let [nx, ny, nz] = grid.dims();

    let mut raw = Vec::with_capacity(12 * vectors_ras.len());
    for v in vectors_ras {
        let lps = Space::Ras.convert_vector(
            Space::Lps,
            nalgebra::Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64),
        );
        for c in 0..3 {
            raw.extend_from_slice(&(lps[c] as f32).to_le_bytes());
        }
    }
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    z.write_all(&raw).map_err(|e| err(e.to_string()))?;
    let compressed = z.finish().map_err(|e| err(e.to_string()))?;

    let header = format!(
        "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n\
         CompressedData = True\nCompressedDataSize = {}\nTransformMatrix = {}\n\
         Offset = {}\nCenterOfRotation = 0 0 0\nElementSpacing = {}\nDimSize = {nx} {ny} {nz}\n\
         ElementNumberOfChannels = 3\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n",
        compressed.len(),
        fmt(&direction),
        fmt(&origin),
        fmt(&sp),
    );
    bs_atomic::write_atomic(file, |f| {
        f.write_all(header.as_bytes())?;
        f.write_all(&compressed)
    })
    .map_err(|e| err(format!("could not write: {e}")))
}
