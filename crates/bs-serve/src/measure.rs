//! What a received message asks of the session: its type and device name read as
//! docs/operating-room.md's table says, its content turned into a typed [`Update`] in the
//! scene's frame and unit, or stored (a client's pre-operative landmarks), or refused with
//! the reason a user can act on. Nothing here solves.

use std::collections::HashMap;

use bs_igtl::{Message, Points, PolyData, Text};
use bs_mesh::{TriSurface, Vector3};
use bs_scene::{BoundaryValues, Update};

use crate::frame::Frame;

/// What the session offers the messages, read when a message arrives.
#[derive(Debug, Clone)]
pub struct Offer {
    /// The scene's frame and unit.
    pub frame: Frame,
    /// The prescribed node set measurements move (`--set`), if any.
    pub set: Option<String>,
    /// Its node ids in set order (the rows of `Displacements`).
    pub set_ids: Vec<u64>,
    /// The node sets of the scene's scanned-surface measurements.
    pub measured: Vec<String>,
    /// The regions still in the model.
    pub regions: Vec<String>,
    /// Whether the scene has a `[gravity]` to turn.
    pub gravity: bool,
}

/// Pre-operative landmarks a client sent (RAS mm), with their names.
#[derive(Debug, Clone, PartialEq)]
pub struct Preop {
    /// Positions.
    pub points: Vec<[f64; 3]>,
    /// Names (may be empty).
    pub names: Vec<String>,
}

/// What a message asks.
#[derive(Debug, Clone, PartialEq)]
pub enum Asked {
    /// Solve these updates; the line says what came.
    Update(Vec<Update>, String),
    /// Kept for a later message (pre-operative landmarks).
    Stored(Preop, String),
    /// Nothing to do (STATUS, a query).
    Nothing(String),
}

/// The types and devices this server takes, for the answer to any other.
pub const TAKES: &str = "it takes POLYDATA 'IntraopSurface', POINT 'PreopLandmarks' + \
    'IntraopLandmarks', STRING 'Displacements', POINT/POLYDATA 'IntraopPoints' (a scan to \
    fit), STRING 'Gravity' (x,y,z in RAS) or STRING 'Resect' (a region)";

/// What `m` asks, given what the session offers and the client's stored pre-operative
/// landmarks; `Err` is the answer's text.
pub fn asked(offer: &Offer, preop: Option<&Preop>, m: &Message) -> Result<Asked, String> {
    let h = &m.header;
    let what = h.to_string();
    let read = |e: bs_igtl::ContentError| format!("{what}: {e}");
    if h.kind == "STATUS" || bs_igtl::Verb::of(&h.kind).is_some() {
        return Ok(Asked::Nothing(format!("  {what}: a status or query message: nothing to do")));
    }
    match (h.kind.as_str(), h.device.as_str()) {
        ("POINT" | "POLYDATA", "IntraopPoints") => {
            let Some(set) = offer.measured.first() else {
                return Err(format!(
                    "{what}: the scene has no [[measurement]] with points to fit \
                     (IntraopSurface imposes a surface)"
                ));
            };
            let points = if h.kind == "POINT" {
                positions(&m.read::<Points>().map_err(read)?, &what)?
            } else {
                let p = m.read::<PolyData>().map_err(read)?;
                p.points.iter().map(|q| q.map(f64::from)).collect()
            };
            finite(&points, &what)?;
            let line = format!("  {what}: {} scanned points for {set}", points.len());
            let points = points.iter().map(|&q| offer.frame.to_scene(q)).collect();
            Ok(Asked::Update(vec![Update::Scan { set: set.clone(), points }], line))
        }
        ("STRING", "Resect") => {
            let region = text(m, &what)?.trim().to_string();
            if !offer.regions.contains(&region) {
                return Err(format!(
                    "{what}: '{region}' is not a region still in the model; the regions are: {}",
                    offer.regions.join(", ")
                ));
            }
            let line = format!("  {what}: resecting {region}");
            Ok(Asked::Update(vec![Update::Resect(region)], line))
        }
        ("STRING", "Gravity") => {
            let d = gravity(&text(m, &what)?, &what)?;
            if !offer.gravity {
                return Err(format!("{what}: the scene has no [gravity] to turn"));
            }
            let line = format!("  {what}: gravity turned to RAS ({}, {}, {})", d.x, d.y, d.z);
            Ok(Asked::Update(vec![Update::Gravity(offer.frame.direction_to_scene(d))], line))
        }
        _ => boundary(offer, preop, m),
    }
}

