//! STRING: an encoding (IANA MIBenum: 3 US-ASCII, 106 UTF-8), a 16-bit length and the text,
//! with no NUL after it. A STRING holds at most 65535 bytes of text.

use super::bytes::{Reader, put_u16};
use super::{Decode, Encode, Encoded, expect};
use crate::error::ContentError;
use crate::frame::Message;

/// IANA MIBenum of US-ASCII.
pub const US_ASCII: u16 = 3;
/// IANA MIBenum of UTF-8.
pub const UTF_8: u16 = 106;
/// The most text bytes a STRING holds.
pub const MAX_TEXT: usize = 0xFFFF;

/// A STRING's content.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Text {
    /// The encoding (MIBenum).
    pub encoding: u16,
    /// The text's bytes.
    pub bytes: Vec<u8>,
}

impl Text {
    /// `text` as US-ASCII when it is, else UTF-8.
    pub fn new(text: &str) -> Text {
        let encoding = if text.is_ascii() { US_ASCII } else { UTF_8 };
        Text { encoding, bytes: text.as_bytes().to_vec() }
    }

    /// [`Text::new`] of `text`, cut at a character boundary with a note saying so when it is
    /// longer than a STRING holds.
    pub fn cut(text: &str) -> Text {
        if text.len() <= MAX_TEXT {
            return Text::new(text);
        }
        let note = " ... (cut: longer than a STRING message holds)";
        let mut end = MAX_TEXT - note.len();
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        Text::new(&format!("{}{note}", &text[..end]))
    }

    /// The text (invalid UTF-8 replaced).
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.bytes).into_owned()
    }
}

impl Decode for Text {
    fn decode(m: &Message) -> Result<Text, ContentError> {
        expect(m, "STRING")?;
        let mut r = Reader::new("STRING", m.content());
        let encoding = r.u16("the encoding")?;
        let length = r.u16("the length")? as usize;
        let bytes = r.take(length, "the text")?.to_vec();
        r.finish()?;
        Ok(Text { encoding, bytes })
    }
}

impl Encode for Text {
    fn kind(&self) -> String {
        "STRING".into()
    }

    fn encode(&self) -> Result<Encoded<'_>, ContentError> {
        let length = u16::try_from(self.bytes.len()).map_err(|_| {
            ContentError::Pack(format!(
                "a STRING of {} bytes: it holds at most {MAX_TEXT} (Text::cut)",
                self.bytes.len()
            ))
        })?;
        let mut out = Vec::with_capacity(4 + self.bytes.len());
        put_u16(&mut out, self.encoding);
        put_u16(&mut out, length);
        out.extend_from_slice(&self.bytes);
        Ok(Encoded::owned(out))
    }
}
