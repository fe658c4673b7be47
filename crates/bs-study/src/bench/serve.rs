//! `cargo xtask bench serve`: the latency of `brainshift serve`, measured in this process:
//! the native server (bs-serve) on loopback, driven by a client of bs-igtl, both here.
//!
//! * fixtures/fit (the MNI152 regions brain, its craniotomy measured, the T1 template as the
//!   pre-operative image): the scan `scan.csv` sent as POINT `IntraopPoints`, three times
//!   (each fitted from the reference state: the same work). From the scan's last byte sent
//!   to the WarpedImage's last byte received, against the same update's solve + warp
//!   measured inside the server (its Report's `serve` seconds): the ratio (target ≤ 1.3×)
//!   and the rest, transport and framing of the 35 MB image (target ≤ 50 ms); where the
//!   time goes.
//! * The MNI152 demo: the craniotomy's nodes moved 1 … 8 mm as STRING `Displacements`, the
//!   sequence of `bench update`: the median latency (target ≤ 0.5 s).
//!
//! Every answer is checked: the report converged, the image on the template's grid.

use std::net::TcpStream;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use crate::util::root;
use bs_igtl::{Envelope, Image, Message, Point, Points, Text, pack_message, read_message};

use super::page::{Page, say};

/// A server running in this process.
struct Running {
    server: Arc<bs_serve::Server>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Running {
    fn start(scene: &Path, image: &Path) -> Result<Running, String> {
        let o = bs_serve::Options {
            scene: scene.to_path_buf(),
            image: image.to_path_buf(),
            host: "127.0.0.1".into(),
            port: 0,
            set: None,
            threads: None,
            no_field: false,
            no_surface: false,
            uncertainty: None,
            max_message_mb: 64.0,
            stall_seconds: 30.0,
            max_clients: 4,
            verbose: false,
        };
        let server =
            Arc::new(bs_serve::Server::bind(&o, bs_serve::Log::to(Box::new(std::io::sink())))?);
        let stop = Arc::new(AtomicBool::new(false));
        let (s, f) = (Arc::clone(&server), Arc::clone(&stop));
        let thread = Some(std::thread::spawn(move || s.serve(&f)));
        Ok(Running { server, stop, thread })
    }

    fn connect(&self) -> Result<TcpStream, String> {
        let port = self.server.address().map_err(|e| e.to_string())?.port();
        let s = TcpStream::connect(("127.0.0.1", port)).map_err(|e| e.to_string())?;
        s.set_nodelay(true).map_err(|e| e.to_string())?;
        Ok(s)
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// One answered update, seconds.
#[derive(Debug, Clone, Copy)]
struct Answer {
    /// Last byte sent → last byte of WarpedImage received.
    latency: f64,
    /// The server's solve (from the message read to the verified answer).
    solve: f64,
    /// The server's inverse map and warp.
    image: f64,
    /// The server's framing (CRC) and sending of the WarpedImage.
    send: f64,
    newton: u64,
    max_u: f64,
}

fn envelope(device: &str) -> Envelope<'_> {
    Envelope { version: 1, device, timestamp: bs_igtl::header::now(), message_id: 0, metadata: &[] }
}

/// Sends `bytes`, reads the replies up to the Report; checks them.
fn exchange(s: &mut TcpStream, bytes: &[u8], dims: [u16; 3]) -> Result<Answer, String> {
    std::io::Write::write_all(s, bytes).map_err(|e| e.to_string())?;
    let sent = Instant::now();
    let mut latency = None;
    loop {
        let (h, body) = read_message(s, u64::MAX, None)
            .map_err(|e| e.to_string())?
            .ok_or("the server closed")?;
        let m = Message::new(h, body).map_err(|e| e.to_string())?;
        match m.header.device.as_str() {
            "WarpedImage" => {
                latency = Some(sent.elapsed().as_secs_f64());
                let i: Image<'static> = m.read().map_err(|e| e.to_string())?;
                if i.size != dims {
                    return Err(format!(
                        "WarpedImage of {:?} voxels, the image has {dims:?}",
                        i.size
                    ));
                }
            }
            "Error" => return Err(m.read::<Text>().map_err(|e| e.to_string())?.text()),
            "Report" => {
                let r: serde_json::Value =
                    serde_json::from_str(&m.read::<Text>().map_err(|e| e.to_string())?.text())
                        .map_err(|e| e.to_string())?;
                if r["converged"] != serde_json::Value::Bool(true) {
                    return Err(format!("not converged: {r}"));
                }
                let f = |k: &str| r["serve"][k].as_f64().unwrap_or(f64::NAN);
                return Ok(Answer {
                    latency: latency.ok_or("a Report before the WarpedImage")?,
                    solve: f("solve_seconds"),
                    image: f("image_seconds"),
                    send: f("warped_image_send_seconds"),
                    newton: r["steps"].as_u64().unwrap_or(0),
                    max_u: r["max_displacement"].as_f64().unwrap_or(f64::NAN),
                });
            }
            _ => {}
        }
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() { f64::NAN } else { v[v.len() / 2] }
}

fn dims_of(image: &Path) -> Result<[u16; 3], String> {
    let (v, _) = bs_image::formats::read_image(image).map_err(|e| e.to_string())?;
    Ok(v.grid.dims().map(|n| n as u16))
}

/// The scan of fixtures/fit as POINT IntraopPoints (RAS mm: the scene is).
fn scan_message(root: &Path) -> Result<Vec<u8>, String> {
    let text =
        std::fs::read_to_string(root.join("fixtures/fit/scan.csv")).map_err(|e| e.to_string())?;
    let points = text
        .lines()
        .skip(1)
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f32> = l.split(',').filter_map(|x| x.trim().parse().ok()).collect();
            Point {
                name: String::new(),
                group: String::new(),
                rgba: [0; 4],
                position: [v[0], v[1], v[2]],
                radius: 0.0,
                owner: String::new(),
            }
        })
        .collect();
    let p = Points { points };
    Ok(pack_message(&p, &envelope("IntraopPoints")).map_err(|e| e.to_string())?.to_vec())
}

fn scans(page: &mut Page, root: &Path) -> Result<(), String> {
    let image = root.join("fixtures/mni152/t1.nii.gz");
    let dims = dims_of(&image)?;
    let started = Instant::now();
    let r = Running::start(&root.join("fixtures/fit/scene.toml"), &image)?;
    say!(
        page,
        "== fixtures/fit: POINT IntraopPoints (scan.csv, fitted), server prepared in {:.2} s",
        started.elapsed().as_secs_f64()
    );
    let bytes = scan_message(root)?;
    let mut s = r.connect()?;
    say!(page, " run  latency  solve s  image s  send s  rest s  ratio");
    let mut answers = Vec::new();
    for k in 1..=3 {
        let a = exchange(&mut s, &bytes, dims)?;
        let inside = a.solve + a.image;
        say!(
            page,
            "{k:>4} {:>8.3} {:>8.3} {:>8.3} {:>7.3} {:>7.3} {:>6.2}",
            a.latency,
            a.solve,
            a.image,
            a.send,
            a.latency - inside,
            a.latency / inside
        );
        answers.push(a);
    }
    let m = |f: fn(&Answer) -> f64| median(answers.iter().map(f).collect());
    let (lat, solve, image_s, send) =
        (m(|a| a.latency), m(|a| a.solve), m(|a| a.image), m(|a| a.send));
    let ratio = m(|a| a.latency / (a.solve + a.image));
    let rest = m(|a| a.latency - a.solve - a.image);
    say!(
        page,
        "scan's last byte -> WarpedImage's last byte: median {lat:.3} s = solve (fit, verification) {solve:.3} s + inverse map and warp {image_s:.3} s + the rest {rest:.3} s (framing and sending the {:.0} MB image: {send:.3} s in the server)",
        4.0 * dims.iter().map(|&d| d as f64).product::<f64>() / 1e6
    );
    say!(
        page,
        "latency / (solve + warp in the server): median {ratio:.2}x (target <= 1.3x: {}); transport and framing {:.0} ms (target <= 50 ms: {})",
        if ratio <= 1.3 { "met" } else { "missed" },
        1e3 * rest,
        if rest <= 0.05 { "met" } else { "missed" }
    );
    Ok(())
}

fn displacements(page: &mut Page, root: &Path) -> Result<(), String> {
    let scene = root.join("fixtures/mni152/scene.toml");
    let image = root.join("fixtures/mni152/t1.nii.gz");
    let dims = dims_of(&image)?;
    let p = bs_scene::Prepared::load(&scene).map_err(|e| e.to_string())?;
    let nodes = p.mesh.node_set("CRANIOTOMY").ok_or("no CRANIOTOMY")?.to_vec();
    let r = Running::start(&scene, &image)?;
    say!(page, "");
    say!(
        page,
        "== MNI152 demo: STRING Displacements (the craniotomy's {} nodes moved k mm along -z)",
        nodes.len()
    );
    say!(page, " mm  latency  solve s  image s  send s Newton  max u");
    let mut s = r.connect()?;
    let mut latencies = Vec::new();
    for k in 1..=8 {
        let mut csv = String::from("node_id,ux,uy,uz\n");
        for &n in &nodes {
            csv += &format!("{},0,0,{}\n", p.mesh.node_ids[n], -(k as f64));
        }
        let bytes = pack_message(&Text::new(&csv), &envelope("Displacements"))
            .map_err(|e| e.to_string())?
            .to_vec();
        let a = exchange(&mut s, &bytes, dims)?;
        say!(
            page,
            "{k:>3} {:>8.3} {:>8.3} {:>8.3} {:>7.3} {:>6} {:>6.2}",
            a.latency,
            a.solve,
            a.image,
            a.send,
            a.newton,
            a.max_u
        );
        latencies.push(a.latency);
    }
    let med = median(latencies.clone());
    say!(
        page,
        "last byte sent -> WarpedImage received: median {med:.3} s, max {:.3} s (target: median <= 0.5 s: {})",
        latencies.iter().cloned().fold(0.0, f64::max),
        if med <= 0.5 { "met" } else { "missed" }
    );
    Ok(())
}

/// Runs the benchmark and writes its block of `docs/benchmarks.md`.
pub fn run() -> Result<(), String> {
    let root = root();
    let mut page = Page::new("serve");
    say!(page, "threads: {} (the server's solver pool: all cores)", rayon::current_num_threads());
    scans(&mut page, &root)?;
    displacements(&mut page, &root)?;
    page.write("cargo xtask bench serve")
}
