//! IMAGE (image header version 1): a 72-byte image header — version, components, scalar
//! type, endianness of the voxels, coordinate frame (1 RAS, 2 LPS), size (3 × u16), the
//! matrix (12 float32: the i, j, k columns with the spacing in them, then the position of
//! the volume's *centre*, as the protocol defines it and 3D Slicer reads it), the
//! sub-volume's offset and size — then the sub-volume's voxels, i fastest.
//!
//! [`Image::ijk_to_world`] and [`Image::set_ijk_to_world`] turn the centre into the
//! position of voxel (0, 0, 0) and back: centre = M · ((n − 1)/2, 1) with M the IJK-to-world
//! matrix rounded to float32 first (the bytes pyigtl writes).

use std::borrow::Cow;

use super::bytes::{Reader, put_f32s, put_u16};
use super::{Decode, Encode, Encoded, expect};
use crate::error::ContentError;
use crate::frame::Message;

/// The image header's size.
pub const IMAGE_HEADER_SIZE: usize = 72;

/// The voxel type (the protocol's scalar type codes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scalar {
    /// 2.
    Int8,
    /// 3.
    Uint8,
    /// 4.
    Int16,
    /// 5.
    Uint16,
    /// 6.
    Int32,
    /// 7.
    Uint32,
    /// 10.
    Float32,
    /// 11.
    Float64,
}

impl Scalar {
    const CODES: [(Scalar, u8, usize); 8] = [
        (Scalar::Int8, 2, 1),
        (Scalar::Uint8, 3, 1),
        (Scalar::Int16, 4, 2),
        (Scalar::Uint16, 5, 2),
        (Scalar::Int32, 6, 4),
        (Scalar::Uint32, 7, 4),
        (Scalar::Float32, 10, 4),
        (Scalar::Float64, 11, 8),
    ];

    /// The type of code `c`.
    pub fn of(c: u8) -> Option<Scalar> {
        Scalar::CODES.iter().find(|x| x.1 == c).map(|x| x.0)
    }

    /// Its code.
    pub fn code(self) -> u8 {
        Scalar::CODES.iter().find(|x| x.0 == self).map_or(0, |x| x.1)
    }

    /// Bytes per value.
    pub fn size(self) -> usize {
        Scalar::CODES.iter().find(|x| x.0 == self).map_or(0, |x| x.2)
    }
}

/// An IMAGE's content.
#[derive(Debug, Clone, PartialEq)]
pub struct Image<'a> {
    /// Values per voxel (1 scalar, 3 a vector image).
    pub components: u8,
    /// Voxel type.
    pub scalar: Scalar,
    /// Whether the voxels are little-endian (endian code 2; 1 is big-endian).
    pub little_endian: bool,
    /// Coordinate frame code: 1 RAS, 2 LPS.
    pub frame: u8,
    /// Voxels along i, j, k.
    pub size: [u16; 3],
    /// The matrix as on the wire: i, j, k columns (spacing in them), then the centre.
    pub matrix: [f32; 12],
    /// The sub-volume's offset.
    pub sub_offset: [u16; 3],
    /// The sub-volume's size (the voxels sent).
    pub sub_size: [u16; 3],
    /// The sub-volume's voxels, i fastest, components interleaved.
    pub data: Cow<'a, [u8]>,
}

/// The frame code of RAS.
pub const RAS: u8 = 1;
/// The frame code of LPS.
pub const LPS: u8 = 2;

