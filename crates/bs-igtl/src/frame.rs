//! A message's body as framed: version 1 is the content alone; version 2 (OpenIGTLink 3, 3D
//! Slicer 5's default) is a 12-byte extended header (its own size, the metadata header's
//! size, the metadata's size, a message id), the content, then the metadata: a u16 count,
//! per entry (key size u16, value encoding u16, value size u32), then the keys and values.
//! The CRC covers the whole body. Metadata keys are kept whatever they are: none is
//! required, an unknown one is not an error.

use crate::crc::crc64;
use crate::error::ContentError;
use crate::header::Header;

/// The extended header's size as written (a reader takes any size of at least this).
pub const EXTENDED_SIZE: usize = 12;

/// One metadata entry.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MetaEntry {
    /// The key (UTF-8 on the wire).
    pub key: String,
    /// The value's encoding (IANA MIBenum: 3 US-ASCII, 106 UTF-8).
    pub encoding: u16,
    /// The value's bytes.
    pub value: Vec<u8>,
}

/// A message as received: its header and body, the body's checksum verified.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Message {
    /// The header.
    pub header: Header,
    /// The whole body.
    pub body: Vec<u8>,
    /// The content's byte range in the body.
    content: std::ops::Range<usize>,
    /// Version 2: the message id.
    pub message_id: Option<u32>,
    /// Version 2: the metadata.
    pub metadata: Vec<MetaEntry>,
}

impl Message {
    /// The message framed from its header and body: the CRC verified, a version-2 body split
    /// into extended header, content and metadata.
    pub fn new(header: Header, body: Vec<u8>) -> Result<Message, ContentError> {
        let computed = crc64(&body, 0);
        if computed != header.crc {
            return Err(ContentError::Crc { computed, header: header.crc });
        }
        if header.version < 2 {
            let content = 0..body.len();
            return Ok(Message { header, body, content, message_id: None, metadata: Vec::new() });
        }
        let (content, message_id, metadata) = split_v2(&body)?;
        Ok(Message { header, body, content, message_id: Some(message_id), metadata })
    }

    /// The content: the body without extended header and metadata.
    pub fn content(&self) -> &[u8] {
        &self.body[self.content.clone()]
    }

    /// A metadata value as text (lossy), by key.
    pub fn meta(&self, key: &str) -> Option<String> {
        let e = self.metadata.iter().find(|e| e.key == key)?;
        Some(String::from_utf8_lossy(&e.value).into_owned())
    }
}

fn be16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}

fn be32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// The content range, message id and metadata of a version-2 body.
fn split_v2(body: &[u8]) -> Result<(std::ops::Range<usize>, u32, Vec<MetaEntry>), ContentError> {
    let err = |message: String| ContentError::Extended { body: body.len(), message };
    if body.len() < EXTENDED_SIZE {
        return Err(err(format!("shorter than its {EXTENDED_SIZE}-byte extended header")));
    }
    let ext = be16(body, 0) as usize;
    let meta_header = be16(body, 2) as usize;
    let meta_body = be32(body, 4) as usize;
    let id = be32(body, 8);
    let meta = meta_header + meta_body;
    if ext < EXTENDED_SIZE || ext + meta > body.len() {
        return Err(err(format!(
            "an extended header of {ext} bytes and metadata of {meta} bytes do not fit it"
        )));
    }
    let end = body.len() - meta;
    let metadata =
        parse_metadata(&body[end..end + meta_header], &body[end + meta_header..]).map_err(err)?;
    Ok((ext..end, id, metadata))
}

/// Metadata entries from the metadata header (count, then 8 bytes per entry) and the keys
/// and values after it. An empty header (size 0) is no metadata.
fn parse_metadata(header: &[u8], data: &[u8]) -> Result<Vec<MetaEntry>, String> {
    if header.is_empty() {
        return if data.is_empty() {
            Ok(Vec::new())
        } else {
            Err(format!("{} bytes of metadata without a metadata header", data.len()))
        };
    }
    if header.len() < 2 {
        return Err("a metadata header of 1 byte (its count needs 2)".into());
    }
    let count = be16(header, 0) as usize;
    if header.len() != 2 + 8 * count {
        return Err(format!(
            "a metadata header of {} bytes for {count} entries (2 + 8 per entry)",
            header.len()
        ));
    }
    let mut entries = Vec::with_capacity(count);
    let mut at = 0usize;
    for k in 0..count {
        let e = 2 + 8 * k;
        let (key_size, encoding) = (be16(header, e) as usize, be16(header, e + 2));
        let value_size = be32(header, e + 4) as usize;
        let end = at + key_size + value_size;
        if end > data.len() {
            return Err(format!("metadata entry {} runs past the metadata", k + 1));
        }
        let key = String::from_utf8_lossy(&data[at..at + key_size]).into_owned();
        let value = data[at + key_size..end].to_vec();
        entries.push(MetaEntry { key, encoding, value });
        at = end;
    }
    if at != data.len() {
        return Err(format!("{} bytes of metadata after its last entry", data.len() - at));
    }
    Ok(entries)
}

