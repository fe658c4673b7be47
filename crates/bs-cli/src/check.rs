//! `brainshift check SCENE`: everything a run needs, checked without running.
//!
//! The loading and resolution here ([`Prepared::load`]) is what `run` builds on, so a scene
//! that passes `check` fails in `run` only for numerical reasons.

use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;

use bs_mesh::{ElementKind, Mesh, TriSurface};

use crate::scene::SolverKind;
use crate::scene::{ElementChoice, Scene};

/// A scene with its files read and its names resolved.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The parsed scene.
    pub scene: Scene,
    /// The brain mesh.
    pub mesh: Mesh,
    /// Element technology after defaults.
    pub element: ElementChoice,
    /// Region index of every element.
    pub region_of_element: Vec<usize>,
    /// Per node: fixed (`Some(0.0)`) or prescribed final displacement per component.
    pub prescribed: Vec<[Option<f64>; 3]>,
    /// The skull, if the scene has contact.
    pub skull: Option<TriSurface>,
    /// Things worth knowing that do not stop a run.
    pub warnings: Vec<String>,
}

/// Why a scene cannot run.
#[derive(Debug)]
pub struct CheckError(pub String);

impl std::fmt::Display for CheckError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CheckError {}

impl Prepared {
    /// Reads the scene, the mesh and the skull and resolves sets; every error names the
    /// file and the key or entity.
    pub fn load(scene_path: &Path) -> Result<Prepared, CheckError> {
        let scene = Scene::load(scene_path).map_err(|e| CheckError(e.to_string()))?;
        let sp = scene_path.display();
        let mesh = bs_mesh::io::read_mesh(&scene.mesh.file)
            .map_err(|e| CheckError(format!("{sp}: [mesh] file: {e}")))?;
        let report = mesh.validate();
        if let Some(first) = report.first_error() {
            return Err(CheckError(format!(
                "{}: the mesh is not usable ({} problem{}); first: {first}",
                scene.mesh.file.display(),
                report.errors.len(),
                if report.errors.len() == 1 { "" } else { "s" }
            )));
        }
        let mut warnings = Vec::new();
        if !report.unused_node_ids.is_empty() {
            warnings.push(format!(
                "{} nodes belong to no element and are ignored (e.g. node {})",
                report.unused_node_ids.len(),
                report.unused_node_ids[0]
            ));
        }

        let (tets, hexes) = mesh.count_by_kind();
        let element = match (scene.mesh.element, tets, hexes) {
            (Some(e), ..) => e,
            (None, _, 0) => ElementChoice::T4anp,
            (None, 0, _) => ElementChoice::H8,
            (None, ..) => {
                return Err(CheckError(format!(
                    "{sp}: [mesh] the mesh mixes {tets} tets and {hexes} hexes; mixed meshes are \
                     not supported by one element technology yet"
                )));
            }
        };
        let wanted =
            if element == ElementChoice::H8 { ElementKind::Hex8 } else { ElementKind::Tet4 };
        if let Some(e) = mesh.elements.iter().position(|e| e.kind() != wanted) {
            return Err(CheckError(format!(
                "{sp}: [mesh] element = \"{}\" but element {} is a {}; choose the element \
                 technology that matches the mesh",
                format!("{element:?}").to_lowercase(),
                mesh.element_ids[e],
                mesh.elements[e].kind().name()
            )));
        }

        // Regions: every element gets exactly one.
        let mut region_of_element = vec![usize::MAX; mesh.elements.len()];
        for (r, region) in scene.regions.iter().enumerate() {
            let members: Vec<usize> = if region.elset == "*" {
                (0..mesh.elements.len()).collect()
            } else {
                mesh.element_set(&region.elset)
                    .ok_or_else(|| {
                        CheckError(format!(
                            "{sp}: [[region]] elset = \"{}\": no such element set in {} (it has: {})",
                            region.elset,
                            scene.mesh.file.display(),
                            names(mesh.element_sets.keys())
                        ))
                    })?
                    .to_vec()
            };
            for e in members {
                if region_of_element[e] != usize::MAX && region_of_element[e] != r {
                    return Err(CheckError(format!(
                        "{sp}: element {} is in two regions ('{}' and '{}'); regions must not overlap",
                        mesh.element_ids[e],
                        scene.regions[region_of_element[e]].elset,
                        region.elset
                    )));
                }
                region_of_element[e] = r;
            }
        }
        if let Some(e) = region_of_element.iter().position(|&r| r == usize::MAX) {
            let missing = region_of_element.iter().filter(|&&r| r == usize::MAX).count();
            return Err(CheckError(format!(
                "{sp}: {missing} elements have no material (e.g. element {}); add a [[region]] for \
                 their element set or use elset = \"*\"",
                mesh.element_ids[e]
            )));
        }

        let prescribed = resolve_boundaries(&scene, &mesh, scene_path)?;
        let n_fixed = prescribed.iter().filter(|p| p.iter().any(Option::is_some)).count();
        if n_fixed == 0 {
            warnings.push(
                "no node has a prescribed or fixed displacement: the problem has no load".into(),
            );
        }

        let skull = match &scene.contact {
            None => None,
            Some(c) => {
                let s = bs_mesh::io::read_surface(&c.skull)
                    .map_err(|e| CheckError(format!("{sp}: [contact] skull: {e}")))?;
                s.require_closed_outward().map_err(|e| {
                    CheckError(format!("{sp}: [contact] skull {}: {e}", c.skull.display()))
                })?;
                Some(s)
            }
        };

        // Unit sanity: a prescribed displacement larger than the brain is a unit mistake.
        if let Some((lo, hi)) = mesh.bounding_box() {
            let size = (hi - lo).norm();
            let biggest = prescribed
                .iter()
                .map(|p| p.iter().flatten().map(|v| v * v).sum::<f64>().sqrt())
                .fold(0.0, f64::max);
            if biggest > 0.5 * size {
                return Err(CheckError(format!(
                    "{sp}: a prescribed displacement of {biggest:.4} {u} exceeds half the mesh size \
                     ({size:.4} {u}); check units = \"{u}\" against the mesh and the displacements",
                    u = scene.units.symbol()
                )));
            }
            if scene.units == crate::scene::Units::Mm && size < 1.0 {
                warnings.push(format!(
                    "the mesh is only {size:.3} mm across; if its coordinates are in metres, set \
                     units = \"m\""
                ));
            }
        }
        for r in &scene.regions {
            if let Some(e) = r.material.youngs_modulus.filter(|e| !(10.0..=1e7).contains(e)) {
                warnings.push(format!(
                    "region '{}': youngs_modulus = {e} Pa is far from soft tissue (brain: ~3000 Pa); \
                     moduli are in Pa",
                    r.elset
                ));
            }
        }
        if scene.contact.is_some()
            && !prescribed.iter().any(|p| p.iter().all(|c| c.is_some_and(|v| v == 0.0)))
        {
            warnings.push(
                "no node is fully fixed: a brain held only by the craniotomy inside a frictionless \
                 skull can twist about the push axis; fix the brain-stem nodes"
                    .into(),
            );
        }
        Ok(Prepared { scene, mesh, element, region_of_element, prescribed, skull, warnings })
    }
}

