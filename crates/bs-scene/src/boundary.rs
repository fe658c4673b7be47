//! Boundary conditions: the scene's `[[boundary]]` tables resolved to per-node prescribed
//! components. A table that prescribes nothing (an empty node set, a `GENERATE` range that
//! matches no node, an empty displacement file) is an error naming it: a dropped boundary
//! condition would silently give a wrong answer.

use std::collections::HashMap;
use std::path::Path;

use bs_mesh::Mesh;

use crate::SceneError;
use crate::scene::Scene;

/// Per node and component: the final displacement it is held at (`Some`; a fixed component
/// is held at 0, the same constraint), or free (`None`).
pub type Prescribed = Vec<[Option<f64>; 3]>;

/// Resolves every `[[boundary]]` of `scene` on `mesh`, with one line per intra-operative
/// load or set-free selection (what `check` reports: the file or selection, how many nodes,
/// the largest displacement).
pub fn resolve_boundaries_with_notes(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
) -> Result<(Prescribed, Vec<String>), SceneError> {
    let mut notes = Vec::new();
    let mut prescribed = vec![[None; 3]; mesh.nodes.len()];
    let mut set = |node: usize, c: usize, v: f64, source: &str| -> Result<(), SceneError> {
        match prescribed[node][c] {
            Some(old) if old != v => Err(SceneError::Node {
                scene: sp.to_path_buf(),
                node_id: mesh.node_ids[node],
                message: format!(
                    "component {} is prescribed twice with different values ({old} and {v}, the \
                     second from {source}); make the boundary sets disjoint",
                    ["x", "y", "z"][c]
                ),
            }),
            _ => {
                prescribed[node][c] = Some(v);
                Ok(())
            }
        }
    };
    for (i, b) in scene.boundaries.iter().enumerate() {
        if let Some(file) = &b.displacement_file {
            let rows = read_displacement_csv(sp, file, mesh)?;
            if rows.is_empty() {
                return Err(SceneError::Read {
                    scene: sp.to_path_buf(),
                    key: format!("[[boundary]] #{} displacement_file", i + 1),
                    message: format!(
                        "{}: the file prescribes no node (only a header or nothing); give one \
                         row node_id,ux,uy,uz per prescribed node",
                        file.display()
                    ),
                });
            }
            for (node, d) in rows {
                for (c, v) in d.into_iter().enumerate() {
                    set(node, c, v, &file.display().to_string())?;
                }
            }
            continue;
        }
        let (name, nodes) = select_nodes(sp, scene, mesh, i, b)?;
        let key = if b.nset.is_some() { " nset" } else { "" };
        let err = |message: String| SceneError::Set {
            scene: sp.to_path_buf(),
            key: format!("[[boundary]] #{}{key}", i + 1),
            set: name.clone(),
            message,
        };
        if nodes.is_empty() {
            let what = if b.nset.is_some() {
                "the node set selects no node of"
            } else {
                "the selection holds no boundary node of"
            };
            return Err(err(format!(
                "{what} {} (empty, its ids not in the mesh, or a sphere or mask away from the \
                 brain's surface); the boundary condition would prescribe nothing",
                scene.mesh.file.display()
            )));
        }
        let source = format!("[[boundary]] #{}", i + 1);
        if b.nset.is_none() && b.surface.is_none() && b.landmarks.is_none() {
            notes.push(format!("[[boundary]] #{} {name}: {} boundary nodes", i + 1, nodes.len()));
        }
        let measured = match (&b.surface, &b.landmarks) {
            (Some(file), _) => {
                let limit = b.max_distance.unwrap_or(mm_in_mesh_units(scene));
                let moves = crate::loads::surface_displacements(sp, i, file, mesh, &nodes, limit)?;
                let what = format!("moved to their closest points (max_distance {limit})");
                Some(("surface", file, moves, what))
            }
            (None, Some(file)) => {
                let limit = b.max_extrapolation.unwrap_or(mm_in_mesh_units(scene));
                let moves = crate::loads::landmark_displacements(sp, i, file, mesh, &nodes, limit)?;
                let what = format!("thin-plate spline (max_extrapolation {limit})");
                Some(("landmarks", file, moves, what))
            }
            (None, None) => None,
        };
        if let Some((kind, file, moves, what)) = measured {
            notes.push(format!(
                "[[boundary]] #{} {kind} {} on {name}: {} nodes {what}, largest move {:.4}",
                i + 1,
                file.display(),
                nodes.len(),
                moves.iter().map(|m| m.norm()).fold(0.0, f64::max)
            ));
            for (&n, d) in nodes.iter().zip(moves) {
                for c in 0..3 {
                    set(n, c, d[c], &source)?;
                }
            }
            continue;
        }
        let source = format!("[[boundary]] #{}", i + 1);
        for &n in &nodes {
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
    Ok((prescribed, notes))
}

/// [`crate::scene::DEFAULT_MAX_DISTANCE_MM`] in the scene's length unit.
fn mm_in_mesh_units(scene: &Scene) -> f64 {
    crate::scene::DEFAULT_MAX_DISTANCE_MM * 1e-3 / scene.units.metres()
}

/// The nodes a `[[boundary]]` selects (sorted indices) and a name for messages: its node
/// set, or the mesh's boundary nodes inside its sphere or mask.
pub(crate) fn select_nodes(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    i: usize,
    b: &crate::scene::Boundary,
) -> Result<(String, Vec<usize>), SceneError> {
    if let Some(name) = &b.nset {
        let nodes = mesh.node_set(name).ok_or_else(|| SceneError::Set {
            scene: sp.to_path_buf(),
            key: format!("[[boundary]] #{} nset", i + 1),
            set: name.clone(),
            message: format!(
                "no such node set in {} (it has: {})",
                scene.mesh.file.display(),
                names(mesh.node_sets.keys())
            ),
        })?;
        return Ok((name.clone(), nodes.to_vec()));
    }
    let surface_nodes = mesh.boundary().volume_node;
    if let Some(sphere) = &b.sphere {
        let c = bs_mesh::Point3::from(sphere.centre);
        let nodes = surface_nodes
            .into_iter()
            .filter(|&n| (mesh.nodes[n] - c).norm() <= sphere.radius)
            .collect();
        let name = format!("sphere centre {:?} radius {}", sphere.centre, sphere.radius);
        return Ok((name, nodes));
    }
    let Some(file) = &b.mask else { return Ok((String::new(), Vec::new())) };
    let mask =
        bs_image::formats::read_labels(file).map(|(v, _)| v).map_err(|e| SceneError::Read {
            scene: sp.to_path_buf(),
            key: format!("[[boundary]] #{} mask", i + 1),
            message: format!("{e}; the mask must be a NIfTI labelmap (non-zero = selected)"),
        })?;
    // Mesh frame and units → the image's world frame (NIfTI: RAS) in mm.
    let space = scene.space;
    let scale = scene.units.metres() / 1e-3;
    let nodes = surface_nodes
        .into_iter()
        .filter(|&n| {
            let p = space.convert_point(bs_image::Space::Ras, mesh.nodes[n] * scale);
            bs_image::sample::nearest(&mask, &p).is_some_and(|v| v != 0)
        })
        .collect();
    Ok((format!("mask {}", file.display()), nodes))
}

/// Reads `node_id,ux,uy,uz` rows (with a header line).
fn read_displacement_csv(
    sp: &Path,
    file: &Path,
    mesh: &Mesh,
) -> Result<Vec<(usize, [f64; 3])>, SceneError> {
    let f = file.display();
    let read = |message: String| SceneError::Read {
        scene: sp.to_path_buf(),
        key: "[[boundary]] displacement_file".into(),
        message,
    };
    let text = std::fs::read_to_string(file).map_err(|e| read(format!("{f}: {e}")))?;
    let index: HashMap<u64, usize> =
        mesh.node_ids.iter().enumerate().map(|(i, &id)| (id, i)).collect();
    let mut rows = Vec::new();
    for (l, line) in text.lines().enumerate() {
        let line = line.trim();
        if l == 0 || line.is_empty() {
            continue; // header
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let bad = || {
            read(format!("{f}:{}: expected node_id,ux,uy,uz with numbers, found '{line}'", l + 1))
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
            .ok_or_else(|| read(format!("{f}:{}: node {id} is not in the mesh", l + 1)))?;
        rows.push((node, d));
    }
    Ok(rows)
}

/// The names of a mesh's sets, for messages.
pub(crate) fn names<'a>(it: impl Iterator<Item = &'a String>) -> String {
    let mut v: Vec<&str> = it.map(String::as_str).collect();
    v.sort_unstable();
    if v.is_empty() { "no sets".into() } else { v.join(", ") }
}
