//! POINT: a list of 136-byte elements: name (64 bytes), group (32), RGBA (4 × u8), position
//! (3 × float32), radius (float32), owner (20: the image the point belongs to).

use super::bytes::{Reader, put_f32s};
use super::{Decode, Encode, Encoded, expect};
use crate::error::ContentError;
use crate::frame::Message;
use crate::name::{read_field, write_field};

/// One element's size, bytes.
pub const ELEMENT_SIZE: usize = 136;

/// One point.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Its name (at most 64 bytes; may be empty).
    pub name: String,
    /// Its group ("Landmark", "Fiducial", ...).
    pub group: String,
    /// Colour.
    pub rgba: [u8; 4],
    /// Position (the sender's frame: RAS mm for 3D Slicer).
    pub position: [f32; 3],
    /// Radius.
    pub radius: f32,
    /// The device name of the image it belongs to.
    pub owner: String,
}

/// A POINT's content.
#[derive(Debug, Clone, PartialEq)]
pub struct Points {
    /// The points, in order.
    pub points: Vec<Point>,
}

impl Decode for Points {
    fn decode(m: &Message) -> Result<Points, ContentError> {
        expect(m, "POINT")?;
        let c = m.content();
        let mut r = Reader::new("POINT", c);
        if !c.len().is_multiple_of(ELEMENT_SIZE) {
            return Err(r.error(format!(
                "{} bytes is not a whole number of {ELEMENT_SIZE}-byte points",
                c.len()
            )));
        }
        let mut points = Vec::with_capacity(c.len() / ELEMENT_SIZE);
        while r.at < c.len() {
            points.push(element(&mut r)?);
        }
        Ok(Points { points })
    }
}

/// The next element.
fn element(r: &mut Reader<'_>) -> Result<Point, ContentError> {
    let name = read_field(r.take(64, "a name")?);
    let group = read_field(r.take(32, "a group")?);
    let c = r.take(4, "a colour")?;
    let rgba = [c[0], c[1], c[2], c[3]];
    let position = r.f32s::<3>("a position")?;
    let radius = r.f32("a radius")?;
    let owner = read_field(r.take(20, "an owner")?);
    Ok(Point { name, group, rgba, position, radius, owner })
}

impl Encode for Points {
    fn kind(&self) -> String {
        "POINT".into()
    }

    fn encode(&self) -> Result<Encoded<'_>, ContentError> {
        let mut out = Vec::with_capacity(ELEMENT_SIZE * self.points.len());
        for p in &self.points {
            write_field(&mut out, &p.name, 64, "point name")?;
            write_field(&mut out, &p.group, 32, "point group")?;
            out.extend_from_slice(&p.rgba);
            put_f32s(&mut out, &p.position);
            put_f32s(&mut out, &[p.radius]);
            write_field(&mut out, &p.owner, 20, "point owner")?;
        }
        Ok(Encoded::owned(out))
    }
}