/// Rough peak memory of a run.
///
/// Dynamic Relaxation, calibrated on fixtures/mni152 (13 975 nodes, 69 140 tets, 8982 skull
/// triangles: 61 MB peak resident measured with /usr/bin/time): about 600 B per node (mesh,
/// solver vectors, boundary), 600 B per tet (mesh element, precomputed gradients, force
/// slots, assembly map), 2.5 kB per hex (adds the 8×8 hourglass matrix) and 1.5 kB per skull
/// triangle (topology, buckets, additional lists, coherence tables).
///
/// Newton–Krylov adds per node the GMRES basis (81 nodal vectors) and the preconditioner
/// (stiffness blocks in double and single precision, the nodal volumetric terms, the
/// prolongator), and a base for the coarse factor: 6.5 kB per node, 1 kB per tet, 12 MB;
/// fitted on the three MNI152 meshes (peak resident 85, 190 and 382 MB for 5021, 13 975 and
/// 31 006 nodes; within 5 %).
fn memory_estimate(p: &Prepared) -> f64 {
    let (tets, hexes) = p.mesh.count_by_kind();
    let nodes = p.mesh.nodes.len() as f64;
    let skull = p.skull.as_ref().map_or(0, |s| s.triangles.len()) as f64;
    match p.scene.solver.kind {
        SolverKind::NewtonKrylov => {
            12e6 + nodes * 6500.0 + tets as f64 * 1000.0 + hexes as f64 * 3500.0 + skull * 1500.0
        }
        SolverKind::Dr | SolverKind::Newton => {
            nodes * 600.0 + tets as f64 * 600.0 + hexes as f64 * 2500.0 + skull * 1500.0
        }
    }
}

