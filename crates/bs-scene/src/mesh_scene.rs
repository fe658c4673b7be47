//! From a segmentation to a model (`brainshift mesh`): a labelmap is meshed by bs-meshgen
//! and written as a scene folder — `brain.vtu` (world frame in its `SPACE` field data),
//! `brain.vtk` (the same for meshio, the frame in its title line), `brain.inp`, `skull.off` and a `scene.toml` with default materials per region, the
//! `FIXED` brain stem and a commented craniotomy — every file written atomically.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use bs_image::Space;
use bs_mesh::io::Fields;
use bs_meshgen::{BRAIN_SET, CRANIOTOMY_SET, FIXED_SET};
/// The meshing types front ends need (re-exported: they build on bs-scene alone).
pub use bs_meshgen::{ElementType, MeshParams, MeshReport, Meshed, RegionSpec};

use crate::SceneError;

/// The files of a meshed scene folder.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneFiles {
    /// `brain.vtu` (for viewing in 3D Slicer and ParaView, with `SPACE` field data).
    pub brain_vtu: PathBuf,
    /// `brain.vtk` (the same as legacy VTK, `SPACE=` in its title line: meshio reads it).
    pub brain_vtk: PathBuf,
    /// `brain.inp` (what the scene reads).
    pub brain_inp: PathBuf,
    /// `skull.off`.
    pub skull: PathBuf,
    /// `scene.toml`.
    pub scene: PathBuf,
}

/// A labelmap meshed and written as a scene folder.
#[derive(Debug, Clone)]
pub struct MeshedScene {
    /// The mesh, skull and report.
    pub meshed: Meshed,
    /// Where they were written.
    pub files: SceneFiles,
    /// What the user must add before `brainshift check` accepts the scene (None: it runs
    /// as written). A scene meshed without `--craniotomy` prescribes no load yet.
    pub missing: Option<String>,
}

/// The step a scene written without its craniotomy load needs: `check` refuses a scene
/// that moves nothing.
pub fn missing_load(scene: &Path) -> String {
    format!(
        "next: {} prescribes no load yet, so `brainshift check` refuses it (nothing to \
         compute): uncomment its [[boundary]] CRANIOTOMY block (and set the displacement, mm) \
         or add your own load (displacement_file, surface, landmarks), or mesh again with \
         --craniotomy",
        scene.display()
    )
}

/// Default material of an element set: Young's modulus (Pa) and Poisson's ratio. Tumours
/// are stiffer than parenchyma, ventricles (CSF-filled, drained or not) far softer and
/// compressible; anything else is parenchyma.
pub fn default_material(set: &str) -> (f64, f64, &'static str) {
    let s = set.to_ascii_lowercase();
    if s.contains("tumo") {
        (9000.0, 0.49, "tumour")
    } else if s.contains("ventric") || s.contains("csf") {
        (100.0, 0.1, "ventricles")
    } else {
        (3000.0, 0.49, "parenchyma")
    }
}

/// Reads the labelmap `labels` (NIfTI), meshes it and writes the scene folder `out`
/// (created if needed). With `craniotomy` the scene's craniotomy load (CRANIOTOMY moved
/// 8 mm along −z) is active, so the scene runs as written; otherwise it is a comment.
pub fn mesh_to_scene(
    labels: &Path,
    out: &Path,
    params: &MeshParams,
    craniotomy: bool,
) -> Result<MeshedScene, SceneError> {
    let volume = bs_image::formats::read_labels(labels)
        .map(|(v, _)| v)
        .map_err(|e| SceneError::Labelmap { file: labels.to_path_buf(), message: e.to_string() })?;
    let meshed = bs_meshgen::mesh_labelmap(&volume, params)
        .map_err(|e| SceneError::Labelmap { file: labels.to_path_buf(), message: e.to_string() })?;
    let files = write_scene_folder(out, &meshed, params, labels, Space::Ras, craniotomy)?;
    let missing = (!craniotomy).then(|| missing_load(&files.scene));
    Ok(MeshedScene { meshed, files, missing })
}

