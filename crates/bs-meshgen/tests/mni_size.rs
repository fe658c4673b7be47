//! MNI152-sized synthetic ellipsoid (197×233×189 1 mm voxels, ~1.9 M brain voxels) at 4 mm.
//! Ignored by default (a timing run): `cargo test --release -p bs-meshgen --test mni_size -- --ignored --nocapture`.

use bs_image::{Grid, Volume};
use bs_meshgen::{MeshParams, mesh_labelmap};

#[test]
#[ignore]
fn mni_sized_ellipsoid_at_4mm() {
    let grid = Grid::axis_aligned([197, 233, 189], [1.0; 3], [-98.0, -134.0, -72.0]).unwrap();
    let mut v = Volume::filled(grid, 0u32);
    let (a, b, c) = (72.0, 90.0, 70.0);
    let (cx, cy, cz) = (0.0, -18.0, 18.0);
    for k in 0..189 {
        for j in 0..233 {
            for i in 0..197 {
                let p = v.grid.world([i as f64, j as f64, k as f64]);
                let (x, y, z) = ((p.x - cx) / a, (p.y - cy) / b, (p.z - cz) / c);
                if x * x + y * y + z * z <= 1.0 {
                    let id = v.grid.index(i, j, k);
                    v.data[id] = 1;
                }
            }
        }
    }
    for _ in 0..3 {
        let t = std::time::Instant::now();
        let m = mesh_labelmap(&v, &MeshParams::default()).unwrap();
        eprintln!("{}\nwall {:.3} s", m.report, t.elapsed().as_secs_f64());
    }
}