/// The version-2 framing around a content: the extended header, and the metadata's header
/// and data (`metadata` may be empty: a count of 0).
pub fn v2_parts(
    message_id: u32,
    metadata: &[MetaEntry],
) -> Result<(Vec<u8>, Vec<u8>), ContentError> {
    let mut head = Vec::with_capacity(2 + 8 * metadata.len());
    let mut data = Vec::new();
    let count = u16::try_from(metadata.len()).map_err(|_| {
        ContentError::Pack(format!("{} metadata entries (at most 65535)", metadata.len()))
    })?;
    head.extend_from_slice(&count.to_be_bytes());
    for e in metadata {
        let key = u16::try_from(e.key.len())
            .map_err(|_| ContentError::Pack(format!("metadata key of {} bytes", e.key.len())))?;
        let value = u32::try_from(e.value.len()).map_err(|_| {
            ContentError::Pack(format!("metadata value of {} bytes", e.value.len()))
        })?;
        head.extend_from_slice(&key.to_be_bytes());
        head.extend_from_slice(&e.encoding.to_be_bytes());
        head.extend_from_slice(&value.to_be_bytes());
        data.extend_from_slice(e.key.as_bytes());
        data.extend_from_slice(&e.value);
    }
    let meta_header = u16::try_from(head.len())
        .map_err(|_| ContentError::Pack("a metadata header over 65535 bytes".into()))?;
    let meta_size =
        u32::try_from(data.len()).map_err(|_| ContentError::Pack("metadata over 4 GiB".into()))?;
    let mut ext = Vec::with_capacity(EXTENDED_SIZE);
    ext.extend_from_slice(&(EXTENDED_SIZE as u16).to_be_bytes());
    ext.extend_from_slice(&meta_header.to_be_bytes());
    ext.extend_from_slice(&meta_size.to_be_bytes());
    ext.extend_from_slice(&message_id.to_be_bytes());
    head.extend_from_slice(&data);
    Ok((ext, head))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(version: u16, body: &[u8]) -> Header {
        Header {
            version,
            kind: "STRING".into(),
            device: "x".into(),
            timestamp: 0,
            body_size: body.len() as u64,
            crc: crc64(body, 0),
        }
    }

    #[test]
    fn a_v2_body_splits_into_content_and_metadata_with_unknown_keys_kept() {
        let meta = vec![
            MetaEntry { key: "Sender".into(), encoding: 3, value: b"Slicer".to_vec() },
            MetaEntry { key: "x-unknown".into(), encoding: 106, value: "é".as_bytes().to_vec() },
        ];
        let (ext, tail) = v2_parts(41, &meta).unwrap();
        let body = [ext, b"content".to_vec(), tail].concat();
        let m = Message::new(header(2, &body), body).unwrap();
        assert_eq!(m.content(), b"content");
        assert_eq!((m.message_id, m.metadata.clone()), (Some(41), meta));
        assert_eq!(m.meta("x-unknown").as_deref(), Some("é"));
    }

    #[test]
    fn a_bad_checksum_or_extended_header_is_an_error_of_the_message() {
        let body = b"content".to_vec();
        let mut h = header(1, &body);
        h.crc ^= 1;
        assert!(matches!(Message::new(h, body.clone()), Err(ContentError::Crc { .. })));
        let short = header(2, &body);
        assert!(matches!(Message::new(short, body), Err(ContentError::Extended { .. })));
        let (mut ext, tail) = v2_parts(1, &[]).unwrap();
        ext[5] = 0xff; // metadata larger than the body
        let body = [ext, tail].concat();
        assert!(matches!(Message::new(header(2, &body), body), Err(ContentError::Extended { .. })));
    }
}
