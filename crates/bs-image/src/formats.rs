//! The image formats by file name: NIfTI-1 (`.nii`, `.nii.gz`) and NRRD (`.nrrd`, `.nhdr`,
//! Slicer's `.seg.nrrd`) read and written through one door, so that every command reads
//! either wherever it reads an image and writes what the output's name says.

use std::path::Path;

use crate::nifti::Header;
use crate::{Grid, ImageError, Volume};

/// An image file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// NIfTI-1, `.nii` or `.nii.gz` (RAS world).
    Nifti,
    /// NRRD, `.nrrd` or `.nhdr` (read: LPS or RAS; written: LPS).
    Nrrd,
    /// MetaImage `.mha` (displacement fields only, written).
    MetaImage,
}

impl ImageFormat {
    /// The format a file name says (case-insensitive), if any.
    pub fn of(path: &Path) -> Option<ImageFormat> {
        let name = path.file_name()?.to_str()?.to_ascii_lowercase();
        if name.ends_with(".nii") || name.ends_with(".nii.gz") {
            Some(ImageFormat::Nifti)
        } else if name.ends_with(".nrrd") || name.ends_with(".nhdr") {
            Some(ImageFormat::Nrrd)
        } else if name.ends_with(".mha") {
            Some(ImageFormat::MetaImage)
        } else {
            None
        }
    }
}

fn unknown(path: &Path, what: &str) -> ImageError {
    ImageError::Invalid {
        file: path.to_path_buf(),
        message: format!("unknown image format; {what}"),
    }
}

const READABLE: &str = "images are read from .nii, .nii.gz (NIfTI-1), .nrrd or .nhdr (NRRD)";

/// Reads a 3-D scalar image (float32) in RAS mm, with the NIfTI header when it is one (so
/// that a NIfTI output on the same grid keeps it).
pub fn read_image(path: &Path) -> Result<(Volume<f32>, Option<Header>), ImageError> {
    match ImageFormat::of(path) {
        Some(ImageFormat::Nifti) => {
            crate::nifti::read_image(path).map(|i| (i.volume, Some(i.header)))
        }
        Some(ImageFormat::Nrrd) => crate::nrrd::read_image(path).map(|v| (v, None)),
        _ => Err(unknown(path, READABLE)),
    }
}

/// Reads a labelmap (non-negative integers) in RAS mm, with the NIfTI header when it is one.
pub fn read_labels(path: &Path) -> Result<(Volume<u32>, Option<Header>), ImageError> {
    match ImageFormat::of(path) {
        Some(ImageFormat::Nifti) => {
            crate::nifti::read_labels_with_header(path).map(|(v, h)| (v, Some(h)))
        }
        Some(ImageFormat::Nrrd) => crate::nrrd::read_labels(path).map(|v| (v, None)),
        _ => Err(unknown(path, READABLE)),
    }
}

const IMAGE_OUT: &str = "write the image as .nii, .nii.gz or .nrrd";

/// Checks that `path` names a format an image can be written in.
pub fn require_image_output(path: &Path) -> Result<ImageFormat, ImageError> {
    match ImageFormat::of(path) {
        Some(f @ (ImageFormat::Nifti | ImageFormat::Nrrd)) => Ok(f),
        _ => Err(unknown(path, IMAGE_OUT)),
    }
}

/// Writes a float32 image in the format `path` names (NIfTI with `like`'s header fields).
pub fn write_image(
    path: &Path,
    volume: &Volume<f32>,
    like: Option<&Header>,
) -> Result<(), ImageError> {
    match require_image_output(path)? {
        ImageFormat::Nifti => crate::nifti::write_image(path, volume, like),
        _ => crate::nrrd::write_image(path, volume),
    }
}

/// Writes a labelmap in the format `path` names.
pub fn write_labels(
    path: &Path,
    volume: &Volume<u32>,
    like: Option<&Header>,
) -> Result<(), ImageError> {
    match require_image_output(path)? {
        ImageFormat::Nifti => crate::nifti::write_labels(path, volume, like),
        _ => crate::nrrd::write_labels(path, volume),
    }
}

/// Checks that `path` names a format a displacement field can be written in.
pub fn require_field_output(path: &Path) -> Result<ImageFormat, ImageError> {
    ImageFormat::of(path).ok_or_else(|| {
        unknown(
            path,
            "a displacement field is written as .nii, .nii.gz (RAS vectors), .mha or .nrrd \
             (LPS, ITK's frame)",
        )
    })
}

/// Writes a displacement field (RAS vectors) in the format `path` names: NIfTI DISPVECT
/// (RAS), MetaImage or vector NRRD (LPS).
pub fn write_displacement(
    path: &Path,
    grid: &Grid,
    vectors_ras: &[[f32; 3]],
    like: Option<&Header>,
) -> Result<(), ImageError> {
    match require_field_output(path)? {
        ImageFormat::Nifti => crate::nifti::write_displacement(path, grid, vectors_ras, like),
        ImageFormat::MetaImage => crate::write_displacement_mha(path, grid, vectors_ras),
        ImageFormat::Nrrd => crate::nrrd::write_displacement(path, grid, vectors_ras),
    }
}
