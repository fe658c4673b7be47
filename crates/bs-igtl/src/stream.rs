//! Messages on a byte stream: reading one (the header checked, the body size bounded, the
//! body read whole, a peer silent in the middle of a message stopped by a stall limit) and
//! writing one in header version 1 or 2, its pieces summed and sent without joining them
//! (a 35 MB image's voxels are not copied into a message buffer).

use std::io::{ErrorKind, Read, Write};
use std::time::Duration;

use crate::crc::crc64;
use crate::error::{ContentError, FrameError};
use crate::frame::{MetaEntry, v2_parts};
use crate::header::{HEADER_SIZE, Header};
use crate::messages::Encoded;

/// A byte stream whose reads can be bounded in time once a message has begun.
pub trait Stream: Read {
    /// Bounds each read by `limit` (`None`: wait for ever).
    fn set_stall(&mut self, limit: Option<Duration>) -> std::io::Result<()>;
}

impl Stream for std::net::TcpStream {
    fn set_stall(&mut self, limit: Option<Duration>) -> std::io::Result<()> {
        self.set_read_timeout(limit)
    }
}

impl Stream for &[u8] {
    fn set_stall(&mut self, _: Option<Duration>) -> std::io::Result<()> {
        Ok(())
    }
}

/// Fills `buf`; `Ok(false)` when the stream ended before its first byte and `may_end`.
fn fill<S: Stream>(
    s: &mut S,
    buf: &mut [u8],
    what: &dyn Fn() -> String,
    offset: u64,
    expected: u64,
    stall: Option<Duration>,
) -> Result<(), FrameError> {
    let mut got = 0;
    while got < buf.len() {
        match s.read(&mut buf[got..]) {
            Ok(0) => {
                return Err(FrameError::Truncated {
                    what: what(),
                    got: offset + got as u64,
                    expected,
                });
            }
            Ok(k) => got += k,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                return Err(FrameError::Stalled {
                    seconds: stall.map_or(0.0, |d| d.as_secs_f64()),
                });
            }
            Err(e) => return Err(FrameError::Io(e)),
        }
    }
    Ok(())
}

/// The next message's header and body; `None` when the peer closed between messages.
/// Between messages the wait is unbounded; once a byte has come, each read waits at most
/// `stall`. A body larger than `max_body` is refused before it is read.
pub fn read_message<S: Stream>(
    s: &mut S,
    max_body: u64,
    stall: Option<Duration>,
) -> Result<Option<(Header, Vec<u8>)>, FrameError> {
    let mut raw = [0u8; HEADER_SIZE];
    loop {
        match s.read(&mut raw[..1]) {
            Ok(0) => return Ok(None),
            Ok(_) => break,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(FrameError::Io(e)),
        }
    }
    s.set_stall(stall)?;
    let result = read_rest(s, &mut raw, max_body, stall);
    s.set_stall(None)?;
    result.map(Some)
}

fn read_rest<S: Stream>(
    s: &mut S,
    raw: &mut [u8; HEADER_SIZE],
    max_body: u64,
    stall: Option<Duration>,
) -> Result<(Header, Vec<u8>), FrameError> {
    let header_what = || "header".to_string();
    fill(s, &mut raw[1..], &header_what, 1, HEADER_SIZE as u64, stall)?;
    let header = Header::parse(raw)?;
    if header.body_size > max_body {
        return Err(FrameError::TooLarge {
            what: header.to_string(),
            size: header.body_size,
            limit: max_body,
        });
    }
    let size = usize::try_from(header.body_size).map_err(|_| FrameError::TooLarge {
        what: header.to_string(),
        size: header.body_size,
        limit: usize::MAX as u64,
    })?;
    let mut body = vec![0u8; size];
    let body_what = || format!("{header} body");
    fill(s, &mut body, &body_what, 0, header.body_size, stall)?;
    Ok((header, body))
}

