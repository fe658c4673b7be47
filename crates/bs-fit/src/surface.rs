//! A scanned surface fitted point-to-surface: the data term of a `[[measurement]] points`.
//!
//! At every linearisation each measured point `p` is matched with its closest point `q` on
//! the deformed patch (the boundary faces of the measurement's node set, through
//! bs-contact's [`Patch`]): inside a face the spring runs along the face normal
//! (point-to-plane: sliding along the surface costs nothing, as a scan cannot see it), on
//! an inner edge or corner along `q − p`. A point whose closest point is on the patch's
//! border is no evidence about the patch (the surface goes on beyond it) and one farther
//! than `max_distance` is not matched at all; neither pulls.
//!
//! The energy of the matched points is
//!
//! `E_d = Σ_f Σ_{i ∈ f} κ A_f w_i / (Σ_{j ∈ f} w_j) · ½ r_i²`,
//!
//! a spring of stiffness per area `κ` spread over each face `f` of area `A_f` by the
//! points that fall on it, each in proportion to its robust weight `w_i` ([`crate::robust`],
//! Tukey's biweight at the re-estimated scale). A face carries the same weight whether a
//! scanner puts one point or fifty on it: the answer does not depend on the point density,
//! and the dense scan's many points per face average their noise. `κ` comes from the noise
//! and the tissue ([`surface_stiffness`]).

use bs_contact::geometry::TriRegion;
use bs_contact::{Patch, PatchPoint};
use bs_dr::{DataTerm, Spring, Springs};
use bs_mesh::{Point3, Vector3};
use rayon::prelude::*;

use crate::robust;

/// The data stiffness per area of a scanned surface, `κ = μ L / σ²`: `μ` the shear modulus
/// of the tissue under the scan, `σ` the scan's noise and `L = √A` the size of the area it
/// covers.
///
/// Why: the brain resists a surface displacement of wavelength `λ` with a stiffness per
/// area of about `4π μ / λ` (an incompressible half-space). The shift a scan measures has
/// the scale of the covered area (`λ ≈ 2L`), noise the scale of the point spacing. With
/// `κ = μ L/σ²` the data outweigh the model at the shift's scale by `L²/(2π σ²)` (about 140
/// for a 30 mm window at σ = 1 mm: the fitted shift is 99 % of the measured one) while a
/// noisier scan (σ = 2 mm: 35) lets the model smooth more. The weight falls as `1/σ²`, as a
/// Gaussian likelihood's does; units: stiffness per area (Pa per length unit).
pub fn surface_stiffness(mu: f64, sigma: f64, covered_area: f64) -> f64 {
    mu * covered_area.max(0.0).sqrt() / (sigma * sigma)
}

/// The settings of a [`SurfaceFit`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceParams {
    /// The measurement's noise (standard deviation, length units): the floor of the robust
    /// scale.
    pub sigma: f64,
    /// The data stiffness per area `κ` ([`surface_stiffness`]).
    pub stiffness: f64,
    /// Points farther than this from the patch are not matched.
    pub max_distance: f64,
}

/// How a measured point took part in the last linearisation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PointStatus {
    /// Matched, with a robust weight above zero.
    Inlier,
    /// Matched, rejected by the robust loss (beyond its cut-off).
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

/// One measured point at the last linearisation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointFit {
    /// How it took part.
    pub status: PointStatus,
    /// Its signed distance from the patch (positive outside the brain, along the outward
    /// normal), length units; the unsigned distance for `Border`, NaN for `Far`.
    pub residual: f64,
    /// Its robust weight in [0, 1] (0 unless `Inlier`).
    pub weight: f64,
}

/// A matched point: its closest patch point and the spring's direction.
#[derive(Debug, Clone, Copy)]
struct Match {
    at: PatchPoint,
    direction: Vector3<f64>,
    /// The signed residual (outside positive) and the spring's residual along `direction`.
    signed: f64,
    along: f64,
}

