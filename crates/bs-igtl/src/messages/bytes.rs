//! Big-endian reads over a content with bounds checked (a short content is an error naming
//! the message type and the offset), and the writes that mirror them.

use crate::error::ContentError;

/// A cursor over a content of message type `kind`.
#[derive(Debug)]
pub(crate) struct Reader<'a> {
    pub kind: &'static str,
    pub data: &'a [u8],
    pub at: usize,
}

impl<'a> Reader<'a> {
    pub fn new(kind: &'static str, data: &'a [u8]) -> Reader<'a> {
        Reader { kind, data, at: 0 }
    }

    /// The next `n` bytes, named `what` in the error.
    pub fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], ContentError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.data.len()).ok_or_else(|| {
            ContentError::content(
                self.kind,
                format!(
                    "{what} needs {n} bytes at offset {}, the content has {}",
                    self.at,
                    self.data.len()
                ),
            )
        })?;
        let s = &self.data[self.at..end];
        self.at = end;
        Ok(s)
    }

    pub fn u8(&mut self, what: &str) -> Result<u8, ContentError> {
        Ok(self.take(1, what)?[0])
    }

    pub fn u16(&mut self, what: &str) -> Result<u16, ContentError> {
        let b = self.take(2, what)?;
        Ok(u16::from_be_bytes([b[0], b[1]]))
    }

    pub fn u32(&mut self, what: &str) -> Result<u32, ContentError> {
        let b = self.take(4, what)?;
        Ok(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    }

    pub fn u64(&mut self, what: &str) -> Result<u64, ContentError> {
        let b = self.take(8, what)?;
        Ok(u64::from_be_bytes(std::array::from_fn(|k| b[k])))
    }

    pub fn f32(&mut self, what: &str) -> Result<f32, ContentError> {
        Ok(f32::from_bits(self.u32(what)?))
    }

    pub fn f32s<const N: usize>(&mut self, what: &str) -> Result<[f32; N], ContentError> {
        let b = self.take(4 * N, what)?;
        Ok(std::array::from_fn(|k| {
            f32::from_be_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]])
        }))
    }

    /// The bytes not read yet.
    pub fn rest(&mut self) -> &'a [u8] {
        let s = &self.data[self.at..];
        self.at = self.data.len();
        s
    }

    /// Refuses bytes left after the last field.
    pub fn finish(&self) -> Result<(), ContentError> {
        if self.at == self.data.len() {
            Ok(())
        } else {
            Err(ContentError::content(
                self.kind,
                format!(
                    "{} bytes after its last field (at offset {}): a body larger than its \
                     content",
                    self.data.len() - self.at,
                    self.at
                ),
            ))
        }
    }

    /// An error of this message type.
    pub fn error(&self, message: impl Into<String>) -> ContentError {
        ContentError::content(self.kind, message)
    }
}

pub(crate) fn put_u16(out: &mut Vec<u8>, x: u16) {
    out.extend_from_slice(&x.to_be_bytes());
}

pub(crate) fn put_u32(out: &mut Vec<u8>, x: u32) {
    out.extend_from_slice(&x.to_be_bytes());
}

pub(crate) fn put_f32s(out: &mut Vec<u8>, xs: &[f32]) {
    for x in xs {
        out.extend_from_slice(&x.to_be_bytes());
    }
}

/// `n` as a u32 field named `what`, or an error.
pub(crate) fn u32_of(n: usize, what: &str) -> Result<u32, ContentError> {
    u32::try_from(n).map_err(|_| ContentError::Pack(format!("{what}: {n} does not fit 32 bits")))
}
