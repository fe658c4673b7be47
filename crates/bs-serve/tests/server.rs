//! The server in this process, driven by a client of bs-igtl over loopback: an update is
//! answered with the four replies, equal to the same update solved by a session here; a
//! client is answered in the header version it last sent; the bytes the C++ library and 3D
//! Slicer send (a device name with bytes after its NUL, a STATUS with an empty name, version
//! 2 metadata with unknown keys, a body larger than its header says) each get a clear
//! answer, and the server stays up.

use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use bs_igtl::{
    Envelope, FrameError, Image, Message, MetaEntry, PolyData, Status, Text, pack_message,
    read_message,
};
use bs_scene::{BoundaryValues, Prepared, Session, Update};
use bs_serve::{Log, Options, Server};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures")
}

struct Running {
    server: Arc<Server>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
    port: u16,
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        self.server.stop();
    }
}

fn start() -> Running {
    let options = Options {
        scene: fixtures().join("ellipsoid/scene.toml"),
        image: fixtures().join("registration/preop.nii.gz"),
        host: "127.0.0.1".into(),
        port: 0,
        set: None,
        threads: Some(1),
        no_field: false,
        no_surface: false,
        uncertainty: None,
        max_message_mb: 64.0,
        stall_seconds: 30.0,
        max_clients: 16,
        verbose: false,
    };
    let server = Arc::new(Server::bind(&options, Log::to(Box::new(std::io::sink()))).unwrap());
    let port = server.address().unwrap().port();
    let stop = Arc::new(AtomicBool::new(false));
    let (s, f) = (Arc::clone(&server), Arc::clone(&stop));
    let thread = Some(std::thread::spawn(move || s.serve(&f)));
    Running { server, stop, thread, port }
}

fn envelope<'a>(version: u16, device: &'a str, metadata: &'a [MetaEntry]) -> Envelope<'a> {
    Envelope { version, device, timestamp: 1 << 32, message_id: 5, metadata }
}

fn text(version: u16, device: &str, t: &str, metadata: &[MetaEntry]) -> Vec<u8> {
    pack_message(&Text::new(t), &envelope(version, device, metadata)).unwrap().to_vec()
}

/// Sends `bytes` on a new connection and reads `n` replies.
fn exchange(port: u16, bytes: &[u8], n: usize) -> Vec<Message> {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    std::io::Write::write_all(&mut s, bytes).unwrap();
    (0..n)
        .map(|_| {
            let (h, body) = read_message(&mut s, u64::MAX, None).unwrap().unwrap();
            Message::new(h, body).unwrap()
        })
        .collect()
}

fn error_of(m: &Message) -> String {
    assert_eq!(m.header.device, "Error", "{}", m.header);
    m.read::<Text>().unwrap().text()
}

/// The CRANIOTOMY displaced uniformly, as CSV rows, and the same update in a session here.
fn uniform(dz: f64) -> (String, Vec<bs_mesh::Point3<f64>>) {
    let p = Prepared::load(&fixtures().join("ellipsoid/scene.toml")).unwrap();
    let mut s = Session::new(p).unwrap();
    let ids = &s.run().prepared.mesh.node_ids;
    let nodes = s.set_nodes("CRANIOTOMY").unwrap();
    let mut csv = String::from("node_id,ux,uy,uz\n");
    for &n in nodes.iter().rev() {
        csv += &format!("{},0,0,{dz}\n", ids[n]);
    }
    let v = BoundaryValues::Uniform(bs_mesh::Vector3::new(0.0, 0.0, dz));
    let solved =
        s.apply(&[Update::Boundary { set: "CRANIOTOMY".into(), values: v }], &mut |_| {}).unwrap();
    let b =
        bs_scene::output::deformed_boundary(&s.run().prepared.mesh, &solved.solution.displacements);
    (csv, b.surface.vertices)
}

#[test]
fn an_update_is_answered_as_the_session_answers_it_in_the_clients_header_version() {
    let r = start();
    let (csv, expected) = uniform(-2.0);
    let meta = [MetaEntry { key: "x-unknown-key".into(), encoding: 3, value: b"kept".to_vec() }];
    let out = exchange(r.port, &text(2, "Displacements", &csv, &meta), 4);
    let devices: Vec<&str> = out.iter().map(|m| m.header.device.as_str()).collect();
    assert_eq!(devices, ["WarpedImage", "DisplacementField", "DeformedBrain", "Report"]);
    assert!(out.iter().all(|m| m.header.version == 2), "answered in version 2");
    let ids: Vec<u32> = out.iter().filter_map(|m| m.message_id).collect();
    assert!(ids.windows(2).all(|w| w[1] == w[0] + 1), "{ids:?}");
    let w: Image<'static> = out[0].read().unwrap();
    assert_eq!((w.size, w.components), ([50, 44, 36], 1));
    let f: Image<'static> = out[1].read().unwrap();
    assert_eq!(f.components, 3);
    let b: PolyData = out[2].read().unwrap();
    assert_eq!(b.points.len(), expected.len());
    for (p, q) in b.points.iter().zip(&expected) {
        assert!((0..3).all(|k| (p[k] as f64 - q[k]).abs() < 1e-3), "{p:?} vs {q}");
    }
    let report = out[3].read::<Text>().unwrap().text();
    assert!(report.contains("\"converged\":true") && report.contains("\"serve\""), "{report}");
}

#[test]
fn what_the_cpp_library_and_slicer_send_gets_a_clear_answer_and_the_server_stays_up() {
    let r = start();
    // Slicer's STATUS with an empty device name: nothing to answer. Then a device name with
    // bytes after its NUL: read up to the NUL, as the C++ library reads it.
    let status =
        Status { code: 1, subcode: 0, error_name: String::new(), message: "connected".into() };
    let mut bytes = pack_message(&status, &envelope(1, "", &[])).unwrap().to_vec();
    let mut junk = text(1, "Displacements", "node_id,ux,uy,uz\n", &[]);
    junk[14 + 13..14 + 18].copy_from_slice(b"\0junk");
    bytes.extend_from_slice(&junk);
    let out = exchange(r.port, &bytes, 1);
    assert!(error_of(&out[0]).contains("nodes of the set have no row"), "{}", error_of(&out[0]));

    // A body 6 bytes longer than its header says: its checksum fails (answered), the 6
    // bytes are no header (answered, the connection closed).
    let mut longer = text(1, "Gravity", "0,-1,0", &[]);
    let size = (longer.len() - 58 - 6) as u64;
    longer[42..50].copy_from_slice(&size.to_be_bytes());
    let mut s = TcpStream::connect(("127.0.0.1", r.port)).unwrap();
    std::io::Write::write_all(&mut s, &longer).unwrap();
    s.shutdown(std::net::Shutdown::Write).unwrap();
    let (h, body) = read_message(&mut s, u64::MAX, None).unwrap().unwrap();
    assert!(error_of(&Message::new(h, body).unwrap()).contains("CRC-64"));
    let (h, body) = read_message(&mut s, u64::MAX, None).unwrap().unwrap();
    let e = error_of(&Message::new(h, body).unwrap());
    assert!(e.contains("truncated") && e.contains("closing the connection"), "{e}");
    assert!(matches!(read_message(&mut s, u64::MAX, None), Ok(None) | Err(FrameError::Io(_))));

    // The server still answers.
    let out = exchange(r.port, &text(1, "Gravity", "0,0,0", &[]), 1);
    assert!(error_of(&out[0]).contains("not a direction"));
}