/// The data term of a scanned surface (see the module documentation).
#[derive(Debug, Clone)]
pub struct SurfaceFit {
    points: Vec<Point3<f64>>,
    /// Patch vertex → model node.
    nodes: Vec<usize>,
    patch: Patch,
    /// Per patch face and local edge `i → i+1`: the edge has no other patch face.
    border_edge: Vec<[bool; 3]>,
    border_vertex: Vec<bool>,
    params: SurfaceParams,
    fits: Vec<PointFit>,
    matches: Vec<Option<Match>>,
    scale: f64,
    scratch: Vec<f64>,
    vertices: Vec<Point3<f64>>,
    face_weight: Vec<f64>,
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
        let (border_edge, border_vertex) = borders(&triangles, nodes.len());
        let vertices: Vec<Point3<f64>> = nodes.iter().map(|&a| positions[a]).collect();
        let n = points.len();
        let face_count = triangles.len();
        SurfaceFit {
            points,
            nodes,
            patch: Patch::new(vertices.clone(), triangles),
            border_edge,
            border_vertex,
            params,
            fits: vec![PointFit { status: PointStatus::Far, residual: f64::NAN, weight: 0.0 }; n],
            matches: vec![None; n],
            scale: params.sigma,
            scratch: Vec::with_capacity(n),
            vertices,
            face_weight: vec![0.0; face_count],
        }
    }

    /// The measured points (after any rigid correction).
    pub fn points(&self) -> &[Point3<f64>] {
        &self.points
    }

    /// Each point at the last linearisation.
    pub fn fits(&self) -> &[PointFit] {
        &self.fits
    }

    /// The robust scale of the last linearisation (length units).
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The settings.
    pub fn params(&self) -> SurfaceParams {
        self.params
    }

    /// Sets the data stiffness per area.
    pub fn set_stiffness(&mut self, stiffness: f64) {
        self.params.stiffness = stiffness;
    }

    /// Replaces the measured points (a new scan of the same patch); the next linearisation
    /// matches them.
    pub fn set_points(&mut self, points: Vec<Point3<f64>>) {
        let n = points.len();
        self.points = points;
        self.fits = vec![PointFit { status: PointStatus::Far, residual: f64::NAN, weight: 0.0 }; n];
        self.matches = vec![None; n];
    }

    /// The model nodes of the patch.
    pub fn patch_nodes(&self) -> &[usize] {
        &self.nodes
    }

    /// The area of the patch faces with at least one point inside the robust cut-off at
    /// the last linearisation (in the configuration of that linearisation).
    pub fn covered_area(&self) -> f64 {
        let mut covered = vec![false; self.patch.triangles().len()];
        for (m, f) in self.matches.iter().zip(&self.fits) {
            if let (Some(m), PointStatus::Inlier) = (m, f.status) {
                covered[m.at.face as usize] = true;
            }
        }
        covered.iter().enumerate().filter(|(_, c)| **c).map(|(i, _)| self.area(i)).sum()
    }

    fn area(&self, face: usize) -> f64 {
        let [a, b, c] = self.patch.triangles()[face].map(|k| self.patch.vertices()[k as usize]);
        0.5 * (b - a).cross(&(c - a)).norm()
    }

    /// Matches every point on the patch at `positions` (parallel; each point on its own, so
    /// the result does not depend on the thread count).
    fn match_points(&mut self, positions: &[Point3<f64>]) {
        for (v, &a) in self.vertices.iter_mut().zip(&self.nodes) {
            *v = positions[a];
        }
        self.patch.update(&self.vertices);
        let (patch, max) = (&self.patch, self.params.max_distance);
        let (be, bv) = (&self.border_edge, &self.border_vertex);
        self.points
            .par_iter()
            .zip(self.matches.par_iter_mut().zip(self.fits.par_iter_mut()))
            .for_each(|(p, (m, fit))| {
                *m = None;
                *fit = PointFit { status: PointStatus::Far, residual: f64::NAN, weight: 0.0 };
                let Some(at) = patch.closest(p, max) else { return };
                if on_border(patch, be, bv, &at) {
                    *fit = PointFit {
                        status: PointStatus::Border,
                        residual: at.distance,
                        weight: 0.0,
                    };
                    return;
                }
                *m = Some(spring_geometry(patch, p, at));
            });
    }
}