/// A message ready to send: its header and body pieces, summed.
#[derive(Debug)]
pub struct Packed<'a> {
    /// The header (body size and CRC set).
    pub header: [u8; HEADER_SIZE],
    head: Vec<u8>,
    data: &'a [u8],
    tail: Vec<u8>,
}

/// What an outgoing message is called and when it was made.
#[derive(Debug, Clone, Copy)]
pub struct Envelope<'a> {
    /// Header version: 1, or 2 (an extended header and metadata).
    pub version: u16,
    /// The device name.
    pub device: &'a str,
    /// The timestamp ([`crate::header::now`], or fixed).
    pub timestamp: u64,
    /// Version 2: the message id.
    pub message_id: u32,
    /// Version 2: the metadata.
    pub metadata: &'a [MetaEntry],
}

/// Frames `content` of message type `kind` as `envelope` says.
pub fn pack<'a>(
    kind: &str,
    envelope: &Envelope<'_>,
    content: Encoded<'a>,
) -> Result<Packed<'a>, ContentError> {
    let Encoded { head: content_head, data } = content;
    let (head, tail) = if envelope.version >= 2 {
        let (ext, tail) = v2_parts(envelope.message_id, envelope.metadata)?;
        ([ext, content_head].concat(), tail)
    } else {
        (content_head, Vec::new())
    };
    let crc = crc64(&tail, crc64(data, crc64(&head, 0)));
    let body_size = (head.len() + data.len() + tail.len()) as u64;
    let header = Header {
        version: envelope.version,
        kind: kind.to_string(),
        device: envelope.device.to_string(),
        timestamp: envelope.timestamp,
        body_size,
        crc,
    }
    .to_bytes()?;
    Ok(Packed { header, head, data, tail })
}

impl Packed<'_> {
    /// Sends the message.
    pub fn write_to<W: Write>(&self, w: &mut W) -> std::io::Result<()> {
        let mut first = Vec::with_capacity(HEADER_SIZE + self.head.len());
        first.extend_from_slice(&self.header);
        first.extend_from_slice(&self.head);
        w.write_all(&first)?;
        w.write_all(self.data)?;
        w.write_all(&self.tail)
    }

    /// The message's bytes in one buffer.
    pub fn to_vec(&self) -> Vec<u8> {
        [&self.header[..], &self.head, self.data, &self.tail].concat()
    }

    /// The whole message's size, bytes.
    pub fn len(&self) -> usize {
        HEADER_SIZE + self.head.len() + self.data.len() + self.tail.len()
    }

    /// Whether the message is empty (never: a header is 58 bytes).
    pub fn is_empty(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::Message;

    fn envelope(version: u16) -> Envelope<'static> {
        Envelope { version, device: "Report", timestamp: 5 << 32, message_id: 9, metadata: &[] }
    }

    #[test]
    fn a_packed_message_reads_back_in_both_versions() {
        for version in [1, 2] {
            let content = Encoded { head: b"ab".to_vec(), data: b"cdef" };
            let bytes = pack("STRING", &envelope(version), content).unwrap().to_vec();
            let (h, body) = read_message(&mut &bytes[..], 1 << 20, None).unwrap().unwrap();
            let m = Message::new(h, body).unwrap();
            assert_eq!(m.content(), b"abcdef");
            assert_eq!(m.message_id, (version == 2).then_some(9));
        }
    }

    #[test]
    fn an_end_between_messages_is_none_and_inside_one_an_error() {
        assert!(read_message(&mut &b""[..], 10, None).unwrap().is_none());
        let bytes = pack("STRING", &envelope(1), Encoded { head: vec![1; 10], data: &[] })
            .unwrap()
            .to_vec();
        for cut in 1..bytes.len() {
            let r = read_message(&mut &bytes[..cut], 1 << 20, None);
            assert!(matches!(r, Err(FrameError::Truncated { .. })), "{cut}: {r:?}");
        }
        let r = read_message(&mut &bytes[..], 9, None);
        assert!(matches!(r, Err(FrameError::TooLarge { size: 10, limit: 9, .. })));
    }
}
