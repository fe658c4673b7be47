//! A resection's cavity in the warped image and labelmap: the box of bs-scene's resection
//! tests (a 40 mm Kuhn box, 6³ cells, base held, top pushed 4 mm; TUMOUR the elements
//! within 9 mm of the centre) with its tumour resected, warped from a synthetic image.

use std::path::{Path, PathBuf};

use bs_mesh::{Mesh, Point3};
use bs_scene::{Prepared, Run};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("bs-resection-warp-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The 40 mm box with a 9 mm tumour at its centre (element sets TUMOUR and BRAIN).
fn box_with_tumour() -> Mesh {
    bs_mesh::structured::box_with_ball(6, 40.0, 9.0, "TUMOUR", "BRAIN")
}

const MATERIAL: &str =
    "material = { model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.45 }";

/// The box scene with `regions`, base held, top pushed `push` mm down.
fn scene(dir: &Path, regions: &str, push: f64) -> PathBuf {
    let text = format!(
        "units = \"mm\"\n[mesh]\nfile = \"box.inp\"\nelement = \"t4\"\n{regions}\
         [[boundary]]\nnset = \"BASE\"\nfix = [\"x\", \"y\", \"z\"]\n\
         [[boundary]]\nnset = \"TOP\"\ndisplacement = {{ z = {} }}\n[solver]\ntolerance = 1e-6\n",
        -push
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn region(elset: &str, extra: &str) -> String {
    format!("[[region]]\nelset = \"{elset}\"\n{MATERIAL}\n{extra}")
}

/// The box's run written as `brainshift run` writes it, into `out`.
fn write_run(scene_path: &Path, out: &Path) {
    let mut run = Run::prepare(Prepared::load(scene_path).unwrap()).unwrap();
    let solved = run.solve(&mut |_| {}).unwrap();
    let ctx = bs_scene::output::RunContext { total_seconds: 0.0, threads: 1 };
    let report = bs_scene::output::report(&run, &solved, ctx);
    bs_scene::output::write_outputs(out, &run.prepared, &solved, &report).unwrap();
}

#[test]
fn the_warped_image_shows_the_cavity_as_the_fluid_around_the_brain() {
    use bs_image::{Grid, Volume};
    let d = tmp("warp");
    bs_mesh::io::write_mesh(&d.join("box.inp"), &box_with_tumour(), &Default::default()).unwrap();
    let regions = region("BRAIN", "") + &region("TUMOUR", "resected = true\n");
    write_run(&scene(&d, &regions, 4.0), &d.join("run"));
    // A pre-operative image: tissue (100) in the box, the tumour included, fluid (7) around.
    let grid = Grid::axis_aligned([56, 56, 56], [1.0; 3], [-8.0; 3]).unwrap();
    let tissue = |n: usize| grid.centre(n).iter().all(|&c| (0.0..=40.0).contains(&c));
    let image = Volume {
        data: (0..grid.len()).map(|n| if tissue(n) { 100.0 } else { 7.0 }).collect(),
        grid: grid.clone(),
    };
    bs_image::nifti::write_image(&d.join("preop.nii"), &image, None).unwrap();
    let labels = Volume {
        data: (0..grid.len()).map(|n| u32::from(tissue(n)) * 5).collect(),
        grid: grid.clone(),
    };
    bs_image::nifti::write_labels(&d.join("labels.nii"), &labels, None).unwrap();
    let out = d.join("warped.nii");
    bs_register::registration::warp_file(&d.join("run"), &d.join("preop.nii"), &out, None, None)
        .unwrap();
    let (warped, _) = bs_image::formats::read_image(&out).unwrap();
    // The cavity's centre (the push moved it about 2 mm down) reads the fluid, not the
    // tumour's tissue the pre-operative image has there; the brain beside it stays tissue.
    let at = |x: f64, y: f64, z: f64| {
        let v = grid.voxel(&Point3::new(x, y, z)).map(|c| c.round() as usize);
        grid.index(v[0], v[1], v[2])
    };
    assert_eq!(warped.data[at(20.0, 20.0, 18.0)], 7.0);
    assert_eq!(warped.data[at(20.0, 20.0, 6.0)], 100.0);
    let out = d.join("labels-warped.nii");
    bs_register::registration::warp_file(
        &d.join("run"),
        &d.join("labels.nii"),
        &out,
        Some(0),
        None,
    )
    .unwrap();
    let (warped, _) = bs_image::formats::read_labels(&out).unwrap();
    assert_eq!(warped.data[at(20.0, 20.0, 18.0)], 0);
    assert_eq!(warped.data[at(20.0, 20.0, 6.0)], 5);
    // A cavity label named: the cavity takes it, every other voxel is as before.
    let named = d.join("labels-cavity.nii");
    bs_register::registration::warp_file(
        &d.join("run"),
        &d.join("labels.nii"),
        &named,
        Some(9),
        None,
    )
    .unwrap();
    let (relabelled, _) = bs_image::formats::read_labels(&named).unwrap();
    assert_eq!(relabelled.data[at(20.0, 20.0, 18.0)], 9);
    let changed = (0..grid.len()).filter(|&n| relabelled.data[n] != warped.data[n]);
    assert!(changed.clone().count() > 0);
    assert!(changed.clone().all(|n| warped.data[n] == 0 && relabelled.data[n] == 9));
}
