//! bs-image's NRRD reader and writers against files written by pynrrd and SimpleITK, and a
//! segmentation written the way 3D Slicer writes `.seg.nrrd` (fixtures/images/nrrd, made by
//! fixtures/images/make_nrrd.py), and the files it must refuse.

use std::path::{Path, PathBuf};

use bs_image::formats::{read_image, read_labels, write_displacement, write_image, write_labels};
use bs_image::{Grid, ImageError, Volume};
use serde_json::Value;

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/images/nrrd")
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bs-nrrd-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Checks a volume against expected.json's shape, RAS world positions and values.
fn check<T: Copy + Into<f64>>(name: &str, v: &Volume<T>, e: &Value) {
    let shape: Vec<usize> =
        e["shape"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as usize).collect();
    assert_eq!(v.grid.dims().to_vec(), shape, "{name}");
    for (n, p) in e["voxels"].as_array().unwrap().iter().enumerate() {
        let ijk: Vec<usize> =
            p.as_array().unwrap().iter().map(|x| x.as_u64().unwrap() as usize).collect();
        let w = v.grid.world([ijk[0] as f64, ijk[1] as f64, ijk[2] as f64]);
        for a in 0..3 {
            // The headers hold the directions in decimal with ≥ 16 significant digits
            // (pynrrd, ITK): agreement to 1e-9 mm over ~50 mm.
            let d = (w[a] - e["world"][n][a].as_f64().unwrap()).abs();
            assert!(d < 1e-9, "{name} {ijk:?} axis {a}: {} vs {}", w[a], e["world"][n][a]);
        }
        let value: f64 = v.at(ijk[0], ijk[1], ijk[2]).into();
        assert_eq!(value, e["values"][n].as_f64().unwrap(), "{name} {ijk:?}");
    }
}

#[test]
fn images_written_by_pynrrd_and_simpleitk_read_with_their_frames() {
    let exp: Value =
        serde_json::from_str(&std::fs::read_to_string(dir().join("expected.json")).unwrap())
            .unwrap();
    for name in ["lps-gzip.nrrd", "ras-raw-big.nrrd", "detached.nhdr", "sitk.nrrd"] {
        let (v, header) = read_image(&dir().join(name)).unwrap();
        assert!(header.is_none(), "a NRRD file has no NIfTI header");
        check(name, &v, &exp[name]);
    }
    let name = "segmentation.seg.nrrd";
    let (labels, _) = read_labels(&dir().join(name)).unwrap();
    check(name, &labels, &exp[name]);
    let mut seen: Vec<u32> = labels.data.clone();
    seen.sort_unstable();
    seen.dedup();
    assert_eq!(seen, [0, 1, 2]);
}

#[test]
fn written_images_labels_and_fields_read_back_exactly() {
    let d = tmpdir("roundtrip");
    let rot = nalgebra::Rotation3::from_euler_angles(0.2, -0.3, 0.5);
    let mut m = nalgebra::Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(
        &(rot.matrix() * nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(0.9, 1.1, 1.7))),
    );
    m[(0, 3)] = -12.5;
    m[(1, 3)] = 33.0;
    m[(2, 3)] = 4.25;
    let grid = Grid::new([7, 5, 4], m).unwrap();
    let image =
        Volume { grid: grid.clone(), data: (0..140).map(|n| n as f32 * 0.37 - 9.0).collect() };
    write_image(&d.join("w.nrrd"), &image, None).unwrap();
    let (back, _) = read_image(&d.join("w.nrrd")).unwrap();
    assert_eq!(back.data, image.data);
    for c in 0..4 {
        for r in 0..3 {
            assert!((back.grid.voxel_to_world()[(r, c)] - m[(r, c)]).abs() < 1e-12);
        }
    }
    let labels = Volume { grid: grid.clone(), data: (0..140).map(|n| n % 5).collect() };
    write_labels(&d.join("l.nrrd"), &labels, None).unwrap();
    assert_eq!(read_labels(&d.join("l.nrrd")).unwrap().0.data, labels.data);
    // A field: 4-D vector NRRD in LPS, as Slicer and ITK write displacement fields.
    let vectors: Vec<[f32; 3]> = (0..140).map(|n| [n as f32, -(n as f32) * 0.5, 2.0]).collect();
    write_displacement(&d.join("f.nrrd"), &grid, &vectors, None).unwrap();
    let bytes = std::fs::read(d.join("f.nrrd")).unwrap();
    let start = bytes.windows(2).position(|w| w == b"\n\n").unwrap() + 2;
    let text = String::from_utf8_lossy(&bytes[..start]);
    for line in [
        "dimension: 4",
        "space: left-posterior-superior",
        "sizes: 3 7 5 4",
        "kinds: vector domain domain domain",
        "space directions: none (",
    ] {
        assert!(text.contains(line), "{line}: {text}");
    }
    // The vectors, decompressed, are LPS: (−x, −y, z) of the RAS ones.
    let mut raw = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&bytes[start..]), &mut raw)
        .unwrap();
    let f: Vec<f32> =
        raw.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    assert_eq!(f.len(), 3 * 140);
    assert_eq!(&f[3 * 9..3 * 10], &[-9.0, 4.5, 2.0]);
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn bad_files_name_the_file_and_the_field() {
    for (name, parts) in [
        ("bad-no-space.nrrd", &["bad-no-space.nrrd", "'space'", "left-posterior-superior"][..]),
        ("bad-space-dimension.nrrd", &["'space dimension: 2'", "contradicts"][..]),
        ("bad-directions-count.nrrd", &["'space directions' lists 2 axes", "'dimension' is 3"][..]),
        ("bad-bzip2.nrrd", &["'encoding: bzip2'", "raw and gzip"][..]),
        ("bad-truncated.nrrd", &["bad-truncated.nrrd", "truncated: 50 bytes", "96"][..]),
        ("bad-truncated-gzip.nrrd", &["bad-truncated-gzip.nrrd", "'encoding: gzip'"][..]),
        ("bad-multilayer.seg.nrrd", &["'sizes'", "2 values per voxel", "labelmap"][..]),
    ] {
        let e = read_image(&dir().join(name)).unwrap_err();
        assert!(matches!(e, ImageError::Invalid { .. }), "{name}: {e}");
        let msg = e.to_string();
        for p in parts {
            assert!(msg.contains(p), "{name}: '{p}' not in: {msg}");
        }
    }
    // An unknown extension and a missing detached data file.
    let e = read_image(Path::new("x.img")).unwrap_err().to_string();
    assert!(e.contains(".nrrd") && e.contains(".nii.gz"), "{e}");
    let d = tmpdir("detached");
    std::fs::copy(dir().join("detached.nhdr"), d.join("detached.nhdr")).unwrap();
    let e = read_image(&d.join("detached.nhdr")).unwrap_err().to_string();
    assert!(e.contains("detached.raw.gz") && e.contains("'data file'"), "{e}");
    let _ = std::fs::remove_dir_all(&d);
}
