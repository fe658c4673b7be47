//! The paper's ellipsoid pushed 10–40 mm on every mesh of fixtures/ellipsoid (coarse,
//! medium, fine, the mesh refined under the craniotomy rim and the hexahedral one) with
//! Newton–Krylov, and the 40 mm push on the rim and hexahedral meshes with Dynamic
//! Relaxation: how far each mesh carries the load.
//! A run that stops says how far it got, in mm.

use std::collections::BTreeSet;

use crate::study::Variant;
use bs_mesh::Mesh;
use bs_scene::Prepared;
use bs_scene::scene::SolverKind;

use super::Cell;
use super::measure::{measure, measured_cell};
use crate::util::root;

/// The scenes' own craniotomy displacement (mm, along −z).
const SCENE_LOAD: f64 = 10.0;

/// The loads of every row (mm).
pub const LOADS: [f64; 4] = [10.0, 20.0, 30.0, 40.0];

/// (name, scene) of every mesh.
pub const MESHES: [(&str, &str); 5] = [
    ("coarse", "scene.toml"),
    ("medium", "scene-medium.toml"),
    ("fine", "scene-fine.toml"),
    ("rim", "scene-rim.toml"),
    ("hex", "scene-hex.toml"),
];

/// (name, scene) of the meshes with a DR row at 40 mm.
pub const DR_MESHES: [(&str, &str); 2] = [("rim", "scene-rim.toml"), ("hex", "scene-hex.toml")];

/// DR load ramps (steps) of the 40 mm rows, as in the coarse mesh's DR rows.
pub const RAMPS: [usize; 3] = [200, 800, 2000];

fn ellipsoid(scene: &str) -> Result<Prepared, String> {
    let path = root().join("fixtures/ellipsoid").join(scene);
    Prepared::load(&path).map_err(|e| format!("{}: {e}", path.display()))
}

fn in_contact(m: &super::measure::Measured) -> String {
    m.result.as_ref().map_or(String::new(), |o| format!("{} in contact", o.nodes_in_contact))
}

/// Mean length of the element edges across the rim of the node set `set` (one node in it,
/// one outside): the size of the elements a push of the set shears most.
pub fn rim_edge(mesh: &Mesh, set: &str) -> Option<f64> {
    let inside = mesh.node_sets.get(set)?;
    let mut is_in = vec![false; mesh.nodes.len()];
    inside.iter().for_each(|&i| is_in[i] = true);
    let mut edges = BTreeSet::new();
    for e in &mesh.elements {
        let n = e.nodes();
        for [a, b] in e.kind().edges() {
            let (a, b) = (n[*a], n[*b]);
            if is_in[a] != is_in[b] {
                edges.insert((a.min(b), a.max(b)));
            }
        }
    }
    let total: f64 = edges.iter().map(|&(a, b)| (mesh.nodes[a] - mesh.nodes[b]).norm()).sum();
    (!edges.is_empty()).then(|| total / edges.len() as f64)
}

/// One mesh's row: 10, 20, 30, 40 mm with Newton–Krylov.
pub fn by_mesh(cells: &mut Vec<Cell>, name: &str, scene: &str) -> Result<(), String> {
    let p = ellipsoid(scene)?;
    let edge = rim_edge(&p.mesh, "CRANIOTOMY").ok_or("the scene has no CRANIOTOMY set")?;
    let row = format!(
        "ellipsoid load by mesh, Newton-Krylov, {name} (edges across the rim {edge:.1} mm)"
    );
    for load in LOADS {
        let v = Variant {
            solver: Some(SolverKind::NewtonKrylov),
            load_factor: Some(load / SCENE_LOAD),
            ..Variant::default()
        };
        let m = measure(&v, &p);
        let note = in_contact(&m);
        cells.push(measured_cell(&row, format!("{load} mm"), &m, Some(load), note));
    }
    Ok(())
}

/// DR on one mesh at 40 mm, with the coarse rows' three load ramps.
pub fn dr_at_40mm(cells: &mut Vec<Cell>, name: &str, scene: &str) -> Result<(), String> {
    let p = ellipsoid(scene)?;
    let row = format!("ellipsoid 40 mm on the {name} mesh, DR");
    let load = LOADS[3];
    for ramp in RAMPS {
        let v = Variant {
            solver: Some(SolverKind::Dr),
            load_factor: Some(load / SCENE_LOAD),
            ramp_steps: Some(ramp),
            ..Variant::default()
        };
        let m = measure(&v, &p);
        let note = in_contact(&m);
        cells.push(measured_cell(&row, format!("ramp {ramp} steps"), &m, Some(load), note));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube split into 6 tets along its diagonal 0–6 with one corner in the set: the
    /// edges across are those from that corner, unit edges, face diagonals and the main
    /// diagonal as the split makes them.
    #[test]
    fn rim_edge_is_the_mean_edge_across_the_set() {
        let mut m = bs_mesh::structured::box_mesh(1, 1.0, true);
        let corner = (0..m.nodes.len()).find(|&i| m.nodes[i].coords.norm() == 0.0).expect("origin");
        m.node_sets.insert("S".into(), vec![corner]);
        // Brute force: every edge of every element from the corner, deduplicated.
        let mut others = BTreeSet::new();
        for e in &m.elements {
            let n = e.nodes();
            if n.contains(&corner) {
                others.extend(n.iter().copied().filter(|&j| j != corner));
            }
        }
        let mean =
            others.iter().map(|&j| m.nodes[j].coords.norm()).sum::<f64>() / others.len() as f64;
        let got = rim_edge(&m, "S").unwrap();
        assert!((got - mean).abs() < 1e-15, "{got} vs {mean}");
        assert!(rim_edge(&m, "NONE").is_none());
    }
}