/// The messages on the prescribed set (`--set`).
fn boundary(offer: &Offer, preop: Option<&Preop>, m: &Message) -> Result<Asked, String> {
    let h = &m.header;
    let what = h.to_string();
    let read = |e: bs_igtl::ContentError| format!("{what}: {e}");
    let known = matches!(
        (h.kind.as_str(), h.device.as_str()),
        ("POLYDATA", "IntraopSurface")
            | ("POINT", "PreopLandmarks" | "IntraopLandmarks")
            | ("STRING", "Displacements")
    );
    if !known {
        return Err(format!("{what}: not a measurement this server takes; {TAKES}"));
    }
    let Some(set) = offer.set.clone() else {
        return Err(format!(
            "{what}: the scene prescribes no node set to move; it takes POINT or POLYDATA \
             'IntraopPoints' (or STRING 'Gravity')"
        ));
    };
    match (h.kind.as_str(), h.device.as_str()) {
        ("POLYDATA", "IntraopSurface") => {
            let p = m.read::<PolyData>().map_err(read)?;
            let s = surface(offer, &p, &what)?;
            let line =
                format!("  {what}: {} points, {} triangles", s.vertices.len(), s.triangles.len());
            let values = BoundaryValues::Surface(s);
            Ok(Asked::Update(vec![Update::Boundary { set, values }], line))
        }
        ("POINT", "PreopLandmarks") => {
            let p = m.read::<Points>().map_err(read)?;
            let points = positions(&p, &what)?;
            finite(&points, &what)?;
            let names = p.points.iter().map(|q| q.name.clone()).collect();
            let line = format!("  {what}: {} pre-operative landmarks kept", points.len());
            Ok(Asked::Stored(Preop { points, names }, line))
        }
        ("POINT", "IntraopLandmarks") => {
            let Some(pre) = preop else {
                return Err(format!(
                    "{what}: send POINT 'PreopLandmarks' first (the pairs' pre-operative positions)"
                ));
            };
            let p = m.read::<Points>().map_err(read)?;
            let intra = positions(&p, &what)?;
            finite(&intra, &what)?;
            let names: Vec<String> = p.points.iter().map(|q| q.name.clone()).collect();
            let (pre, intra) = pair(pre, &intra, &names, &what)?;
            let line = format!("  {what}: {} landmark pairs", intra.len());
            let to = |v: &[[f64; 3]]| v.iter().map(|&q| offer.frame.to_scene(q)).collect();
            Ok(Asked::Update(
                vec![Update::Landmarks { set, pre: to(&pre), intra: to(&intra) }],
                line,
            ))
        }
        _ => {
            let d = displacements_of_csv(&text(m, &what)?, &offer.set_ids, &what)?;
            let line = format!("  {what}: {} node displacements", d.len());
            let values = BoundaryValues::PerNode(d);
            Ok(Asked::Update(vec![Update::Boundary { set, values }], line))
        }
    }
}

fn text(m: &Message, what: &str) -> Result<String, String> {
    Ok(m.read::<Text>().map_err(|e| format!("{what}: {e}"))?.text())
}

fn positions(p: &Points, what: &str) -> Result<Vec<[f64; 3]>, String> {
    if p.points.is_empty() {
        return Err(format!("{what}: no points"));
    }
    Ok(p.points.iter().map(|q| q.position.map(f64::from)).collect())
}

fn finite(points: &[[f64; 3]], what: &str) -> Result<(), String> {
    match points.iter().position(|q| !q.iter().all(|x| x.is_finite())) {
        Some(i) => Err(format!("{what}: point {} is not finite", i + 1)),
        None => Ok(()),
    }
}

/// The measured surface (scene frame and unit): polygons fanned, strips split.
fn surface(offer: &Offer, p: &PolyData, what: &str) -> Result<TriSurface, String> {
    let triangles = p.triangles();
    if triangles.is_empty() {
        return Err(format!("{what}: no triangles (polygons or triangle strips) to measure with"));
    }
    if p.points.is_empty() {
        return Err(format!("{what}: no points"));
    }
    let points: Vec<[f64; 3]> = p.points.iter().map(|q| q.map(f64::from)).collect();
    finite(&points, what)?;
    let vertices = points.iter().map(|&q| offer.frame.to_scene(q)).collect();
    let triangles = triangles.iter().map(|t| t.map(|k| k as usize)).collect();
    Ok(TriSurface::new(vertices, triangles))
}

/// Gravity's direction from `x,y,z` (RAS; any length but zero).
pub fn gravity(text: &str, what: &str) -> Result<Vector3<f64>, String> {
    let parsed: Result<Vec<f64>, _> = text.split(',').map(|c| c.trim().parse::<f64>()).collect();
    match parsed {
        Ok(v) if v.len() == 3 && v.iter().all(|x| x.is_finite()) && v.iter().any(|&x| x != 0.0) => {
            Ok(Vector3::new(v[0], v[1], v[2]))
        }
        _ => Err(format!(
            "{what}: {text:?} is not a direction: send three numbers x,y,z in RAS, not all zero \
             (a supine patient: 0,-1,0)"
        )),
    }
}

/// Points in RAS mm.
type Positions = Vec<[f64; 3]>;

