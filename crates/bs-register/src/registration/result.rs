//! A run's result read back: the reference mesh, its displacements, frame and unit.

use std::path::{Path, PathBuf};

use bs_image::Space;
use bs_mesh::{Mesh, TriSurface, Vector3};

use bs_scene::SceneError;
use bs_scene::scene::Units;

/// A run's result read back from its directory.
#[derive(Debug, Clone)]
pub struct RunResult {
    /// The directory (for messages).
    pub dir: PathBuf,
    /// The reference mesh.
    pub mesh: Mesh,
    /// Nodal displacements, in the mesh's frame and unit.
    pub displacements: Vec<Vector3<f64>>,
    /// The frame of the mesh coordinates and displacements.
    pub space: Space,
    /// The length unit of the mesh.
    pub units: Units,
    /// The skull cavity of the scene (closed, outward), in the mesh's frame and unit:
    /// `skull.off` of the result directory. None: the scene had no skull.
    pub skull: Option<TriSurface>,
    /// Things worth knowing (e.g. a report written before frames were recorded).
    pub notes: Vec<String>,
    /// The run resected a region (report.json's `resected`): gap voxels the deformed brain
    /// encloses are its cavity, filled with fluid by the warps.
    pub resected: bool,
    /// Total σ per node (mesh units): the `sigma` point field of result.vtu, written by
    /// `run --uncertainty`; none without it.
    pub sigma: Option<Vec<f64>>,
}

impl RunResult {
    /// Reads `dir/result.vtu` (mesh and `displacement` point data), `dir/report.json`
    /// (`space`, `units`) and, when there, `dir/skull.off` (the scene's skull), as
    /// `brainshift run` writes them.
    pub fn load(dir: &Path) -> Result<RunResult, SceneError> {
        let err = |message: String| SceneError::Result { dir: dir.to_path_buf(), message };
        let vtu = dir.join("result.vtu");
        let report = dir.join("report.json");
        if !vtu.is_file() || !report.is_file() {
            return Err(err(format!(
                "not a result directory: {} and {} are needed (written by `brainshift run \
                 SCENE --out DIR`)",
                vtu.display(),
                report.display()
            )));
        }
        let read = bs_scene::output::RunReport::read(&report).map_err(err)?;
        let mut notes = Vec::new();
        let space = match read.space {
            None => {
                notes.push(format!(
                    "{} names no \"space\" (written before frames were recorded): the mesh is \
                     taken as RAS; re-run the scene to record it",
                    report.display()
                ));
                Space::Ras
            }
            Some(s) => s,
        };
        let units = read.units.ok_or_else(|| {
            err(format!("{}: names no \"units\"; expected \"mm\" or \"m\"", report.display()))
        })?;
        let (mesh, fields) = match bs_mesh::io::read(&vtu).map_err(|e| err(e.to_string()))? {
            bs_mesh::io::MeshFile::Volume(m, f) => (m, f),
            bs_mesh::io::MeshFile::Surface(_) => {
                return Err(err(format!("{}: holds a surface, not a volume mesh", vtu.display())));
            }
        };
        if let Some((_, s)) = fields.field_data.iter().find(|(n, _)| n == "SPACE")
            && Space::from_name(s) != Some(space)
        {
            return Err(err(format!(
                "{} says SPACE = \"{s}\" but {} says \"{}\"; the two files come from \
                 different runs",
                vtu.display(),
                report.display(),
                space.name()
            )));
        }
        let field = fields.point.iter().find(|f| f.name == "displacement").ok_or_else(|| {
            err(format!("{}: no point data named \"displacement\"", vtu.display()))
        })?;
        if field.components != 3 || field.values.len() != 3 * mesh.nodes.len() {
            return Err(err(format!(
                "{}: \"displacement\" has {} components × {} values for {} nodes; expected 3 \
                 per node",
                vtu.display(),
                field.components,
                field.values.len() / field.components.max(1),
                mesh.nodes.len()
            )));
        }
        let displacements: Vec<Vector3<f64>> =
            field.values.chunks_exact(3).map(|c| Vector3::new(c[0], c[1], c[2])).collect();
        let sigma = match fields.point.iter().find(|f| f.name == "sigma") {
            None => None,
            Some(f) if f.components == 1 && f.values.len() == mesh.nodes.len() => {
                Some(f.values.clone())
            }
            Some(f) => {
                return Err(err(format!(
                    "{}: \"sigma\" has {} components × {} values for {} nodes; expected one \
                     per node (the total σ `run --uncertainty` writes)",
                    vtu.display(),
                    f.components,
                    f.values.len() / f.components.max(1),
                    mesh.nodes.len()
                )));
            }
        };
        let skull_file = dir.join("skull.off");
        let skull = if skull_file.is_file() {
            Some(bs_mesh::io::read_surface(&skull_file).map_err(|e| err(e.to_string()))?)
        } else {
            if read.algorithm != bs_scene::scene::Algorithm::None {
                notes.push(format!(
                    "{} names a contact algorithm but {} is missing (a result written before \
                     the skull was kept with it): the map outside the brain decays over a band \
                     instead of stopping at the skull; re-run the scene to keep its skull",
                    report.display(),
                    skull_file.display()
                ));
            }
            None
        };
        let resected = read.resected.is_some();
        RunResult::new(dir, mesh, displacements, space, units).map(|mut r| {
            r.notes.extend(notes);
            r.skull = skull;
            r.resected = resected;
            r.sigma = sigma;
            r
        })
    }

    /// A result from its parts (e.g. a run held in memory); checks that every node has a
    /// finite displacement.
    pub fn new(
        dir: &Path,
        mesh: Mesh,
        displacements: Vec<Vector3<f64>>,
        space: Space,
        units: Units,
    ) -> Result<RunResult, SceneError> {
        let err = |message: String| SceneError::Result { dir: dir.to_path_buf(), message };
        if displacements.len() != mesh.nodes.len() {
            return Err(err(format!(
                "{} displacements for {} nodes",
                displacements.len(),
                mesh.nodes.len()
            )));
        }
        if let Some(n) = displacements.iter().position(|u| !u.iter().all(|x| x.is_finite())) {
            return Err(err(format!("node {}: the displacement is not finite", mesh.node_ids[n])));
        }
        if mesh.elements.is_empty() {
            return Err(err("the mesh has no elements".into()));
        }
        Ok(RunResult {
            dir: dir.to_path_buf(),
            mesh,
            displacements,
            space,
            units,
            skull: None,
            notes: vec![],
            resected: false,
            sigma: None,
        })
    }

    /// The same result with the scene's skull (mesh frame and unit).
    pub fn with_skull(mut self, skull: Option<TriSurface>) -> RunResult {
        self.skull = skull;
        self
    }

    /// Largest nodal displacement (mm).
    pub fn max_displacement_mm(&self) -> f64 {
        let scale = self.units.metres() / 1e-3;
        self.displacements.iter().map(|u| u.norm() * scale).fold(0.0, f64::max)
    }
}
