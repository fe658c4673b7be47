//! Resection: the elements of every `[[region]]` with `resected = true` leave the model
//! (their stiffness, mass and contact with them), the cavity's walls become free surfaces
//! (loaded by the region's `cavity_pressure`, a dead pressure on the walls' reference
//! area), and nodes left without an element are held where they are (they drop out of the
//! solve; the report counts them). Node numbering is kept, so results, sessions and images
//! see the same nodes. A part of the brain that the resection leaves with no held node and
//! no skull to rest on, or a resection of every element, is refused naming the part.

use std::collections::HashMap;
use std::path::Path;

use bs_mesh::{BoundarySurface, Mesh, Vector3};

use crate::SceneError;
use crate::boundary::Prescribed;
use crate::scene::Scene;

/// What a resection removed.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Resection {
    /// The resected regions' element sets.
    pub regions: Vec<String>,
    /// Elements removed.
    pub elements: usize,
    /// Nodes left without an element (held at their place).
    pub orphans: Vec<usize>,
    /// The cavity walls: triangles of the remaining mesh's boundary (volume nodes, normals
    /// out of the brain, into the cavity) that faced a removed element, with the pressure
    /// (Pa) of its region.
    pub walls: Vec<([usize; 3], f64)>,
}

/// Removes the elements of the scene's resected regions from `mesh` (element sets
/// renumbered, `region_of_element` filtered). `None` when the scene resects nothing.
pub fn apply(
    sp: &Path,
    scene: &Scene,
    mesh: &mut Mesh,
    region_of_element: &mut Vec<usize>,
) -> Result<Option<Resection>, SceneError> {
    let resected: Vec<bool> = scene.regions.iter().map(|r| r.resected).collect();
    if !resected.contains(&true) {
        return Ok(None);
    }
    let keep: Vec<bool> = region_of_element.iter().map(|&r| !resected[r]).collect();
    if !keep.contains(&true) {
        return Err(SceneError::Unsupported {
            scene: sp.to_path_buf(),
            message: format!(
                "the resection removes every element of the brain ({}): resect a part of it",
                names(scene)
            ),
        });
    }
    let before = BoundarySurface::extract(mesh);
    let pressure = |e: usize| scene.regions[region_of_element[e]].cavity_pressure.unwrap_or(0.0);
    let removed_of_node = removed_elements_of_nodes(mesh, &keep, pressure);
    let removed = filter_elements(mesh, region_of_element, &keep);
    let after = BoundarySurface::extract(mesh);
    let walls = cavity_walls(&before, &after, &removed_of_node);
    let mut used = vec![false; mesh.nodes.len()];
    mesh.elements.iter().flat_map(|e| e.nodes()).for_each(|&n| used[n] = true);
    let orphans = (0..mesh.nodes.len()).filter(|&n| !used[n]).collect();
    Ok(Some(Resection { regions: names_of(scene), elements: removed, orphans, walls }))
}

fn names_of(scene: &Scene) -> Vec<String> {
    scene.regions.iter().filter(|r| r.resected).map(|r| r.elset.clone()).collect()
}

fn names(scene: &Scene) -> String {
    names_of(scene).iter().map(|n| format!("'{n}'")).collect::<Vec<_>>().join(", ")
}

/// Per node, the removed elements it belongs to, with their cavity pressure (Pa).
fn removed_elements_of_nodes(
    mesh: &Mesh,
    keep: &[bool],
    pressure: impl Fn(usize) -> f64,
) -> HashMap<usize, Vec<(usize, f64)>> {
    let mut of: HashMap<usize, Vec<(usize, f64)>> = HashMap::new();
    for (e, el) in mesh.elements.iter().enumerate().filter(|(e, _)| !keep[*e]) {
        for &n in el.nodes() {
            of.entry(n).or_default().push((e, pressure(e)));
        }
    }
    of
}

/// Keeps the elements with `keep`, renumbering the element sets; returns how many left.
fn filter_elements(mesh: &mut Mesh, region_of_element: &mut Vec<usize>, keep: &[bool]) -> usize {
    let mut new_index = vec![usize::MAX; keep.len()];
    let mut k = 0;
    for (e, &kept) in keep.iter().enumerate() {
        if kept {
            new_index[e] = k;
            k += 1;
        }
    }
    retain_kept(&mut mesh.elements, keep);
    retain_kept(&mut mesh.element_ids, keep);
    retain_kept(region_of_element, keep);
    for members in mesh.element_sets.values_mut() {
        *members = members.iter().map(|&e| new_index[e]).filter(|&e| e != usize::MAX).collect();
    }
    keep.len() - k
}

