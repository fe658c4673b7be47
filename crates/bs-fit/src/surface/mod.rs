//! A scanned surface fitted point-to-surface: the data term of a `[[measurement]] points`.
//!
//! The scan is a surface known through noisy points; the brain's exposed patch (the
//! boundary faces of the measurement's node set) is pulled onto it. At every linearisation
//! three quadrature points of each face of the deformed patch (barycentric (2/3, 1/6, 1/6)
//! and its permutations) find the scan's surface near them: a robust plane through the
//! points around the line along the patch's normal there ([`plane`]: moving least squares
//! of degree one, Tukey-weighted, so outliers do not tilt it). A spring pulls the
//! quadrature point onto that plane along the plane's normal. Sliding along the surface
//! costs nothing (a scan cannot see it); a part of the patch with no scan near it is not
//! pulled ("nodes with no data nearby stay free"), one at the edge of the scanned area fades
//! out. The energy is the quadrature of the squared distance between the two surfaces,
//!
//! `E_d = κ ∫_patch c · ½ d(x, scan)² dA ≈ Σ_q κ (A_f / 3) c_q · ½ (n_q · (x_q − p_q))²`,
//!
//! `A_f` the face's area (in the reference configuration: the integral is over the
//! reference patch, so the weights do not change as the patch deforms), `c_q` the coverage of quadrature point `q`, `(n_q, p_q)` its plane
//! and `κ` the data stiffness per area ([`surface_stiffness`]): the weight does not depend on
//! how densely the scanner sampled, each plane averages the noise of every point within the
//! radius `R ≥ 3σ`, and pulling whole faces (not only nodes) onto the scan leaves the
//! surface less room to slide where the scan's shape says where it is. Every weight is a
//! continuous function of where the plane is looked for, so the data force is continuous
//! in the displacements and the Newton iteration settles (scan points matched to the
//! faceted model instead hop between faces as the model moves, each hop changing a force
//! by the stiffness times the noise, and the iteration did not settle at σ = 1 mm).
//!
//! After the solve, [`SurfaceFit::classify`] measures each point against the fitted
//! surface (its distance, robust weight, inlier or not) for the reports.

pub mod plane;
pub mod slide;

use bs_contact::Patch;
use bs_contact::grid::BucketGrid;
use bs_dr::{DataTerm, Spring, Springs};
use bs_mesh::{Point3, Vector3};
use rayon::prelude::*;

use self::plane::{Cylinder, LocalPlane};
use self::slide::Slide;
use crate::robust;

/// The data stiffness per area of a scanned surface: `κ = min(μ L / σ², 100 μ / h)`, `μ`
/// the shear modulus of the tissue under the scan, `σ` the scan's noise, `L = √A` the size
/// of the area it covers and `h` the patch's mean edge.
///
/// Why `μ L / σ²`: the brain resists a surface displacement of wavelength `λ` with a
/// stiffness per area of about `4π μ / λ` (an incompressible half-space). The shift a scan
/// measures has the scale of the covered area (`λ ≈ 2L`): with `κ = μ L/σ²` the data
/// outweigh the model there by `L²/(2π σ²)` (about 140 for a 30 mm window at σ = 1 mm), and
/// the weight falls as `1/σ²`, as a Gaussian likelihood's does. Why the cap: beyond about a
/// hundred times the stiffness of the tissue under a face (`μ/h` per area) the springs
/// already hold the surface on the scan, and stiffer ones only slow the linear solves,
/// whose preconditioner knows the tissue, not the data (docs/fit.md measures both).
/// Units: stiffness per area (Pa per length unit).
pub fn surface_stiffness(mu: f64, sigma: f64, covered_area: f64, edge: f64) -> f64 {
    (mu * covered_area.max(0.0).sqrt() / (sigma * sigma)).min(STIFFNESS_CAP * mu / edge)
}

/// The cap of [`surface_stiffness`], in units of the tissue's `μ/h`.
pub const STIFFNESS_CAP: f64 = 100.0;