fn names<'a>(it: impl Iterator<Item = &'a String>) -> String {
    let v: Vec<&str> = it.map(String::as_str).collect();
    if v.is_empty() { "no sets".into() } else { v.join(", ") }
}

fn resolve_boundaries(
    scene: &Scene,
    mesh: &Mesh,
    scene_path: &Path,
) -> Result<Vec<[Option<f64>; 3]>, CheckError> {
    let sp = scene_path.display();
    let mut prescribed = vec![[None; 3]; mesh.nodes.len()];
    let mut set = |node: usize, c: usize, v: f64, source: &str| -> Result<(), CheckError> {
        match prescribed[node][c] {
            Some(old) if old != v => Err(CheckError(format!(
                "{sp}: node {} component {} is prescribed twice with different values ({old} and \
                 {v}, the second from {source}); make the boundary sets disjoint",
                mesh.node_ids[node],
                ["x", "y", "z"][c]
            ))),
            _ => {
                prescribed[node][c] = Some(v);
                Ok(())
            }
        }
    };
    for (i, b) in scene.boundaries.iter().enumerate() {
        if let Some(file) = &b.displacement_file {
            for (node, d) in read_displacement_csv(file, mesh)? {
                for (c, v) in d.into_iter().enumerate() {
                    set(node, c, v, &file.display().to_string())?;
                }
            }
            continue;
        }
        let name = b.nset.as_deref().unwrap_or_default();
        let nodes = mesh.node_set(name).ok_or_else(|| {
            CheckError(format!(
                "{sp}: [[boundary]] #{} nset = \"{name}\": no such node set in {} (it has: {})",
                i + 1,
                scene.mesh.file.display(),
                names(mesh.node_sets.keys())
            ))
        })?;
        let source = format!("[[boundary]] #{}", i + 1);
        for &n in nodes {
            if let Some(fix) = &b.fix {
                for c in fix {
                    set(n, c.index(), 0.0, &source)?;
                }
            }
            if let Some(d) = &b.displacement {
                for (c, v) in d.components().into_iter().enumerate() {
                    if let Some(v) = v {
                        set(n, c, v, &source)?;
                    }
                }
            }
        }
    }
    Ok(prescribed)
}

