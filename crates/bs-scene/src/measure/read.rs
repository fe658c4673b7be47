//! The `[[measurement]]` tables resolved at preparation: files read, the node set turned
//! into the patch of boundary faces a scan is matched on, and everything checked that can
//! be checked before solving (so `check` refuses what `run` would): an empty or unreadable
//! cloud, a node set off the boundary or already prescribed, bone points without a skull,
//! and data in the wrong frame or units (no point near the patch: every point would be an
//! outlier).

use std::path::Path;

use bs_contact::Patch;
use bs_mesh::{Mesh, Point3, TriSurface};

use super::{Measured, MeasuredData};
use crate::SceneError;
use crate::boundary::{Prescribed, names};
use crate::scene::{DEFAULT_MEASUREMENT_DISTANCE_MM, LandmarkFiles, Measurement, Scene};

/// Reads and checks every measurement of `scene` on `mesh`; `prescribed` are the
/// boundaries' components (a fitted node must be free).
pub(crate) fn read_measurements(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    prescribed: &Prescribed,
    skull: Option<&TriSurface>,
) -> Result<Vec<Measured>, SceneError> {
    check_combination(sp, scene)?;
    scene
        .measurements
        .iter()
        .enumerate()
        .map(|(i, m)| read_one(sp, scene, mesh, prescribed, skull, i, m))
        .collect()
}

/// Landmarks fitted alone go through their node set; beside a scan, or alone without a set,
/// they are evidence for gravity's unknowns (a scan pulls the boundary; alone, the answer
/// is the model at the estimate), so they need `[gravity] estimate`. Two landmark
/// measurements are one: their files are merged.
fn check_combination(sp: &Path, scene: &Scene) -> Result<(), SceneError> {
    let err = |i: usize, key: &str, message: &str| SceneError::Read {
        scene: sp.to_path_buf(),
        key: format!("[[measurement]] #{} {key}", i + 1),
        message: message.into(),
    };
    let scans = scene.measurements.iter().filter(|m| m.points.is_some()).count();
    let landmarks: Vec<usize> = (0..scene.measurements.len())
        .filter(|&i| scene.measurements[i].landmarks.is_some())
        .collect();
    if landmarks.len() > 1 {
        return Err(err(
            landmarks[1],
            "landmarks",
            "one landmark measurement per scene: merge the pair files into one",
        ));
    }
    let Some(&i) = landmarks.first() else { return Ok(()) };
    let m = &scene.measurements[i];
    let estimates = scene.gravity.as_ref().is_some_and(|g| g.estimate.is_some());
    match (scans, &m.nset) {
        (0, None) if !estimates => Err(err(
            i,
            "nset",
            "landmarks fitted alone need nset: the boundary nodes the shift comes through \
             (e.g. nset = \"CRANIOTOMY\"); the fit finds their displacement. Or, with \
             [gravity] estimate = { level = … }, landmarks without nset are evidence for \
             gravity's unknowns and nothing is prescribed",
        )),
        (0, None) => Ok(()),
        (0, Some(_)) => Ok(()),
        (_, Some(_)) => Err(err(
            i,
            "nset",
            "landmarks beside a scan name no nset: the scan pulls the boundary, and the \
             landmarks are evidence for gravity's unknowns ([gravity] estimate); remove nset, \
             or fit the landmarks alone",
        )),
        (_, None) if !estimates => Err(err(
            i,
            "landmarks",
            "landmarks beside a scan are evidence for gravity's unknowns: add [gravity] with \
             estimate = { level = … }, or fit the landmarks alone (their springs beside a \
             scan made the fit worse than the scan alone on one draw of three, \
             docs/decisions.md)",
        )),
        (_, None) => Ok(()),
    }
}

