//! `serve --uncertainty N`: a scan fitted in the session is answered with IMAGE
//! `Uncertainty` after the WarpedImage, the σ a session here samples for the same scan
//! (the run's sampling, bs-scene), on the image's grid; a scene that fits nothing is refused
//! at start.

use std::net::TcpStream;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use bs_igtl::{Envelope, Image, Message, PolyData, Text, pack_message, read_message};
use bs_image::{Grid, Volume};
use bs_mesh::Point3;
use bs_scene::{Prepared, Session, Update};
use bs_serve::{Log, Options, Server};

/// A 40 mm box (5³ nodes) held on its symmetry planes whose top (ZMAX) is fitted to a scan,
/// and a 2 mm image over it, in a fresh folder.
fn box_scene(name: &str, fitted: bool) -> (PathBuf, PathBuf) {
    let dir = std::env::temp_dir().join(format!("bs-serve-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut mesh = bs_mesh::structured::box_mesh(4, 40.0, true);
    for (set, axis, value) in
        [("XMIN", 0, 0.0), ("YMIN", 1, 0.0), ("ZMIN", 2, 0.0), ("ZMAX", 2, 40.0)]
    {
        let nodes = (0..mesh.nodes.len()).filter(|&n| mesh.nodes[n][axis] == value).collect();
        mesh.node_sets.insert(set.into(), nodes);
    }
    bs_mesh::io::write_mesh(&dir.join("box.inp"), &mesh, &Default::default()).unwrap();
    std::fs::write(dir.join("scan.csv"), plane_csv(&scan(36.0))).unwrap();
    let data = if fitted {
        "[[measurement]]\npoints = \"scan.csv\"\nnset = \"ZMAX\"\nsigma = 0.5\nsliding = \"free\"\n"
    } else {
        "[[boundary]]\nnset = \"ZMAX\"\ndisplacement = { z = -2.0 }\n"
    };
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        format!(
            "units = \"mm\"\n[mesh]\nfile = \"box.inp\"\nelement = \"t4\"\n[[region]]\nelset = \"*\"\n\
             material = {{ model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.3 }}\n\
             [[boundary]]\nnset = \"XMIN\"\nfix = [\"x\"]\n[[boundary]]\nnset = \"YMIN\"\nfix = [\"y\"]\n\
             [[boundary]]\nnset = \"ZMIN\"\nfix = [\"z\"]\n{data}"
        ),
    )
    .unwrap();
    let grid = Grid::axis_aligned([24, 24, 24], [2.0; 3], [-3.0, -3.0, -3.0]).unwrap();
    let values = (0..grid.len()).map(|n| (n % 97) as f32).collect();
    let image = dir.join("preop.nii.gz");
    bs_image::formats::write_image(&image, &Volume { grid, data: values }, None).unwrap();
    (scene, image)
}

/// A scan of the plane z = `z` over the box's top and around it (1 mm, deterministic
/// noise-free points: the σ comes from the measurement's own σ).
fn scan(z: f64) -> Vec<Point3<f64>> {
    let mut p = Vec::new();
    for j in 0..=48 {
        for i in 0..=48 {
            p.push(Point3::new(i as f64 - 4.0, j as f64 - 4.0, z));
        }
    }
    p
}

fn plane_csv(points: &[Point3<f64>]) -> String {
    let mut s = String::from("x,y,z\n");
    for q in points {
        s += &format!("{},{},{}\n", q.x, q.y, q.z);
    }
    s
}

fn options(scene: PathBuf, image: PathBuf, uncertainty: Option<usize>) -> Options {
    Options {
        scene,
        image,
        host: "127.0.0.1".into(),
        port: 0,
        set: None,
        threads: Some(1),
        no_field: true,
        no_surface: true,
        uncertainty,
        max_message_mb: 64.0,
        stall_seconds: 30.0,
        max_clients: 16,
        verbose: false,
    }
}

#[test]
fn a_fitted_scan_is_answered_with_its_uncertainty_after_the_warped_image() {
    let (scene, image) = box_scene("fitted", true);
    let o = options(scene.clone(), image.clone(), Some(8));
    let server = Arc::new(Server::bind(&o, Log::to(Box::new(std::io::sink()))).unwrap());
    let port = server.address().unwrap().port();
    let stop = Arc::new(AtomicBool::new(false));
    let (s, f) = (Arc::clone(&server), Arc::clone(&stop));
    let thread = std::thread::spawn(move || s.serve(&f));
    // A new scan: the top 3 mm lower.
    let points = scan(37.0);
    let body = PolyData {
        points: points.iter().map(|q| [q.x as f32, q.y as f32, q.z as f32]).collect(),
        ..Default::default()
    };
    let envelope = Envelope {
        version: 1,
        device: "IntraopPoints",
        timestamp: 0,
        message_id: 0,
        metadata: &[],
    };
    let mut c = TcpStream::connect(("127.0.0.1", port)).unwrap();
    std::io::Write::write_all(&mut c, &pack_message(&body, &envelope).unwrap().to_vec()).unwrap();
    let out: Vec<Message> = (0..3)
        .map(|_| {
            let (h, body) = read_message(&mut c, u64::MAX, None).unwrap().unwrap();
            Message::new(h, body).unwrap()
        })
        .collect();
    stop.store(true, Ordering::SeqCst);
    drop(c);
    thread.join().unwrap();
    server.stop();
    let devices: Vec<&str> = out.iter().map(|m| m.header.device.as_str()).collect();
    assert_eq!(devices, ["WarpedImage", "Uncertainty", "Report"]);
    let u: Image<'static> = out[1].read().unwrap();
    assert_eq!((u.size, u.components), ([24, 24, 24], 1));
    let got: Vec<f32> =
        u.data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    // The same scan in a session here, σ sampled as run --uncertainty samples it.
    let mut session = Session::new(Prepared::load(&scene).unwrap()).unwrap();
    let update = Update::Scan { set: "ZMAX".into(), points };
    let solved = session.apply(&[update], &mut |_| {}).unwrap();
    let params = bs_scene::uncertainty::UncertaintyParams { samples: 8, ..Default::default() };
    let sigma = session.uncertainty(&solved, &params).unwrap();
    let totals: Vec<f64> = (0..sigma.sigma.len()).map(|a| sigma.total(a)).collect();
    let p = &session.run().prepared;
    let result = bs_register::registration::RunResult::new(
        &p.path,
        p.mesh.clone(),
        solved.solution.displacements.clone(),
        p.scene.space,
        p.scene.units,
    )
    .unwrap();
    let (grid, _) = bs_image::formats::read_image(&image).unwrap();
    let map = bs_register::registration::InverseMap::new(&result, &grid.grid, &image).unwrap();
    let expected = map.nodal(&totals);
    let top = expected.iter().copied().fold(0.0f32, f32::max);
    assert!(top > 0.0, "σ is positive under the scan");
    for (n, (g, e)) in got.iter().zip(&expected).enumerate() {
        assert!((g - e).abs() <= 1e-5 * top, "voxel {n}: {g} sent, {e} here");
    }
    // Outside the box (the first voxel's centre is at −3 mm): zero.
    assert_eq!(got[0], 0.0);
    let report: serde_json::Value =
        serde_json::from_str(&out[2].read::<Text>().unwrap().text()).unwrap();
    assert_eq!(report["uncertainty"]["samples"], 8, "{report}");
    let max = report["uncertainty"]["max_sigma"].as_f64().unwrap();
    assert!((max - totals.iter().copied().fold(0.0, f64::max)).abs() < 1e-9, "{max}");
}

#[test]
fn a_scene_that_fits_nothing_is_refused_at_start_and_so_is_one_sample() {
    let (scene, image) = box_scene("imposed", false);
    let refused = |o: Options| match Server::bind(&o, Log::to(Box::new(std::io::sink()))) {
        Ok(_) => panic!("{}: served", o.scene.display()),
        Err(e) => e,
    };
    let e = refused(options(scene, image, Some(8)));
    assert!(e.to_string().contains("fits nothing"), "{e}");
    let (scene, image) = box_scene("one", true);
    let e = refused(options(scene, image, Some(1)));
    assert!(e.to_string().contains("give at least 2 samples"), "{e}");
}
