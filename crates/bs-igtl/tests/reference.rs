//! Byte-exact round trips of messages written by independent implementations: the reference
//! C++ library (Debian's libopenigtlink 1.11: header version 1) and pyigtl 0.3.4 (header
//! version 2 with metadata), from `fixtures/igtl/make.sh`. Each file is read, decoded,
//! encoded and framed again, and must come back byte for byte; its fields are checked
//! against what the writing scripts set. Then every truncation and every single-bit flip of
//! every file: an error, or (a flip in the header's names or timestamp, which the CRC does
//! not cover) the same content — never a panic.

use std::path::PathBuf;

use bs_igtl::messages::query::Verb;
use bs_igtl::{
    Decode, Encode, Envelope, FrameError, Image, Message, Points, PolyData, Query, Status, Text,
    Transform, pack_message, read_message,
};

fn fixture(name: &str) -> Vec<u8> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/igtl").join(name);
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn message(bytes: &[u8]) -> Message {
    let (h, body) = read_message(&mut &bytes[..], 1 << 30, None).unwrap().unwrap();
    Message::new(h, body).unwrap()
}

/// `m` decoded as `T`, encoded and framed with `m`'s own envelope.
fn again<T: Decode + Encode>(m: &Message) -> Result<Vec<u8>, String> {
    let t: T = m.read().map_err(|e| e.to_string())?;
    let envelope = Envelope {
        version: m.header.version,
        device: &m.header.device,
        timestamp: m.header.timestamp,
        message_id: m.message_id.unwrap_or(0),
        metadata: &m.metadata,
    };
    Ok(pack_message(&t, &envelope).map_err(|e| e.to_string())?.to_vec())
}

