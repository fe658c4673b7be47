//! Pack then unpack is the identity, for arbitrary contents of every message type with
//! fields, in both header versions, with arbitrary metadata.

use bs_igtl::{
    Cells, Decode, Encode, Envelope, Message, MetaEntry, Point, Points, PolyData, Status, Text,
    Transform, pack_message, read_message,
};
use proptest::prelude::*;

fn round_trip<T: Encode + Decode>(t: &T, version: u16, metadata: &[MetaEntry]) -> (T, Message) {
    let e = Envelope { version, device: "dev", timestamp: 77, message_id: 3, metadata };
    let bytes = pack_message(t, &e).unwrap().to_vec();
    let (h, body) = read_message(&mut &bytes[..], u64::MAX, None).unwrap().unwrap();
    let m = Message::new(h, body).unwrap();
    (m.read().unwrap(), m)
}

fn metadata() -> impl Strategy<Value = Vec<MetaEntry>> {
    prop::collection::vec(
        ("[a-zA-Z-]{0,12}", any::<u16>(), prop::collection::vec(any::<u8>(), 0..20))
            .prop_map(|(key, encoding, value)| MetaEntry { key, encoding, value }),
        0..4,
    )
}

fn finite() -> impl Strategy<Value = f32> {
    -1e6f32..1e6f32
}

proptest! {
    #[test]
    fn polydata_round_trips(
        points in prop::collection::vec([finite(), finite(), finite()], 1..20),
        cells in prop::collection::vec(prop::collection::vec(0u32..1, 0..6), 0..8),
        version in 1u16..=2,
        meta in metadata(),
    ) {
        let n = points.len() as u32;
        let cells: Vec<Vec<u32>> = cells.iter().map(|c| c.iter().enumerate().map(|(k, _)| k as u32 % n).collect()).collect();
        let p = PolyData {
            points,
            polygons: Cells::of(cells.iter().map(Vec::as_slice)),
            strips: Cells::of(cells.iter().rev().map(Vec::as_slice)),
            ..PolyData::default()
        };
        let (q, m) = round_trip(&p, version, &meta);
        prop_assert_eq!(q, p);
        if version == 2 {
            prop_assert_eq!(m.metadata, meta);
        }
    }

    #[test]
    fn points_text_status_and_transforms_round_trip(
        names in prop::collection::vec("[ -~]{0,64}", 0..5),
        xyz in [finite(), finite(), finite()],
        text in "\\PC{0,200}",
        code in any::<u16>(),
        subcode in any::<i64>(),
        columns in prop::array::uniform12(finite()),
        version in 1u16..=2,
    ) {
        let points = Points { points: names.iter().map(|n| Point {
            name: n.clone(), group: "Landmark".into(), rgba: [1, 2, 3, 4], position: xyz,
            radius: 0.5, owner: String::new() }).collect() };
        prop_assert_eq!(round_trip(&points, version, &[]).0, points);
        let t = Text::new(&text);
        prop_assert_eq!(round_trip(&t, version, &[]).0.text(), text.clone());
        let s = Status { code, subcode, error_name: "e".into(), message: text.replace('\0', "") };
        prop_assert_eq!(round_trip(&s, version, &[]).0, s);
        let tr = Transform { columns };
        prop_assert_eq!(round_trip(&tr, version, &[]).0, tr);
    }
}
