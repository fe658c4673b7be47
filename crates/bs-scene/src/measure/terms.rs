//! Composition: the prepared measurements become bs-fit's data terms. A scan with bone
//! points first has its rigid misalignment estimated against the skull and undone; each
//! scan's data stiffness comes from the shear modulus of the tissue under it, its noise and
//! the area it covers ([`bs_fit::surface_stiffness`]).

use bs_contact::Patch;
use bs_dr::{DataTerm, Springs};
use bs_fit::{Fits, LandmarkFit, RigidFit, RigidParams, SurfaceFit, SurfaceParams, Term};
use bs_mesh::{Point3, TriSurface};

use super::{Measured, MeasuredData};
use crate::SceneError;
use crate::prepare::Prepared;

/// The prior of the rigid fit, in mm and degrees: several times a navigation system's
/// registration error (1–2 mm, 1–2°), so only the motions the bone does not observe feel it.
const PRIOR_TRANSLATION_MM: f64 = 5.0;
const PRIOR_ROTATION_DEGREES: f64 = 5.0;

/// The data terms of a scene and what composing them found.
#[derive(Debug, Clone)]
pub struct FitState {
    /// Every measurement as one data term (the solver's).
    pub fits: Fits,
    /// Per measurement: the rigid misalignment estimated from its bone points.
    pub rigid: Vec<Option<RigidFit>>,
    /// Per measurement: the data stiffness per area and the area covered at composition.
    pub stiffness: Vec<f64>,
    pub covered_area: Vec<f64>,
    /// The springs of the last linearisation at the answer (verification's data forces).
    pub springs: Springs,
    /// Model solves the last fit took (landmarks are fitted by a sequence of solves,
    /// crate::inverse; a scan by one).
    pub solves: usize,
    /// How far the data pull at composition: the largest matched residual (the length
    /// scale of the fit, in place of a prescribed displacement's).
    pub reach: f64,
}

/// The data terms of `p`'s measurements, `None` without any.
pub fn compose_fits(p: &Prepared) -> Result<Option<FitState>, SceneError> {
    if p.measurements.is_empty() {
        return Ok(None);
    }
    let mut terms = Vec::new();
    let (mut rigid, mut stiffness, mut covered) = (Vec::new(), Vec::new(), Vec::new());
    let mut reach = 0.0f64;
    for m in &p.measurements {
        let (term, fit, kappa, area, pull) = match &m.data {
            MeasuredData::Surface { points, faces, face_elements, bone, slide, .. } => {
                let scan =
                    Scan { points, faces, face_elements, bone: bone.as_ref(), slide: *slide };
                surface_term(p, m, &scan)?
            }
            MeasuredData::Landmarks { pairs, anchors, .. } => landmark_term(m, pairs, anchors),
        };
        reach = reach.max(pull);
        terms.push(term);
        rigid.push(fit);
        stiffness.push(kappa);
        covered.push(area);
    }
    Ok(Some(FitState {
        fits: Fits::new(terms),
        rigid,
        stiffness,
        covered_area: covered,
        springs: Springs::new(),
        solves: 1,
        reach,
    }))
}

/// One composed measurement: its term, its rigid fit, its stiffness, the area it covers
/// and how far it pulls.
type MeasurementTerm = (Term, Option<RigidFit>, f64, f64, f64);

/// What a scan measurement holds (the fields of `MeasuredData::Surface`).
struct Scan<'a> {
    points: &'a [Point3<f64>],
    faces: &'a [[usize; 3]],
    face_elements: &'a [usize],
    bone: Option<&'a (std::path::PathBuf, Vec<Point3<f64>>)>,
    slide: Option<Option<bs_mesh::Vector3<f64>>>,
}

