//! Registration outputs (`bs_register::registration`): the warp and the displacement field
//! checked against closed forms (translations and affine maps, for which the
//! piecewise-linear FE map is exact), against the node positions (d(X + u) = −u), and
//! against SimpleITK applying a field brainshift exported (fixtures/registration).

use std::path::{Path, PathBuf};

use bs_image::{Grid, Space, Volume};
use bs_mesh::io::{Field, Fields};
use bs_mesh::{Mesh, Point3, Vector3};
use bs_register::registration::{GAP_SEARCH_VOXELS, InverseMap, RunResult, field_file, warp_file};
use bs_scene::SceneError;
use bs_scene::scene::Units;
use nalgebra::{Matrix3, Matrix4};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bs-registration-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A 4×4×4 Kuhn box of side 40 mm at `origin` (384 tets).
fn box_at(origin: [f64; 3], tets: bool) -> Mesh {
    let mut m = bs_mesh::structured::box_mesh(4, 40.0, tets);
    for p in &mut m.nodes {
        *p += Vector3::from(origin);
    }
    m
}

/// The 1 mm grid 64³ with origin (−2.3, −1.6, −2.9): no voxel centre on a mesh face.
fn grid() -> Grid {
    Grid::axis_aligned([64, 64, 64], [1.0, 1.0, 1.0], [-2.3, -1.6, -2.9]).unwrap()
}

/// A linear intensity: trilinear interpolation reproduces it exactly (up to f32 rounding).
fn linear(p: &Point3<f64>) -> f64 {
    100.0 + 2.0 * p.x - 1.5 * p.y + 0.75 * p.z
}

fn image_of(grid: &Grid, f: impl Fn(&Point3<f64>) -> f64) -> Volume<f32> {
    let [nx, ny, nz] = grid.dims();
    let mut data = Vec::with_capacity(grid.len());
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                data.push(f(&grid.world([i as f64, j as f64, k as f64])) as f32);
            }
        }
    }
    Volume { grid: grid.clone(), data }
}

/// x = A X + b applied to every node of `mesh`.
fn affine_result(mesh: &Mesh, a: &Matrix3<f64>, b: Vector3<f64>) -> RunResult {
    let u = mesh.nodes.iter().map(|p| a * p.coords + b - p.coords).collect();
    RunResult::new(Path::new("(test)"), mesh.clone(), u, Space::Ras, Units::Mm).unwrap()
}

fn voxel_world(grid: &Grid, n: usize) -> Point3<f64> {
    let [nx, ny, _] = grid.dims();
    grid.world([(n % nx) as f64, ((n / nx) % ny) as f64, (n / (nx * ny)) as f64])
}

/// The face neighbours of voxel `n` on `grid`.
fn neighbours(grid: &Grid, n: usize) -> impl Iterator<Item = usize> {
    let [nx, ny, nz] = grid.dims();
    let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
    let (sj, sk) = (nx, nx * ny);
    [
        (i > 0).then(|| n - 1),
        (i + 1 < nx).then(|| n + 1),
        (j > 0).then(|| n - sj),
        (j + 1 < ny).then(|| n + sj),
        (k > 0).then(|| n - sk),
        (k + 1 < nz).then(|| n + sk),
    ]
    .into_iter()
    .flatten()
}

