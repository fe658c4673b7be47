//! STATUS: a code (u16; 1 OK), a subcode (i64), an error name (20 bytes) and a message that
//! ends with a NUL (read up to its first NUL, as the C++ library reads it).

use super::bytes::{Reader, put_u16};
use super::{Decode, Encode, Encoded, expect};
use crate::error::ContentError;
use crate::frame::Message;
use crate::name::{read_field, write_field};

/// A STATUS's content.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Status {
    /// The status code (1 OK, 0 invalid, 2 unknown error, ...).
    pub code: u16,
    /// The device's own subcode.
    pub subcode: i64,
    /// The error's name (at most 20 bytes).
    pub error_name: String,
    /// The message.
    pub message: String,
}

impl Decode for Status {
    fn decode(m: &Message) -> Result<Status, ContentError> {
        expect(m, "STATUS")?;
        let mut r = Reader::new("STATUS", m.content());
        let code = r.u16("the code")?;
        let subcode = r.u64("the subcode")? as i64;
        let error_name = read_field(r.take(20, "the error name")?);
        let rest = r.rest();
        if !rest.contains(&0) {
            return Err(r.error("the status message does not end with a NUL"));
        }
        Ok(Status { code, subcode, error_name, message: read_field(rest) })
    }
}

impl Encode for Status {
    fn kind(&self) -> String {
        "STATUS".into()
    }

    fn encode(&self) -> Result<Encoded<'_>, ContentError> {
        if self.message.contains('\0') {
            return Err(ContentError::Pack("a STATUS message holding a NUL".into()));
        }
        let mut out = Vec::with_capacity(31 + self.message.len());
        put_u16(&mut out, self.code);
        out.extend_from_slice(&self.subcode.to_be_bytes());
        write_field(&mut out, &self.error_name, 20, "status error name")?;
        out.extend_from_slice(self.message.as_bytes());
        out.push(0);
        Ok(Encoded::owned(out))
    }
}