/// The direction and residuals of the spring of `p` matched at `at`.
fn spring_geometry(patch: &Patch, p: &Point3<f64>, at: PatchPoint) -> Match {
    let [a, b, c] = patch.triangles()[at.face as usize].map(|k| patch.vertices()[k as usize]);
    let normal = (b - a).cross(&(c - a));
    let normal = if normal.norm() > 0.0 { normal.normalize() } else { Vector3::z() };
    let gap = p - at.point;
    let direction = match at.region {
        TriRegion::Face => normal,
        _ if at.distance > 0.0 => gap / at.distance,
        _ => normal,
    };
    let sign = if normal.dot(&gap) < 0.0 { -1.0 } else { 1.0 };
    let signed = match at.region {
        TriRegion::Face => normal.dot(&gap),
        _ => sign * at.distance,
    };
    Match { at, direction, signed, along: -direction.dot(&gap) }
}

/// Whether a patch point lies on the patch's border (a border edge or vertex).
fn on_border(patch: &Patch, edge: &[[bool; 3]], vertex: &[bool], at: &PatchPoint) -> bool {
    let f = at.face as usize;
    match at.region {
        TriRegion::Face => false,
        TriRegion::Edge(i) => edge[f][i as usize],
        TriRegion::Vertex(i) => vertex[patch.triangles()[f][i as usize] as usize],
    }
}

/// The border edges (per face, local edge `i → i+1`) and border vertices of a patch: edges
/// that belong to one patch face only.
fn borders(triangles: &[[u32; 3]], vertices: usize) -> (Vec<[bool; 3]>, Vec<bool>) {
    let mut count = std::collections::HashMap::new();
    let key = |a: u32, b: u32| if a < b { (a, b) } else { (b, a) };
    for t in triangles {
        for i in 0..3 {
            *count.entry(key(t[i], t[(i + 1) % 3])).or_insert(0usize) += 1;
        }
    }
    let mut vertex = vec![false; vertices];
    let edge = triangles
        .iter()
        .map(|t| {
            std::array::from_fn(|i| {
                let border = count[&key(t[i], t[(i + 1) % 3])] == 1;
                if border {
                    vertex[t[i] as usize] = true;
                    vertex[t[(i + 1) % 3] as usize] = true;
                }
                border
            })
        })
        .collect();
    (edge, vertex)
}