impl<'a> Image<'a> {
    /// A whole float32 image (`components` per voxel) on a grid of `size` voxels with
    /// `ijk_to_world` (rows; voxel index → world), in frame `frame` (RAS or LPS); `voxels`
    /// are written little-endian into `buffer` (caller-owned: reused between messages).
    pub fn float32(
        size: [u16; 3],
        components: u8,
        ijk_to_world: &[[f64; 4]; 4],
        frame: u8,
        voxels: &[f32],
        buffer: &'a mut Vec<u8>,
    ) -> Result<Image<'a>, ContentError> {
        buffer.clear();
        buffer.reserve(4 * voxels.len());
        buffer.extend(voxels.iter().flat_map(|v| v.to_le_bytes()));
        Image::float32_le(size, components, ijk_to_world, frame, buffer)
    }

    /// [`Image::float32`] of voxels already written as little-endian float32 bytes
    /// (`bytes`, borrowed: a caller may convert them in parallel).
    pub fn float32_le(
        size: [u16; 3],
        components: u8,
        ijk_to_world: &[[f64; 4]; 4],
        frame: u8,
        bytes: &'a [u8],
    ) -> Result<Image<'a>, ContentError> {
        let expected = size.iter().map(|&n| n as usize).product::<usize>() * components as usize;
        if bytes.len() != 4 * expected {
            return Err(ContentError::Pack(format!(
                "{} bytes for {size:?} voxels of {components} float32 components",
                bytes.len()
            )));
        }
        let mut image = Image {
            components,
            scalar: Scalar::Float32,
            little_endian: true,
            frame,
            size,
            matrix: [0.0; 12],
            sub_offset: [0; 3],
            sub_size: size,
            data: Cow::Borrowed(bytes),
        };
        image.set_ijk_to_world(ijk_to_world);
        Ok(image)
    }

    /// Sets the matrix from `ijk_to_world` (rows): the columns, and the centre computed
    /// from them rounded to float32.
    #[allow(clippy::needless_range_loop)] // matrix indices read as the formula
    pub fn set_ijk_to_world(&mut self, m: &[[f64; 4]; 4]) {
        let m32 = m.map(|row| row.map(|x| x as f32 as f64));
        let half = self.size.map(|n| (n as f64 - 1.0) / 2.0);
        for col in 0..3 {
            for row in 0..3 {
                self.matrix[3 * col + row] = m32[row][col] as f32;
            }
        }
        for row in 0..3 {
            let c = m32[row][3] + (0..3).map(|k| m32[row][k] * half[k]).sum::<f64>();
            self.matrix[9 + row] = c as f32;
        }
    }

    /// The IJK-to-world matrix (rows) this image's matrix and size mean: voxel (0, 0, 0)
    /// at centre − M · (n − 1)/2.
    #[allow(clippy::needless_range_loop)] // matrix indices read as the formula
    pub fn ijk_to_world(&self) -> [[f64; 4]; 4] {
        let half = self.size.map(|n| (n as f64 - 1.0) / 2.0);
        let mut m = [[0.0; 4]; 4];
        for row in 0..3 {
            for col in 0..3 {
                m[row][col] = self.matrix[3 * col + row] as f64;
            }
            m[row][3] =
                self.matrix[9 + row] as f64 - (0..3).map(|k| m[row][k] * half[k]).sum::<f64>();
        }
        m[3][3] = 1.0;
        m
    }

    /// The sub-volume's bytes its header announces.
    fn data_size(&self) -> usize {
        self.sub_size.iter().map(|&n| n as usize).product::<usize>()
            * self.components as usize
            * self.scalar.size()
    }
}

impl Decode for Image<'static> {
    fn decode(m: &Message) -> Result<Image<'static>, ContentError> {
        expect(m, "IMAGE")?;
        let mut r = Reader::new("IMAGE", m.content());
        let version = r.u16("the image header's version")?;
        if version != 1 {
            return Err(r.error(format!("image header version {version} (this reads version 1)")));
        }
        let components = r.u8("the components")?;
        let code = r.u8("the scalar type")?;
        let scalar = Scalar::of(code).ok_or_else(|| r.error(format!("scalar type {code}")))?;
        let endian = r.u8("the endianness")?;
        if !(1..=2).contains(&endian) {
            return Err(r.error(format!("endianness {endian} (1 big, 2 little)")));
        }
        let frame = r.u8("the coordinate frame")?;
        let mut u16s = || -> Result<[u16; 3], ContentError> {
            Ok([r.u16("a size")?, r.u16("a size")?, r.u16("a size")?])
        };
        let size = u16s()?;
        let matrix = r.f32s::<12>("the matrix")?;
        let sub_offset = [r.u16("an offset")?, r.u16("an offset")?, r.u16("an offset")?];
        let sub_size = [r.u16("a size")?, r.u16("a size")?, r.u16("a size")?];
        if (0..3).any(|k| sub_offset[k] as usize + sub_size[k] as usize > size[k] as usize) {
            return Err(r.error(format!(
                "the sub-volume at {sub_offset:?} of {sub_size:?} voxels leaves the image of {size:?}"
            )));
        }
        let mut image = Image {
            components,
            scalar,
            little_endian: endian == 2,
            frame,
            size,
            matrix,
            sub_offset,
            sub_size,
            data: Cow::Borrowed(&[]),
        };
        let data = r.rest();
        if data.len() != image.data_size() {
            return Err(r.error(format!(
                "{} bytes of voxels; its header announces {} ({sub_size:?} voxels of {components} \
                 × {} bytes)",
                data.len(),
                image.data_size(),
                scalar.size()
            )));
        }
        image.data = Cow::Owned(data.to_vec());
        Ok(image)
    }
}

impl Encode for Image<'_> {
    fn kind(&self) -> String {
        "IMAGE".into()
    }

    fn encode(&self) -> Result<Encoded<'_>, ContentError> {
        if self.data.len() != self.data_size() {
            return Err(ContentError::Pack(format!(
                "{} bytes of voxels for a sub-volume of {} bytes",
                self.data.len(),
                self.data_size()
            )));
        }
        let mut h = Vec::with_capacity(IMAGE_HEADER_SIZE);
        put_u16(&mut h, 1);
        h.extend_from_slice(&[
            self.components,
            self.scalar.code(),
            if self.little_endian { 2 } else { 1 },
            self.frame,
        ]);
        self.size.iter().for_each(|&n| put_u16(&mut h, n));
        put_f32s(&mut h, &self.matrix);
        self.sub_offset.iter().chain(&self.sub_size).for_each(|&n| put_u16(&mut h, n));
        Ok(Encoded { head: h, data: &self.data })
    }
}
