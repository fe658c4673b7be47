//! A regular voxel grid and its map to world coordinates.

use nalgebra::{Matrix3, Matrix4, Point3, Vector3};

use crate::ImageError;

/// A regular grid of `dims` voxels with the affine map from (continuous) voxel indices
/// (i, j, k) to world coordinates in mm. The voxel centre of (i, j, k) is at integer indices.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    dims: [usize; 3],
    voxel_to_world: Matrix4<f64>,
    world_to_voxel: Matrix4<f64>,
}

impl Grid {
    /// A grid of `dims` voxels (each ≥ 1) whose voxel (i, j, k) sits at
    /// `voxel_to_world * (i, j, k, 1)`; the affine's last row must be (0, 0, 0, 1) and its
    /// 3×3 part invertible.
    pub fn new(dims: [usize; 3], voxel_to_world: Matrix4<f64>) -> Result<Grid, ImageError> {
        if dims.contains(&0) {
            return Err(ImageError::Grid(format!("grid size {dims:?} has a zero dimension")));
        }
        if voxel_to_world.iter().any(|v| !v.is_finite()) {
            return Err(ImageError::Grid(
                "the voxel-to-world affine has a non-finite entry".into(),
            ));
        }
        let last = voxel_to_world.row(3);
        if last[0] != 0.0 || last[1] != 0.0 || last[2] != 0.0 || last[3] != 1.0 {
            return Err(ImageError::Grid("the affine's last row is not (0, 0, 0, 1)".into()));
        }
        let linear: Matrix3<f64> = voxel_to_world.fixed_view::<3, 3>(0, 0).into_owned();
        let det = linear.determinant();
        let scale = linear.norm().max(f64::MIN_POSITIVE);
        if det.abs() <= 1e-12 * scale * scale * scale {
            return Err(ImageError::Grid(
                "the voxel-to-world affine is singular (a zero voxel size or collinear axes)"
                    .into(),
            ));
        }
        let world_to_voxel = voxel_to_world
            .try_inverse()
            .ok_or_else(|| ImageError::Grid("the voxel-to-world affine is singular".into()))?;
        Ok(Grid { dims, voxel_to_world, world_to_voxel })
    }

    /// An axis-aligned grid: voxel (i, j, k) at `origin + (i sx, j sy, k sz)`.
    pub fn axis_aligned(
        dims: [usize; 3],
        spacing: [f64; 3],
        origin: [f64; 3],
    ) -> Result<Grid, ImageError> {
        let mut m = Matrix4::identity();
        for a in 0..3 {
            m[(a, a)] = spacing[a];
            m[(a, 3)] = origin[a];
        }
        Grid::new(dims, m)
    }

    /// Number of voxels along i, j, k.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Total number of voxels.
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Never true: a grid has at least one voxel.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The voxel-to-world affine (world frame of the image, mm).
    pub fn voxel_to_world(&self) -> &Matrix4<f64> {
        &self.voxel_to_world
    }

    /// The world-to-voxel affine.
    pub fn world_to_voxel(&self) -> &Matrix4<f64> {
        &self.world_to_voxel
    }

    /// Voxel sizes in mm (lengths of the affine's columns).
    pub fn spacing(&self) -> [f64; 3] {
        let m = &self.voxel_to_world;
        [0, 1, 2].map(|c| Vector3::new(m[(0, c)], m[(1, c)], m[(2, c)]).norm())
    }

    /// Volume of one voxel in mm³.
    pub fn voxel_volume(&self) -> f64 {
        self.voxel_to_world.fixed_view::<3, 3>(0, 0).determinant().abs()
    }

    /// Linear index of voxel (i, j, k): `i + nx (j + ny k)`.
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// World position of continuous voxel indices.
    #[inline]
    pub fn world(&self, ijk: [f64; 3]) -> Point3<f64> {
        self.voxel_to_world.transform_point(&Point3::new(ijk[0], ijk[1], ijk[2]))
    }

    /// World position of the centre of the voxel with linear index `n` (`i + nx (j + ny k)`).
    #[inline]
    pub fn centre(&self, n: usize) -> Point3<f64> {
        let [nx, ny, _] = self.dims;
        self.world([(n % nx) as f64, ((n / nx) % ny) as f64, (n / (nx * ny)) as f64])
    }

    /// Continuous voxel indices of a world point.
    #[inline]
    pub fn voxel(&self, p: &Point3<f64>) -> [f64; 3] {
        let v = self.world_to_voxel.transform_point(p);
        [v.x, v.y, v.z]
    }
}

/// Voxel values on a grid, first index fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct Volume<T> {
    /// The grid and its world map.
    pub grid: Grid,
    /// `grid.len()` values, `data[grid.index(i, j, k)]`.
    pub data: Vec<T>,
}

impl<T: Copy> Volume<T> {
    /// A volume with every voxel set to `value`.
    pub fn filled(grid: Grid, value: T) -> Volume<T> {
        let data = vec![value; grid.len()];
        Volume { grid, data }
    }

    /// The value of voxel (i, j, k).
    #[inline]
    pub fn at(&self, i: usize, j: usize, k: usize) -> T {
        self.data[self.grid.index(i, j, k)]
    }
}