/// Keeps the entries `i` of `v` with `keep[i]`.
fn retain_kept<T>(v: &mut Vec<T>, keep: &[bool]) {
    let mut i = 0;
    v.retain(|_| {
        i += 1;
        keep[i - 1]
    });
}

/// The triangles of `after` that are not in `before` (the cavity's walls), each with the
/// pressure of the removed element that held its three nodes.
fn cavity_walls(
    before: &BoundarySurface,
    after: &BoundarySurface,
    removed_of_node: &HashMap<usize, Vec<(usize, f64)>>,
) -> Vec<([usize; 3], f64)> {
    let key = |b: &BoundarySurface, t: &[usize; 3]| {
        let mut k = t.map(|v| b.volume_node[v]);
        k.sort_unstable();
        k
    };
    let old: std::collections::HashSet<[usize; 3]> =
        before.surface.triangles.iter().map(|t| key(before, t)).collect();
    let holds =
        |n: &usize, e: usize| removed_of_node.get(n).is_some_and(|l| l.iter().any(|x| x.0 == e));
    after
        .surface
        .triangles
        .iter()
        .filter(|t| !old.contains(&key(after, t)))
        .map(|t| {
            let nodes = t.map(|v| after.volume_node[v]);
            let pressure = removed_of_node
                .get(&nodes[0])
                .and_then(|es| es.iter().find(|(e, _)| nodes[1..].iter().all(|n| holds(n, *e))))
                .map_or(0.0, |(_, p)| *p);
            (nodes, pressure)
        })
        .collect()
}

/// Refuses a mesh with a part (elements connected through shared nodes) that has no held
/// or prescribed node while the scene has no skull to rest it on: nothing would hold it.
pub fn require_support(
    sp: &Path,
    scene: &Scene,
    mesh: &Mesh,
    prescribed: &Prescribed,
) -> Result<(), SceneError> {
    if scene.contact.is_some() {
        return Ok(());
    }
    let n = mesh.nodes.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    for el in &mesh.elements {
        let nodes = el.nodes();
        for &b in &nodes[1..] {
            let (ra, rb) = (root(&mut parent, nodes[0]), root(&mut parent, b));
            parent[ra.max(rb)] = ra.min(rb);
        }
    }
    let mut held = vec![false; n];
    // Orphan nodes (held, in no element) are parts of their own: they hold nothing.
    for (a, p) in prescribed.iter().enumerate() {
        if p.iter().any(Option::is_some) {
            let r = root(&mut parent, a);
            held[r] = true;
        }
    }
    let mut size: HashMap<usize, (usize, usize)> = HashMap::new();
    for (e, el) in mesh.elements.iter().enumerate() {
        let r = root(&mut parent, el.nodes()[0]);
        size.entry(r).or_insert((0, e)).0 += 1;
    }
    let mut parts: Vec<(usize, (usize, usize))> = size.into_iter().collect();
    parts.sort_by_key(|(_, (_, first))| *first);
    if let Some((_, (count, first))) = parts.iter().find(|(r, _)| !held[*r]) {
        return Err(SceneError::Unsupported {
            scene: sp.to_path_buf(),
            message: format!(
                "after the resection of {} a part of the brain of {count} elements (element {} \
                 among them) has no held node and there is no skull to rest on: nothing holds \
                 it; hold a node set of that part, add [contact], or resect less",
                names(scene),
                mesh.element_ids[*first]
            ),
        });
    }
    Ok(())
}

/// Holds every node that belongs to no element where it is (each free component at
/// zero): with no stiffness and no mass it would otherwise be a free, singular unknown.
pub fn hold_unused(mesh: &Mesh, prescribed: &mut Prescribed) {
    let mut used = vec![false; mesh.nodes.len()];
    mesh.elements.iter().flat_map(|e| e.nodes()).for_each(|&n| used[n] = true);
    for (p, _) in prescribed.iter_mut().zip(&used).filter(|(_, u)| !**u) {
        p.iter_mut().filter(|c| c.is_none()).for_each(|c| *c = Some(0.0));
    }
}

impl Resection {
    /// The dead nodal forces of the cavities' pressures (Pa on the walls' reference area:
    /// each triangle's `−p A n` shared equally by its nodes), added into `f`.
    pub fn add_pressure_loads(&self, mesh: &Mesh, f: &mut [Vector3<f64>]) {
        for (t, p) in &self.walls {
            if *p == 0.0 {
                continue;
            }
            let [a, b, c] = t.map(|n| mesh.nodes[n]);
            let area_normal = (b - a).cross(&(c - a)) * 0.5;
            for &n in t {
                f[n] -= area_normal * (*p / 3.0);
            }
        }
    }
}
