//! "Model no more than a scene needs": what `brainshift check` advises, from the cheapest
//! configurations that `cargo xtask chart` measured on the benchmark cases (the MNI152
//! brain and the paper's ellipsoid; `docs/speed-accuracy.md`). The measurements are
//! embedded at build time ([`crate::speed_accuracy`]).

use crate::prepare::Prepared;
use crate::scene::ElementChoice;
use crate::speed_accuracy::{Findings, Target};

fn element_rank(e: &str) -> u8 {
    // T4ANP is at least as accurate as T4 on every mesh of the chart (T4 locks).
    match e {
        "t4anp" => 1,
        _ => 0,
    }
}

/// Advice lines for a scene: the benchmark case closest in size, its cheapest
/// configuration per target, and how the scene's own settings compare.
pub fn advise(p: &Prepared, f: &Findings) -> Vec<String> {
    let mm = p.scene.units.metres() * 1000.0;
    let diagonal = p.mesh.bounding_box().map_or(f64::NAN, |(a, b)| (b - a).norm()) * mm;
    let Some(case) = f.cases.iter().min_by(|a, b| {
        (a.diagonal_mm - diagonal).abs().total_cmp(&(b.diagonal_mm - diagonal).abs())
    }) else {
        return Vec::new();
    };
    let edge = bs_mesh::quality::mean_edge_length(&p.mesh) * mm;
    let tolerance = p.scene.solver.tolerance * mm;
    let element = p.element.name();
    let mut out = vec![format!(
        "advice (model no more than the scene needs): on the {} benchmark (`cargo xtask chart`, \
         docs/speed-accuracy.md) the cheapest configurations were",
        case.case
    )];
    for t in &case.targets {
        out.push(format!(
            "  mean error <= {} mm: {} with {}, mean edge {:.1} mm, tolerance {:.0e} mm \
             (measured mean {:.3} mm, max {:.2} mm; {:.1} s there)",
            t.target_mm,
            t.element,
            t.solver,
            t.mean_edge_mm,
            t.tolerance_mm,
            t.mean_error_mm,
            t.max_error_mm,
            t.seconds
        ));
    }
    let mut verdict =
        format!("  this scene: {element}, mean edge {edge:.1} mm, tolerance {tolerance:.0e} mm");
    if p.element == ElementChoice::H8 {
        verdict.push_str(" (no hexahedral benchmark: no comparison)");
        out.push(verdict);
        return out;
    }
    // A scene "uses at least" a configuration when its mesh is no coarser (10 % slack:
    // meshers do not hit a target edge exactly), its tolerance no looser and its element no
    // less accurate.
    let at_least = |t: &Target| {
        edge <= 1.1 * t.mean_edge_mm
            && tolerance <= t.tolerance_mm * (1.0 + 1e-9)
            && element_rank(element) >= element_rank(&t.element)
    };
    let mut targets: Vec<&Target> = case.targets.iter().collect();
    targets.sort_by(|a, b| a.target_mm.total_cmp(&b.target_mm));
    let met = targets.iter().find(|t| at_least(t));
    let loosest = targets.last().map_or(f64::NAN, |t| t.target_mm);
    verdict.push_str(&match met {
        Some(t) if t.target_mm < loosest => format!(
            ": at least the <= {} mm configuration; where <= {loosest} mm is enough, the \
             cheaper configuration above will do",
            t.target_mm
        ),
        Some(t) => {
            format!(": at least the <= {} mm configuration, not the tighter ones", t.target_mm)
        }
        None => format!(
            ": coarser than every measured configuration; expect a mean error above \
             {loosest} mm (refine the mesh, use t4anp or tighten the tolerance)"
        ),
    });
    out.push(verdict);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::speed_accuracy::CaseFindings;

    fn target(target_mm: f64, element: &str, mean_edge_mm: f64, tolerance_mm: f64) -> Target {
        Target {
            target_mm,
            element: element.into(),
            solver: "newton-krylov".into(),
            tolerance_mm,
            mean_edge_mm,
            seconds: 1.0,
            mean_error_mm: target_mm / 2.0,
            max_error_mm: target_mm,
            handler: "coherent".into(),
            level: "bench".into(),
        }
    }

    fn findings_with(targets: Vec<Target>) -> Findings {
        Findings {
            generated_by: "test".into(),
            note: String::new(),
            cases: vec![CaseFindings {
                case: "bench".into(),
                reference_mean_edge_mm: 0.1,
                diagonal_mm: 1.7,
                reference_seconds: 1.0,
                targets,
            }],
        }
    }

    /// The unit-cube T4 scene (tolerance 1e-10 mm) against hand-made findings: the verdict
    /// follows from comparing its mesh, element and tolerance with each target's.
    #[test]
    fn verdicts_compare_the_scene_with_each_target() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../fixtures/cube/uniaxial-t4.toml");
        let p = Prepared::load(&path).unwrap();
        let edge = bs_mesh::quality::mean_edge_length(&p.mesh);
        let last = |f: &Findings| advise(&p, f).last().cloned().unwrap();

        // Both targets reached with a coarser mesh and looser tolerance: the scene does at
        // least the tight one, and the loose one is cheaper.
        let f = findings_with(vec![
            target(0.1, "t4", 1.5 * edge, 1e-4),
            target(0.5, "t4", 3.0 * edge, 1e-2),
        ]);
        let v = last(&f);
        assert!(v.contains("at least the <= 0.1 mm configuration; where <= 0.5 mm"), "{v}");
        assert_eq!(advise(&p, &f).len(), 4, "{:?}", advise(&p, &f));

        // The tight target needs a mesh twice as fine: only the loose one is met.
        let f = findings_with(vec![
            target(0.1, "t4", 0.5 * edge, 1e-4),
            target(0.5, "t4", 3.0 * edge, 1e-2),
        ]);
        assert!(last(&f).contains("at least the <= 0.5 mm configuration, not the tighter"));

        // Both need T4ANP, which this T4 scene is not.
        let f = findings_with(vec![
            target(0.1, "t4anp", 3.0 * edge, 1e-2),
            target(0.5, "t4anp", 3.0 * edge, 1e-2),
        ]);
        assert!(last(&f).contains("coarser than every measured configuration"));
    }

    /// The embedded file parses and names both benchmark cases with both targets.
    #[test]
    fn embedded_findings_parse() {
        let f = Findings::embedded().unwrap();
        let names: Vec<&str> = f.cases.iter().map(|c| c.case.as_str()).collect();
        assert!(names.contains(&"mni152") && names.contains(&"ellipsoid"), "{names:?}");
        for c in &f.cases {
            assert!(c.targets.len() == 2, "{c:?}");
            for t in &c.targets {
                assert!(t.mean_error_mm <= t.target_mm, "{t:?}");
            }
        }
    }
}