/// A scan's term: misalignment undone, stiffness per area and sliding prior from the tissue
/// under it.
fn surface_term(
    p: &Prepared,
    m: &Measured,
    scan: &Scan<'_>,
) -> Result<MeasurementTerm, SceneError> {
    let fit = match scan.bone {
        Some((_, b)) if m.rigid => Some(estimate_rigid(p, m, b)?),
        _ => None,
    };
    let corrected: Vec<Point3<f64>> = match &fit {
        Some(f) => scan.points.iter().map(|q| f.rigid.apply(q)).collect(),
        None => scan.points.to_vec(),
    };
    let mu = tissue_modulus(p, scan.face_elements);
    let params = SurfaceParams { sigma: m.sigma, stiffness: 1.0, max_distance: m.max_distance };
    let mut term = SurfaceFit::new(corrected, scan.faces, &p.mesh.nodes, params);
    term.set_slide(slide_prior(&term, scan.slide, mu));
    let mut springs = Springs::new();
    term.linearise(&p.mesh.nodes, &mut springs);
    term.classify(&p.mesh.nodes);
    let area = term.covered_area();
    let kappa = bs_fit::surface_stiffness(mu, m.sigma, area, term.mean_edge());
    term.set_stiffness(kappa);
    let pull = term
        .fits()
        .iter()
        .filter(|f| f.status == bs_fit::PointStatus::Inlier)
        .map(|f| f.residual.abs())
        .fold(0.0, f64::max);
    Ok((Term::Surface(Box::new(term)), fit, kappa, area, pull))
}

/// Landmarks' term: it measures (stiffness zero); the fit goes through the boundary
/// (crate::inverse). Its pull is the largest landmark displacement.
fn landmark_term(
    m: &Measured,
    pairs: &super::pairs::Pairs,
    anchors: &[(usize, bs_fit::Anchor)],
) -> MeasurementTerm {
    let pull = pairs.pre.iter().zip(&pairs.intra).map(|(a, b)| (b - a).norm()).fold(0.0, f64::max);
    let fit = LandmarkFit::new(
        anchors.iter().map(|(_, a)| *a).collect(),
        pairs.intra.clone(),
        m.sigma,
        vec![0.0; anchors.len()],
    );
    (Term::Landmarks(fit), None, 0.0, 0.0, pull)
}

/// The sliding prior of a scan's term: `slide` is `None` for free sliding, else the sag
/// direction (`None`: the patch's mean inward normal); `mu` the tissue's shear modulus.
pub(crate) fn slide_prior(
    term: &SurfaceFit,
    slide: Option<Option<bs_mesh::Vector3<f64>>>,
    mu: f64,
) -> Option<bs_fit::Slide> {
    let direction = slide?.or_else(|| term.inward_normal())?;
    Some(bs_fit::Slide { direction, stiffness: bs_fit::slide_stiffness(mu, term.area()) })
}

/// The shear modulus of the stiffest tissue under a scan's faces (Pa).
pub(crate) fn tissue_modulus(p: &Prepared, face_elements: &[usize]) -> f64 {
    face_elements.iter().map(|&e| shear_modulus(p, e)).fold(0.0f64, f64::max)
}

/// The shear modulus of element `e`'s material (Pa).
pub(crate) fn shear_modulus(p: &Prepared, e: usize) -> f64 {
    p.scene.regions[p.region_of_element[e]].material.moduli().map_or(0.0, |m| m.mu)
}

/// The scan's misalignment from its bone points against the skull.
fn estimate_rigid(
    p: &Prepared,
    m: &Measured,
    bone: &[Point3<f64>],
) -> Result<RigidFit, SceneError> {
    let skull: &TriSurface = p.skull.as_ref().expect("checked at preparation: bone needs a skull");
    let patch = Patch::new(
        skull.vertices.clone(),
        skull.triangles.iter().map(|t| t.map(|k| k as u32)).collect(),
    );
    let mm = 1e-3 / p.scene.units.metres();
    let params = RigidParams {
        sigma: m.sigma,
        prior_translation: PRIOR_TRANSLATION_MM * mm,
        prior_rotation: PRIOR_ROTATION_DEGREES.to_radians(),
        max_distance: m.max_distance,
        iterations: 50,
    };
    bs_fit::fit_rigid(bone, &patch, &params).map_err(|e| match e {
        bs_fit::RigidError::TooFewMatched { matched, given } => SceneError::Read {
            scene: p.path.clone(),
            key: format!("{} skull_points", m.key()),
            message: format!(
                "only {matched} of {given} bone points lie within max_distance = {} of the \
                 skull; at least 6 are needed to estimate a rigid misalignment (check the \
                 points' frame and units)",
                m.max_distance
            ),
        },
    })
}