fn read_one(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    prescribed: &Prescribed,
    skull: Option<&TriSurface>,
    i: usize,
    m: &Measurement,
) -> Result<Measured, SceneError> {
    let key = |k: &str| format!("[[measurement]] #{} {k}", i + 1);
    let max_distance =
        m.max_distance.unwrap_or(DEFAULT_MEASUREMENT_DISTANCE_MM * 1e-3 / scene.units.metres());
    let nset = m.nset.clone().unwrap_or_default();
    let Some(file) = &m.points else {
        let files = m.landmarks.clone().expect("validated: points or landmarks");
        if m.nset.is_some() {
            control_nodes(sp, scene, mesh, prescribed, &key("nset"), &nset)?;
        }
        let data = read_landmarks(sp, scene, mesh, &key("landmarks"), files)?;
        return Ok(Measured { index: i, nset, sigma: m.sigma, max_distance, rigid: false, data });
    };
    let (faces, face_elements) = patch_faces(sp, scene, mesh, prescribed, &key("nset"), &nset)?;
    let points = read_cloud(sp, &key("points"), file)?;
    check_frame(sp, scene, mesh, &key("points"), file, &points, &faces, max_distance)?;
    let bone = match &m.skull_points {
        None => None,
        Some(f) => {
            if skull.is_none() {
                return Err(SceneError::Read {
                    scene: sp.to_path_buf(),
                    key: key("skull_points"),
                    message: "bone points are registered to the skull, but the scene has no \
                              [contact] skull; add one"
                        .into(),
                });
            }
            Some((f.clone(), read_cloud(sp, &key("skull_points"), f)?))
        }
    };
    Ok(Measured {
        index: i,
        nset,
        sigma: m.sigma,
        max_distance,
        rigid: m.rigid,
        data: MeasuredData::Surface {
            file: file.clone(),
            points,
            faces,
            face_elements,
            bone,
            slide: match m.sliding_with(scene.gravity.is_some()) {
                crate::scene::Sliding::Free => None,
                crate::scene::Sliding::Resisted => {
                    Some(m.sag_direction.map(|d| bs_mesh::Vector3::from(d).normalize()))
                }
            },
        },
    })
}

/// Landmarks farther than this outside the mesh (mm) are refused: a landmark picked on the
/// brain's surface in the image may lie a voxel outside the meshed surface, not more.
const LANDMARK_OUTSIDE_MM: f64 = 1.0;

/// Landmark pairs read into the scene's frame, each pre-operative position located in its
/// tetrahedron (its material point); one outside the brain is an error naming its line.
fn read_landmarks(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    key: &str,
    files: LandmarkFiles,
) -> Result<MeasuredData, SceneError> {
    let pairs = super::pairs::read_pairs(&files, scene.space).map_err(|message| {
        SceneError::Read { scene: sp.to_path_buf(), key: key.to_string(), message }
    })?;
    let anchors = locate_landmarks(sp, scene, mesh, key, &files, &pairs)?;
    Ok(MeasuredData::Landmarks { files, pairs, anchors })
}

/// Each pre-operative position of `pairs` (read from `files`) located in its tetrahedron:
/// the element and its material point there; one more than [`LANDMARK_OUTSIDE_MM`] outside
/// the mesh is an error naming its line or label.
pub(crate) fn locate_landmarks(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    key: &str,
    files: &LandmarkFiles,
    pairs: &super::pairs::Pairs,
) -> Result<Vec<(usize, bs_fit::Anchor)>, SceneError> {
    let err = |message: String| SceneError::Read {
        scene: sp.to_path_buf(),
        key: key.to_string(),
        message,
    };
    let locator = bs_mesh::TetLocator::new(mesh)
        .map_err(|e| err(format!("landmarks are located in the mesh's tetrahedra: {e}")))?;
    let tolerance = LANDMARK_OUTSIDE_MM * 1e-3 / scene.units.metres();
    let mut anchors = Vec::with_capacity(pairs.pre.len());
    for (p, origin) in pairs.pre.iter().zip(&pairs.origin) {
        let at = locator.locate(p);
        if at.distance > tolerance {
            let file = match files {
                LandmarkFiles::Pairs(f) | LandmarkFiles::Split([f, _]) => f.display(),
            };
            return Err(err(format!(
                "{file}: {origin}: the pre-operative landmark ({:.2}, {:.2}, {:.2}) lies {:.2} \
                 outside the brain mesh (at most {tolerance} is accepted): a landmark is a \
                 point of the brain; check its frame ({}) and units, or drop it",
                p.x,
                p.y,
                p.z,
                at.distance,
                scene.space.name()
            )));
        }
        let nodes = locator.element_nodes(at.element);
        anchors.push((at.element, bs_fit::Anchor { nodes, weights: at.weights }));
    }
    Ok(anchors)
}

