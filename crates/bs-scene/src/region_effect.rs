//! "Model no more than a scene needs", measured on the scene itself: how much each region
//! with its own material (ventricles, a tumour) changes the displacements. The scene is
//! solved as it is, then once per other region with that region's elements made part of
//! the largest region (the parenchyma: its material, and for T4ANP its volume averaging),
//! and the displacements compared. What `brainshift check --region-effect` prints;
//! docs/regions.md is the same measurement on fixtures/mni152-regions.

use bs_dr::Progress;
use bs_mesh::Vector3;

use crate::SceneError;
use crate::prepare::Prepared;
use crate::run::Run;

/// What one region changes.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionEffect {
    /// The region's element set.
    pub elset: String,
    /// Largest |u_scene − u_without| over every node, mm, and where (node id).
    pub max_mm: f64,
    pub max_node: u64,
    /// Largest and mean |u_scene − u_without| over the nodes of the region's elements, mm.
    pub region_max_mm: f64,
    pub region_mean_mm: f64,
    /// Nodes of the region's elements.
    pub region_nodes: usize,
    /// Seconds of the solve without the region.
    pub solve_seconds: f64,
}

/// The scene's solve and the effect of each region other than the largest.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionEffects {
    /// The largest region (by elements): what the others are replaced by.
    pub base: String,
    /// Largest displacement of the scene as it is, mm.
    pub max_displacement_mm: f64,
    /// Seconds of the scene's own solve.
    pub solve_seconds: f64,
    pub regions: Vec<RegionEffect>,
}

/// The region index with the most elements.
fn largest_region(p: &Prepared) -> usize {
    let mut count = vec![0usize; p.scene.regions.len()];
    p.region_of_element.iter().for_each(|&r| count[r] += 1);
    (0..count.len()).max_by_key(|&r| (count[r], std::cmp::Reverse(r))).unwrap_or(0)
}

/// `p` with the elements of region `r` made part of region `base`.
fn without_region(p: &Prepared, r: usize, base: usize) -> Prepared {
    let mut q = p.clone();
    q.region_of_element.iter_mut().filter(|x| **x == r).for_each(|x| *x = base);
    q
}

fn solve(
    p: Prepared,
    observer: &mut dyn FnMut(&Progress),
) -> Result<(Vec<Vector3<f64>>, f64), SceneError> {
    let mut run = Run::prepare(p)?;
    let s = run.solve(observer)?;
    Ok((s.solution.displacements, s.solve_seconds))
}

/// Solves the scene, then the scene without each region but the largest; `announce` is
/// called with a region's element set before its solve, `observer` sees every solve's
/// progress. Errors are the solves'.
pub fn region_effects(
    p: &Prepared,
    announce: &mut dyn FnMut(&str),
    observer: &mut dyn FnMut(&Progress),
) -> Result<RegionEffects, SceneError> {
    let mm = p.scene.units.metres() * 1000.0;
    let base = largest_region(p);
    let (full, solve_seconds) = solve(p.clone(), observer)?;
    let mut regions = Vec::new();
    for r in (0..p.scene.regions.len()).filter(|&r| r != base) {
        let elset = p.scene.regions[r].elset.clone();
        announce(&elset);
        let (u, seconds) = solve(without_region(p, r, base), observer)?;
        let diff: Vec<f64> = full.iter().zip(&u).map(|(a, b)| (a - b).norm() * mm).collect();
        let (max_at, max_mm) = diff
            .iter()
            .copied()
            .enumerate()
            .fold((0, 0.0), |m, (n, d)| if d > m.1 { (n, d) } else { m });
        let mut in_region = vec![false; p.mesh.nodes.len()];
        for (e, _) in p.region_of_element.iter().enumerate().filter(|(_, x)| **x == r) {
            p.mesh.elements[e].nodes().iter().for_each(|&n| in_region[n] = true);
        }
        let nodes: Vec<f64> =
            diff.iter().zip(&in_region).filter(|(_, i)| **i).map(|(d, _)| *d).collect();
        regions.push(RegionEffect {
            elset,
            max_mm,
            max_node: p.mesh.node_ids[max_at],
            region_max_mm: nodes.iter().copied().fold(0.0, f64::max),
            region_mean_mm: nodes.iter().sum::<f64>() / nodes.len().max(1) as f64,
            region_nodes: nodes.len(),
            solve_seconds: seconds,
        });
    }
    Ok(RegionEffects {
        base: p.scene.regions[base].elset.clone(),
        max_displacement_mm: full.iter().map(|u| u.norm() * mm).fold(0.0, f64::max),
        solve_seconds,
        regions,
    })
}