/// Every file and the type it holds.
const FILES: [(&str, Again); 18] = [
    ("image_scalar.igtl", again::<Image<'static>>),
    ("image_vector.igtl", again::<Image<'static>>),
    ("pyigtl_image.igtl", again::<Image<'static>>),
    ("polydata.igtl", again::<PolyData>),
    ("triangles.igtl", again::<PolyData>),
    ("v2_polydata.igtl", again::<PolyData>),
    ("point.igtl", again::<Points>),
    ("v2_point.igtl", again::<Points>),
    ("string.igtl", again::<Text>),
    ("string_gravity.igtl", again::<Text>),
    ("v2_string.igtl", again::<Text>),
    ("v2_empty_metadata.igtl", again::<Text>),
    ("status.igtl", again::<Status>),
    ("transform.igtl", again::<Transform>),
    ("get_image.igtl", again::<Query>),
    ("stt_tdata.igtl", again::<Query>),
    ("stp_tdata.igtl", again::<Query>),
    ("rts_tdata.igtl", again::<Query>),
];

#[test]
fn every_reference_message_round_trips_byte_for_byte() {
    for (name, again) in FILES {
        let bytes = fixture(name);
        let m = message(&bytes);
        assert_eq!(again(&m).unwrap(), bytes, "{name}");
    }
}

#[test]
fn the_cpp_librarys_fields_read_as_it_wrote_them() {
    let m = message(&fixture("status.igtl"));
    assert_eq!((m.header.version, m.header.device.as_str()), (1, "")); // Slicer's empty name
    let s: Status = m.read().unwrap();
    assert_eq!(
        (s.code, s.subcode, s.error_name.as_str(), s.message.as_str()),
        (1, -7, "none", "connected")
    );
    assert_eq!(m.header.timestamp, (1_700_000_000 << 32) | 0x8000_0000);

    let p: PolyData = message(&fixture("polydata.igtl")).read().unwrap();
    assert_eq!(p.points.len(), 6);
    assert_eq!(p.points[5], [5.0, -5.0, 2.5]);
    assert_eq!((p.vertices.count, p.lines.count, p.polygons.count, p.strips.count), (1, 1, 2, 1));
    // The quad fanned, the strip split with its middle triangle flipped.
    let expected = [[0, 1, 4], [0, 1, 2], [0, 2, 3], [0, 1, 3], [3, 1, 2], [3, 2, 4]];
    assert_eq!(p.triangles(), expected);
    let names: Vec<&str> = p.attributes.iter().map(|a| a.name.as_str()).collect();
    assert_eq!(names, ["distance", "flows"]);
    assert_eq!((p.attributes[1].components, p.attributes[1].count), (3, 6));
    assert_eq!(p.attributes[0].data, [0.5, 1.5, 2.5, 3.5, 4.5, 5.5]);

    let pts: Points = message(&fixture("point.igtl")).read().unwrap();
    let names: Vec<&str> = pts.points.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["L1", "anterior commissure", ""]);
    assert_eq!(pts.points[1].position, [0.0, 22.5, -7.0]);
    assert_eq!((pts.points[1].owner.as_str(), pts.points[2].rgba), ("T1", [255, 128, 0, 200]));

    let t: Transform = message(&fixture("transform.igtl")).read().unwrap();
    let m = t.matrix();
    assert_eq!(m[0], [0.0, -1.0, 0.0, 12.5]);
    assert_eq!(m[2], [0.0, 0.0, 1.0, 100.0]);

    let q: Query = message(&fixture("stt_tdata.igtl")).read().unwrap();
    assert_eq!((q.verb, q.target.as_str(), q.content.len()), (Verb::Start, "TDATA", 36));
    let text: Text = message(&fixture("string.igtl")).read().unwrap();
    assert_eq!(text.text(), "node_id,ux,uy,uz\n12,0,0,-2.5\n");
}

#[test]
fn the_image_matrix_locates_the_volumes_centre() {
    // write_reference.cpp: spacing (2, 1, 1.5), i along +y, j along -x, centre (10.5, -3, 7).
    let i: Image<'static> = message(&fixture("image_scalar.igtl")).read().unwrap();
    assert_eq!((i.size, i.components, i.frame), ([4, 3, 2], 1, 1));
    let m = i.ijk_to_world();
    assert_eq!(m[0], [0.0, -1.0, 0.0, 10.5 + 1.0]);
    assert_eq!(m[1], [2.0, 0.0, 0.0, -3.0 - 3.0]);
    assert_eq!(m[2], [0.0, 0.0, 1.5, 7.0 - 0.75]);
    let v: Image<'static> = message(&fixture("image_vector.igtl")).read().unwrap();
    assert_eq!((v.components, v.data.len()), (3, 4 * 3 * 2 * 3 * 4));

    // pyigtl from an IJK-to-RAS matrix (write_v2.py): the same matrix back, and the same
    // bytes when the image is made here from that matrix.
    let affine =
        [[0.0, -1.0, 0.0, 10.5], [0.9, 0.0, 0.0, -3.0], [0.0, 0.0, 1.2, 7.0], [0.0, 0.0, 0.0, 1.0]];
    let bytes = fixture("pyigtl_image.igtl");
    let m = message(&bytes);
    let p: Image<'static> = m.read().unwrap();
    for (r, row) in p.ijk_to_world().iter().enumerate() {
        for (c, x) in row.iter().enumerate() {
            assert!((x - affine[r][c]).abs() < 1e-5, "{r} {c}: {x}");
        }
    }
    let mut mine = p.clone();
    mine.matrix = [0.0; 12];
    mine.set_ijk_to_world(&affine);
    assert_eq!(mine.matrix, p.matrix);
}

#[test]
fn version_2_metadata_and_message_ids_are_read_unknown_keys_kept() {
    let m = message(&fixture("v2_string.igtl"));
    assert_eq!((m.header.version, m.message_id), (2, Some(7)));
    assert_eq!(m.meta("Sender").as_deref(), Some("Slicer"));
    assert_eq!(m.meta("x-unknown-key").as_deref(), Some("kept, not read"));
    assert_eq!(m.read::<Text>().unwrap().text(), "0,-1,0");
    let e = message(&fixture("v2_empty_metadata.igtl"));
    assert!(e.metadata.is_empty());
    let p: PolyData = message(&fixture("v2_polydata.igtl")).read().unwrap();
    assert_eq!(p.triangles(), [[0, 1, 2], [0, 2, 3]]);
}

#[test]
fn every_truncation_is_an_error() {
    for (name, _) in FILES {
        let bytes = fixture(name);
        assert!(read_message(&mut &bytes[..0], 1 << 30, None).unwrap().is_none());
        for cut in 1..bytes.len() {
            match read_message(&mut &bytes[..cut], 1 << 30, None) {
                Err(FrameError::Truncated { .. }) => {}
                other => panic!("{name} cut at {cut}: {other:?}"),
            }
        }
    }
}

/// Reads `bytes` through framing and `decode` to the end: Ok with the content read, or the
/// first error as text.
type Again = fn(&Message) -> Result<Vec<u8>, String>;

fn through(bytes: &[u8], decode: Again) -> Result<(Message, Vec<u8>), String> {
    let (h, body) = match read_message(&mut &bytes[..], 1 << 30, None) {
        Ok(Some(x)) => x,
        Ok(None) => return Err("empty".into()),
        Err(e) => return Err(e.to_string()),
    };
    let m = Message::new(h, body).map_err(|e| e.to_string())?;
    let content = decode(&m)?;
    Ok((m, content))
}

#[test]
fn every_bit_flip_is_an_error_or_leaves_the_content_as_it_was() {
    for (name, decode) in FILES {
        let bytes = fixture(name);
        let original = message(&bytes);
        for bit in 0..8 * bytes.len() {
            let mut b = bytes.clone();
            b[bit / 8] ^= 1 << (bit % 8);
            if let Ok((m, _)) = through(&b, decode) {
                // Only the header's names (a type still of the same family: after its NUL, or
                // a query's target) and timestamp escape the CRC.
                assert!((2..42).contains(&(bit / 8)), "{name} bit {bit}: read as {m:?}");
                assert_eq!(m.content(), original.content(), "{name} bit {bit}");
            }
        }
    }
}