/// Checks warp and field of x = A X + b on the box at (10, 12, 9) against the closed form.
fn check_affine(a: Matrix3<f64>, b: Vector3<f64>, tets: bool) {
    let mesh = box_at([10.0, 12.0, 9.0], tets);
    let result = affine_result(&mesh, &a, b);
    let g = grid();
    let map = InverseMap::new(&result, &g, Path::new("(image)")).unwrap();
    let image = image_of(&g, linear);
    let warped = map.warp(&image, &image.data);
    let field = map.field();
    let a_inv = a.try_inverse().unwrap();
    // The pre-operative gap in closed form: outside the reference box, and no face
    // neighbour inside it.
    let in_reference = |m: usize| {
        let y = voxel_world(&g, m);
        (0..3).all(|c| {
            let lo = [10.0, 12.0, 9.0][c];
            y[c] > lo && y[c] < lo + 40.0
        })
    };
    let old_gap: Vec<bool> =
        (0..g.len()).map(|m| !in_reference(m) && !neighbours(&g, m).any(in_reference)).collect();
    let mut inside = 0;
    for n in 0..g.len() {
        let y = voxel_world(&g, n);
        let x_ref = Point3::from(a_inv * (y.coords - b));
        // Inside the deformed box ⇔ the closed-form preimage lies in the reference box;
        // within 1e-6 mm of a face either answer is right (rounding decides).
        let in_box = |margin: f64| {
            (0..3).all(|c| {
                let lo = [10.0, 12.0, 9.0][c];
                x_ref[c] > lo + margin && x_ref[c] < lo + 40.0 - margin
            })
        };
        match map.reference_point(n) {
            Some(x) => {
                assert!(
                    in_box(-1e-6),
                    "voxel {n} at {y} mapped but its preimage {x_ref} is outside"
                );
                inside += 1;
                // Exact for affine maps: rounding of a 3×3 solve on ~50 mm coordinates.
                assert!((x - x_ref).norm() < 1e-9, "voxel {n}: {x} vs {x_ref}");
                // The field is stored in f32: |d| ≤ ~20 mm, f32 relative precision 6e-8, so
                // 1e-5 mm is generous.
                let d = Vector3::new(field[n][0] as f64, field[n][1] as f64, field[n][2] as f64);
                assert!((d - (x_ref - y)).norm() < 1e-5, "voxel {n}: d {d} vs {}", x_ref - y);
                // Trilinear interpolation of a linear intensity is exact; f32 values of
                // magnitude ≤ ~300 round at ~3e-5, the interpolation sums 8 of them.
                let expect = linear(&x_ref);
                assert!((warped[n] as f64 - expect).abs() < 1e-3, "voxel {n}");
            }
            None => {
                assert!(!in_box(1e-6), "voxel {n} at {y} (preimage {x_ref}) not mapped");
                match map.mapped_point(n) {
                    // In the band around the box (no skull here): y + d(y), d extended.
                    Some(x) => {
                        // The skin (a face neighbour inside the deformed box) samples at
                        // y + d(y); beyond it, where the trilinear cell of y + d(y) holds a
                        // voxel outside the old gap (the voxels that neither lie in the
                        // reference box nor touch it across a face), the nearest old-gap
                        // voxel's centre. The field is that point minus y, and the warp the
                        // plain sample there: what ITK resampling through the field gives.
                        let skin = neighbours(&g, n).any(|m| map.reference_point(m).is_some());
                        let x = if skin {
                            x
                        } else {
                            bs_image::sample::settle_within(&g, &x, &old_gap, GAP_SEARCH_VOXELS)
                        };
                        let d = x - y;
                        let f = Vector3::new(
                            field[n][0] as f64,
                            field[n][1] as f64,
                            field[n][2] as f64,
                        );
                        assert!((f - d).norm() < 1e-5, "voxel {n}");
                        let expect = bs_image::sample::trilinear(&image, &x);
                        let expect = expect.unwrap_or(image.data[n]);
                        assert!((warped[n] - expect).abs() < 1e-3, "voxel {n}");
                    }
                    None => {
                        assert_eq!(field[n], [0.0; 3]);
                        assert_eq!(warped[n], image.data[n], "an unmapped voxel keeps its value");
                    }
                }
            }
        }
    }
    assert!(!map.gap_voxels().is_empty());
    assert_eq!(inside, map.inside_count());
    assert!(inside > 20_000, "{inside}");
}

#[test]
fn the_pre_operative_gap_starts_half_a_voxel_and_half_a_millimetre_from_the_brain() {
    // The box at (10, 12, 9), undeformed, on grids of 1, 1.5 and 4 mm (origins off every
    // face and every shifted face). Closed form: a voxel is in the old gap when its centre
    // y and the six points y ± m e_a lie outside the box, m = min(h/2 + 0.5 mm, h): on the
    // 1 mm grid the face neighbours, on the 4 mm grid 2.5 mm (a 4 mm voxel whose centre is
    // 2.5 mm out holds no brain; a whole voxel of margin dropped most of a thin gap).
    let mesh = box_at([10.0, 12.0, 9.0], true);
    let result = affine_result(&mesh, &Matrix3::identity(), Vector3::new(0.0, 0.0, 0.1));
    let in_box = |p: &Point3<f64>| {
        (0..3).all(|c| {
            let lo = [10.0, 12.0, 9.0][c];
            p[c] > lo && p[c] < lo + 40.0
        })
    };
    for (h, n) in [(1.0, 64usize), (1.5, 44), (4.0, 16)] {
        let g = Grid::axis_aligned([n; 3], [h; 3], [-2.13, -1.61, -2.87]).unwrap();
        let map = InverseMap::new(&result, &g, Path::new("(image)")).unwrap();
        let gap = map.preop_gap(&g).unwrap();
        let m: f64 = (0.5 * h + 0.5f64).min(h);
        let (mut kept, mut wrong) = (0usize, 0usize);
        for (v, &got) in gap.iter().enumerate() {
            let y = voxel_world(&g, v);
            let near = in_box(&y)
                || (0..3).any(|a| {
                    [-1.0, 1.0].iter().any(|s| {
                        let mut q = y;
                        q[a] += s * m;
                        in_box(&q)
                    })
                });
            kept += usize::from(got);
            wrong += usize::from(got == near);
        }
        assert_eq!(wrong, 0, "{h} mm grid: {wrong} voxels misclassified");
        assert!(kept > 0 && kept < g.len(), "{h} mm grid: {kept}");
    }
}

