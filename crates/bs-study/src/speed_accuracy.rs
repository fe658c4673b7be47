//! The speed-against-accuracy study's points, typed end to end: one solved (or failed)
//! configuration ([`ChartPoint`]), the Pareto front, the cheapest configuration per accuracy
//! target, the CSV and markdown the chart writes, and the findings `brainshift check` embeds
//! (bs-scene's `speed_accuracy::Findings`, built by [`findings_of`]).

use std::fmt::Write as _;

use bs_scene::speed_accuracy::{CaseFindings, Findings, Target};

/// Accuracy targets named in the findings (mean nodal error, mm).
pub const TARGETS: [f64; 2] = [0.1, 0.5];

/// One solved (or failed) configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct ChartPoint {
    /// Case name (`ellipsoid`, `mni152`).
    pub case: String,
    /// Legend entry the point belongs to.
    pub series: String,
    /// Mesh level label.
    pub level: String,
    /// Element technology (`t4`, `t4anp`) or CalculiX's element.
    pub element: String,
    /// `dr`, `newton` or `calculix`.
    pub solver: String,
    /// Contact handler (`none` without skull, `penalty` for CalculiX).
    pub handler: String,
    /// DR/Newton tolerance (mm); NaN for CalculiX.
    pub tolerance: f64,
    /// Nodes of the mesh.
    pub nodes: usize,
    /// Mean element edge of the mesh (mm).
    pub mean_edge: f64,
    /// Bounding-box diagonal of the mesh (mm).
    pub diagonal: f64,
    /// Wall time: setup and solve (s).
    pub seconds: f64,
    /// DR steps or Newton iterations (0 for CalculiX).
    pub steps: usize,
    /// Mean nodal |u − u_ref| (mm).
    pub mean_error: f64,
    /// Largest nodal |u − u_ref| (mm).
    pub max_error: f64,
    /// Mean nodal |u − u_ccx(K=10)| where that reference exists on this mesh (mm).
    pub mean_error_ccx: Option<f64>,
    /// Whether this point is the case's reference (error 0 by definition).
    pub is_reference: bool,
}

impl ChartPoint {
    /// A short name of the configuration.
    pub fn label(&self) -> String {
        if self.solver == "calculix" {
            return format!("CalculiX {} ({})", self.handler, self.level);
        }
        format!(
            "{} {} {} tol {:.0e}{}",
            self.level,
            self.element,
            self.solver,
            self.tolerance,
            if self.handler == "none" { String::new() } else { format!(" {}", self.handler) }
        )
    }
}

/// Indices of the points on the Pareto front (no other point is both faster and more
/// accurate), sorted by time. Reference points and CalculiX are left out: the front is of
/// brainshift's own configurations.
pub fn pareto_front(points: &[ChartPoint]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..points.len())
        .filter(|&i| {
            let p = &points[i];
            !p.is_reference && p.solver != "calculix" && p.seconds.is_finite()
        })
        .collect();
    idx.sort_by(|&a, &b| {
        points[a]
            .seconds
            .total_cmp(&points[b].seconds)
            .then(points[a].mean_error.total_cmp(&points[b].mean_error))
    });
    let mut front = Vec::new();
    let mut best = f64::INFINITY;
    for i in idx {
        if points[i].mean_error < best {
            best = points[i].mean_error;
            front.push(i);
        }
    }
    front
}

/// The fastest of brainshift's configurations whose mean error is within `target`.
pub fn cheapest(points: &[ChartPoint], target: f64) -> Option<&ChartPoint> {
    points
        .iter()
        .filter(|p| !p.is_reference && p.solver != "calculix" && p.mean_error <= target)
        .min_by(|a, b| a.seconds.total_cmp(&b.seconds))
}

/// The points as CSV (one row each).
/// The points as CSV (one row per point; the mesh diagonal is not stored).
pub fn to_csv(points: &[ChartPoint]) -> String {
    let mut s = String::from(
        "case,series,level,element,solver,handler,tolerance_mm,nodes,mean_edge_mm,seconds,steps,\
         mean_error_mm,max_error_mm,mean_error_vs_ccx_k10_mm,reference\n",
    );
    for p in points {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{:e},{},{:.3},{:.3},{},{:.4e},{:.4e},{},{}",
            p.case,
            p.series,
            p.level,
            p.element,
            p.solver,
            p.handler,
            p.tolerance,
            p.nodes,
            p.mean_edge,
            p.seconds,
            p.steps,
            p.mean_error,
            p.max_error,
            p.mean_error_ccx.map_or(String::new(), |e| format!("{e:.4e}")),
            p.is_reference
        );
    }
    s
}

