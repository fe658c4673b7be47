//! The 58-byte header every OpenIGTLink message starts with (big-endian): version (u16: 1,
//! or 2 for the extended header of OpenIGTLink 3), type (12 bytes), device name (20 bytes),
//! timestamp (u64: seconds in the high 32 bits, the fraction of a second in 2⁻³² in the
//! low), body size (u64) and the body's CRC-64.

use crate::error::{ContentError, FrameError};
use crate::name::{read_field, write_field};

/// The header's size, bytes.
pub const HEADER_SIZE: usize = 58;
/// Width of the type field.
pub const TYPE_WIDTH: usize = 12;
/// Width of the device name field.
pub const DEVICE_WIDTH: usize = 20;

/// A message header as read (names up to their first NUL).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Header {
    /// 1, or 2 (extended header and metadata in the body).
    pub version: u16,
    /// The message type (`IMAGE`, `GET_STATUS`, ...).
    pub kind: String,
    /// The device name (may be empty: 3D Slicer's STATUS on connecting).
    pub device: String,
    /// Seconds (high 32 bits) and fraction in 2⁻³² s (low 32 bits).
    pub timestamp: u64,
    /// Bytes of body that follow.
    pub body_size: u64,
    /// CRC-64 of the body.
    pub crc: u64,
}

impl Header {
    /// Reads a header; an unknown version or a type that is not printable ASCII means the
    /// stream is not (or no longer) OpenIGTLink.
    pub fn parse(raw: &[u8; HEADER_SIZE]) -> Result<Header, FrameError> {
        let u64_at = |at: usize| u64::from_be_bytes(std::array::from_fn(|k| raw[at + k]));
        let version = u16::from_be_bytes([raw[0], raw[1]]);
        if !(1..=2).contains(&version) {
            return Err(FrameError::Version(version));
        }
        let kind = read_field(&raw[2..2 + TYPE_WIDTH]);
        if kind.is_empty() || !kind.bytes().all(|b| (0x20..0x7f).contains(&b)) {
            return Err(FrameError::Type(kind));
        }
        Ok(Header {
            version,
            kind,
            device: read_field(&raw[14..14 + DEVICE_WIDTH]),
            timestamp: u64_at(34),
            body_size: u64_at(42),
            crc: u64_at(50),
        })
    }

    /// The header's bytes (names NUL-padded); refuses names too long for their fields.
    pub fn to_bytes(&self) -> Result<[u8; HEADER_SIZE], ContentError> {
        let mut v = Vec::with_capacity(HEADER_SIZE);
        v.extend_from_slice(&self.version.to_be_bytes());
        write_field(&mut v, &self.kind, TYPE_WIDTH, "message type")?;
        write_field(&mut v, &self.device, DEVICE_WIDTH, "device name")?;
        for x in [self.timestamp, self.body_size, self.crc] {
            v.extend_from_slice(&x.to_be_bytes());
        }
        let mut out = [0u8; HEADER_SIZE];
        out.copy_from_slice(&v);
        Ok(out)
    }
}

impl std::fmt::Display for Header {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} '{}'", self.kind, self.device)
    }
}

/// A timestamp in the header's form from seconds since the epoch.
pub fn timestamp_of(seconds: f64) -> u64 {
    let s = seconds.max(0.0);
    let whole = s.floor().min(u32::MAX as f64);
    let fraction = ((s - whole) * 4_294_967_296.0).min(u32::MAX as f64);
    ((whole as u64) << 32) | fraction as u64
}

/// Now, in the header's form.
pub fn now() -> u64 {
    let t = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH);
    timestamp_of(t.map_or(0.0, |d| d.as_secs_f64()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> Header {
        Header {
            version: 1,
            kind: "STRING".into(),
            device: "Report".into(),
            timestamp: timestamp_of(1234.5),
            body_size: 7,
            crc: 0xDEAD_BEEF,
        }
    }

    #[test]
    fn a_header_round_trips_and_its_names_end_at_their_first_nul() {
        let h = header();
        let mut raw = h.to_bytes().unwrap();
        assert_eq!(Header::parse(&raw).unwrap(), h);
        raw[14 + 7] = b'X'; // after "Report\0": ignored, as the C++ library does
        assert_eq!(Header::parse(&raw).unwrap().device, "Report");
        assert_eq!(h.timestamp, (1234 << 32) | (1 << 31));
    }

    #[test]
    fn a_stream_that_is_not_openigtlink_is_refused() {
        let mut raw = header().to_bytes().unwrap();
        raw[1] = 3;
        assert!(matches!(Header::parse(&raw), Err(FrameError::Version(3))));
        let mut raw = header().to_bytes().unwrap();
        raw[2] = 0;
        assert!(matches!(Header::parse(&raw), Err(FrameError::Type(t)) if t.is_empty()));
        raw[2] = 0x07;
        assert!(matches!(Header::parse(&raw), Err(FrameError::Type(_))));
    }
}
