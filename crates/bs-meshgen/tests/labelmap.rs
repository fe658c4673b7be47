//! Synthetic labelmaps against analytic shapes.

use bs_image::{Grid, Volume};
use bs_meshgen::{MeshParams, mesh_labelmap};
use nalgebra::{Matrix4, Point3, Rotation3, Vector3};

/// A labelmap on `grid` whose voxel label is `label(world centre)`.
fn labelmap(grid: Grid, label: impl Fn(&Point3<f64>) -> u32) -> Volume<u32> {
    let [nx, ny, nz] = grid.dims();
    let mut v = Volume::filled(grid, 0u32);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = v.grid.world([i as f64, j as f64, k as f64]);
                let id = v.grid.index(i, j, k);
                v.data[id] = label(&p);
            }
        }
    }
    v
}

#[test]
fn ball_probe() {
    let grid = Grid::axis_aligned([60, 60, 60], [1.0; 3], [-30.0, -30.0, -30.0]).unwrap();
    let r = 20.0;
    let lm = labelmap(grid, |p| u32::from(p.coords.norm() <= r));
    let params = MeshParams { size: 2.0, ..Default::default() };
    let m = mesh_labelmap(&lm, &params).unwrap();
    eprintln!("{}", m.report);
    let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
    eprintln!("vs analytic {:+.3}%", 100.0 * (m.report.mesh_volume / exact - 1.0));
}
