//! Loads from intra-operative data, alternatives to a typed displacement in `[[boundary]]`:
//! an intra-operative surface (each selected node moves to its closest point on it, found
//! through bs-contact's bucket grid of the surface's triangles, `Patch`) and landmark pairs (the selected nodes move
//! by bs-mesh's thin-plate spline of the landmark displacements). Both are in the mesh's
//! frame and units. Nodes too far from the data are errors listing them, never silently
//! extrapolated.

use std::path::Path;

use bs_mesh::tps::ThinPlateSpline;
use bs_mesh::{Mesh, Point3, TriSurface, Vector3};

use crate::SceneError;

/// How many offending nodes an error lists.
const LIST: usize = 8;

fn list(rows: &[(u64, f64)]) -> String {
    let v: Vec<String> =
        rows.iter().take(LIST).map(|(n, d)| format!("node {n} ({d:.3})")).collect();
    format!("{}{}", v.join(", "), if rows.len() > LIST { ", ..." } else { "" })
}

/// The displacement of each of `nodes` to its closest point on the surface in `file`.
pub(crate) fn surface_displacements(
    sp: &Path,
    i: usize,
    file: &Path,
    mesh: &Mesh,
    nodes: &[usize],
    max_distance: f64,
) -> Result<Vec<Vector3<f64>>, SceneError> {
    let key = format!("[[boundary]] #{} surface", i + 1);
    let surface = bs_mesh::io::read_surface(file).map_err(|e| SceneError::Read {
        scene: sp.to_path_buf(),
        key: key.clone(),
        message: e.to_string(),
    })?;
    let label = file.display().to_string();
    surface_moves(sp, key, &label, &surface, mesh, nodes, max_distance)
}

/// The displacement of each of `nodes` to its closest point on `surface` (in memory;
/// `label` names it in messages), found through bs-contact's bucket grid of its
/// triangles ([`bs_contact::Patch`]): exact, ties to the lowest triangle.
pub(crate) fn surface_moves(
    sp: &Path,
    key: String,
    label: &str,
    surface: &TriSurface,
    mesh: &Mesh,
    nodes: &[usize],
    max_distance: f64,
) -> Result<Vec<Vector3<f64>>, SceneError> {
    let v = &surface.vertices;
    let bad_index = surface.triangles.iter().flatten().any(|&k| k >= v.len());
    if surface.triangles.is_empty()
        || bad_index
        || v.iter().any(|p| !p.iter().all(|x| x.is_finite()))
    {
        return Err(SceneError::Read {
            scene: sp.to_path_buf(),
            key,
            message: format!(
                "{label}: the surface has no triangles, a triangle naming a missing vertex, or a \
                 non-finite vertex"
            ),
        });
    }
    let triangles = surface.triangles.iter().map(|t| t.map(|k| k as u32)).collect();
    let patch = bs_contact::Patch::new(v.clone(), triangles);
    let mut moves = Vec::with_capacity(nodes.len());
    let mut far = Vec::new();
    for &n in nodes {
        let p = mesh.nodes[n];
        let Some(q) = patch.closest(&p, f64::INFINITY) else {
            far.push((mesh.node_ids[n], f64::INFINITY));
            moves.push(Vector3::zeros());
            continue;
        };
        if q.distance > max_distance {
            far.push((mesh.node_ids[n], q.distance));
        }
        moves.push(q.point - p);
    }
    too_far(
        sp,
        key,
        label,
        nodes.len(),
        far,
        &format!("are farther than max_distance = {max_distance} from the surface"),
        "check the surface's frame and units, or select only the exposed nodes",
    )?;
    Ok(moves)
}

/// Landmarks: pre-operative positions and their displacements.
type Landmarks = (Vec<Point3<f64>>, Vec<Vector3<f64>>);