/// The settings of a [`SurfaceFit`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceParams {
    /// The measurement's noise (standard deviation, length units): the floor of the robust
    /// scale.
    pub sigma: f64,
    /// The data stiffness per area `κ` ([`surface_stiffness`]).
    pub stiffness: f64,
    /// Scan points farther than this from the patch are not used.
    pub max_distance: f64,
}

/// How a measured point relates to the fitted surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointStatus {
    /// Within the robust cut-off of the fitted surface.
    Inlier,
    /// Beyond it: rejected.
    Outlier,
    /// Its closest point is on the patch's border: no evidence about the patch.
    Border,
    /// Farther than `max_distance` from the patch.
    Far,
}

impl PointStatus {
    /// The name in reports (`inlier`, `outlier`, `border`, `far`).
    pub fn name(self) -> &'static str {
        match self {
            PointStatus::Inlier => "inlier",
            PointStatus::Outlier => "outlier",
            PointStatus::Border => "border",
            PointStatus::Far => "far",
        }
    }
}

/// One measured point against the fitted surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointFit {
    /// How it relates.
    pub status: PointStatus,
    /// Its signed distance from the patch (positive outside the brain, along the outward
    /// normal), length units; the unsigned distance for `Border`, NaN for `Far`.
    pub residual: f64,
    /// Its robust weight in [0, 1] (0 unless `Inlier`).
    pub weight: f64,
}

/// The data term of a scanned surface (see the module documentation).
#[derive(Debug, Clone)]
pub struct SurfaceFit {
    points: Vec<Point3<f64>>,
    grid: BucketGrid,
    /// Patch vertex → model node.
    nodes: Vec<usize>,
    patch: Patch,
    /// The patch's border edges (vertex pairs).
    border: Vec<[u32; 2]>,
    params: SurfaceParams,
    /// The radius of the nodes' cylinders.
    radius: f64,
    /// Per quadrature point (three per face) at the last linearisation: its plane of the
    /// scan.
    planes: Vec<Option<LocalPlane>>,
    fits: Vec<PointFit>,
    scale: f64,
    vertices: Vec<Point3<f64>>,
    normals: Vec<Vector3<f64>>,
    areas: Vec<f64>,
    /// The patch nodes where the planes were last found, and the springs found there.
    anchor: Vec<Point3<f64>>,
    springs: Springs,
    /// The patch vertices where the term was made (the reference), their lumped areas, and
    /// the sliding prior ([`slide`]).
    reference: Vec<Point3<f64>>,
    lumped: Vec<f64>,
    slide: Option<Slide>,
}

impl SurfaceFit {
    /// The term of `points` on the patch `faces` (corner node indices of the model,
    /// outward-oriented boundary triangles) at the model's `positions`.
    pub fn new(
        points: Vec<Point3<f64>>,
        faces: &[[usize; 3]],
        positions: &[Point3<f64>],
        params: SurfaceParams,
    ) -> Self {
        let mut local = std::collections::HashMap::new();
        let mut nodes = Vec::new();
        let triangles: Vec<[u32; 3]> = faces
            .iter()
            .map(|f| {
                f.map(|a| {
                    *local.entry(a).or_insert_with(|| {
                        nodes.push(a);
                        (nodes.len() - 1) as u32
                    })
                })
            })
            .collect();
        let border = border_edges(&triangles);
        let vertices: Vec<Point3<f64>> = nodes.iter().map(|&a| positions[a]).collect();
        let edge = mean_edge(&vertices, &triangles);
        let lumped = slide::lumped_areas(&vertices, &triangles);
        let reference = vertices.clone();
        let mut fit = SurfaceFit {
            points: Vec::new(),
            grid: BucketGrid::new(&[], Vector3::repeat(1.0)),
            nodes,
            patch: Patch::new(vertices.clone(), triangles),
            border,
            params,
            radius: edge,
            planes: vec![None; 3 * faces.len()],
            fits: Vec::new(),
            scale: params.sigma,
            vertices,
            normals: Vec::new(),
            areas: triangles_areas(positions, faces),
            anchor: Vec::new(),
            springs: Springs::new(),
            reference,
            lumped,
            slide: None,
        };
        fit.set_points(points);
        fit
    }