/// The findings of a case: the cheapest configuration per target and the Pareto front.
pub fn markdown(case: &str, points: &[ChartPoint]) -> String {
    let mut s = format!("### {case}\n\n");
    if let Some(r) = points.iter().find(|p| p.is_reference) {
        let _ = writeln!(
            s,
            "Reference: {} ({} nodes, mean edge {:.2} mm), {:.1} s, {} steps.\n",
            r.label(),
            r.nodes,
            r.mean_edge,
            r.seconds,
            r.steps
        );
    }
    s.push_str("| target (mean error) | cheapest configuration | time (s) | mean / max error (mm) |\n|---|---|---:|---|\n");
    for t in TARGETS {
        match cheapest(points, t) {
            Some(p) => {
                let _ = writeln!(
                    s,
                    "| ≤ {t} mm | {} (mean edge {:.2} mm) | {:.2} | {:.3} / {:.3} |",
                    p.label(),
                    p.mean_edge,
                    p.seconds,
                    p.mean_error,
                    p.max_error
                );
            }
            None => {
                let _ = writeln!(s, "| ≤ {t} mm | none measured meets it | | |");
            }
        }
    }
    s.push_str("\nPareto front (fastest first):\n\n| configuration | time (s) | mean error (mm) | vs CalculiX K=10 (mm) |\n|---|---:|---:|---:|\n");
    for i in pareto_front(points) {
        let p = &points[i];
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.3e} | {} |",
            p.label(),
            p.seconds,
            p.mean_error,
            p.mean_error_ccx.map_or("–".into(), |e| format!("{e:.3e}"))
        );
    }
    for p in points.iter().filter(|p| p.solver == "calculix") {
        let _ = writeln!(
            s,
            "\n{}: {:.1} s (stored run time), mean error {:.3e} mm, max {:.3e} mm.",
            p.label(),
            p.seconds,
            p.mean_error,
            p.max_error
        );
    }
    s
}

/// Points read back from [`to_csv`]'s text (`source` names it in messages); the diagonal of
/// each mesh level comes from `diagonal_of(level)`.
pub fn from_csv(
    text: &str,
    source: &str,
    diagonal_of: &dyn Fn(&str) -> f64,
) -> Result<Vec<ChartPoint>, String> {
    let mut points = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let bad = |what: &str| format!("{source}:{}: {what}", n + 1);
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 15 {
            return Err(bad("expected 15 columns"));
        }
        let num = |i: usize| {
            f[i].parse::<f64>().map_err(|_| bad(&format!("column {} is not a number", i + 1)))
        };
        let int = |i: usize| {
            f[i].parse::<usize>().map_err(|_| bad(&format!("column {} is not a count", i + 1)))
        };
        points.push(ChartPoint {
            case: f[0].into(),
            series: f[1].into(),
            level: f[2].into(),
            element: f[3].into(),
            solver: f[4].into(),
            handler: f[5].into(),
            tolerance: num(6)?,
            nodes: int(7)?,
            mean_edge: num(8)?,
            diagonal: diagonal_of(f[2]),
            seconds: num(9)?,
            steps: int(10)?,
            mean_error: num(11)?,
            max_error: num(12)?,
            mean_error_ccx: if f[13].is_empty() { None } else { Some(num(13)?) },
            is_reference: f[14] == "true",
        });
    }
    Ok(points)
}