impl DataTerm for SurfaceFit {
    fn linearise(&mut self, positions: &[Point3<f64>], springs: &mut Springs) {
        springs.clear();
        self.match_points(positions);
        let sigma = self.params.sigma;
        let residuals = self.matches.iter().flatten().map(|m| m.along);
        self.scale = robust::scale(residuals, sigma, &mut self.scratch);
        self.face_weight.iter_mut().for_each(|w| *w = 0.0);
        for (m, fit) in self.matches.iter().zip(self.fits.iter_mut()) {
            let Some(m) = m else { continue };
            let w = robust::tukey(m.along, self.scale);
            let status = if w > 0.0 { PointStatus::Inlier } else { PointStatus::Outlier };
            *fit = PointFit { status, residual: m.signed, weight: w };
            self.face_weight[m.at.face as usize] += w;
        }
        for (i, m) in self.matches.iter().enumerate() {
            let (Some(m), w) = (m, self.fits[i].weight) else { continue };
            if w == 0.0 {
                continue;
            }
            let face = m.at.face as usize;
            let k = self.params.stiffness * self.area(face) * w / self.face_weight[face];
            let t = self.patch.triangles()[face];
            let p = self.points[i];
            springs.push(Spring {
                nodes: [
                    self.nodes[t[0] as usize],
                    self.nodes[t[1] as usize],
                    self.nodes[t[2] as usize],
                    0,
                ],
                weights: [m.at.bary[0], m.at.bary[1], m.at.bary[2], 0.0],
                direction: m.direction,
                target: m.direction.dot(&p.coords),
                stiffness: k,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat square patch of 2 × 2 cells (8 triangles) in z = 0, outward +z.
    fn square() -> (Vec<Point3<f64>>, Vec<[usize; 3]>) {
        let mut p = Vec::new();
        for j in 0..3 {
            for i in 0..3 {
                p.push(Point3::new(i as f64, j as f64, 0.0));
            }
        }
        let mut t = Vec::new();
        for j in 0..2 {
            for i in 0..2 {
                let a = j * 3 + i;
                t.push([a, a + 1, a + 4]);
                t.push([a, a + 4, a + 3]);
            }
        }
        (p, t)
    }

    fn params() -> SurfaceParams {
        SurfaceParams { sigma: 0.1, stiffness: 2.0, max_distance: 1.0 }
    }

    /// Points above the patch pull along +z with residual −height; the springs of one face
    /// share the face's weight κ A; a point beyond the border and a far one do not pull.
    #[test]
    fn springs_follow_the_points_and_share_each_face() {
        let (x, faces) = square();
        let points = vec![
            Point3::new(0.6, 0.3, 0.2), // face 0 (triangle 0,1,4)
            Point3::new(0.7, 0.2, 0.1), // face 0 too
            Point3::new(1.6, 1.3, -0.1),
            Point3::new(2.5, 1.0, 0.0), // beyond the border x = 2
            Point3::new(1.0, 1.0, 5.0), // far
        ];
        let mut fit = SurfaceFit::new(points, &faces, &x, params());
        let mut springs = Springs::new();
        fit.linearise(&x, &mut springs);
        let status: Vec<_> = fit.fits().iter().map(|f| f.status).collect();
        assert_eq!(
            status,
            [
                PointStatus::Inlier,
                PointStatus::Inlier,
                PointStatus::Inlier,
                PointStatus::Border,
                PointStatus::Far
            ]
        );
        assert_eq!(springs.len(), 3);
        assert!((fit.fits()[0].residual - 0.2).abs() < 1e-12);
        assert!((fit.fits()[2].residual + 0.1).abs() < 1e-12);
        // Face 0 has area ½: its two springs share κ A = 1 in proportion to their weights.
        let k: f64 = springs.terms()[..2].iter().map(|s| s.stiffness).sum();
        assert!((k - 1.0).abs() < 1e-12, "{k}");
        // The spring measures along the normal, so the force on the patch pulls it towards
        // the point: f = k r d with r = −0.2 along +z for the first point.
        let zero = vec![Vector3::zeros(); x.len()];
        let r = springs.terms()[0].residual(&x, &zero);
        assert!((r.abs() - 0.2).abs() < 1e-12);
    }

    /// With a gross outlier among points at the noise level, the scale stays near σ and the
    /// outlier gets weight zero.
    #[test]
    fn a_gross_outlier_is_rejected() {
        let (x, faces) = square();
        let mut rng = bs_mesh::rng::SplitMix64::new(3);
        let mut points: Vec<_> = (0..200)
            .map(|_| Point3::new(rng.range(0.1, 1.9), rng.range(0.1, 1.9), 0.1 * rng.normal()))
            .collect();
        points.push(Point3::new(1.0, 1.0, 0.9));
        let mut fit = SurfaceFit::new(points, &faces, &x, params());
        let mut springs = Springs::new();
        fit.linearise(&x, &mut springs);
        assert!((fit.scale() - 0.1).abs() < 0.03, "{}", fit.scale());
        assert_eq!(fit.fits()[200].status, PointStatus::Outlier);
        let inliers = fit.fits().iter().filter(|f| f.status == PointStatus::Inlier).count();
        assert!(inliers >= 199, "{inliers}");
        assert!((fit.covered_area() - 4.0).abs() < 1e-12);
    }

    #[test]
    fn the_border_of_a_square_is_its_outline() {
        let (_, faces) = square();
        let tris: Vec<[u32; 3]> = faces.iter().map(|f| f.map(|a| a as u32)).collect();
        let (edge, vertex) = borders(&tris, 9);
        assert_eq!(edge.iter().flatten().filter(|&&b| b).count(), 8);
        assert_eq!(vertex.iter().filter(|&&b| b).count(), 8); // all but the centre
        assert!(!vertex[4]);
    }

    #[test]
    fn the_stiffness_rule_scales_with_area_and_noise() {
        assert_eq!(surface_stiffness(1000.0, 1.0, 900.0), 30_000.0);
        assert_eq!(surface_stiffness(1000.0, 2.0, 900.0), 7_500.0);
    }
}
