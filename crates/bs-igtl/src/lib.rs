//! OpenIGTLink as the reference C++ library and 3D Slicer's OpenIGTLinkIF speak it, knowing
//! nothing of brains, meshes or images beyond the bytes.
//!
//! Files:
//! * `header.rs`: the 58-byte header (version, type, device name, timestamp, body size, CRC);
//! * `name.rs`: the fixed-width text fields, read up to their first NUL as the C++ library
//!   reads them, written NUL-padded;
//! * `frame.rs`: a body as framed — version 1, or version 2 with its extended header,
//!   message id and metadata (unknown keys kept) — with its CRC verified;
//! * `crc.rs`: CRC-64 ECMA-182 (not reflected, initial value 0), slicing by eight, long
//!   inputs in pieces on scoped threads;
//! * `stream.rs`: reading a message off a stream (body size bounded, a stall limit once a
//!   message has begun) and writing one in version 1 or 2 without copying a large block;
//! * `error.rs`: `FrameError` and `ContentError`;
//! * `messages/`: the `Decode` and `Encode` traits (`mod.rs`), bounds-checked big-endian
//!   reads and writes (`bytes.rs`), and one file per type: `image.rs` (IMAGE, scalar and
//!   vector; the matrix locates the volume's centre), `polydata.rs` (POLYDATA: points, the
//!   four cell arrays with their sizes in bytes, attributes), `point.rs` (POINT),
//!   `string.rs` (STRING), `status.rs` (STATUS, text ending with a NUL), `transform.rs`
//!   (TRANSFORM) and `query.rs` (the GET_/STT_/STP_/RTS_ queries). Other types are framed
//!   and verified like any message; a reader skips them.
//!
//! Two kinds of failure: a [`FrameError`] means the stream cannot be read on (answer and
//! close); a [`ContentError`] is one message (answer and go on). No input panics: the
//! tests feed every truncation and every single-bit flip of the C++ library's own messages.
//!
//! Architecture invariant: the standard library and thiserror only; no scene, mesh or image
//! type (bs-serve maps messages to them).

pub mod crc;
mod error;
pub mod frame;
pub mod header;
pub mod messages;
pub mod name;
pub mod stream;

pub use error::{ContentError, FrameError};
pub use frame::{Message, MetaEntry};
pub use header::{HEADER_SIZE, Header};
pub use messages::image::Image;
pub use messages::point::{Point, Points};
pub use messages::polydata::{Attribute, Cells, PolyData};
pub use messages::query::{Query, Verb};
pub use messages::status::Status;
pub use messages::string::Text;
pub use messages::transform::Transform;
pub use messages::{Decode, Encode, Encoded};
pub use stream::{Envelope, Packed, Stream, pack, read_message};

/// Frames `message` as `envelope` says: the bytes to send.
pub fn pack_message<'a, M: Encode>(
    message: &'a M,
    envelope: &Envelope<'_>,
) -> Result<Packed<'a>, ContentError> {
    pack(&message.kind(), envelope, message.encode()?)
}

impl Message {
    /// The content read as `T`.
    pub fn read<T: Decode>(&self) -> Result<T, ContentError> {
        T::decode(self)
    }
}
