//! The exact inverse map on an image grid, its extension between brain and skull, and the warp,
//! labels and field it gives.

use std::path::Path;

use bs_image::{Grid, Space, Volume};
use bs_mesh::lattice::{LatticeLocation, OUTSIDE, TetAffine, tetrahedra};
use bs_mesh::{Point3, TriSurface, Vector3};
use nalgebra::Matrix4;
use rayon::prelude::*;

use super::result::RunResult;
use crate::outside::{Outside, OutsideReport};
use bs_scene::SceneError;

/// The inverse of a result's deformation on an image grid: for every voxel centre y inside
/// the deformed mesh, the reference point X(y) (image frame, mm); between the deformed
/// brain and the skull, y + d(y) with d the harmonic extension ([`crate::outside`]).
#[derive(Debug, Clone)]
pub struct InverseMap {
    grid: Grid,
    location: LatticeLocation,
    /// Reference node positions in the image frame (mm).
    reference: Vec<Point3<f64>>,
    /// The tetrahedra of the mesh (hexes split) with their element ids.
    tets: Vec<[usize; 4]>,
    ids: Vec<u64>,
    /// The extension outside the deformed brain (None: identity there).
    outside: Option<Outside>,
    /// The scene's skull in the image frame (mm), for the pre-operative gap on an image's
    /// grid (None: no skull, or the identity outside the brain).
    skull: Option<TriSurface>,
    /// The gap voxels the deformed brain encloses (a resection's cavity; ascending), which
    /// the warps fill with fluid.
    enclosed: Vec<u32>,
}

/// What the map does outside the deformed brain.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutsideChoice {
    /// The harmonic extension to the skull (or over a band without one).
    Extend,
    /// The identity (d = 0): the map of earlier versions, kept to measure against.
    Identity,
}

/// Axis-aligned extent of points, for messages.
fn extent(points: impl Iterator<Item = Point3<f64>>) -> (Point3<f64>, Point3<f64>) {
    points.fold(
        (Point3::from([f64::INFINITY; 3]), Point3::from([f64::NEG_INFINITY; 3])),
        |(lo, hi), p| (lo.inf(&p), hi.sup(&p)),
    )
}

fn show(e: &(Point3<f64>, Point3<f64>)) -> String {
    format!(
        "x {:.1}…{:.1}, y {:.1}…{:.1}, z {:.1}…{:.1} mm",
        e.0.x, e.1.x, e.0.y, e.1.y, e.0.z, e.1.z
    )
}

/// The world frame of every image brainshift holds: RAS mm (bs-image converts LPS files
/// when it reads them), whatever the result's own frame.
pub const IMAGE_SPACE: Space = Space::Ras;

impl InverseMap {
    /// The inverse map of `result` on `grid`, an image (file `image`, for messages) in
    /// [`IMAGE_SPACE`]. Refuses a result whose deformed mesh mostly lies
    /// outside the image (fewer than half its nodes inside the image's extent).
    pub fn new(result: &RunResult, grid: &Grid, image: &Path) -> Result<InverseMap, SceneError> {
        InverseMap::with_outside(result, grid, image, OutsideChoice::Extend)
    }

