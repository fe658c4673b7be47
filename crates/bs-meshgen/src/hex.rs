//! H8 meshes: one hexahedron per cell of a world-aligned grid of spacing `h` whose centre
//! is inside the (smoothed) brain; the boundary follows the grid (a staircase).

use nalgebra::{Point3, Vector3};
use rayon::prelude::*;

/// A hexahedral grid mesh: nodes, elements (Abaqus/VTK order, positively oriented) and the
/// region of each element (0 = rest of the brain, `r + 1` = region `r`).
#[derive(Debug, Clone, Default)]
pub struct HexGrid {
    /// Node positions.
    pub nodes: Vec<Point3<f64>>,
    /// Elements.
    pub hexes: Vec<[usize; 8]>,
    /// Region of each element.
    pub label: Vec<u8>,
}

/// Cells of side `h` covering `lo..hi`; a cell is kept when `inside(centre) < 0`, and
/// belongs to the first region whose field is negative at its centre.
pub fn hex_grid<F, R>(
    inside: &F,
    regions: &[R],
    lo: Point3<f64>,
    hi: Point3<f64>,
    h: f64,
) -> HexGrid
where
    F: Fn(&Point3<f64>) -> f64 + Sync,
    R: Fn(&Point3<f64>) -> f64 + Sync,
{
    let n = [0, 1, 2].map(|a| ((hi[a] - lo[a]) / h).ceil().max(1.0) as usize + 2);
    let centre = Point3::from((lo.coords + hi.coords) * 0.5);
    let origin = centre - Vector3::new(n[0] as f64, n[1] as f64, n[2] as f64) * (0.5 * h);
    let cells = n[0] * n[1] * n[2];
    // Region per cell: u8::MAX outside.
    let cell_label: Vec<u8> = (0..cells)
        .into_par_iter()
        .map(|c| {
            let (i, j, k) = (c % n[0], (c / n[0]) % n[1], c / (n[0] * n[1]));
            let p = origin + Vector3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * h;
            if inside(&p) >= 0.0 {
                return u8::MAX;
            }
            regions.iter().position(|r| r(&p) < 0.0).map_or(0, |r| (r + 1) as u8)
        })
        .collect();
    let (px, py) = (n[0] + 1, n[1] + 1);
    let mut node_id = vec![usize::MAX; px * py * (n[2] + 1)];
    let mut out = HexGrid::default();
    for (c, &l) in cell_label.iter().enumerate() {
        if l == u8::MAX {
            continue;
        }
        let (i, j, k) = (c % n[0], (c / n[0]) % n[1], c / (n[0] * n[1]));
        let corner = [
            (0, 0, 0),
            (1, 0, 0),
            (1, 1, 0),
            (0, 1, 0),
            (0, 0, 1),
            (1, 0, 1),
            (1, 1, 1),
            (0, 1, 1),
        ];
        let hex = corner.map(|(a, b, d)| {
            let g = (i + a) + px * ((j + b) + py * (k + d));
            if node_id[g] == usize::MAX {
                node_id[g] = out.nodes.len();
                out.nodes.push(
                    origin + Vector3::new((i + a) as f64, (j + b) as f64, (k + d) as f64) * h,
                );
            }
            node_id[g]
        });
        out.hexes.push(hex);
        out.label.push(l);
    }
    out
}
