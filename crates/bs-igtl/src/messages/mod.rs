//! The message types brainshift speaks, one file each, behind two small traits: [`Decode`]
//! reads a received [`Message`]'s content (its type checked), [`Encode`] gives the content
//! to frame as its own bytes plus at most one borrowed block (an image's voxels). Every
//! decoder checks every count and size against the bytes there are: a bad message is a
//! [`ContentError`], never a panic.

use crate::error::ContentError;
use crate::frame::Message;

pub mod image;
pub mod point;
pub mod polydata;
pub mod query;
pub mod status;
pub mod string;
pub mod transform;

mod bytes;

/// A content to frame: `head`, then `data` (borrowed, not copied).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Encoded<'a> {
    /// The content's own bytes.
    pub head: Vec<u8>,
    /// A block after them (empty for most types).
    pub data: &'a [u8],
}

impl Encoded<'_> {
    /// A content in one piece.
    pub fn owned(head: Vec<u8>) -> Encoded<'static> {
        Encoded { head, data: &[] }
    }
}

/// A message type read from a received message.
pub trait Decode: Sized {
    /// Reads `m`'s content; refuses a message of another type.
    fn decode(m: &Message) -> Result<Self, ContentError>;
}

/// A message type to send.
pub trait Encode {
    /// The header's type (`IMAGE`, `GET_IMAGE`, ...).
    fn kind(&self) -> String;
    /// The content.
    fn encode(&self) -> Result<Encoded<'_>, ContentError>;
}

/// Refuses a message whose header type is not `kind`.
pub(crate) fn expect(m: &Message, kind: &'static str) -> Result<(), ContentError> {
    if m.header.kind == kind {
        Ok(())
    } else {
        Err(ContentError::Type { expected: kind, found: m.header.kind.clone() })
    }
}
