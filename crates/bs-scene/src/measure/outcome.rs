//! What a fit did, per measurement: report.json's `measurements` entries (points read,
//! matched, inliers, the residuals after the fit, the rigid correction, how far the data
//! moved the model) and residuals.csv's rows (one per point: position, residual, weight,
//! status).

use bs_fit::{PointStatus, Term};
use bs_mesh::Vector3;
use serde::{Deserialize, Serialize};

use super::{FitState, MeasuredData};
use crate::prepare::Prepared;

/// The rigid correction of a scan, `x ↦ R x + t` (scene frame and units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigidReport {
    /// Unit rotation axis.
    pub axis: [f64; 3],
    /// Rotation angle, degrees.
    pub angle_degrees: f64,
    /// Translation `t`.
    pub translation: [f64; 3],
    /// Bone points matched to the skull, and those inside the robust cut-off.
    pub bone_points: usize,
    pub bone_inliers: usize,
    /// RMS distance of the bone inliers to the skull before and after the correction.
    pub bone_rms_before: f64,
    pub bone_rms_after: f64,
}

/// What a measurement measured, as report.json names it (`"points"`, `"landmarks"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MeasurementKind {
    /// A scanned surface.
    Points,
    /// Landmark pairs.
    Landmarks,
}

/// One measurement after the fit (report.json's `measurements` entries).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeasurementReport {
    /// A scanned surface or landmark pairs.
    pub kind: MeasurementKind,
    /// The data file (landmarks from two markups files: both, comma-separated).
    pub file: String,
    /// The node set it pulled.
    pub nset: String,
    /// The noise it was given, and the robust scale at the answer (≥ sigma).
    pub sigma: f64,
    pub scale: f64,
    /// Points read; matched on the patch; inside the robust cut-off; rejected as outliers;
    /// on the patch's border (no evidence); farther than max_distance.
    pub points: usize,
    pub matched: usize,
    pub inliers: usize,
    pub outliers: usize,
    pub border: usize,
    pub far: usize,
    /// RMS and largest distance of the inliers from the fitted surface (landmarks: of the
    /// material points from their intra-operative positions).
    pub rms_residual: f64,
    pub max_residual: f64,
    /// The data stiffness per area (Pa per length unit) and the area it covered (landmarks:
    /// 0 and 0, they are fitted through the boundary).
    pub stiffness: f64,
    pub covered_area: f64,
    /// Model solves the fit took (landmarks: one per boundary update; a scan: 1).
    pub solves: usize,
    /// The rigid correction, when one was estimated.
    pub rigid: Option<RigidReport>,
    /// The sliding prior of a scan (docs/fit.md): the sag direction its patch moves along
    /// freely and the stiffness per area (Pa per length unit) resisting motion across it;
    /// `None` and 0 with `sliding = "free"` and for landmarks.
    #[serde(default)]
    pub sag_direction: Option<[f64; 3]>,
    #[serde(default)]
    pub sliding_stiffness: f64,
    /// How far the data moved the model: the largest and mean displacement of the nodes
    /// the measurement pulls.
    pub max_pull: f64,
    pub mean_pull: f64,
}

/// One point of residuals.csv.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointRow {
    /// The measurement (from 1, as in the scene's order) and the point (from 0).
    pub measurement: usize,
    pub point: usize,
    /// The point as read, and after the rigid correction (landmarks: the intra-operative
    /// position, twice).
    pub measured: [f64; 3],
    pub corrected: [f64; 3],
    /// Signed distance from the fitted surface (positive outside the brain); landmarks: the
    /// distance of the material point from its intra-operative position.
    pub residual: f64,
    /// Robust weight in [0, 1].
    pub weight: f64,
    /// `inlier`, `outlier`, `border` or `far`.
    pub status: &'static str,
}

/// The reports and rows of every measurement at displacements `u`.
pub fn outcome(
    p: &Prepared,
    state: &FitState,
    u: &[Vector3<f64>],
) -> (Vec<MeasurementReport>, Vec<PointRow>) {
    let mut reports = Vec::new();
    let mut rows = Vec::new();
    for (k, (m, term)) in p.measurements.iter().zip(&state.fits.terms).enumerate() {
        match (&m.data, term) {
            (MeasuredData::Surface { file, points, .. }, Term::Surface(fit)) => {
                let report = surface_report(state, k, m, file, points.len(), fit, u);
                reports.push(report);
                rows.extend(surface_rows(k, points, fit));
            }
            (MeasuredData::Landmarks { files, pairs, .. }, Term::Landmarks(fit)) => {
                reports.push(landmark_report(state, k, m, files, fit, u));
                rows.extend(landmark_rows(k, &pairs.intra, fit));
            }
            _ => unreachable!("terms are composed in the measurements' order and kind"),
        }
    }
    (reports, rows)
}

/// RMS and largest absolute value of the inliers' residuals.
fn inlier_residuals(fits: &[bs_fit::PointFit]) -> (f64, f64) {
    let inl: Vec<f64> =
        fits.iter().filter(|f| f.status == PointStatus::Inlier).map(|f| f.residual).collect();
    let rms = (inl.iter().map(|r| r * r).sum::<f64>() / inl.len().max(1) as f64).sqrt();
    (rms, inl.iter().map(|r| r.abs()).fold(0.0, f64::max))
}

