//! The fixed-width text fields of OpenIGTLink (a header's 12-byte type and 20-byte device
//! name, a POINT's name and group, a STATUS's error name): read as the C++ library reads
//! them, up to the first NUL (bytes after it ignored, a field without one taken whole), and
//! written NUL-padded. Text is taken as UTF-8 where it is, byte for byte as Latin-1
//! otherwise, so that every field can be read and named in an answer.

use crate::error::ContentError;

/// The text of a fixed-width field: the bytes before its first NUL.
pub fn read_field(raw: &[u8]) -> String {
    let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
    let text = &raw[..end];
    match std::str::from_utf8(text) {
        Ok(s) => s.to_string(),
        Err(_) => text.iter().map(|&b| b as char).collect(),
    }
}

/// Writes `text` into a field of `width` bytes, NUL-padded; refuses text longer than the
/// field or holding a NUL (it would be read back shorter).
pub fn write_field(
    out: &mut Vec<u8>,
    text: &str,
    width: usize,
    what: &'static str,
) -> Result<(), ContentError> {
    let bytes = text.as_bytes();
    if bytes.len() > width || bytes.contains(&0) {
        return Err(ContentError::Field { what, width, text: text.to_string() });
    }
    out.extend_from_slice(bytes);
    out.resize(out.len() + width - bytes.len(), 0);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_field_ends_at_its_first_nul_as_the_cpp_library_reads_it() {
        assert_eq!(read_field(b"Intraop\0junk\0\0"), "Intraop");
        assert_eq!(read_field(b"\0Intraop"), "");
        assert_eq!(read_field(b"TwentyBytesNoNulHere"), "TwentyBytesNoNulHere");
        assert_eq!(read_field(b"caf\xe9\0"), "café"); // Latin-1 when not UTF-8
    }

    #[test]
    fn writing_pads_and_refuses_what_would_not_read_back() {
        let mut out = Vec::new();
        write_field(&mut out, "Report", 20, "device name").unwrap();
        assert_eq!(out.len(), 20);
        assert_eq!(read_field(&out), "Report");
        assert!(write_field(&mut out, "a name of twenty-one!", 20, "device name").is_err());
        assert!(write_field(&mut out, "a\0b", 20, "device name").is_err());
    }
}