/// The nodes of a landmark measurement's set, whose displacement the fit finds: they must
/// exist, lie on the boundary and be free of every `[[boundary]]`.
fn control_nodes(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    prescribed: &Prescribed,
    key: &str,
    name: &str,
) -> Result<(), SceneError> {
    let err = |message: String| SceneError::Set {
        scene: sp.to_path_buf(),
        key: key.to_string(),
        set: name.to_string(),
        message,
    };
    let nodes = measured_set(scene, mesh, name).map_err(err)?;
    if let Some(&n) = nodes.iter().find(|&&n| prescribed[n].iter().any(Option::is_some)) {
        return Err(err(format!(
            "node {} is also held by a [[boundary]]: the landmarks' fit decides the \
             displacement of every node of its set; take the node out of one of them",
            mesh.node_ids[n]
        )));
    }
    let boundary = mesh.boundary();
    let mut on = vec![false; mesh.nodes.len()];
    for &v in &boundary.volume_node {
        on[v] = true;
    }
    if let Some(&n) = nodes.iter().find(|&&n| !on[n]) {
        return Err(err(format!(
            "node {} is inside the brain: the landmarks' set is the boundary the shift comes \
             through (e.g. the craniotomy's exposed nodes)",
            mesh.node_ids[n]
        )));
    }
    Ok(())
}

/// `prescribed` with every node of a landmark measurement's set prescribed in all three
/// components (at zero until the fit sets them): the solver's preparation holds them, the
/// fit changes their values.
pub(crate) fn control(
    mesh: &Mesh,
    mut prescribed: Prescribed,
    measurements: &[Measured],
) -> Prescribed {
    for m in measurements {
        if let MeasuredData::Landmarks { .. } = m.data
            && let Some(nodes) = mesh.node_set(&m.nset)
        {
            for &n in nodes {
                prescribed[n] = [Some(0.0); 3];
            }
        }
    }
    prescribed
}

/// The nodes of node set `name`, or the message naming the sets the mesh has.
fn measured_set<'m>(scene: &Scene, mesh: &'m Mesh, name: &str) -> Result<&'m [usize], String> {
    mesh.node_set(name).ok_or_else(|| {
        format!(
            "no such node set in {} (it has: {})",
            scene.mesh.file.display(),
            names(mesh.node_sets.keys())
        )
    })
}

/// A point cloud, refused when empty.
fn read_cloud(sp: &Path, key: &str, file: &Path) -> Result<Vec<Point3<f64>>, SceneError> {
    let err = |message: String| SceneError::Read {
        scene: sp.to_path_buf(),
        key: key.to_string(),
        message,
    };
    let points = bs_mesh::io::points::read_points(file).map_err(|e| err(e.to_string()))?;
    if points.is_empty() {
        return Err(err(format!("{}: the file holds no points", file.display())));
    }
    Ok(points)
}

/// The boundary faces whose three nodes are in the node set `name` (outward triangles of
/// mesh node indices) and the element of each; errors when the set is unknown, off the
/// boundary, or holds prescribed nodes.
fn patch_faces(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    prescribed: &Prescribed,
    key: &str,
    name: &str,
) -> Result<(Vec<[usize; 3]>, Vec<usize>), SceneError> {
    let err = |message: String| SceneError::Set {
        scene: sp.to_path_buf(),
        key: key.to_string(),
        set: name.to_string(),
        message,
    };
    let nodes = measured_set(scene, mesh, name).map_err(err)?;
    let mut member = vec![false; mesh.nodes.len()];
    for &n in nodes {
        member[n] = true;
    }
    // A symmetry plane may hold a component at zero; a node moved by a boundary, or held in
    // every direction, is the boundary's, not the data's.
    let taken = |c: &[Option<f64>; 3]| {
        c.iter().all(Option::is_some) || c.iter().flatten().any(|v| *v != 0.0)
    };
    if let Some(&n) = nodes.iter().find(|&&n| taken(&prescribed[n])) {
        return Err(err(format!(
            "node {} is also moved or held by a [[boundary]]: a measurement pulls free nodes \
             (the fit decides where they go); take the measured nodes out of the boundary's set",
            mesh.node_ids[n]
        )));
    }
    let boundary = mesh.boundary();
    let mut faces = Vec::new();
    let mut elements = Vec::new();
    for (t, &e) in boundary.surface.triangles.iter().zip(&boundary.element) {
        let f = t.map(|k| boundary.volume_node[k]);
        if f.iter().all(|&n| member[n]) {
            faces.push(f);
            elements.push(e);
        }
    }
    if faces.is_empty() {
        return Err(err(format!(
            "no boundary face of {} has all three nodes in the set: a measurement's node set \
             must be a patch of the brain's surface (e.g. the craniotomy's exposed nodes)",
            scene.mesh.file.display()
        )));
    }
    Ok((faces, elements))
}