    /// Replaces the measured points (a new scan of the same patch).
    pub fn set_points(&mut self, points: Vec<Point3<f64>>) {
        let areas = crate::density::point_areas(&points);
        let mut sorted = areas.clone();
        let spacing = if sorted.is_empty() {
            0.0
        } else {
            let mid = sorted.len() / 2;
            sorted.select_nth_unstable_by(mid, f64::total_cmp).1.sqrt()
        };
        let edge = mean_edge(self.patch.vertices(), self.patch.triangles());
        self.radius = (3.0 * self.params.sigma).max(0.5 * edge).max(4.0 * spacing);
        let items: Vec<(u32, Point3<f64>)> =
            points.iter().enumerate().map(|(i, p)| (i as u32, *p)).collect();
        self.grid = BucketGrid::new(&items, Vector3::repeat(self.radius.max(1e-9)));
        self.fits = vec![
            PointFit { status: PointStatus::Far, residual: f64::NAN, weight: 0.0 };
            points.len()
        ];
        self.points = points;
        // A new scan: the planes are found again at the next linearisation.
        self.anchor.clear();
    }

    /// The measured points (after any rigid correction).
    pub fn points(&self) -> &[Point3<f64>] {
        &self.points
    }

    /// Each point against the surface at the last [`classify`](Self::classify).
    pub fn fits(&self) -> &[PointFit] {
        &self.fits
    }

    /// The robust scale of the points' distances at the last classification (length units).
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The settings.
    pub fn params(&self) -> SurfaceParams {
        self.params
    }

    /// The radius of the scan's neighbourhoods (length units).
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The patch's mean edge length at the last linearisation.
    pub fn mean_edge(&self) -> f64 {
        mean_edge(self.patch.vertices(), self.patch.triangles())
    }

    /// Sets the data stiffness per area (the springs are made again at the next
    /// linearisation).
    pub fn set_stiffness(&mut self, stiffness: f64) {
        self.params.stiffness = stiffness;
        self.anchor.clear();
    }

    /// Sets the sliding prior ([`slide`]; `None`: sliding is free), made into springs at
    /// the next linearisation.
    pub fn set_slide(&mut self, slide: Option<Slide>) {
        self.slide = slide;
        self.anchor.clear();
    }

    /// The sliding prior.
    pub fn slide(&self) -> Option<Slide> {
        self.slide
    }

    /// The patch's mean inward normal where the term was made (the default direction of the
    /// sliding prior; `None` if its normals cancel).
    pub fn inward_normal(&self) -> Option<Vector3<f64>> {
        slide::inward_normal(&self.reference, self.patch.triangles())
    }

    /// The patch's area where the term was made.
    pub fn area(&self) -> f64 {
        self.lumped.iter().sum()
    }

    /// The model nodes of the patch.
    pub fn patch_nodes(&self) -> &[usize] {
        &self.nodes
    }

    /// The reference patch area the scan covered at the last linearisation (`Σ A_f/3 · c_q`).
    pub fn covered_area(&self) -> f64 {
        self.planes
            .iter()
            .enumerate()
            .filter_map(|(q, p)| p.map(|p| self.areas[q / 3] / 3.0 * p.coverage))
            .sum()
    }

    /// The patch at `positions`, its vertex normals and areas.
    fn move_patch(&mut self, positions: &[Point3<f64>]) {
        for (v, &a) in self.vertices.iter_mut().zip(&self.nodes) {
            *v = positions[a];
        }
        self.patch.update(&self.vertices);
        let n = self.vertices.len();
        self.normals.clear();
        self.normals.resize(n, Vector3::zeros());
        for t in self.patch.triangles() {
            let [a, b, c] = t.map(|k| self.vertices[k as usize]);
            let m = (b - a).cross(&(c - a));
            for &k in t {
                self.normals[k as usize] += m;
            }
        }
        for v in &mut self.normals {
            let l = v.norm();
            if l > 0.0 {
                *v /= l;
            }
        }
    }

