//! `brainshift demo`: the bundled MNI152 case, from its ready mesh or (`--from-image`)
//! from its labelmap: image → mesh → solve → warped image, the whole path a newcomer would
//! take.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use crate::{mesh, run};

/// The bundled MNI152 brain mask (fixtures/mni152/make_labels.py).
pub fn default_labelmap() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/mni152/mask.nii.gz")
}

/// The demo's element size from the image: 7 mm stuffing gives about the element count of
/// the bundled mesh (69 000 tetrahedra; 4 mm gives 360 000 and a solve 5× longer), and the
/// speed-versus-accuracy chart shows the coarse mesh is enough for 0.1 mm
/// (docs/speed-accuracy.md).
pub const DEMO_SIZE_MM: f64 = 7.0;

/// Runs the demo into `out`. With `from_image` the brain mask is meshed first
/// ([`DEMO_SIZE_MM`] tetrahedra, a skull cavity 3 mm out, the craniotomy pushed 8 mm in)
/// into `out/mesh/`,
/// and that scene is solved. Then the MNI152 T1 template is warped by the result
/// (`out/warped_t1.nii.gz`) and the displacement field written (`out/field.nii.gz`).
pub fn run(out: &Path, from_image: bool) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let scene = if from_image {
        let mesh_dir = out.join("mesh");
        crate::emit(&format!(
            "meshing {} ({DEMO_SIZE_MM} mm tetrahedra, skull cavity 3 mm out) into {}\n",
            default_labelmap().display(),
            mesh_dir.display()
        ));
        mesh::run(&mesh::MeshOptions {
            labels: default_labelmap(),
            out: mesh_dir.clone(),
            brain: None,
            regions: Vec::new(),
            size: DEMO_SIZE_MM,
            element: "t4".into(),
            skull_offset: 3.0,
            cavity: None,
            craniotomy: true,
        })?;
        mesh_dir.join("scene.toml")
    } else {
        run::default_scene()
    };
    let code = run::run(&run::RunOptions {
        scene,
        out: out.to_path_buf(),
        threads: None,
        quiet: false,
        uncertainty: None,
        uncertainty_grid: None,
        uncertainty_tolerance: None,
    })?;
    if code != ExitCode::SUCCESS {
        return Ok(code);
    }
    demo_images(out)
}

/// `demo`'s registration outputs: the bundled MNI152 T1 template warped by the result in
/// `out` (out/warped_t1.nii.gz, with out/preview.png), and the displacement field on its
/// grid (out/field.nii.gz).
pub fn demo_images(out: &Path) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let t1 = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/mni152/t1.nii.gz");
    crate::warp::run(
        &t1,
        out,
        &out.join("warped_t1.nii.gz"),
        None,
        (Some(&out.join("preview.png")), None),
    )?;
    crate::field::run(&t1, out, &out.join("field.nii.gz"))?;
    Ok(ExitCode::SUCCESS)
}