/// Landmark pairs: by name when both lists have the same unique non-empty names, else by
/// order (then the counts must agree).
pub fn pair(
    pre: &Preop,
    intra: &[[f64; 3]],
    names: &[String],
    what: &str,
) -> Result<(Positions, Positions), String> {
    let unique = |n: &[String]| {
        let mut v: Vec<&String> = n.iter().collect();
        v.sort();
        v.dedup();
        v.len() == n.len() && n.iter().all(|x| !x.is_empty())
    };
    if unique(names) && unique(&pre.names) && names.len() == pre.names.len() {
        let index: HashMap<&str, usize> =
            pre.names.iter().enumerate().map(|(k, n)| (n.as_str(), k)).collect();
        if let Some(order) =
            names.iter().map(|n| index.get(n.as_str()).copied()).collect::<Option<Vec<_>>>()
        {
            return Ok((order.iter().map(|&k| pre.points[k]).collect(), intra.to_vec()));
        }
    }
    if pre.points.len() != intra.len() {
        return Err(format!(
            "{what}: {} intra-operative landmarks for {} pre-operative ones (pairs are matched \
             by name when both lists have the same names, else by order)",
            intra.len(),
            pre.points.len()
        ));
    }
    Ok((pre.points.clone(), intra.to_vec()))
}

/// Displacements in set order from CSV rows `node_id,ux,uy,uz` (a header line first), one
/// per node of the set.
pub fn displacements_of_csv(
    text: &str,
    set_ids: &[u64],
    what: &str,
) -> Result<Vec<Vector3<f64>>, String> {
    let index: HashMap<u64, usize> = set_ids.iter().enumerate().map(|(k, &i)| (i, k)).collect();
    let mut d: Vec<Option<Vector3<f64>>> = vec![None; set_ids.len()];
    for (l, line) in text.lines().enumerate().skip(1) {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let bad = || {
            format!("{what} line {}: expected node_id,ux,uy,uz with numbers, found '{line}'", l + 1)
        };
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 4 {
            return Err(bad());
        }
        let node: u64 = f[0].parse().map_err(|_| bad())?;
        let u: Vec<f64> =
            f[1..].iter().map(|x| x.parse::<f64>()).collect::<Result<_, _>>().map_err(|_| bad())?;
        if !u.iter().all(|x| x.is_finite()) {
            return Err(bad());
        }
        let k = *index.get(&node).ok_or_else(|| {
            format!("{what} line {}: node {node} is not in the measured node set", l + 1)
        })?;
        d[k] = Some(Vector3::new(u[0], u[1], u[2]));
    }
    let missing: Vec<usize> = (0..d.len()).filter(|&k| d[k].is_none()).collect();
    if let Some(&first) = missing.first() {
        return Err(format!(
            "{what}: {} nodes of the set have no row (first: node {}); every node of the set \
             needs one",
            missing.len(),
            set_ids[first]
        ));
    }
    Ok(d.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn landmarks_pair_by_name_else_by_order() {
        let pre = Preop {
            points: (0..4).map(|k| [k as f64; 3]).collect(),
            names: ["a", "b", "c", "d"].map(String::from).to_vec(),
        };
        let intra: Vec<[f64; 3]> = [2, 0, 3, 1].iter().map(|&k| [k as f64 + 1.0; 3]).collect();
        let names = ["c", "a", "d", "b"].map(String::from).to_vec();
        let (a, b) = pair(&pre, &intra, &names, "x").unwrap();
        assert!(a.iter().zip(&b).all(|(p, q)| q[0] - p[0] == 1.0));
        let unnamed = vec![String::new(); 4];
        let (a, _) =
            pair(&Preop { names: unnamed.clone(), ..pre.clone() }, &intra, &unnamed, "x").unwrap();
        assert_eq!(a, pre.points);
        let e = pair(&pre, &intra[..3], &names[..3], "x").unwrap_err();
        assert!(e.contains("3 intra-operative landmarks for 4"), "{e}");
    }

    #[test]
    fn displacement_rows_in_set_order() {
        let ids = [7, 3, 9];
        let d = displacements_of_csv("node_id,ux,uy,uz\n9,1,2,3\n7,4,5,6\n\n3,7,8,9\n", &ids, "m")
            .unwrap();
        assert_eq!(
            d,
            [Vector3::new(4.0, 5.0, 6.0), Vector3::new(7.0, 8.0, 9.0), Vector3::new(1.0, 2.0, 3.0)]
        );
        let e = displacements_of_csv("h\n5,0,0,0\n", &ids, "m").unwrap_err();
        assert!(e.contains("line 2: node 5 is not in the measured node set"), "{e}");
        let e = displacements_of_csv("h\n9,0,0,0\n", &ids, "m").unwrap_err();
        assert!(e.contains("2 nodes of the set have no row"), "{e}");
        let e = displacements_of_csv("h\n9,0,0,nan\n", &ids, "m").unwrap_err();
        assert!(e.contains("line 2: expected node_id,ux,uy,uz"), "{e}");
    }

    #[test]
    fn gravity_is_three_numbers_not_all_zero() {
        assert_eq!(gravity("0, -1,0", "g").unwrap(), Vector3::new(0.0, -1.0, 0.0));
        for bad in ["0,0,0", "1,2", "x,y,z", "1,2,inf"] {
            assert!(gravity(bad, "g").unwrap_err().contains("not a direction"), "{bad}");
        }
    }
}