/// Refuses data of which no point lies within `max_distance` of the patch (reference
/// configuration): a scan in the wrong frame or units, where every point would be an
/// outlier. Says which reading would fit: LPS ↔ RAS, or metres.
#[allow(clippy::too_many_arguments)]
pub(crate) fn check_frame(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    key: &str,
    file: &Path,
    points: &[Point3<f64>],
    faces: &[[usize; 3]],
    max_distance: f64,
) -> Result<(), SceneError> {
    let mut local = std::collections::HashMap::new();
    let mut vertices = Vec::new();
    let tris: Vec<[u32; 3]> = faces
        .iter()
        .map(|f| {
            f.map(|a| {
                *local.entry(a).or_insert_with(|| {
                    vertices.push(mesh.nodes[a]);
                    (vertices.len() - 1) as u32
                })
            })
        })
        .collect();
    let patch = Patch::new(vertices, tris);
    let near = |map: &dyn Fn(&Point3<f64>) -> Point3<f64>| {
        points.iter().filter(|p| patch.closest(&map(p), max_distance).is_some()).count()
    };
    if near(&|p| *p) > 0 {
        return Ok(());
    }
    let nearest = points
        .iter()
        .filter_map(|p| patch.closest(p, f64::INFINITY))
        .map(|q| q.distance)
        .fold(f64::INFINITY, f64::min);
    let mut hints = Vec::new();
    let other = match scene.space {
        bs_image::Space::Ras => bs_image::Space::Lps,
        bs_image::Space::Lps => bs_image::Space::Ras,
    };
    let flipped = near(&|p| scene.space.convert_point(other, *p));
    if flipped > 0 {
        let other = other.name();
        hints.push(format!(
            "read as {other} (x and y negated) {flipped} of them would be: convert the scan to \
             the scene's frame"
        ));
    }
    for (factor, what) in [(1e3, "metres"), (1e-3, "micrometres")] {
        let scaled = near(&|p| Point3::from(p.coords * factor));
        if scaled > 0 {
            hints.push(format!(
                "scaled from {what} to the scene's unit {scaled} of them would be: convert it"
            ));
        }
    }
    let hint = if hints.is_empty() {
        "check the scan's frame (the scene is ".to_string()
            + scene.space.name()
            + ") and units, and the node set"
    } else {
        hints.join("; ")
    };
    Err(SceneError::Read {
        scene: sp.to_path_buf(),
        key: key.to_string(),
        message: format!(
            "{}: none of its {} points lies within max_distance = {max_distance} of the \
             measured patch (the nearest is {nearest:.1} away): every point would be an \
             outlier; {hint}",
            file.display(),
            points.len()
        ),
    })
}

/// The data an `estimate` needs: a scan, or landmarks (beside a scan, alone as evidence,
/// or fitted through their set with gravity's unknowns: crate::landmark_fit).
pub(crate) fn check_estimate_data(
    e: &crate::scene::Estimate,
    measurements: &[super::Measured],
) -> Result<(), String> {
    let names = e.named().iter().map(|(k, _)| *k).collect::<Vec<_>>().join(", ");
    if measurements.is_empty() {
        return Err(format!(
            "[gravity] estimate ({names}) needs data: without a [[measurement]] nothing tells \
             the parameters from their prior. Add a scan ([[measurement]] points = …) or \
             remove estimate to solve with the scene's values"
        ));
    }
    Ok(())
}