#[test]
fn a_uniform_translation_gives_the_translated_image() {
    check_affine(Matrix3::identity(), Vector3::new(3.3, -2.1, 4.7), true);
}

#[test]
fn an_affine_map_is_inverted_exactly() {
    // Stretch, shear and a small rotation (det > 0), as a deformation of the box.
    let a = Matrix3::new(1.08, 0.05, -0.03, -0.04, 0.93, 0.06, 0.02, -0.05, 1.11);
    check_affine(a, Vector3::new(-1.7, 2.2, 0.9), true);
}

#[test]
fn hexahedral_results_are_split_into_tetrahedra_and_stay_exact_for_affine_maps() {
    let a = Matrix3::new(1.05, 0.02, 0.0, 0.0, 0.97, 0.03, -0.02, 0.0, 1.04);
    check_affine(a, Vector3::new(0.6, -0.4, 1.3), false);
}

#[test]
fn the_field_at_a_deformed_node_is_minus_its_displacement() {
    // A non-linear displacement: not reproduced by the FE map between nodes, but at a node
    // the inverse map is exact: d(X + u) = X − (X + u) = −u.
    let mut mesh = bs_mesh::structured::jittered_box_mesh(5, 40.0, true, 0.15, 3);
    for p in &mut mesh.nodes {
        *p += Vector3::new(10.0, 10.0, 10.0);
    }
    let u: Vec<Vector3<f64>> = mesh
        .nodes
        .iter()
        .map(|p| {
            let s = ((p.x - 10.0) / 40.0, (p.y - 10.0) / 40.0, (p.z - 10.0) / 40.0);
            Vector3::new(2.0 * s.1 * s.2, -1.5 * s.0 * s.0, 3.0 * (s.0 * 3.0).sin() * s.2)
        })
        .collect();
    // An interior node (not on the box's faces).
    let node = (0..mesh.nodes.len())
        .find(|&n| mesh.nodes[n].iter().all(|&c| c > 18.0 && c < 42.0))
        .unwrap();
    let x = mesh.nodes[node] + u[node];
    // A 0.8 mm grid with a voxel centre exactly at x (voxel (30, 31, 32)).
    let origin = [x.x - 30.0 * 0.8, x.y - 31.0 * 0.8, x.z - 32.0 * 0.8];
    let g = Grid::axis_aligned([80, 80, 80], [0.8, 0.8, 0.8], origin).unwrap();
    let result =
        RunResult::new(Path::new("(test)"), mesh.clone(), u.clone(), Space::Ras, Units::Mm)
            .unwrap();
    let map = InverseMap::new(&result, &g, Path::new("(image)")).unwrap();
    let field = map.field();
    let n = g.index(30, 31, 32);
    let d = Vector3::new(field[n][0] as f64, field[n][1] as f64, field[n][2] as f64);
    // The voxel centre equals x up to rounding of the grid origin (~1e-14 mm); the field is
    // f32 (|u| ≤ 3 mm → ~2e-7 mm).
    assert!((d + u[node]).norm() < 1e-5, "d {d} vs u {}", u[node]);
}

/// Writes a result directory as `brainshift run` does (result.vtu, report.json).
fn write_rundir(dir: &Path, mesh: &Mesh, u: &[Vector3<f64>], space: &str, units: &str) {
    std::fs::create_dir_all(dir).unwrap();
    let fields = Fields {
        point: vec![Field::new(
            "displacement",
            3,
            u.iter().flat_map(|d| [d.x, d.y, d.z]).collect(),
        )],
        ..Default::default()
    };
    bs_mesh::io::write_mesh(&dir.join("result.vtu"), mesh, &fields).unwrap();
    std::fs::write(
        dir.join("report.json"),
        format!("{{\"converged\": true, \"units\": \"{units}\", \"space\": \"{space}\"}}"),
    )
    .unwrap();
}

