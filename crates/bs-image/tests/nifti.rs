//! bs-image's NIfTI reader and writers against files written by nibabel (fixtures/images,
//! made by fixtures/images/make.py): an independent implementation of the format.

use std::path::{Path, PathBuf};

use bs_image::nifti::{self, INTENT_DISPVECT};
use bs_image::sample::{nearest, trilinear};
use bs_image::{Grid, ImageError, Volume, write_displacement_mha};
use nalgebra::{Matrix4, Point3};
use serde_json::Value;

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/images")
}

fn expected() -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir().join("expected.json")).unwrap()).unwrap()
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bs-image-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// World positions agree with nibabel's affine to 1e-4 mm: the sform is stored in float32
/// (relative 6e-8 of coordinates below 100 mm) and the qform as a float32 quaternion
/// (rotation error ~1e-7 rad over ~30 mm): both far below 1e-4.
#[test]
fn world_positions_and_values_match_nibabel() {
    let exp = expected();
    for name in ["oblique-sform.nii.gz", "flipped-qform.nii"] {
        let e = &exp[name];
        let img = nifti::read_image(&dir().join(name)).unwrap();
        let shape: Vec<usize> =
            e["shape"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as usize).collect();
        assert_eq!(img.volume.grid.dims().to_vec(), shape, "{name}");
        for (n, v) in e["voxels"].as_array().unwrap().iter().enumerate() {
            let ijk: Vec<usize> =
                v.as_array().unwrap().iter().map(|x| x.as_u64().unwrap() as usize).collect();
            let w = img.volume.grid.world([ijk[0] as f64, ijk[1] as f64, ijk[2] as f64]);
            let ew = &e["world"][n];
            for a in 0..3 {
                let d = (w[a] - ew[a].as_f64().unwrap()).abs();
                assert!(d < 1e-4, "{name} voxel {ijk:?} axis {a}: {} vs {}", w[a], ew[a]);
            }
            // values: slope 0.5 and intercept 3 applied (exact in float32)
            let value = img.volume.at(ijk[0], ijk[1], ijk[2]);
            assert_eq!(value as f64, e["values"][n].as_f64().unwrap(), "{name} {ijk:?}");
            // and the inverse map
            let back = img.volume.grid.voxel(&w);
            for a in 0..3 {
                assert!((back[a] - ijk[a] as f64).abs() < 1e-9);
            }
        }
    }
}

#[test]
fn integer_and_float_labelmaps_read_the_same() {
    let exp = expected();
    let u8 = nifti::read_labels(&dir().join("labels-u8.nii.gz")).unwrap();
    let f32 = nifti::read_labels(&dir().join("labels-f32.nii.gz")).unwrap();
    assert_eq!(u8, f32);
    for (label, count) in exp["labels-u8.nii.gz"]["counts"].as_object().unwrap() {
        let l: u32 = label.parse().unwrap();
        let n = u8.data.iter().filter(|&&v| v == l).count();
        assert_eq!(n as u64, count.as_u64().unwrap(), "label {l}");
    }
    assert!((u8.grid.voxel_volume() - 8.0).abs() < 1e-12);
}

#[test]
fn bad_images_are_refused_with_the_file_and_the_fix() {
    let exp = expected();
    for (name, words) in exp["bad"].as_object().unwrap() {
        let path = dir().join(name);
        let err = nifti::read_labels(&path).expect_err(name);
        let msg = err.to_string();
        assert!(msg.contains(name), "{name}: message does not name the file: {msg}");
        assert!(msg.contains(words.as_str().unwrap()), "{name}: {msg}");
        assert!(matches!(err, ImageError::Invalid { .. }), "{name}: {err:?}");
    }
    let missing = nifti::read_image(&dir().join("no-such.nii.gz")).unwrap_err();
    assert!(missing.to_string().contains("no such file"), "{missing}");
}