    /// [`InverseMap::new`] with the map outside the deformed brain chosen.
    pub fn with_outside(
        result: &RunResult,
        grid: &Grid,
        image: &Path,
        choice: OutsideChoice,
    ) -> Result<InverseMap, SceneError> {
        let scale = result.units.metres() / 1e-3; // mesh unit → mm
        let to_image = |p: Point3<f64>| result.space.convert_point(IMAGE_SPACE, p * scale);
        let reference: Vec<Point3<f64>> = result.mesh.nodes.iter().map(|&p| to_image(p)).collect();
        let deformed: Vec<Point3<f64>> = result
            .mesh
            .nodes
            .iter()
            .zip(&result.displacements)
            .map(|(&p, u)| to_image(p + u))
            .collect();
        // The image's extent: voxel centres widened by half a voxel.
        let [nx, ny, nz] = grid.dims();
        let corners = (0..8).map(|c| {
            let pick = |bit: usize, n: usize| if c >> bit & 1 == 1 { n as f64 - 0.5 } else { -0.5 };
            grid.world([pick(0, nx), pick(1, ny), pick(2, nz)])
        });
        let image_extent = extent(corners);
        let inside = deformed
            .iter()
            .filter(|p| {
                grid.voxel(p)
                    .iter()
                    .zip(grid.dims())
                    .all(|(&v, n)| v >= -0.5 && v <= n as f64 - 0.5)
            })
            .count();
        if 2 * inside < deformed.len() {
            let mesh_extent = extent(deformed.iter().copied());
            return Err(SceneError::Image {
                file: image.to_path_buf(),
                message: format!(
                    "the deformed mesh of {} does not lie in this image: only {inside} of {} \
                     nodes are inside it. Mesh ({} in the result, shown in the image's {} \
                     frame, mm): {}; image ({} world frame): {}. Check the scene's space = \
                     \"RAS\" | \"LPS\" and units, and that this is the image the mesh was made \
                     from",
                    result.dir.display(),
                    deformed.len(),
                    result.space.name(),
                    IMAGE_SPACE.name(),
                    show(&mesh_extent),
                    IMAGE_SPACE.name(),
                    show(&image_extent),
                ),
            });
        }
        let (tets, source) = tetrahedra(&result.mesh);
        let ids: Vec<u64> = source.iter().map(|&e| result.mesh.element_ids[e]).collect();
        let location =
            LatticeLocation::new(&deformed, &tets, &ids, grid.dims(), grid.world_to_voxel())
                .map_err(|e| SceneError::Result {
                    dir: result.dir.clone(),
                    message: format!("the deformed mesh cannot be searched: {e}"),
                })?;
        let mut map = InverseMap {
            grid: grid.clone(),
            location,
            reference,
            tets,
            ids,
            outside: None,
            skull: None,
            enclosed: Vec::new(),
        };
        if choice == OutsideChoice::Extend {
            map.skull = result.skull.as_ref().map(|s| TriSurface {
                vertices: s.vertices.iter().map(|&p| to_image(p)).collect(),
                triangles: s.triangles.clone(),
            });
            let cavity = map.skull.as_ref().map(|s| cavity(s, grid));
            let in_brain = map.inside_mask();
            let outside = crate::outside::extend(
                grid,
                &in_brain,
                cavity.as_deref(),
                result.max_displacement_mm(),
                |n| map.exact_displacement(n).unwrap_or([0.0; 3]),
                |n| map.extrapolated_displacement(n),
            );
            if result.resected {
                map.enclosed = crate::outside::enclosed(grid, &outside.voxels, &in_brain);
            }
            map.outside = Some(outside);
        }
        Ok(map)
    }

    /// d(y) = X(y) − y at voxel `n` inside the deformed mesh (the exact inverse).
    fn exact_displacement(&self, n: usize) -> Option<[f64; 3]> {
        let x = self.reference_point(n)?;
        let d = x - self.voxel_centre(n);
        Some([d.x, d.y, d.z])
    }

    /// d at voxel `n` just outside the deformed mesh by the affine map of the tetrahedron
    /// holding a face-neighbouring voxel (the first inside one, in the order −i, +i, −j,
    /// +j, −k, +k): the finite-element inverse continued linearly across the surface.
    fn extrapolated_displacement(&self, n: usize) -> Option<[f64; 3]> {
        let [nx, ny, nz] = self.grid.dims();
        let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
        let dims = [nx, ny, nz];
        let stride = [1, nx, nx * ny];
        let owners = self.location.owners();
        for a in 0..3 {
            for up in [false, true] {
                let q = if up {
                    (ijk[a] + 1 < dims[a]).then(|| n + stride[a])
                } else {
                    (ijk[a] > 0).then(|| n - stride[a])
                };
                let Some(q) = q else { continue };
                let t = owners[q];
                if t == OUTSIDE {
                    continue;
                }
                let w = self.location.barycentric(t as usize, ijk);
                let x = self.location.interpolate(t as usize, &w, &self.reference);
                let d = x - self.voxel_centre(n);
                return Some([d.x, d.y, d.z]);
            }
        }
        None
    }

    fn voxel_centre(&self, n: usize) -> Point3<f64> {
        self.grid.centre(n)
    }