fn count(fits: &[bs_fit::PointFit], s: PointStatus) -> usize {
    fits.iter().filter(|f| f.status == s).count()
}

fn surface_report(
    state: &FitState,
    k: usize,
    m: &super::Measured,
    file: &std::path::Path,
    points: usize,
    fit: &bs_fit::SurfaceFit,
    u: &[Vector3<f64>],
) -> MeasurementReport {
    let (rms, max) = inlier_residuals(fit.fits());
    let pulls: Vec<f64> = fit.patch_nodes().iter().map(|&a| u[a].norm()).collect();
    let rigid = state.rigid[k].map(|r| {
        let (axis, angle) = r.rigid.axis_angle_degrees();
        RigidReport {
            axis: axis.into(),
            angle_degrees: angle,
            translation: r.rigid.translation.into(),
            bone_points: r.matched,
            bone_inliers: r.inliers,
            bone_rms_before: r.rms_before,
            bone_rms_after: r.rms_after,
        }
    });
    let (inliers, outliers) =
        (count(fit.fits(), PointStatus::Inlier), count(fit.fits(), PointStatus::Outlier));
    MeasurementReport {
        kind: MeasurementKind::Points,
        file: file.display().to_string(),
        nset: m.nset.clone(),
        sigma: m.sigma,
        scale: fit.scale(),
        points,
        matched: inliers + outliers,
        inliers,
        outliers,
        border: count(fit.fits(), PointStatus::Border),
        far: count(fit.fits(), PointStatus::Far),
        rms_residual: rms,
        max_residual: max,
        stiffness: state.stiffness[k],
        covered_area: state.covered_area[k],
        solves: state.solves,
        rigid,
        sag_direction: fit.slide().map(|s| s.direction.into()),
        sliding_stiffness: fit.slide().map_or(0.0, |s| s.stiffness),
        max_pull: pulls.iter().copied().fold(0.0, f64::max),
        mean_pull: pulls.iter().sum::<f64>() / pulls.len().max(1) as f64,
    }
}

fn surface_rows(
    k: usize,
    points: &[bs_mesh::Point3<f64>],
    fit: &bs_fit::SurfaceFit,
) -> Vec<PointRow> {
    points
        .iter()
        .zip(fit.fits())
        .enumerate()
        .map(|(i, (q, f))| PointRow {
            measurement: k + 1,
            point: i,
            measured: q.coords.into(),
            corrected: fit.points()[i].coords.into(),
            residual: f.residual,
            weight: f.weight,
            status: f.status.name(),
        })
        .collect()
}

/// Landmarks: residuals are distances of each material point from its intra-operative
/// position (never negative); the pull is the displacement at the material points.
fn landmark_report(
    state: &FitState,
    k: usize,
    m: &super::Measured,
    files: &crate::scene::LandmarkFiles,
    fit: &bs_fit::LandmarkFit,
    u: &[Vector3<f64>],
) -> MeasurementReport {
    let (rms, max) = inlier_residuals(fit.fits());
    let pulls: Vec<f64> = fit
        .anchors()
        .iter()
        .map(|a| {
            a.nodes.iter().zip(&a.weights).map(|(&n, &b)| u[n] * b).sum::<Vector3<f64>>().norm()
        })
        .collect();
    let n = fit.fits().len();
    let (inliers, outliers) =
        (count(fit.fits(), PointStatus::Inlier), count(fit.fits(), PointStatus::Outlier));
    MeasurementReport {
        kind: MeasurementKind::Landmarks,
        file: files.describe(),
        nset: m.nset.clone(),
        sigma: m.sigma,
        scale: fit.scale(),
        points: n,
        matched: n,
        inliers,
        outliers,
        border: 0,
        far: 0,
        rms_residual: rms,
        max_residual: max,
        stiffness: state.stiffness[k],
        covered_area: 0.0,
        solves: state.solves,
        rigid: None,
        sag_direction: None,
        sliding_stiffness: 0.0,
        max_pull: pulls.iter().copied().fold(0.0, f64::max),
        mean_pull: pulls.iter().sum::<f64>() / pulls.len().max(1) as f64,
    }
}

fn landmark_rows(
    k: usize,
    intra: &[bs_mesh::Point3<f64>],
    fit: &bs_fit::LandmarkFit,
) -> Vec<PointRow> {
    intra
        .iter()
        .zip(fit.fits())
        .enumerate()
        .map(|(i, (q, f))| PointRow {
            measurement: k + 1,
            point: i,
            measured: q.coords.into(),
            corrected: q.coords.into(),
            residual: f.residual,
            weight: f.weight,
            status: f.status.name(),
        })
        .collect()
}

/// residuals.csv's text: a header, then one line per point.
pub fn residuals_csv(rows: &[PointRow]) -> String {
    let mut s = String::from(
        "measurement,point,x,y,z,x_corrected,y_corrected,z_corrected,residual,weight,status\n",
    );
    for r in rows {
        let [x, y, z] = r.measured;
        let [a, b, c] = r.corrected;
        s += &format!(
            "{},{},{x},{y},{z},{a},{b},{c},{},{},{}\n",
            r.measurement, r.point, r.residual, r.weight, r.status
        );
    }
    s
}
