//! The skull cavity: a closed, outward triangle surface around the brain.
//!
//! *Offset* (default): the brain mask is dilated by `offset + closing` mm and eroded by
//! `closing` mm (exact Euclidean distance transforms), i.e. the brain offset by `offset` and
//! then morphologically closed with a ball of radius `closing`: the cavity keeps at least
//! `offset` from every brain voxel but bridges sulci and fissures narrower than
//! `2 (offset + closing)`. The signed field `closing − dist(x, outside of the dilation)`
//! (negative inside) is smoothed by a Gaussian of one voxel and its zero set is meshed.
//!
//! *Labels*: the inside of a skull segmentation: voxels not in the skull labels that cannot
//! be reached from the border of the image without crossing them; its smoothed indicator's
//! 1/2 level is meshed.
//!
//! The surface is the boundary of an isosurface-stuffed volume (only the shell of lattice
//! tetrahedra touching the surface is built): closed, manifold, no self-intersection, with
//! triangles that are faces of quality tetrahedra.

use std::collections::HashMap;
use std::collections::VecDeque;

use bs_mesh::TriSurface;
use nalgebra::Point3;
use rayon::prelude::*;

use crate::edt::squared_distance;
use crate::implicit::{SampledField, WorkGrid, gaussian_blur};
use crate::stuffing::{Fill, Stuffed, stuff};

/// The smoothed offset-and-close field of a brain mask on `work` (negative inside the
/// cavity, in mm), computed on blocks of `coarsen`³ voxels (the block is brain when at
/// least half of it is: volume-neutral, positions within half a block).
pub fn offset_field(
    work: &WorkGrid,
    brain: &[f32],
    offset: f64,
    closing: f64,
    coarsen: usize,
) -> SampledField {
    let (grid, brain) = if coarsen > 1 {
        crate::implicit::coarsen(&work.grid, brain, coarsen)
    } else {
        (work.grid.clone(), brain.to_vec())
    };
    let dims = grid.dims();
    let spacing = grid.spacing();
    let inside: Vec<bool> = brain.par_iter().map(|&v| v >= 0.5).collect();
    let d1 = squared_distance(&inside, dims, spacing);
    let reach = ((offset + closing) * (offset + closing)) as f32;
    let outside_dilation: Vec<bool> = d1.par_iter().map(|&d| d > reach).collect();
    drop(d1);
    let d2 = squared_distance(&outside_dilation, dims, spacing);
    let r = closing as f32;
    // Samples are `dist − closing` (positive inside, like an indicator), so that
    // `eval = 0 − sample` is negative inside.
    let mut g: Vec<f32> =
        d2.par_iter().map(|&d| if d.is_finite() { d.sqrt() - r } else { 1e3 }).collect();
    gaussian_blur(&mut g, dims, [1.0; 3]);
    SampledField { grid, data: g, outside: -r.max(1.0), level: 0.0 }
}

/// The smoothed indicator of the region enclosed by `skull` voxels on `work` (6-connected
/// flood fill of the outside from the grid's border), as a field negative inside.
pub fn enclosed_field(work: &WorkGrid, skull: &[f32], sigma_vox: [f64; 3]) -> SampledField {
    let [nx, ny, nz] = work.dims();
    let n = nx * ny * nz;
    let mut outside = vec![false; n];
    let mut queue = VecDeque::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if i == 0 || j == 0 || k == 0 || i + 1 == nx || j + 1 == ny || k + 1 == nz {
                    let id = i + nx * (j + ny * k);
                    if skull[id] < 0.5 && !outside[id] {
                        outside[id] = true;
                        queue.push_back(id);
                    }
                }
            }
        }
    }
    while let Some(id) = queue.pop_front() {
        let (i, j, k) = (id % nx, (id / nx) % ny, id / (nx * ny));
        let mut visit = |nb: usize| {
            if skull[nb] < 0.5 && !outside[nb] {
                outside[nb] = true;
                queue.push_back(nb);
            }
        };
        if i > 0 {
            visit(id - 1);
        }
        if i + 1 < nx {
            visit(id + 1);
        }
        if j > 0 {
            visit(id - nx);
        }
        if j + 1 < ny {
            visit(id + nx);
        }
        if k > 0 {
            visit(id - nx * ny);
        }
        if k + 1 < nz {
            visit(id + nx * ny);
        }
    }
    let mut ind: Vec<f32> =
        (0..n).map(|id| if !outside[id] && skull[id] < 0.5 { 1.0 } else { 0.0 }).collect();
    gaussian_blur(&mut ind, [nx, ny, nz], sigma_vox);
    SampledField { grid: work.grid.clone(), data: ind, outside: 0.0, level: 0.5 }
}

/// The zero set of `field` inside the box `lo..hi`, meshed as the boundary of an
/// isosurface-stuffed volume with lattice spacing `h`.
pub fn surface(field: &SampledField, lo: Point3<f64>, hi: Point3<f64>, h: f64) -> TriSurface {
    let f = |p: &Point3<f64>| field.eval(p);
    boundary_of(&stuff(&f, lo, hi, h, Fill::Shell))
}

/// The boundary triangles of a stuffed mesh (faces with all three nodes on the surface,
/// used by one tetrahedron), outward, with unused vertices dropped.
pub fn boundary_of(s: &Stuffed) -> TriSurface {
    // Outward faces of a positively oriented tetrahedron.
    const FACES: [[usize; 3]; 4] = [[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]];
    let mut faces: HashMap<[u32; 3], (u32, [u32; 3])> = HashMap::new();
    for t in &s.tets {
        for f in FACES {
            let tri = f.map(|i| t[i]);
            if tri.iter().all(|&v| s.on_surface[v as usize]) {
                let mut key = tri;
                key.sort_unstable();
                faces.entry(key).or_insert((0, tri)).0 += 1;
            }
        }
    }
    let mut tris: Vec<[u32; 3]> =
        faces.into_values().filter(|(c, _)| *c == 1).map(|(_, t)| t).collect();
    tris.sort_unstable();
    let mut map = vec![u32::MAX; s.nodes.len()];
    let mut vertices = Vec::new();
    let triangles = tris
        .iter()
        .map(|t| {
            t.map(|v| {
                if map[v as usize] == u32::MAX {
                    map[v as usize] = vertices.len() as u32;
                    vertices.push(s.nodes[v as usize]);
                }
                map[v as usize] as usize
            })
        })
        .collect();
    TriSurface::new(vertices, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn shell_boundary_of_a_ball_is_closed_outward() {
        let f = |p: &Point3<f64>| p.coords.norm() - 5.0;
        let lo = Point3::from(Vector3::repeat(-6.0));
        let s = stuff(&f, lo, -lo, 1.0, Fill::Shell);
        let b = boundary_of(&s);
        let c = b.check().unwrap();
        let all = boundary_of(&stuff(&f, lo, -lo, 1.0, Fill::All));
        assert_eq!(all.triangles.len(), b.triangles.len());
        assert!(c.is_closed_outward(), "{c:?}");
    }
}
