//! `brainshift check SCENE`: everything a run needs, checked without running
//! ([`bs_scene::check`]), and a summary printed.

use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;

use bs_scene::SceneError;
use bs_scene::check::CheckReport;

/// Runs `check`: prints a summary (or, with `json`, the report as JSON), exits non-zero
/// (with the reason) if the scene cannot run. With `region_effect`, also solves the scene
/// once as it is and once per region other than the largest with that region made
/// parenchyma, and prints what each changes.
pub fn run(scene_path: &Path, region_effect: bool, json: bool) -> Result<ExitCode, SceneError> {
    let checked = bs_scene::check::check(scene_path)?;
    let report = checked.report();
    if json {
        let text = serde_json::to_string_pretty(&report).expect("a check report serialises");
        crate::emit(&format!("{text}\n"));
        return Ok(ExitCode::SUCCESS);
    }
    let mut o = text(scene_path, &report);
    if checked.prepared.scene.regions.len() > 1 && !region_effect {
        let _ = writeln!(
            o,
            "  regions: {} materials; `brainshift check --region-effect` solves the scene with \
             each region but the largest as that one and prints how much each changes the \
             displacements here (on fixtures/mni152-regions under an 8 mm push: at most 0.18 \
             mm, docs/regions.md)",
            report.regions.len()
        );
    }
    crate::emit(&o);
    if region_effect {
        print_region_effects(&checked.prepared)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The report as the text `brainshift check` prints.
fn text(scene_path: &Path, r: &CheckReport) -> String {
    let mut o = String::new();
    let u = &r.units;
    let _ = writeln!(o, "{}: OK", scene_path.display());
    let _ = writeln!(
        o,
        "  mesh: {} ({} nodes, {} tet4, {} hex8), element technology {}, units {u}",
        r.mesh.display(),
        r.nodes,
        r.tet4,
        r.hex8,
        r.element
    );
    for g in &r.regions {
        let _ = writeln!(
            o,
            "  region '{}': {} elements, {}, mu = {:.6} Pa, kappa = {:.6} Pa",
            g.elset, g.elements, g.model, g.shear_modulus, g.bulk_modulus
        );
    }
    let _ = writeln!(
        o,
        "  boundary: {} nodes fully fixed, {} nodes with prescribed displacement",
        r.fixed_nodes, r.moved_nodes
    );
    for line in &r.loads {
        let _ = writeln!(o, "  {line}");
    }
    match &r.skull {
        Some(s) => {
            let _ = writeln!(
                o,
                "  skull: {} ({} vertices, {} triangles, closed, outward), algorithm {}",
                s.file.display(),
                s.vertices,
                s.triangles,
                s.algorithm
            );
        }
        None => {
            let _ = writeln!(o, "  contact: none");
        }
    }
    if let Some((min, max)) = r.initial_gap {
        let _ = writeln!(
            o,
            "  initial gap: min {min:.4} {u}, max {max:.4} {u} over {} slave nodes (all inside)",
            r.slave_nodes
        );
    }
    let _ = writeln!(o, "  solver: {}, tolerance {} {u}", r.solver, r.tolerance);
    let _ = writeln!(
        o,
        "  stable time step: {:.4e} s (smallest element: id {}); Dynamic Relaxation uses \
         fictitious masses, so this sets no step count",
        r.stable_time_step, r.smallest_element
    );
    let _ = writeln!(o, "  expected memory: about {:.0} MB", r.memory_estimate_bytes / 1e6);
    for w in &r.warnings {
        let _ = writeln!(o, "  warning: {w}");
    }
    for line in &r.advice {
        let _ = writeln!(o, "  {line}");
    }
    o
}

/// `--region-effect`: the solves, with a line per solve on standard error, then the table.
fn print_region_effects(p: &bs_scene::Prepared) -> Result<(), SceneError> {
    if p.scene.regions.len() < 2 {
        crate::emit("  region effect: the scene has one region, nothing to compare\n");
        return Ok(());
    }
    eprintln!("solving the scene as it is ...");
    let mut announce =
        |elset: &str| eprintln!("solving with '{elset}' made part of the largest region ...");
    let e = bs_scene::region_effect::region_effects(p, &mut announce, &mut |_| {})?;
    let tolerance_mm = p.scene.solver.tolerance * p.scene.units.metres() * 1000.0;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "  region effect ({} solves; each region's elements made '{}', its material and volume \
         averaging): the scene as it is moves up to {:.3} mm ({:.2} s)",
        1 + e.regions.len(),
        e.base,
        e.max_displacement_mm,
        e.solve_seconds
    );
    for r in &e.regions {
        let verdict = if r.max_mm <= tolerance_mm {
            format!("below the solver tolerance ({tolerance_mm:.0e} mm): not needed for this load")
        } else {
            format!("model it where displacements must be better than {:.2} mm", r.max_mm)
        };
        let _ = writeln!(
            o,
            "    '{}' changes displacements by up to {:.4} mm (node {}), by {:.4} mm on average \
             and {:.4} mm at most over its {} nodes ({:.2} s): {verdict}",
            r.elset,
            r.max_mm,
            r.max_node,
            r.region_mean_mm,
            r.region_max_mm,
            r.region_nodes,
            r.solve_seconds
        );
    }
    crate::emit(&o);
    Ok(())
}