#[test]
fn images_and_labels_round_trip_with_their_header() {
    let d = tmpdir("roundtrip");
    let img = nifti::read_image(&dir().join("oblique-sform.nii.gz")).unwrap();
    let out = d.join("copy.nii.gz");
    nifti::write_image(&out, &img.volume, Some(&img.header)).unwrap();
    let back = nifti::read_image(&out).unwrap();
    assert_eq!(back.volume.data, img.volume.data);
    assert!((back.volume.grid.voxel_to_world() - img.volume.grid.voxel_to_world()).norm() < 1e-5);

    // qform-only input: the written file keeps a frame (the sform is written)
    let img = nifti::read_image(&dir().join("flipped-qform.nii")).unwrap();
    let out = d.join("flipped.nii");
    nifti::write_image(&out, &img.volume, Some(&img.header)).unwrap();
    let back = nifti::read_image(&out).unwrap();
    assert!((back.volume.grid.voxel_to_world() - img.volume.grid.voxel_to_world()).norm() < 1e-4);

    let labels = nifti::read_labels(&dir().join("labels-u8.nii.gz")).unwrap();
    let out = d.join("labels.nii.gz");
    nifti::write_labels(&out, &labels, None).unwrap();
    assert_eq!(nifti::read_labels(&out).unwrap(), labels);
    // no temporary files left behind
    let left: Vec<_> = std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left.len(), 3, "{left:?}");
    std::fs::remove_dir_all(&d).unwrap();
}

fn oblique_grid() -> Grid {
    let mut m = Matrix4::identity();
    let lin = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.5).matrix()
        * nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(1.5, 2.0, 1.0));
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&lin);
    m[(0, 3)] = 10.0;
    m[(1, 3)] = -4.0;
    m[(2, 3)] = 2.5;
    Grid::new([5, 4, 3], m).unwrap()
}

/// The displacement field's layout read back through the `nifti` crate's own reader:
/// 5-D (nx, ny, nz, 1, 3), DISPVECT, component c of voxel (i, j, k) at [i, j, k, 0, c].
#[test]
fn displacement_field_is_5d_dispvect() {
    use ::nifti::{IntoNdArray as _, NiftiObject as _};
    let d = tmpdir("field");
    let grid = oblique_grid();
    let vectors: Vec<[f32; 3]> =
        (0..grid.len()).map(|n| [n as f32, -(n as f32) * 0.5, 1000.0 + n as f32]).collect();
    let out = d.join("field.nii.gz");
    nifti::write_displacement(&out, &grid, &vectors, None).unwrap();
    let obj = ::nifti::ReaderOptions::new().read_file(&out).unwrap();
    let h = obj.header().clone();
    assert_eq!(h.dim[..6], [5, 5, 4, 3, 1, 3]);
    assert_eq!(h.intent_code, INTENT_DISPVECT);
    assert_eq!(h.datatype, 16);
    let a = obj.into_volume().into_ndarray::<f32>().unwrap();
    for k in 0..3 {
        for j in 0..4 {
            for i in 0..5 {
                let n = grid.index(i, j, k);
                for c in 0..3 {
                    assert_eq!(a[[i, j, k, 0, c].as_slice()], vectors[n][c]);
                }
            }
        }
    }
    // its grid reads back as the one written (the reader takes the first three dims)
    let back = ::nifti::NiftiHeader::from_file(&out).unwrap();
    assert_eq!(back.sform_code, 1);
    std::fs::remove_dir_all(&d).unwrap();
}