/// Reads `node_id,ux,uy,uz` rows (with a header line).
fn read_displacement_csv(file: &Path, mesh: &Mesh) -> Result<Vec<(usize, [f64; 3])>, CheckError> {
    let f = file.display();
    let text = std::fs::read_to_string(file).map_err(|e| CheckError(format!("{f}: {e}")))?;
    let index: std::collections::HashMap<u64, usize> =
        mesh.node_ids.iter().enumerate().map(|(i, &id)| (id, i)).collect();
    let mut rows = Vec::new();
    for (l, line) in text.lines().enumerate() {
        let line = line.trim();
        if l == 0 || line.is_empty() {
            continue; // header
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let bad = || {
            CheckError(format!(
                "{f}:{}: expected node_id,ux,uy,uz with numbers, found '{line}'",
                l + 1
            ))
        };
        if fields.len() != 4 {
            return Err(bad());
        }
        let id: u64 = fields[0].parse().map_err(|_| bad())?;
        let mut d = [0.0f64; 3];
        for c in 0..3 {
            d[c] = fields[c + 1].parse().map_err(|_| bad())?;
            if !d[c].is_finite() {
                return Err(bad());
            }
        }
        let node = *index
            .get(&id)
            .ok_or_else(|| CheckError(format!("{f}:{}: node {id} is not in the mesh", l + 1)))?;
        rows.push((node, d));
    }
    Ok(rows)
}

/// Runs `check`: prints a summary, exits non-zero (with the reason) if the scene cannot run.
pub fn run(scene_path: &Path) -> Result<ExitCode, CheckError> {
    let p = Prepared::load(scene_path)?;
    let composed = crate::compose::compose(&p)?;
    let gap = composed.check_initial_gap(&p)?;
    let mut o = String::new();
    let u = p.scene.units.symbol();
    let (tets, hexes) = p.mesh.count_by_kind();
    let _ = writeln!(o, "{}: OK", scene_path.display());
    let _ = writeln!(
        o,
        "  mesh: {} ({} nodes, {} tet4, {} hex8), element technology {:?}, units {u}",
        p.scene.mesh.file.display(),
        p.mesh.nodes.len(),
        tets,
        hexes,
        p.element
    );
    for (r, region) in p.scene.regions.iter().enumerate() {
        let n = p.region_of_element.iter().filter(|&&x| x == r).count();
        let m = region.material.moduli().expect("checked at parse time");
        let _ = writeln!(
            o,
            "  region '{}': {n} elements, {:?}, mu = {:.6} Pa, kappa = {:.6} Pa",
            region.elset, region.material.model, m.mu, m.kappa
        );
    }
    let fixed = p.prescribed.iter().filter(|c| c.iter().all(|v| *v == Some(0.0))).count();
    let moved = p.prescribed.iter().filter(|c| c.iter().flatten().any(|v| *v != 0.0)).count();
    let _ = writeln!(
        o,
        "  boundary: {fixed} nodes fully fixed, {moved} nodes with prescribed displacement"
    );
    if let (Some(s), Some(c)) = (&p.skull, &p.scene.contact) {
        let _ = writeln!(
            o,
            "  skull: {} ({} vertices, {} triangles, closed, outward), algorithm {:?}",
            c.skull.display(),
            s.vertices.len(),
            s.triangles.len(),
            c.algorithm
        );
    } else {
        let _ = writeln!(o, "  contact: none");
    }
    if let Some((min, max)) = gap {
        let _ = writeln!(
            o,
            "  initial gap: min {min:.4} {u}, max {max:.4} {u} over {} slave nodes (all inside)",
            composed.slaves.len()
        );
    }
    let _ = writeln!(
        o,
        "  solver: {:?}, tolerance {} {u}",
        p.scene.solver.kind, p.scene.solver.tolerance
    );
    let (dt, e) = composed.model.critical_time_step();
    let _ = writeln!(
        o,
        "  stable time step: {:.4e} s (smallest element: id {}); Dynamic Relaxation uses \
         fictitious masses, so this sets no step count",
        dt * p.scene.units.metres(),
        p.mesh.element_ids[e]
    );
    let _ = writeln!(o, "  expected memory: about {:.0} MB", memory_estimate(&p) / 1e6);
    for w in &p.warnings {
        let _ = writeln!(o, "  warning: {w}");
    }
    match crate::advice::findings() {
        Ok(f) => {
            for line in crate::advice::advise(&p, &f) {
                let _ = writeln!(o, "  {line}");
            }
        }
        Err(e) => {
            let _ = writeln!(o, "  (no advice: {e})");
        }
    }
    crate::emit(&o);
    Ok(ExitCode::SUCCESS)
}
