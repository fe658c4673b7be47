//! `brainshift check SCENE`: everything a run needs, checked without running
//! ([`bs_scene::check`]), and a summary printed.

use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;

use bs_scene::SceneError;

/// Runs `check`: prints a summary, exits non-zero (with the reason) if the scene cannot run.
/// With `region_effect`, also solves the scene once as it is and once per region other
/// than the largest with that region made parenchyma, and prints what each changes.
pub fn run(scene_path: &Path, region_effect: bool) -> Result<ExitCode, SceneError> {
    let checked = bs_scene::check::check(scene_path)?;
    let (p, composed, gap) = (&checked.prepared, &checked.composed, checked.initial_gap);
    let mut o = String::new();
    let u = p.scene.units.symbol();
    let (tets, hexes) = p.mesh.count_by_kind();
    let _ = writeln!(o, "{}: OK", scene_path.display());
    let _ = writeln!(
        o,
        "  mesh: {} ({} nodes, {} tet4, {} hex8), element technology {}, units {u}",
        p.scene.mesh.file.display(),
        p.mesh.nodes.len(),
        tets,
        hexes,
        p.element.name()
    );
    for (r, region) in p.scene.regions.iter().enumerate() {
        let n = p.region_of_element.iter().filter(|&&x| x == r).count();
        let m = region.material.moduli().expect("checked at parse time");
        let _ = writeln!(
            o,
            "  region '{}': {n} elements, {:?}, mu = {:.6} Pa, kappa = {:.6} Pa",
            region.elset, region.material.model, m.mu, m.kappa
        );
    }
    let fixed = p.prescribed.iter().filter(|c| c.iter().all(|v| *v == Some(0.0))).count();
    let moved = p.prescribed.iter().filter(|c| c.iter().flatten().any(|v| *v != 0.0)).count();
    let _ = writeln!(
        o,
        "  boundary: {fixed} nodes fully fixed, {moved} nodes with prescribed displacement"
    );
    for line in &p.loads {
        let _ = writeln!(o, "  {line}");
    }
    if let (Some(s), Some(c)) = (&p.skull, &p.scene.contact) {
        let _ = writeln!(
            o,
            "  skull: {} ({} vertices, {} triangles, closed, outward), algorithm {:?}",
            c.skull.display(),
            s.vertices.len(),
            s.triangles.len(),
            c.algorithm
        );
    } else {
        let _ = writeln!(o, "  contact: none");
    }
    if let Some((min, max)) = gap {
        let _ = writeln!(
            o,
            "  initial gap: min {min:.4} {u}, max {max:.4} {u} over {} slave nodes (all inside)",
            composed.slaves.len()
        );
    }
    let _ = writeln!(
        o,
        "  solver: {}, tolerance {} {u}",
        p.scene.solver.kind.name(),
        p.scene.solver.tolerance
    );
    let (dt, e) = composed.model.critical_time_step();
    let _ = writeln!(
        o,
        "  stable time step: {:.4e} s (smallest element: id {}); Dynamic Relaxation uses \
         fictitious masses, so this sets no step count",
        dt * p.scene.units.metres(),
        p.mesh.element_ids[e]
    );
    let _ = writeln!(o, "  expected memory: about {:.0} MB", checked.memory_estimate / 1e6);
    for w in &p.warnings {
        let _ = writeln!(o, "  warning: {w}");
    }
    match &checked.advice {
        Ok(lines) => {
            for line in lines {
                let _ = writeln!(o, "  {line}");
            }
        }
        Err(e) => {
            let _ = writeln!(o, "  (no advice: {e})");
        }
    }
    if p.scene.regions.len() > 1 && !region_effect {
        let _ = writeln!(
            o,
            "  regions: {} materials; `brainshift check --region-effect` solves the scene with \
             each region but the largest as that one and prints how much each changes the \
             displacements here (on fixtures/mni152-regions under an 8 mm push: at most 0.18 \
             mm, docs/regions.md)",
            p.scene.regions.len()
        );
    }
    crate::emit(&o);
    if region_effect {
        print_region_effects(p)?;
    }
    Ok(ExitCode::SUCCESS)
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