    /// Every point measured against the patch at `positions`: its signed distance, and
    /// inlier or outlier by the biweight at the robust scale of those distances; points
    /// whose closest patch point is on the border, or that are farther than `max_distance`,
    /// apart. (For the reports; the fit itself does not use it.)
    pub fn classify(&mut self, positions: &[Point3<f64>]) {
        self.move_patch(positions);
        let (patch, border, max) = (&self.patch, &self.border, self.params.max_distance);
        let tiny = 1e-9 * (1.0 + self.radius);
        let raw: Vec<(PointStatus, f64)> = self
            .points
            .par_iter()
            .map(|p| match patch.closest(p, max) {
                None => (PointStatus::Far, f64::NAN),
                Some(at) if on_border(patch, border, &at.point, tiny) => {
                    (PointStatus::Border, at.distance)
                }
                Some(at) => {
                    let [a, b, c] =
                        patch.triangles()[at.face as usize].map(|k| patch.vertices()[k as usize]);
                    let n = (b - a).cross(&(c - a));
                    let sign = if n.dot(&(p - at.point)) < 0.0 { -1.0 } else { 1.0 };
                    (PointStatus::Inlier, sign * at.distance)
                }
            })
            .collect();
        let matched = raw.iter().filter(|(s, _)| *s == PointStatus::Inlier).map(|(_, r)| *r);
        self.scale = robust::scale(matched, self.params.sigma, &mut Vec::new());
        for (f, (status, r)) in self.fits.iter_mut().zip(raw) {
            *f = match status {
                PointStatus::Inlier => {
                    let w = robust::tukey(r, self.scale);
                    let status = if w > 0.0 { PointStatus::Inlier } else { PointStatus::Outlier };
                    PointFit { status, residual: r, weight: w }
                }
                s => PointFit { status: s, residual: r, weight: 0.0 },
            };
        }
    }
}

/// The area of each face at `positions` (the reference): the data energy is an integral
/// over the reference patch, so the springs' weights do not change as it deforms.
fn triangles_areas(positions: &[Point3<f64>], faces: &[[usize; 3]]) -> Vec<f64> {
    faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|k| positions[k]);
            0.5 * (b - a).cross(&(c - a)).norm()
        })
        .collect()
}

/// Whether patch point `q` lies on a border edge.
fn on_border(patch: &Patch, border: &[[u32; 2]], q: &Point3<f64>, tiny: f64) -> bool {
    let v = patch.vertices();
    border.iter().any(|e| {
        let (a, b) = (v[e[0] as usize], v[e[1] as usize]);
        (bs_contact::geometry::closest_point_segment(q, &a, &b).0 - q).norm() <= tiny
    })
}

/// The mean edge length of triangles.
fn mean_edge(v: &[Point3<f64>], triangles: &[[u32; 3]]) -> f64 {
    let sum: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|k| v[k as usize]);
            (b - a).norm() + (c - b).norm() + (a - c).norm()
        })
        .sum();
    if triangles.is_empty() { 1.0 } else { sum / (3 * triangles.len()) as f64 }
}

/// The border edges of a patch: edges that belong to one patch face only.
fn border_edges(triangles: &[[u32; 3]]) -> Vec<[u32; 2]> {
    let mut count = std::collections::HashMap::new();
    let key = |a: u32, b: u32| if a < b { [a, b] } else { [b, a] };
    for t in triangles {
        for i in 0..3 {
            *count.entry(key(t[i], t[(i + 1) % 3])).or_insert(0usize) += 1;
        }
    }
    let mut edges: Vec<[u32; 2]> =
        count.into_iter().filter(|(_, c)| *c == 1).map(|(e, _)| e).collect();
    edges.sort_unstable();
    edges
}

