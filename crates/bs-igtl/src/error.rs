//! The two kinds of failure on an OpenIGTLink connection: a stream that cannot be read on
//! ([`FrameError`]: a bad header, an oversize, truncated or stalled body; the connection is
//! answered and closed) and one message that cannot be taken ([`ContentError`]: a bad
//! checksum, an unreadable extended header, metadata or content; it is answered and the
//! connection goes on). Each says what is wrong and what the sender should do.

/// The byte stream cannot be read on.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The header's version is neither 1 nor 2.
    #[error(
        "header version {0}: OpenIGTLink speaks header versions 1 and 2; this is not an \
         OpenIGTLink stream, or it lost its framing (a body longer than its header's body size?)"
    )]
    Version(u16),
    /// The header's type is empty or not printable ASCII.
    #[error(
        "the header's message type {0:?} is not printable ASCII: this is not an OpenIGTLink \
         stream, or it lost its framing (a body longer than its header's body size?)"
    )]
    Type(String),
    /// The body announced is larger than the reader accepts.
    #[error(
        "{what}: a body of {size} bytes exceeds the limit of {limit} bytes (the server's \
         --max-message-mb)"
    )]
    TooLarge {
        /// The message (type and device).
        what: String,
        /// The header's body size.
        size: u64,
        /// The limit.
        limit: u64,
    },
    /// The peer closed in the middle of a message.
    #[error("{what} truncated: {got} of {expected} bytes, then the peer closed")]
    Truncated {
        /// The header, or the message's body.
        what: String,
        /// Bytes received.
        got: u64,
        /// Bytes announced.
        expected: u64,
    },
    /// No byte arrived for the stall limit in the middle of a message.
    #[error("no byte for {seconds} s in the middle of a message")]
    Stalled {
        /// The limit, seconds.
        seconds: f64,
    },
    /// The connection failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

/// One message that cannot be taken; the stream goes on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ContentError {
    /// The body's checksum differs from the header's.
    #[error(
        "the CRC-64 of the body is {computed:#018x}, the header says {header:#018x}: \
         corrupted in transit, or a body of another size than its header's; message ignored"
    )]
    Crc {
        /// Computed over the body.
        computed: u64,
        /// The header's.
        header: u64,
    },
    /// A version-2 body whose extended header or metadata does not fit it.
    #[error("version-2 body of {body} bytes: {message}")]
    Extended {
        /// The body's size.
        body: usize,
        /// What does not fit.
        message: String,
    },
    /// The content does not hold what its type says.
    #[error("{kind}: {message}")]
    Content {
        /// The message type read.
        kind: &'static str,
        /// What is wrong, with the byte offset where it helps.
        message: String,
    },
    /// A message of another type was asked to be read as this one.
    #[error("a {found} message read as {expected}")]
    Type {
        /// The type wanted.
        expected: &'static str,
        /// The header's type.
        found: String,
    },
    /// A text field too long for its width, or holding a NUL (when packing).
    #[error("the {what} {text:?} does not fit {width} bytes without a NUL")]
    Field {
        /// The field.
        what: &'static str,
        /// Its width.
        width: usize,
        /// The text.
        text: String,
    },
    /// A value that the message's fields cannot carry (when packing).
    #[error("{0}")]
    Pack(String),
}

impl ContentError {
    /// A content error of message type `kind`.
    pub fn content(kind: &'static str, message: impl Into<String>) -> ContentError {
        ContentError::Content { kind, message: message.into() }
    }
}