/// Landmark pairs read from a CSV with header `x,y,z,x2,y2,z2`.
pub(crate) fn read_landmarks(sp: &Path, key: &str, file: &Path) -> Result<Landmarks, SceneError> {
    let read = |message: String| SceneError::Read {
        scene: sp.to_path_buf(),
        key: key.to_string(),
        message: format!("{}: {message}", file.display()),
    };
    let text = std::fs::read_to_string(file).map_err(|e| read(e.to_string()))?;
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let header: Vec<String> = lines
        .next()
        .map(|(_, h)| h.split(',').map(|s| s.trim().to_ascii_lowercase()).collect())
        .unwrap_or_default();
    if header != ["x", "y", "z", "x2", "y2", "z2"] {
        return Err(read(
            "line 1: the header must be x,y,z,x2,y2,z2 (pre-operative, then intra-operative \
             position)"
                .into(),
        ));
    }
    let (mut points, mut moves) = (Vec::new(), Vec::<Vector3<f64>>::new());
    let mut lines_of = Vec::new();
    for (l, line) in lines {
        let v: Vec<f64> = line.split(',').filter_map(|s| s.trim().parse().ok()).collect();
        if v.len() != 6 || line.split(',').count() != 6 {
            return Err(read(format!("line {}: expected 6 numbers, found '{line}'", l + 1)));
        }
        if !v.iter().all(|x| x.is_finite()) {
            return Err(read(format!("line {}: a coordinate is not finite: '{line}'", l + 1)));
        }
        let p = Point3::new(v[0], v[1], v[2]);
        if let Some(k) = points.iter().position(|q: &Point3<f64>| (q - p).norm() == 0.0) {
            return Err(read(format!(
                "line {}: the pre-operative point repeats line {}; each landmark once",
                l + 1,
                lines_of[k]
            )));
        }
        points.push(p);
        moves.push(Vector3::new(v[3], v[4], v[5]) - p.coords);
        lines_of.push(l + 1);
    }
    Ok((points, moves))
}

/// The thin-plate spline of the landmark displacements at each of `nodes`. A node farther
/// than `max_extrapolation` outside the landmarks' (pre-operative) bounding box is an error.
pub(crate) fn landmark_displacements(
    sp: &Path,
    i: usize,
    file: &Path,
    mesh: &Mesh,
    nodes: &[usize],
    max_extrapolation: f64,
) -> Result<Vec<Vector3<f64>>, SceneError> {
    let key = format!("[[boundary]] #{} landmarks", i + 1);
    let (points, moves) = read_landmarks(sp, &key, file)?;
    let tps = ThinPlateSpline::fit(&points, &moves).map_err(|e| SceneError::Read {
        scene: sp.to_path_buf(),
        key: key.clone(),
        message: format!("{}: {e}", file.display()),
    })?;
    let lo = points.iter().fold(Point3::from([f64::INFINITY; 3]), |a, p| a.inf(p));
    let hi = points.iter().fold(Point3::from([f64::NEG_INFINITY; 3]), |a, p| a.sup(p));
    let mut far = Vec::new();
    let mut out = Vec::with_capacity(nodes.len());
    for &n in nodes {
        let p = mesh.nodes[n];
        let outside = Vector3::from_fn(|c, _| (lo[c] - p[c]).max(p[c] - hi[c]).max(0.0));
        if outside.norm() > max_extrapolation {
            far.push((mesh.node_ids[n], outside.norm()));
        }
        out.push(tps.evaluate(&p));
    }
    too_far(
        sp,
        key,
        &file.display().to_string(),
        nodes.len(),
        far,
        &format!(
            "lie farther than max_extrapolation = {max_extrapolation} outside the landmarks' \
             bounding box"
        ),
        "add landmarks around them or select fewer nodes",
    )?;
    Ok(out)
}

/// The error for selected nodes beyond a load's distance limit (`far`: node id and
/// distance), the farthest first; `Ok` when there are none.
fn too_far(
    sp: &Path,
    key: String,
    file: &str,
    selected: usize,
    mut far: Vec<(u64, f64)>,
    what: &str,
    fix: &str,
) -> Result<(), SceneError> {
    if far.is_empty() {
        return Ok(());
    }
    far.sort_by(|a, b| b.1.total_cmp(&a.1));
    Err(SceneError::Set {
        scene: sp.to_path_buf(),
        key,
        set: file.to_string(),
        message: format!(
            "{} of {selected} selected nodes {what}: {} (distance, mesh units); {fix}",
            far.len(),
            list(&far)
        ),
    })
}