fn write_image(path: &Path, v: &Volume<f32>) {
    bs_image::nifti::write_image(path, v, None).unwrap();
}

#[test]
fn a_result_in_lps_or_metres_is_converted_to_the_image_frame() {
    // The same translation given in RAS mm, in LPS mm and in RAS metres: the same warp.
    let d = tmp("frames");
    let g = grid();
    let image = image_of(&g, linear);
    let preop = d.join("preop.nii.gz");
    write_image(&preop, &image);
    let b = Vector3::new(3.3, -2.1, 4.7);
    let ras = box_at([10.0, 12.0, 9.0], true);
    let mut lps = ras.clone();
    for p in &mut lps.nodes {
        *p = Point3::new(-p.x, -p.y, p.z);
    }
    let mut metres = ras.clone();
    for p in &mut metres.nodes {
        *p = Point3::from(p.coords * 1e-3);
    }
    let n = ras.nodes.len();
    write_rundir(&d.join("ras"), &ras, &vec![b; n], "RAS", "mm");
    write_rundir(&d.join("lps"), &lps, &vec![Vector3::new(-b.x, -b.y, b.z); n], "LPS", "mm");
    write_rundir(&d.join("m"), &metres, &vec![b * 1e-3; n], "RAS", "m");
    let mut outs = Vec::new();
    for case in ["ras", "lps", "m"] {
        let out = d.join(format!("warped-{case}.nii.gz"));
        let s = warp_file(&d.join(case), &preop, &out, None, None).unwrap();
        assert!(s.inside > 20_000);
        outs.push(bs_image::nifti::read_image(&out).unwrap().volume.data);
    }
    for n in 0..g.len() {
        let y = voxel_world(&g, n);
        // Voxels more than 1e-6 mm inside the translated box: f(y − b) exactly (f32).
        let x = y - b;
        let inside = (0..3).all(|c| {
            let lo = [10.0, 12.0, 9.0][c];
            x[c] > lo + 1e-6 && x[c] < lo + 40.0 - 1e-6
        });
        // Outside the box the three give the same extension (compared with the first).
        let expect = if inside { linear(&x) } else { outs[0][n] as f64 };
        for o in &outs {
            assert!((o[n] as f64 - expect).abs() < 1e-3, "voxel {n}: {} vs {expect}", o[n]);
        }
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn labels_are_warped_by_nearest_voxel() {
    let d = tmp("labels");
    let g = grid();
    // Labels: 1 + (the 8 mm cube index along x), so a translation by whole voxels moves
    // them exactly.
    let labels = Volume {
        grid: g.clone(),
        data: (0..g.len())
            .map(|n| 1 + (voxel_world(&g, n).x / 8.0).floor().max(0.0) as u32)
            .collect(),
    };
    let path = d.join("labels.nii.gz");
    bs_image::nifti::write_labels(&path, &labels, None).unwrap();
    let mesh = box_at([10.0, 12.0, 9.0], true);
    let b = Vector3::new(3.0, 0.0, 0.0);
    write_rundir(&d.join("run"), &mesh, &vec![b; mesh.nodes.len()], "RAS", "mm");
    let out = d.join("warped-labels.nii.gz");
    warp_file(&d.join("run"), &path, &out, Some(0), None).unwrap();
    let warped = bs_image::nifti::read_labels(&out).unwrap();
    let map = InverseMap::new(&RunResult::load(&d.join("run")).unwrap(), &g, Path::new("(image)"))
        .unwrap();
    for n in 0..g.len() {
        let expect = match (map.reference_point(n), map.mapped_point(n)) {
            // X = y − (3, 0, 0): the voxel three to the left, an exact voxel centre.
            (Some(_), _) => labels.data[n - 3],
            // In the band around the box: the nearest label at y + d(y) (no label here is
            // mostly inside the box, so none is excluded).
            (None, Some(x)) => bs_image::sample::nearest(&labels, &x).unwrap(),
            (None, None) => labels.data[n],
        };
        assert_eq!(warped.data[n], expect, "voxel {n}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn bad_inputs_are_clear_errors_and_write_nothing() {
    let d = tmp("bad");
    let g = grid();
    let preop = d.join("preop.nii.gz");
    write_image(&preop, &image_of(&g, linear));
    let mesh = box_at([10.0, 12.0, 9.0], true);
    let u = vec![Vector3::new(1.0, 0.0, 0.0); mesh.nodes.len()];
    write_rundir(&d.join("run"), &mesh, &u, "RAS", "mm");
    let out = d.join("out.nii.gz");

    // A mesh far outside the image (e.g. the wrong frame): both frames and extents named.
    let mut far = mesh.clone();
    for p in &mut far.nodes {
        *p += Vector3::new(200.0, 0.0, 0.0);
    }
    write_rundir(&d.join("far"), &far, &u, "LPS", "mm");
    let e = warp_file(&d.join("far"), &preop, &out, None, None).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, SceneError::Image { .. }), "{msg}");
    for part in ["LPS", "RAS", "0 of 125 nodes", "image (RAS world frame)", "space ="] {
        assert!(msg.contains(part), "{part}: {msg}");
    }

    // A 4-D image: bs-image refuses it and names the file.
    let four_d = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/images/bad-4d.nii.gz");
    let e = warp_file(&d.join("run"), &four_d, &out, None, None).unwrap_err();
    assert!(e.to_string().contains("bad-4d.nii.gz"), "{e}");

    // Not a result directory.
    let e = warp_file(&d, &preop, &out, None, None).unwrap_err();
    assert!(matches!(e, SceneError::Result { .. }) && e.to_string().contains("result.vtu"), "{e}");

    // A report with an unknown frame.
    write_rundir(&d.join("frame"), &mesh, &u, "RAI", "mm");
    let e = warp_file(&d.join("frame"), &preop, &out, None, None).unwrap_err();
    assert!(e.to_string().contains("\"RAI\""), "{e}");

    // Output names the formats cannot hold.
    let e = warp_file(&d.join("run"), &preop, &d.join("out.mha"), None, None).unwrap_err();
    assert!(e.to_string().contains(".nii"), "{e}");
    let e = field_file(&d.join("run"), &preop, &d.join("field.vtk")).unwrap_err();
    assert!(e.to_string().contains(".mha"), "{e}");

    // Nothing was written by any of them (no output, no temporary file).
    let mut left: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["far", "frame", "preop.nii.gz", "run"]);
    let _ = std::fs::remove_dir_all(&d);
}

/// Mean absolute difference inside the deformed brain, and the preop intensity range.
fn compare(ours: &[f32], theirs: &[f32], mask: &[bool]) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for ((a, b), &m) in ours.iter().zip(theirs).zip(mask) {
        if m {
            sum += (*a as f64 - *b as f64).abs();
            n += 1;
        }
    }
    assert!(n > 1000, "{n} voxels inside");
    sum / n as f64
}