/// The findings of solved cases: per case, its reference and the cheapest configuration
/// meeting each of [`TARGETS`]. Cases without a reference point are left out.
pub fn findings_of(all: &[(String, Vec<ChartPoint>)]) -> Findings {
    let cases = all
        .iter()
        .filter_map(|(case, points)| {
            let r = points.iter().find(|p| p.is_reference)?;
            let targets = TARGETS
                .iter()
                .filter_map(|&t| {
                    cheapest(points, t).map(|p| Target {
                        target_mm: t,
                        element: p.element.clone(),
                        solver: p.solver.clone(),
                        handler: p.handler.clone(),
                        tolerance_mm: p.tolerance,
                        mean_edge_mm: p.mean_edge,
                        seconds: p.seconds,
                        mean_error_mm: p.mean_error,
                        max_error_mm: p.max_error,
                        level: p.level.clone(),
                    })
                })
                .collect();
            Some(CaseFindings {
                case: case.clone(),
                reference_mean_edge_mm: r.mean_edge,
                diagonal_mm: r.diagonal,
                reference_seconds: r.seconds,
                targets,
            })
        })
        .collect();
    Findings {
        generated_by: "cargo xtask chart".into(),
        note: "cheapest configuration meeting each mean-error target, measured against the \
               finest converged solution"
            .into(),
        cases,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(seconds: f64, mean_error: f64) -> ChartPoint {
        ChartPoint {
            case: "t".into(),
            series: "s".into(),
            level: "l".into(),
            element: "t4".into(),
            solver: "dr".into(),
            handler: "paper".into(),
            tolerance: 1e-3,
            nodes: 1,
            mean_edge: 1.0,
            diagonal: 1.0,
            seconds,
            steps: 1,
            mean_error,
            max_error: mean_error,
            mean_error_ccx: None,
            is_reference: false,
        }
    }

    /// The front of a hand-made set, checked against the definition by brute force: a point
    /// is on it iff no other point is at least as fast and strictly more accurate.
    #[test]
    fn pareto_front_matches_its_definition() {
        let pts: Vec<ChartPoint> =
            [(1.0, 0.5), (2.0, 0.6), (2.0, 0.2), (3.0, 0.2), (4.0, 0.05), (5.0, 0.3), (6.0, 0.01)]
                .iter()
                .map(|&(s, e)| point(s, e))
                .collect();
        let front = pareto_front(&pts);
        assert_eq!(front, vec![0, 2, 4, 6]);
        for (i, p) in pts.iter().enumerate() {
            let dominated = pts.iter().enumerate().any(|(j, q)| {
                j != i
                    && q.seconds <= p.seconds
                    && q.mean_error <= p.mean_error
                    && (q.seconds < p.seconds || q.mean_error < p.mean_error)
            });
            assert_eq!(front.contains(&i), !dominated, "point {i}");
        }
        assert_eq!(cheapest(&pts, 0.25).map(|p| p.seconds), Some(2.0));
        assert_eq!(cheapest(&pts, 0.001), None);
    }

    /// References and CalculiX never count as brainshift's configurations.
    #[test]
    fn references_and_calculix_are_not_candidates() {
        let mut r = point(0.1, 0.0);
        r.is_reference = true;
        let mut c = point(0.2, 0.0);
        c.solver = "calculix".into();
        let pts = vec![r, c, point(1.0, 0.3)];
        assert_eq!(pareto_front(&pts), vec![2]);
        assert_eq!(cheapest(&pts, 0.5).map(|p| p.seconds), Some(1.0));
    }

    /// What the chart writes is what `check` reads: the findings of hand-made points
    /// survive a JSON round trip, and each target is the cheapest point meeting it.
    #[test]
    fn findings_round_trip_through_json() {
        let mut r = point(9.0, 0.0);
        r.is_reference = true;
        let all =
            vec![("t".to_string(), vec![r, point(1.0, 0.4), point(3.0, 0.05), point(2.0, 0.3)])];
        let f = findings_of(&all);
        let back: Findings = serde_json::from_str(&serde_json::to_string(&f).unwrap()).unwrap();
        assert_eq!(back, f);
        let t: Vec<(f64, f64)> =
            f.cases[0].targets.iter().map(|t| (t.target_mm, t.seconds)).collect();
        assert_eq!(t, vec![(0.1, 3.0), (0.5, 1.0)]);
        assert_eq!(f.cases[0].reference_seconds, 9.0);
    }

    /// The CSV the chart writes reads back to the same points (numbers at the precision it
    /// prints).
    #[test]
    fn points_round_trip_through_csv() {
        let mut p = point(1.25, 0.0123);
        p.mean_error_ccx = Some(0.5);
        let back = from_csv(&to_csv(std::slice::from_ref(&p)), "t", &|_| 1.0).unwrap();
        assert_eq!(back, vec![p]);
    }
}