    /// What the extension outside the deformed brain did (None: identity there).
    pub fn outside_report(&self) -> Option<OutsideReport> {
        self.outside.as_ref().map(|o| o.report(&self.grid, |n| self.exact_displacement(n)))
    }

    /// Voxels mapped by the extension (between the deformed brain and the skull).
    pub fn gap_voxels(&self) -> &[u32] {
        self.outside.as_ref().map_or(&[], |o| &o.voxels)
    }

    /// The point X(y) = y + d(y) a voxel samples: the exact inverse inside the deformed
    /// mesh, the extension in the gap, `None` elsewhere (the identity).
    pub fn mapped_point(&self, n: usize) -> Option<Point3<f64>> {
        if let Some(x) = self.reference_point(n) {
            return Some(x);
        }
        let d = self.outside.as_ref()?.get(n)?;
        Some(self.voxel_centre(n) + Vector3::from(d))
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Whether each voxel centre lies inside the deformed mesh, where the map is the exact
    /// inverse of the finite-element map (voxel order `i + nx (j + ny k)`).
    pub fn inside_mask(&self) -> Vec<bool> {
        self.location.owners().par_iter().map(|&o| o != OUTSIDE).collect()
    }

    /// Voxel centres inside the deformed mesh.
    pub fn inside_count(&self) -> usize {
        self.location.inside_count()
    }

    /// The reference point X(y) of voxel `n`'s centre y (image frame, mm) by the exact
    /// inverse of the finite-element map, `None` outside the deformed mesh.
    pub fn reference_point(&self, n: usize) -> Option<Point3<f64>> {
        let (t, w) = self.location.locate(n)?;
        Some(self.location.interpolate(t, &w, &self.reference))
    }

    /// A nodal quantity of the result (one value per node, e.g. σ) on the intra-operative
    /// grid: at each voxel centre inside the deformed mesh, interpolated linearly in the
    /// element holding it (the value of its reference point X(y)); zero outside the brain.
    pub fn nodal(&self, values: &[f64]) -> Vec<f32> {
        (0..self.grid.len())
            .into_par_iter()
            .map(|n| match self.location.locate(n) {
                Some((t, w)) => self.location.interpolate_scalar(t, &w, values) as f32,
                None => 0.0,
            })
            .collect()
    }

    /// The pre-operative `image` (on this grid or any other in the same world frame)
    /// resampled into the intra-operative configuration on this grid: trilinear at X(y) inside
    /// the deformed mesh; every other voxel keeps the value of `keep` (the input on the same
    /// grid), as does a voxel whose X(y) falls outside `image`.
    ///
    /// In the gap to the skull a voxel samples at the point [`field`](Self::field) gives it
    /// (see [`gap_points`](Self::gap_points)): beyond the skin never the pre-operative
    /// brain or bone, so the warp equals resampling through the exported field (ITK,
    /// Slicer) on the map's grid.
    ///
    /// After a resection, the cavity (the gap voxels the deformed brain encloses) shows
    /// fluid: the median of what the rest of the gap shows (the fluid that was between
    /// brain and skull).
    pub fn warp(&self, image: &Volume<f32>, keep: &[f32]) -> Vec<f32> {
        let gap = self.outside.as_ref().and_then(|_| self.preop_gap(&image.grid));
        let mut out = self.warp_with_gap(image, keep, gap.as_deref());
        if !self.enclosed.is_empty() {
            let fluid = self.outer_gap_median(&out);
            self.enclosed.iter().for_each(|&n| out[n as usize] = fluid);
        }
        out
    }

    /// The median of `values` over the gap voxels not enclosed by the brain.
    fn outer_gap_median(&self, values: &[f32]) -> f32 {
        let mut outer: Vec<f32> = self
            .gap_voxels()
            .iter()
            .filter(|n| self.enclosed.binary_search(n).is_err())
            .map(|&n| values[n as usize])
            .filter(|v| v.is_finite())
            .collect();
        if outer.is_empty() {
            return 0.0;
        }
        let mid = outer.len() / 2;
        *outer.select_nth_unstable_by(mid, f32::total_cmp).1
    }

    /// The gap voxels the deformed brain encloses (a resection's cavity), ascending.
    pub fn enclosed_voxels(&self) -> &[u32] {
        &self.enclosed
    }

    /// [`warp`](Self::warp) with the pre-operative gap on the image's grid given (it depends
    /// on the reference mesh, the skull and the grid only: a live session computes it once).
    /// `gap`: [`preop_gap`](Self::preop_gap) of `image.grid`, None to sample plainly.
    pub fn warp_with_gap(
        &self,
        image: &Volume<f32>,
        keep: &[f32],
        gap: Option<&[bool]>,
    ) -> Vec<f32> {
        let maps = self.location.affine_maps(&self.reference, image.grid.world_to_voxel());
        let mut out = self
            .location
            .map_inside(Some(keep), &maps, |s| bs_image::sample::trilinear_at(image, s));
        let points = self.gap_points(gap.map(|g| (&image.grid, g)));
        self.resample_gap(&mut out, &points, |x| bs_image::sample::trilinear(image, x));
        out
    }

    /// The points X(y) the gap voxels sample, in the order of
    /// [`gap_voxels`](Self::gap_voxels): y + d(y) (the harmonic extension), except beyond
    /// the skin (the layer of gap voxels touching the deformed brain, which keeps the
    /// brain's edge) where a trilinear sample at y + d(y) on the grid of `gap` (the
    /// [`preop_gap`](Self::preop_gap) on it) would read a voxel outside the pre-operative
    /// gap: there X(y) is the centre of the nearest voxel of that gap within
    /// [`GAP_SEARCH_VOXELS`] ([`bs_image::sample::settle_within`]), else y + d(y). So a voxel
    /// in the space the brain left shows what filled the old gap, never the old brain or
    /// bone: where the old gap was thin (the brain touched the skull and moved away) the
    /// extension sends the vacated voxels onto the old surface layer or across it
    /// ([`crate::outside`]), and a plain sample stretched the old cortex over them (spikes
    /// of one to three voxels above the MNI152 demo's craniotomy). `gap` None: y + d(y)
    /// everywhere.
    pub fn gap_points(&self, gap: Option<(&Grid, &[bool])>) -> Vec<Point3<f64>> {
        let Some(o) = &self.outside else { return Vec::new() };
        o.voxels
            .par_iter()
            .zip(&o.values)
            .zip(&o.skin)
            .map(|((&n, d), &skin)| {
                let x = self.voxel_centre(n as usize) + Vector3::from(*d);
                match gap {
                    Some((grid, g)) if !skin => {
                        bs_image::sample::settle_within(grid, &x, g, GAP_SEARCH_VOXELS)
                    }
                    _ => x,
                }
            })
            .collect()
    }

    /// The pre-operative gap on `grid`: voxels inside the skull cavity (anywhere, for a
    /// scene without a skull) whose centre lies neither in the reference (pre-operative)
    /// mesh nor within [`BRAIN_MARGIN_MM`] plus half a voxel of it along a grid axis (at
    /// most a voxel: on a grid of 1 mm, no face neighbour in the mesh). Such a voxel holds
    /// no brain: a voxel's content reaches half a voxel from its centre, and a mesh made
    /// from a segmentation runs within that margin of its mask's voxel centres (the MNI152
    /// demo's top surface 0.1–0.5 mm below the centres of the mask's top voxels, which
    /// hold cortex). None when the reference mesh cannot be located on `grid`.
    pub fn preop_gap(&self, grid: &Grid) -> Option<Vec<bool>> {
        let near = self.near_reference(grid)?;
        let cavity = self.skull.as_ref().map(|s| cavity(s, grid));
        Some(
            near.par_iter()
                .enumerate()
                .with_min_len(4096)
                .map(|(n, &near)| !near && cavity.as_ref().is_none_or(|c| c[n]))
                .collect(),
        )
    }

    /// Voxels of `grid` whose centre lies in the reference mesh or within the brain margin
    /// of it along an axis ([`preop_gap`](Self::preop_gap)): the face neighbours along an
    /// axis whose spacing is at most the margin, the mesh located on the grid shifted by
    /// the margin both ways along the others.
    fn near_reference(&self, grid: &Grid) -> Option<Vec<bool>> {
        let inside = self.reference_inside(grid, grid.world_to_voxel())?;
        let dims = grid.dims();
        // The margin in voxels along each axis: half a voxel plus BRAIN_MARGIN_MM, at most one.
        let margin = grid.spacing().map(|h| (0.5 + BRAIN_MARGIN_MM / h).min(1.0));
        let along = margin.map(|s| s >= 1.0);
        let mut near: Vec<bool> = (0..inside.len())
            .into_par_iter()
            .with_min_len(4096)
            .map(|n| bs_image::mask::touches_along(&inside, dims, along, n))
            .collect();
        for (a, &s) in margin.iter().enumerate().filter(|(a, _)| !along[*a]) {
            for sign in [-1.0, 1.0] {
                // Voxel (i, j, k) of the shifted lattice is the point (i, j, k) + s e_a.
                let mut shift = Matrix4::identity();
                shift[(a, 3)] = -sign * s;
                let shifted = self.reference_inside(grid, &(shift * grid.world_to_voxel()))?;
                near.par_iter_mut().zip(&shifted).for_each(|(v, &m)| *v |= m);
            }
        }
        Some(near)
    }

    /// A key of what [`preop_gap`](Self::preop_gap) depends on besides the grid: the
    /// reference nodes, the tetrahedra and the skull, hashed. Two maps with equal keys (the
    /// updates of one live session) have equal gaps on one grid, so a front end can keep
    /// the gap with the image.
    pub fn preop_key(&self) -> u64 {
        use std::hash::{Hash, Hasher};
        let mut h = std::hash::DefaultHasher::new();
        let point = |h: &mut std::hash::DefaultHasher, p: &Point3<f64>| {
            p.coords.iter().for_each(|c| c.to_bits().hash(h))
        };
        self.reference.iter().for_each(|p| point(&mut h, p));
        self.tets.hash(&mut h);
        if let Some(s) = &self.skull {
            s.vertices.iter().for_each(|p| point(&mut h, p));
            s.triangles.hash(&mut h);
        }
        h.finish()
    }

    /// Voxel centres of `grid` (indices mapped by `world_to_voxel`) inside the reference
    /// (pre-operative) mesh; None when it cannot be located there (the deformed mesh was
    /// searchable, so the reference one is: a node moved onto another would have failed
    /// verification).
    fn reference_inside(&self, grid: &Grid, world_to_voxel: &Matrix4<f64>) -> Option<Vec<bool>> {
        let r = LatticeLocation::new(
            &self.reference,
            &self.tets,
            &self.ids,
            grid.dims(),
            world_to_voxel,
        )
        .ok()?;
        Some(r.owners().par_iter().map(|&o| o != OUTSIDE).collect())
    }

    /// [`InverseMap::warp`] for a labelmap: the nearest voxel's label. In the gap (the
    /// space between the deformed brain and the skull) a label of the brain is never used:
    /// a label is the brain's when most of its voxels lie inside the pre-operative mesh,
    /// and a gap voxel whose X(y) falls on one takes the nearest label at X(y) that is not
    /// (within [`GAP_SEARCH_VOXELS`] voxels), else 0 (background). A resection's cavity
    /// (fluid) takes the label `cavity` (0: background).
    pub fn warp_labels(&self, labels: &Volume<u32>, keep: &[u32], cavity: u32) -> Vec<u32> {
        let maps = self.location.affine_maps(&self.reference, labels.grid.world_to_voxel());
        let mut out = self
            .location
            .map_inside(Some(keep), &maps, |s| bs_image::sample::nearest_at(labels, s));
        if self.outside.is_some() {
            let brain = self.brain_labels(labels);
            let points = self.gap_points(None);
            self.resample_gap(&mut out, &points, |x| {
                Some(bs_image::sample::nearest_excluding(labels, x, &brain, GAP_SEARCH_VOXELS))
            });
        }
        // A resection's cavity is fluid: the label named for it.
        self.enclosed.iter().for_each(|&n| out[n as usize] = cavity);
        out
    }

    /// The labels most of whose voxels lie inside the pre-operative (reference) mesh.
    fn brain_labels(&self, labels: &Volume<u32>) -> Vec<u32> {
        self.reference_inside(&labels.grid, labels.grid.world_to_voxel())
            .map_or_else(Vec::new, |inside| {
                bs_image::sample::labels_mostly_inside(&labels.data, &inside)
            })
    }

    /// `out` with every gap voxel replaced by `sample(x)` at its point `x` of `points` (in
    /// the order of [`gap_voxels`](Self::gap_voxels)) where it has a value: sampled in
    /// parallel, written in order.
    fn resample_gap<T: Copy + Send>(
        &self,
        out: &mut [T],
        points: &[Point3<f64>],
        sample: impl Fn(&Point3<f64>) -> Option<T> + Sync,
    ) {
        let samples: Vec<Option<T>> = points.par_iter().map(&sample).collect();
        for (&n, v) in self.gap_voxels().iter().zip(samples) {
            if let Some(v) = v {
                out[n as usize] = v;
            }
        }
    }

    /// The displacement field d(y) = X(y) − y on this grid (image frame, mm), the map
    /// [`warp`](Self::warp) samples through: the exact inverse inside the deformed mesh, in
    /// the gap the points of [`gap_points`](Self::gap_points) with the pre-operative gap on
    /// this grid, zero beyond the skull; voxel order `i + nx (j + ny k)`. Resampling an
    /// image on this grid through it (ITK, Slicer: trilinear) gives [`warp`](Self::warp)'s
    /// image.
    pub fn field(&self) -> Vec<[f32; 3]> {
        let gap = if self.gap_voxels().is_empty() { None } else { self.preop_gap(&self.grid) };
        self.field_with_gap(gap.as_deref())
    }

    /// [`field`](Self::field) with the pre-operative gap on this map's grid given (None: the
    /// harmonic extension y + d(y) in the whole gap, as [`harmonic_field`](Self::harmonic_field)).
    pub fn field_with_gap(&self, gap: Option<&[bool]>) -> Vec<[f32; 3]> {
        // d = X(y) − y: the interpolant of X minus the grid's index-to-world map.
        let to_world = self.grid.voxel_to_world();
        let maps: Vec<TetAffine> = self
            .location
            .affine_maps(&self.reference, &Matrix4::identity())
            .iter()
            .map(|a| a.minus(to_world))
            .collect();
        let mut out = self.location.map_inside(None, &maps, |d| Some(d.map(|c| c as f32)));
        let points = self.gap_points(gap.map(|g| (&self.grid, g)));
        for (&n, x) in self.gap_voxels().iter().zip(&points) {
            let d = x - self.voxel_centre(n as usize);
            out[n as usize] = [d.x as f32, d.y as f32, d.z as f32];
        }
        out
    }

    /// The map with the harmonic extension y + d(y) in the whole gap (continuous; what
    /// [`outside_report`](Self::outside_report)'s fold count measures and the preview's
    /// |d| shows), as a displacement field like [`field`](Self::field).
    pub fn harmonic_field(&self) -> Vec<[f32; 3]> {
        self.field_with_gap(None)
    }
}

/// How far (voxels, per axis) a gap voxel of a warp looks for a voxel of the pre-operative
/// gap (an image) or a label that is not the brain's (a labelmap, which takes 0 beyond).
/// Where the brain touched the skull the old gap has no voxel for several millimetres
/// around (on a ball of 50 mm a millimetre below its skull, the nearest lies 8–10 voxels
/// of 1.5 mm away); the search stops at the first voxel found, so the radius only bounds
/// the cost where there is none.
pub const GAP_SEARCH_VOXELS: usize = 12;

/// How far beyond half a voxel from its centre a voxel may still hold brain (mm): a mesh
/// made from a segmentation runs up to about half a millimetre from its mask's voxel
/// centres (the MNI152 demo's: 0.1–0.5 mm). [`InverseMap::preop_gap`] keeps the voxels
/// farther than half a voxel plus this from the reference mesh along every axis.
pub const BRAIN_MARGIN_MM: f64 = 0.5;

/// Voxel centres of `grid` inside the closed surface `skull` (image frame).
fn cavity(skull: &TriSurface, grid: &Grid) -> Vec<bool> {
    bs_mesh::lattice_inside::inside_closed_surface(
        &skull.vertices,
        &skull.triangles,
        grid.dims(),
        grid.world_to_voxel(),
    )
}