#[test]
fn simpleitk_applying_the_exported_fields_gives_the_warp() {
    // fixtures/registration/make.py resampled preop.nii.gz with SimpleITK through
    // DisplacementFieldTransform, from field.nii.gz, field.mha and field.nrrd, each written
    // by `brainshift field` from run/ (see the fixture's README): the fields include the
    // extension between the brain and the skull, so the whole head is compared.
    let fx = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/registration");
    let d = tmp("sitk");
    let out = d.join("warped.nii.gz");
    warp_file(&fx.join("run"), &fx.join("preop.nii.gz"), &out, None, None).unwrap();
    let ours = bs_image::nifti::read_image(&out).unwrap().volume;
    let preop = bs_image::nifti::read_image(&fx.join("preop.nii.gz")).unwrap().volume;
    let result = RunResult::load(&fx.join("run")).unwrap();
    let map = InverseMap::new(&result, &preop.grid, Path::new("preop")).unwrap();
    let mask: Vec<bool> = (0..preop.grid.len()).map(|n| map.reference_point(n).is_some()).collect();
    let (lo, hi) = preop.data.iter().fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    let range = (hi - lo) as f64;
    // The warp moved something: it differs from the pre-operative image inside the brain.
    let moved = compare(&ours.data, &preop.data, &mask);
    assert!(moved > 0.01 * range, "the warp barely changed the image ({moved})");
    for name in ["sitk-from-nii.nii.gz", "sitk-from-mha.nii.gz", "sitk-from-nrrd.nii.gz"] {
        let theirs = bs_image::nifti::read_image(&fx.join(name)).unwrap().volume;
        assert_eq!(theirs.grid.dims(), preop.grid.dims());
        let mad = compare(&ours.data, &theirs.data, &mask);
        // SimpleITK interpolates the f32 field at the voxel centres (its own values) and
        // the image trilinearly, as we do: agreement to f32 rounding is expected; the
        // acceptance bound is 1 % of the intensity range.
        assert!(mad <= 0.01 * range, "{name}: mean |difference| {mad} vs range {range}");
        let everywhere = compare(&ours.data, &theirs.data, &vec![true; mask.len()]);
        assert!(everywhere <= 0.01 * range, "{name}: outside the brain too ({everywhere})");
        // Voxel by voxel, the gap included: the warp samples where the field points (beyond
        // the skin, the pre-operative gap's voxel centres). What is left is the f32 field's
        // rounding (the MetaImage and NRRD vectors also go through LPS): 1.1e-3 measured,
        // bound 1e-4 of the range. Until the field carried the warp's gap rule SimpleITK
        // differed by up to 681 on 1168 gap voxels.
        let worst =
            ours.data.iter().zip(&theirs.data).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        assert!((worst as f64) <= 1e-4 * range, "{name}: {worst} at worst");
        eprintln!(
            "{name}: mean |ours − SimpleITK| {mad:.3e} inside the brain, {everywhere:.3e} over \
             the whole image, at most {worst:.3e}, range {range}, warp moved {moved:.3}"
        );
    }
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn the_field_summary_gives_the_brains_and_the_gaps_largest_displacement_apart() {
    let fx = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/registration");
    let d = tmp("summary");
    let s = field_file(&fx.join("run"), &fx.join("preop.nii.gz"), &d.join("f.nii.gz")).unwrap();
    let result = RunResult::load(&fx.join("run")).unwrap();
    let nodal = result.max_displacement_mm();
    // Inside the deformed brain d(y) = −Σ w_i u_i (barycentric weights of the deformed
    // tetrahedron), so |d| ≤ max |u_i|: the nodal largest bounds it; the 4 mm voxels sample
    // the craniotomy's top within a few percent of it.
    assert!(s.max_displacement <= nodal + 1e-4, "{} vs {nodal}", s.max_displacement);
    assert!(s.max_displacement > 0.9 * nodal, "{} vs {nodal}", s.max_displacement);
    // In the gap on these 4 mm voxels points move to the pre-operative gap, farther than
    // the brain moved (fixtures/registration/README.md: 15.0 mm), but within the search:
    // the harmonic extension's components stay within the brain's (maximum principle), and
    // a point moves at most GAP_SEARCH_VOXELS voxels along each axis.
    let gap = s.gap_max_displacement.expect("a gap between brain and skull");
    let h = 4.0 * 3f64.sqrt();
    assert!(gap > nodal && gap <= 3f64.sqrt() * nodal + GAP_SEARCH_VOXELS as f64 * h, "{gap}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_grid_with_an_oblique_flipped_affine_gives_the_same_reference_points() {
    // The same world points on two grids (one axis-aligned, one with flipped i and a
    // permutation of axes): X(y) depends on y only.
    let mesh = box_at([10.0, 12.0, 9.0], true);
    let a = Matrix3::new(1.08, 0.05, -0.03, -0.04, 0.93, 0.06, 0.02, -0.05, 1.11);
    let result = affine_result(&mesh, &a, Vector3::new(-1.7, 2.2, 0.9));
    let mut m = Matrix4::zeros();
    // world x = 61.7 − k, world y = i − 1.6, world z = j − 2.9 (1 mm voxels).
    m[(0, 2)] = -1.0;
    m[(0, 3)] = 61.7;
    m[(1, 0)] = 1.0;
    m[(1, 3)] = -1.6;
    m[(2, 1)] = 1.0;
    m[(2, 3)] = -2.9;
    m[(3, 3)] = 1.0;
    let g2 = Grid::new([64, 64, 64], m).unwrap();
    let g1 = grid();
    let m1 = InverseMap::new(&result, &g1, Path::new("a")).unwrap();
    let m2 = InverseMap::new(&result, &g2, Path::new("b")).unwrap();
    assert_eq!(m1.inside_count(), m2.inside_count());
    for (i, j, k) in [(20, 30, 25), (15, 40, 33), (35, 22, 41)] {
        let y = g1.world([i as f64, j as f64, k as f64]);
        let v = g2.voxel(&y).map(|c| c.round() as usize);
        let p1 = m1.reference_point(g1.index(i, j, k)).unwrap();
        let p2 = m2.reference_point(g2.index(v[0], v[1], v[2])).unwrap();
        assert!((p1 - p2).norm() < 1e-9);
    }
}
