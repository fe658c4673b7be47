//! The queries: `GET_<TYPE>` (send me one), `STT_<TYPE>` (start streaming), `STP_<TYPE>`
//! (stop) and `RTS_<TYPE>` (ready to send: the answer to STT_/STP_). Their content is kept as
//! bytes (`STT_TDATA`'s resolution and frame name, `RTS_`'s status byte); brainshift answers
//! none of them and needs none of their fields.

use super::{Decode, Encode, Encoded};
use crate::error::ContentError;
use crate::frame::Message;

/// The four query prefixes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verb {
    /// `GET_`.
    Get,
    /// `STT_`.
    Start,
    /// `STP_`.
    Stop,
    /// `RTS_`.
    Ready,
}

impl Verb {
    const ALL: [(Verb, &'static str); 4] =
        [(Verb::Get, "GET_"), (Verb::Start, "STT_"), (Verb::Stop, "STP_"), (Verb::Ready, "RTS_")];

    /// The prefix (`GET_`, ...).
    pub fn prefix(self) -> &'static str {
        Verb::ALL.iter().find(|(v, _)| *v == self).map_or("", |(_, p)| p)
    }

    /// The verb and the type it is about, when `kind` is a query.
    pub fn of(kind: &str) -> Option<(Verb, &str)> {
        Verb::ALL.iter().find_map(|&(v, p)| kind.strip_prefix(p).map(|t| (v, t)))
    }
}

/// A query message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Query {
    /// Its verb.
    pub verb: Verb,
    /// The type asked about (`IMAGE`, `TDATA`, ...).
    pub target: String,
    /// Its content, as sent.
    pub content: Vec<u8>,
}

impl Decode for Query {
    fn decode(m: &Message) -> Result<Query, ContentError> {
        let (verb, target) = Verb::of(&m.header.kind).ok_or_else(|| ContentError::Type {
            expected: "GET_, STT_, STP_ or RTS_",
            found: m.header.kind.clone(),
        })?;
        Ok(Query { verb, target: target.to_string(), content: m.content().to_vec() })
    }
}

impl Encode for Query {
    fn kind(&self) -> String {
        format!("{}{}", self.verb.prefix(), self.target)
    }

    fn encode(&self) -> Result<Encoded<'_>, ContentError> {
        Ok(Encoded { head: Vec::new(), data: &self.content })
    }
}