/// The barycentric coordinates of a face's three quadrature points (exact for quadratic
/// integrands on a triangle).
const QUADRATURE: [[f64; 3]; 3] = [
    [2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0],
    [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0],
    [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0],
];

impl SurfaceFit {
    /// Quadrature point `q`'s face corners (patch vertices), weights, position and the
    /// interpolated vertex normal there (the axis of its cylinder).
    fn quadrature(&self, q: usize) -> ([u32; 3], [f64; 3], Point3<f64>, Vector3<f64>) {
        let t = self.patch.triangles()[q / 3];
        let w = QUADRATURE[q % 3];
        let x = Point3::from(
            (0..3).map(|k| self.vertices[t[k] as usize].coords * w[k]).sum::<Vector3<f64>>(),
        );
        let n: Vector3<f64> = (0..3).map(|k| self.normals[t[k] as usize] * w[k]).sum();
        let n = if n.norm() > 0.0 { n.normalize() } else { Vector3::z() };
        (t, w, x, n)
    }
}

impl DataTerm for SurfaceFit {
    fn linearise(&mut self, positions: &[Point3<f64>], springs: &mut Springs) {
        let moved = self
            .anchor
            .iter()
            .zip(&self.nodes)
            .map(|(x, &a)| (positions[a] - x).norm())
            .fold(0.0f64, f64::max);
        if self.anchor.len() == self.nodes.len() && moved <= REFRESH * self.radius {
            springs.clone_from(&self.springs);
            return;
        }
        self.anchor = self.nodes.iter().map(|&a| positions[a]).collect();
        self.planes_at(positions);
        springs.clone_from(&self.springs);
    }
}

/// The planes are looked for again once a patch node has moved this many radii from where
/// they were last found; between, the springs stay as they are.
const REFRESH: f64 = 0.2;

impl SurfaceFit {
    /// The planes of every quadrature point at `positions`, and their springs.
    fn planes_at(&mut self, positions: &[Point3<f64>]) {
        let mut springs = std::mem::take(&mut self.springs);
        springs.clear();
        self.move_patch(positions);
        let c = Cylinder {
            radius: self.radius,
            length: self.params.max_distance,
            sigma: self.params.sigma,
        };
        let reach = self.params.max_distance + plane::TILT * self.radius;
        let count = 3 * self.patch.triangles().len();
        let this = &*self;
        let planes: Vec<Option<LocalPlane>> = (0..count)
            .into_par_iter()
            .map_init(
                || (Vec::new(), Vec::<plane::Sample>::new()),
                |(near, scratch), q| {
                    let (_, _, x, n) = this.quadrature(q);
                    near.clear();
                    this.grid
                        .for_each_in_box(&x, reach, |id, _| near.push(this.points[id as usize]));
                    let nearest =
                        this.grid.nearest(&x, false).map_or(f64::INFINITY, |m| m.d2.sqrt());
                    plane::fit(&x, &n, near, &c, nearest, scratch)
                },
            )
            .collect();
        self.planes = planes;
        for (q, plane) in self.planes.iter().enumerate() {
            let Some(p) = plane else { continue };
            let (t, w, _, _) = self.quadrature(q);
            let (direction, target) = (p.normal, p.normal.dot(&p.point.coords));
            springs.push(Spring {
                nodes: [
                    self.nodes[t[0] as usize],
                    self.nodes[t[1] as usize],
                    self.nodes[t[2] as usize],
                    0,
                ],
                weights: [w[0], w[1], w[2], 0.0],
                direction,
                target,
                stiffness: self.params.stiffness * self.areas[q / 3] / 3.0 * p.coverage,
            });
        }
        if let Some(s) = &self.slide {
            slide::push_springs(s, &self.nodes, &self.reference, &self.lumped, &mut springs);
        }
        self.springs = springs;
    }
}

#[cfg(test)]
mod tests;
