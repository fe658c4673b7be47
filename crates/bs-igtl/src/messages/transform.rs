//! TRANSFORM: a rigid or affine transform as 12 float32, column by column of its upper 3×4
//! part (the three direction columns, then the translation).

use super::bytes::{Reader, put_f32s};
use super::{Decode, Encode, Encoded, expect};
use crate::error::ContentError;
use crate::frame::Message;

/// A TRANSFORM's content: the 12 values as on the wire.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// `m[0..3]` the first column, ..., `m[9..12]` the translation.
    pub columns: [f32; 12],
}

impl Transform {
    /// The 4×4 matrix (rows), last row (0, 0, 0, 1).
    pub fn matrix(&self) -> [[f64; 4]; 4] {
        let c = |k: usize| self.columns[k] as f64;
        let mut m = [[0.0; 4]; 4];
        for (row, line) in m.iter_mut().enumerate().take(3) {
            for (col, x) in line.iter_mut().enumerate() {
                *x = c(3 * col + row);
            }
        }
        m[3][3] = 1.0;
        m
    }
}

impl Decode for Transform {
    fn decode(m: &Message) -> Result<Transform, ContentError> {
        expect(m, "TRANSFORM")?;
        let mut r = Reader::new("TRANSFORM", m.content());
        let columns = r.f32s::<12>("the matrix")?;
        r.finish()?;
        Ok(Transform { columns })
    }
}

impl Encode for Transform {
    fn kind(&self) -> String {
        "TRANSFORM".into()
    }

    fn encode(&self) -> Result<Encoded<'_>, ContentError> {
        let mut out = Vec::with_capacity(48);
        put_f32s(&mut out, &self.columns);
        Ok(Encoded::owned(out))
    }
}