/// Writes `brain.vtu`, `brain.inp`, `skull.off` and `scene.toml` into `out`.
pub fn write_scene_folder(
    out: &Path,
    meshed: &Meshed,
    params: &MeshParams,
    source: &Path,
    space: Space,
    craniotomy: bool,
) -> Result<SceneFiles, SceneError> {
    let werr = |path: &Path, e: &dyn std::fmt::Display| SceneError::Write {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    std::fs::create_dir_all(out).map_err(|e| werr(out, &e))?;
    let files = SceneFiles {
        brain_vtu: out.join("brain.vtu"),
        brain_vtk: out.join("brain.vtk"),
        brain_inp: out.join("brain.inp"),
        skull: out.join("skull.off"),
        scene: out.join("scene.toml"),
    };
    bs_mesh::io::write_mesh_in_space(
        &files.brain_vtu,
        &meshed.mesh,
        &Fields::default(),
        space.name(),
    )
    .map_err(|e| werr(&files.brain_vtu, &e))?;
    bs_mesh::io::write_mesh_in_space(
        &files.brain_vtk,
        &meshed.mesh,
        &Fields::default(),
        space.name(),
    )
    .map_err(|e| werr(&files.brain_vtk, &e))?;
    bs_mesh::io::write_mesh(&files.brain_inp, &meshed.mesh, &Fields::default())
        .map_err(|e| werr(&files.brain_inp, &e))?;
    bs_mesh::io::write_surface(&files.skull, &meshed.skull).map_err(|e| werr(&files.skull, &e))?;
    let text = scene_text(meshed, params, source, space, craniotomy);
    bs_mesh::io::write_atomic(&files.scene, |w| w.write_all(text.as_bytes()))
        .map_err(|e| werr(&files.scene, &e))?;
    Ok(files)
}

/// The `scene.toml` of a meshed labelmap. With `craniotomy` the craniotomy block is active
/// (for tests and scripts); otherwise it is a comment to edit and uncomment.
pub fn scene_text(
    meshed: &Meshed,
    params: &MeshParams,
    source: &Path,
    space: Space,
    craniotomy: bool,
) -> String {
    let r = &meshed.report;
    let mut s = String::new();
    let _ = writeln!(s, "# Made by `brainshift mesh` from {}:", source.display());
    let _ = writeln!(
        s,
        "# {} elements of {} mm, {} nodes; skull cavity {}.",
        r.elements,
        params.size,
        r.nodes,
        match &params.cavity_labels {
            Some(l) => format!("inside the labels {l:?}"),
            None => format!("{} mm outside the brain", params.skull_offset),
        }
    );
    let _ = writeln!(
        s,
        "# Coordinates: the image's world frame ({}), mm; brain.vtu carries SPACE = \"{}\".",
        space.name(),
        space.name()
    );
    let _ = writeln!(s, "units = \"mm\"\n");
    let _ = writeln!(s, "[mesh]\nfile = \"brain.inp\"");
    let element = match params.element {
        ElementType::T4 => "t4anp",
        ElementType::H8 => "h8",
    };
    let _ = writeln!(s, "element = \"{element}\"\n");
    let mut sets: Vec<&str> = vec![BRAIN_SET];
    let region_names: Vec<String> =
        params.regions.iter().map(|g| g.name.to_ascii_uppercase()).collect();
    sets.extend(region_names.iter().map(String::as_str));
    for set in sets {
        if meshed.mesh.element_set(set).is_none_or(|e| e.is_empty()) {
            let _ = writeln!(s, "# (element set {set} is empty at this size: no region written)\n");
            continue;
        }
        let (e, nu, what) = default_material(set);
        let _ = writeln!(s, "[[region]]  # {what}\nelset = \"{set}\"");
        let _ = writeln!(
            s,
            "material = {{ model = \"neo-hookean\", youngs_modulus = {e:.1}, poisson_ratio = {nu}, density = 1000.0 }}\n"
        );
    }
    let _ = writeln!(
        s,
        "# The brain stem: surface nodes at the inferior-most part of the brain, held."
    );
    let _ = writeln!(s, "[[boundary]]\nnset = \"{FIXED_SET}\"\nfix = [\"x\", \"y\", \"z\"]\n");
    let _ = writeln!(
        s,
        "# A craniotomy: {CRANIOTOMY_SET} holds the surface nodes near the top of the brain \
         ({} nodes); edit the displacement (mm) and uncomment to load the brain.",
        r.craniotomy_nodes
    );
    let c = if craniotomy { "" } else { "# " };
    let _ = writeln!(
        s,
        "{c}[[boundary]]\n{c}nset = \"{CRANIOTOMY_SET}\"\n{c}displacement = {{ x = 0.0, y = 0.0, z = -8.0 }}\n"
    );
    let _ = writeln!(s, "[contact]\nskull = \"skull.off\"\nalgorithm = \"coherent\"\n");
    let _ = writeln!(s, "[solver]\nkind = \"newton-krylov\"\ntolerance = 1e-3");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use bs_image::{Grid, Volume};
    use bs_meshgen::RegionSpec;

    /// A labelmap written as NIfTI (oblique affine), meshed into a folder: every file is
    /// there, the scene parses, and with the craniotomy switched on `check` passes — sets
    /// resolved, materials valid, the skull closed and outward, and every brain surface
    /// node inside it by the exact distance (the gap must be positive; 3 mm offset minus
    /// half a voxel and the 2 mm cavity blocks leaves about 2.5 mm).
    #[test]
    fn labelmap_to_scene_folder_that_checks() {
        let dir = std::env::temp_dir().join(format!("bs-mesh-scene-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, 0.2, -0.4).to_homogeneous();
        let mut m = rot * nalgebra::Matrix4::new_scaling(1.0);
        m[(3, 3)] = 1.0;
        m[(0, 3)] = -20.0;
        m[(1, 3)] = -25.0;
        m[(2, 3)] = -15.0;
        let grid = Grid::new([44, 44, 44], m).unwrap();
        let mut v = Volume::filled(grid, 0u32);
        for k in 0..44 {
            for j in 0..44 {
                for i in 0..44 {
                    let r = (nalgebra::Vector3::new(i as f64, j as f64, k as f64)
                        - nalgebra::Vector3::repeat(21.5))
                    .norm();
                    let id = v.grid.index(i, j, k);
                    v.data[id] = if r < 5.0 {
                        5
                    } else if r < 16.0 {
                        1
                    } else {
                        0
                    };
                }
            }
        }
        let labels = dir.join("labels.nii.gz");
        bs_image::nifti::write_labels(&labels, &v, None).unwrap();
        let params = MeshParams {
            size: 2.5,
            regions: vec![RegionSpec { name: "tumour".into(), labels: vec![5] }],
            ..MeshParams::default()
        };
        let out = dir.join("model");
        let done = mesh_to_scene(&labels, &out, &params, false).unwrap();
        for f in
            [&done.files.brain_vtu, &done.files.brain_inp, &done.files.skull, &done.files.scene]
        {
            assert!(f.is_file(), "{}", f.display());
        }
        let vtu = std::fs::read_to_string(&done.files.brain_vtu).unwrap();
        assert!(vtu.contains("Name=\"SPACE\"") && vtu.contains("82 65 83 0"));
        let scene = crate::Scene::load(&done.files.scene).unwrap();
        assert_eq!(scene.regions.len(), 2);
        assert_eq!(scene.regions[1].elset, "TUMOUR");
        assert_eq!(scene.regions[1].material.youngs_modulus, Some(9000.0));
        // As written (no load) `check` refuses the scene, and the meshing said what to add.
        let e = crate::check::check(&done.files.scene).unwrap_err().to_string();
        assert!(e.contains("nothing to compute") || e.contains("prescribes nothing"), "{e}");
        let missing = done.missing.as_deref().unwrap();
        assert!(missing.contains("CRANIOTOMY") && missing.contains("--craniotomy"), "{missing}");
        // The legacy VTK copy carries the frame in its title line.
        let vtk = std::fs::read_to_string(&done.files.brain_vtk).unwrap();
        assert_eq!(vtk.lines().nth(1), Some("brainshift output. SPACE=RAS"));
        // With the commented craniotomy active the scene is complete: check it.
        let loaded = out.join("scene-craniotomy.toml");
        std::fs::write(&loaded, scene_text(&done.meshed, &params, &labels, Space::Ras, true))
            .unwrap();
        let checked = crate::check::check(&loaded).unwrap();
        let (min_gap, _) = checked.initial_gap.unwrap();
        assert!(min_gap > 1.5, "initial gap {min_gap}");
        // A labelmap that cannot be read names the file.
        let e = mesh_to_scene(&dir.join("missing.nii"), &out, &params, false).unwrap_err();
        assert!(e.to_string().contains("missing.nii"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