/// MetaImage: origin and direction in LPS, vectors negated in x and y.
#[test]
fn mha_field_is_in_lps() {
    use std::io::Read as _;
    let d = tmpdir("mha");
    let grid = oblique_grid();
    let vectors: Vec<[f32; 3]> = (0..grid.len()).map(|n| [1.0, 2.0, n as f32]).collect();
    let out = d.join("field.mha");
    write_displacement_mha(&out, &grid, &vectors).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    let needle = b"ElementDataFile = LOCAL";
    let split = bytes.windows(needle.len()).position(|w| w == needle).unwrap();
    let header_end = bytes[split..].iter().position(|&b| b == b'\n').unwrap() + split + 1;
    let header = std::str::from_utf8(&bytes[..header_end]).unwrap();
    let key = |k: &str| -> Vec<f64> {
        let line = header.lines().find(|l| l.starts_with(k)).unwrap();
        line.split('=').nth(1).unwrap().split_whitespace().map(|x| x.parse().unwrap()).collect()
    };
    let m = grid.voxel_to_world();
    assert_eq!(key("Offset"), vec![-m[(0, 3)], -m[(1, 3)], m[(2, 3)]]);
    let dir = key("TransformMatrix");
    let sp = grid.spacing();
    // direction of the j axis (second triple), LPS
    for r in 0..3 {
        let ras = m[(r, 1)] / sp[1];
        let lps = if r < 2 { -ras } else { ras };
        assert!((dir[3 + r] - lps).abs() < 1e-12);
    }
    let mut raw = Vec::new();
    flate2_decode(&bytes[header_end..], &mut raw);
    assert_eq!(raw.len(), 12 * grid.len());
    let f = |o: usize| f32::from_le_bytes(raw[o..o + 4].try_into().unwrap());
    let n = 17;
    assert_eq!([f(12 * n), f(12 * n + 4), f(12 * n + 8)], [-1.0, -2.0, 17.0]);
    std::fs::remove_dir_all(&d).unwrap();

    fn flate2_decode(data: &[u8], out: &mut Vec<u8>) {
        let mut z = flate2::read::ZlibDecoder::new(data);
        z.read_to_end(out).unwrap();
    }
}

/// Trilinear interpolation reproduces a linear function of world position exactly (up to
/// rounding) on an oblique grid; nearest picks the closest voxel centre.
#[test]
fn sampling_is_exact_on_linear_fields() {
    let grid = oblique_grid();
    let f = |p: &Point3<f64>| 3.0 * p.x - 2.0 * p.y + 0.5 * p.z + 7.0;
    let mut vol = Volume::filled(grid.clone(), 0f32);
    for k in 0..3 {
        for j in 0..4 {
            for i in 0..5 {
                let p = grid.world([i as f64, j as f64, k as f64]);
                vol.data[grid.index(i, j, k)] = f(&p) as f32;
            }
        }
    }
    for ijk in [[0.3, 0.7, 1.2], [3.99, 2.5, 0.01], [4.0, 3.0, 2.0], [0.0, 0.0, 0.0]] {
        let p = grid.world(ijk);
        let v = trilinear(&vol, &p).unwrap();
        // float32 storage: values below ~60 carry 4e-6 of rounding
        assert!((v as f64 - f(&p)).abs() < 1e-4, "{ijk:?}: {v} vs {}", f(&p));
    }
    assert!(trilinear(&vol, &grid.world([-0.1, 1.0, 1.0])).is_none());
    assert!(trilinear(&vol, &grid.world([4.2, 1.0, 1.0])).is_none());
    let p = grid.world([2.4, 1.6, 0.51]);
    assert_eq!(nearest(&vol, &p), Some(vol.at(2, 2, 1)));
}

/// The real labelmap (fixtures/mni152/make_labels.py): the voxel counts and affine nilearn
/// and nibabel give (PROVENANCE-labels.txt).
#[test]
fn mni152_labelmaps_read_as_nibabel_reads_them() {
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/mni152");
    let mask = nifti::read_labels(&base.join("mask.nii.gz")).unwrap();
    assert_eq!(mask.grid.dims(), [197, 233, 189]);
    assert_eq!(mask.data.iter().filter(|&&v| v == 1).count(), 1_882_989);
    assert_eq!(mask.grid.world([0.0, 0.0, 0.0]), Point3::new(-98.0, -134.0, -72.0));
    let labels = nifti::read_labels(&base.join("labels.nii.gz")).unwrap();
    assert_eq!(labels.data.iter().filter(|&&v| v == 4).count(), 7_332);
    assert_eq!(labels.data.iter().filter(|&&v| v != 0).count(), 1_882_989);
}
