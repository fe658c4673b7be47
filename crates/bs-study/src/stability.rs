//! `cargo xtask stability`: where methods fail, as a map. Each cell is one run with its
//! outcome: converged, stopped by a guard (which one), or failed silently — a run that
//! returned a result that is not finite, has an inverted element or leaves a brain node
//! outside the skull. The last must never happen; the test below runs the quick rows and
//! asserts it.
//!
//! Rows (each a parameter swept on one scene; most for both solvers, Dynamic Relaxation and
//! Newton–Krylov):
//! * DR time step as a multiple of the element-bound critical step, 0.5…3; for
//!   Newton–Krylov, which has no time step, how loosely its linear systems are solved;
//! * Poisson's ratio 0.45…0.4999 for T4 and for T4ANP (T4 locks: its deviation from T4ANP
//!   is recorded);
//! * H8 hourglass control on and off;
//! * growing indentation until an element inverts;
//! * the paper's ellipsoid pushed 10…40 mm with kinematic contact, with CalculiX's stored
//!   outcome beside it, on every mesh of the fixture (coarse, medium, fine, refined under
//!   the craniotomy rim; [`meshes`]);
//! * contact at sharp skull corners with and without the §3.2 additional lists;
//! * the MNI152 brain's craniotomy pushed over the clinical range, and the same brain at
//!   ν = 0.49…0.4999 ([`clinical`]).
//!
//! The block scenes are generated here (a structured 40 mm block, written as Abaqus `.inp`
//! and read back through the normal scene path), so the block rows need no extra fixtures.
//! The rows of the real meshes record, beside the outcome, what each run cost (Newton
//! steps, GMRES iterations, force evaluations, seconds) and, for a run that stopped, how
//! far the load got ([`measure`]). The Newton–Krylov block cells are also run perturbed
//! (`knife_edge`, a test): the same verdict and iteration count with the material
//! constants changed in the last digits and the node order permuted.

mod chart;
mod clinical;
pub mod measure;
mod meshes;
pub mod trace;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::study::{ContactChoice, Failure, Outcome, Variant, difference};
use crate::verdict::{Verdict, classify};
use bs_mesh::io::Fields;
use bs_mesh::{Mesh, Point3, TriSurface};
use bs_scene::Prepared;
use bs_scene::scene::{Algorithm, ElementChoice, SolverKind};

use self::measure::{Measured, Metrics, measure, measured_cell};

use crate::calculix::read_reference;
use crate::plot::{self};
use crate::util::{escape_cell, replace_block, root};

/// One cell of the map.
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    /// Row (experiment).
    pub row: String,
    /// Parameter value as shown.
    pub value: String,
    /// Outcome.
    pub verdict: Verdict,
    /// DR steps (0 if stopped before or not ours).
    pub steps: usize,
    /// A number worth seeing (deviation from the row's reference, step of the guard, …).
    pub note: String,
    /// A setting no scene can reach (an internal switch turned off to show why it is on):
    /// its silent failures are findings, not defects.
    pub ablation: bool,
    /// What the run cost and how far it got (the measured rows).
    pub metrics: Option<Metrics>,
}

/// A structured block [0, L]³ of n³ cells, hexahedra or each split into 6 tetrahedra,
/// with node sets BOTTOM (z = 0), TOP (z = L) and PATCH (top nodes within L/4 of the top
/// centre in x and y).
pub fn block(n: usize, l: f64, tets: bool) -> Mesh {
    let mut mesh = bs_mesh::structured::box_mesh(n, l, tets);
    let top: Vec<usize> = (0..mesh.nodes.len()).filter(|&i| mesh.nodes[i].z >= l - 1e-9).collect();
    let patch: Vec<usize> = top
        .iter()
        .copied()
        .filter(|&i| {
            let p = mesh.nodes[i];
            (p.x - l / 2.0).abs() <= l / 4.0 + 1e-9 && (p.y - l / 2.0).abs() <= l / 4.0 + 1e-9
        })
        .collect();
    let bottom: Vec<usize> = (0..mesh.nodes.len()).filter(|&i| mesh.nodes[i].z <= 1e-9).collect();
    mesh.node_sets.insert("BOTTOM".into(), bottom);
    mesh.node_sets.insert("TOP".into(), top);
    mesh.node_sets.insert("PATCH".into(), patch);
    mesh.element_sets.insert("BLOCK".into(), (0..mesh.elements.len()).collect());
    mesh
}

/// A faceted box around [lo, hi]: the convex hull of its corners and `per_face` random
/// points on each face, each bumped outward by up to `bump`. The faces become irregular,
/// often skinny triangles meeting at sharp 90° box edges: where the closest skull node to
/// a penetrating brain node is often not a vertex of the face it penetrates (the paper's
/// Fig. 2c in three dimensions).
pub fn faceted_box(
    lo: Point3<f64>,
    hi: Point3<f64>,
    per_face: usize,
    bump: f64,
    seed: u64,
) -> TriSurface {
    let mut rng = bs_contact::shapes::Rng::new(seed);
    let mut points: Vec<Point3<f64>> = (0..8)
        .map(|i| {
            Point3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    for axis in 0..3 {
        for high in [false, true] {
            for _ in 0..per_face {
                let mut p = Point3::origin();
                for k in 0..3 {
                    p[k] =
                        rng.range(lo[k] + 0.02 * (hi[k] - lo[k]), hi[k] - 0.02 * (hi[k] - lo[k]));
                }
                let b = rng.range(0.1 * bump, bump);
                p[axis] = if high { hi[axis] + b } else { lo[axis] - b };
                points.push(p);
            }
        }
    }
    bs_contact::shapes::convex_hull(&points)
}

/// Writes `mesh` (and `skull`) with a scene into `dir` and loads it the way `run` does.
fn scene(
    dir: &Path,
    name: &str,
    mesh: &Mesh,
    skull: Option<&TriSurface>,
    body: &str,
) -> Result<Prepared, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let inp = dir.join(format!("{name}.inp"));
    bs_mesh::io::write_mesh(&inp, mesh, &Fields::default()).map_err(|e| e.to_string())?;
    let mut toml = format!(
        "units = \"mm\"\n[mesh]\nfile = \"{name}.inp\"\n[[region]]\nelset = \"BLOCK\"\nmaterial = \
         {{ model = \"neo-hookean\", youngs_modulus = 3000.0, poisson_ratio = 0.49, density = \
         1000.0 }}\n[[boundary]]\nnset = \"BOTTOM\"\nfix = [\"x\", \"y\", \"z\"]\n{body}"
    );
    if let Some(s) = skull {
        let off = dir.join(format!("{name}-skull.off"));
        bs_mesh::io::write_surface(&off, s).map_err(|e| e.to_string())?;
        let _ = write!(toml, "[contact]\nskull = \"{name}-skull.off\"\nalgorithm = \"paper\"\n");
    }
    toml.push_str("[solver]\nkind = \"dr\"\ntolerance = 1e-3\n");
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, toml).map_err(|e| format!("{}: {e}", path.display()))?;
    Prepared::load(&path).map_err(|e| format!("{}: {e}", path.display()))
}

/// Block side (mm) and cells per side of the generated scenes.
const SIDE: f64 = 40.0;
const CELLS: usize = 8;

/// A change of the generated block before it is written (the knife-edge test permutes its
/// node order); [`as_built`] keeps it.
pub type Reorder = fn(Mesh) -> Mesh;

/// The block as generated.
pub fn as_built(mesh: Mesh) -> Mesh {
    mesh
}

/// Indentation of the block's top patch by `depth` mm, bottom fixed, no skull.
fn indentation(dir: &Path, tets: bool, depth: f64, reorder: Reorder) -> Result<Prepared, String> {
    let name = if tets { "indent-t4" } else { "indent-h8" };
    let body = format!(
        "[[boundary]]\nnset = \"PATCH\"\ndisplacement = {{ x = 0.0, y = 0.0, z = {} }}\n",
        -depth
    );
    scene(dir, name, &reorder(block(CELLS, SIDE, tets)), None, &body)
}

/// One cell to run: a scene (or why it could not be made) and the variant to solve it with.
pub struct Spec {
    /// Row (experiment).
    pub row: String,
    /// Parameter value as shown.
    pub value: String,
    /// The scene, or `check`'s refusal of it (a guard too).
    pub scene: Result<Prepared, String>,
    /// What to change in it.
    pub variant: Variant,
}

impl std::fmt::Debug for Spec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Spec")
            .field("row", &self.row)
            .field("value", &self.value)
            .field("scene", &self.scene.as_ref().map(|_| "prepared"))
            .field("variant", &self.variant)
            .finish()
    }
}

impl Spec {
    /// Solves the cell.
    pub fn solve(&self) -> Result<Outcome, Failure> {
        match &self.scene {
            Ok(p) => self.variant.solve(p),
            Err(e) => Err(Failure::Setup(e.clone())),
        }
    }

    /// Solves the cell, keeping the last progress report.
    pub fn measure(&self) -> Measured {
        match &self.scene {
            Ok(p) => measure(&self.variant, p),
            Err(e) => {
                Measured { result: Err(Failure::Setup(e.clone())), last: None, wall_seconds: 0.0 }
            }
        }
    }
}

/// Newton–Krylov's forcing cap on the 8 mm indentation `t4`: from accurate to barely solved
/// linear systems, it must converge or stop.
fn forcing_specs(t4: &Prepared) -> Vec<Spec> {
    [0.01, 0.1, 0.5, 0.9]
        .into_iter()
        .map(|eta| Spec {
            row: "Newton-Krylov forcing (max GMRES relative residual)".into(),
            value: format!("{eta}"),
            scene: Ok(t4.clone()),
            variant: Variant {
                element: Some(ElementChoice::T4anp),
                forcing_max: Some(eta),
                solver: NK,
                ..Variant::default()
            },
        })
        .collect()
}

/// Growing indentation of the 40 mm block until an element inverts.
fn indentation_specs(dir: &Path, solver: Option<SolverKind>, reorder: Reorder) -> Vec<Spec> {
    [8.0, 16.0, 24.0, 30.0, 34.0]
        .into_iter()
        .map(|depth| Spec {
            row: format!("indentation depth (40 mm block), {}", label(solver)),
            value: format!("{depth} mm"),
            scene: indentation(dir, true, depth, reorder),
            variant: Variant { element: Some(ElementChoice::T4anp), solver, ..Variant::default() },
        })
        .collect()
}

/// Poisson's ratio 0.45…0.4999 of `element` on the 8 mm indentation `t4`.
fn poisson_specs(t4: &Prepared, solver: Option<SolverKind>, element: ElementChoice) -> Vec<Spec> {
    let name = if element == ElementChoice::T4 { "T4" } else { "T4ANP" };
    [0.45, 0.49, 0.495, 0.499, 0.4999]
        .into_iter()
        .map(|nu| Spec {
            row: format!("Poisson ratio, {name}, {}", label(solver)),
            value: format!("{nu}"),
            scene: Ok(t4.clone()),
            variant: Variant {
                element: Some(element),
                poisson_ratio: Some(nu),
                solver,
                ..Variant::default()
            },
        })
        .collect()
}

/// The Newton–Krylov cells of the block rows (forcing, indentation, Poisson's ratio for T4
/// and T4ANP), with the block changed by `reorder`, written into `dir`: the cells the
/// knife-edge test perturbs.
pub fn newton_krylov_block_specs(dir: &Path, reorder: Reorder) -> Result<Vec<Spec>, String> {
    let t4 = indentation(dir, true, 8.0, reorder)?;
    let mut specs = forcing_specs(&t4);
    specs.extend(indentation_specs(dir, NK, reorder));
    for element in [ElementChoice::T4, ElementChoice::T4anp] {
        specs.extend(poisson_specs(&t4, NK, element));
    }
    Ok(specs)
}

/// The tetrahedral block compressed by 20 % (top pushed down in z, free in x and y) inside
/// a faceted box skull 0.4–0.7 mm away from its sides: the sides bulge into its faces.
fn boxed(dir: &Path) -> Result<Prepared, String> {
    let g = 0.4;
    let skull = faceted_box(
        Point3::new(-g, -g, -2.0),
        Point3::new(SIDE + g, SIDE + g, SIDE + 2.0),
        12,
        0.3,
        11,
    );
    let body = "[[boundary]]\nnset = \"TOP\"\ndisplacement = { z = -8.0 }\n";
    scene(dir, "boxed", &block(CELLS, SIDE, true), Some(&skull), body)
}

/// Which rows to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scope {
    /// The block rows (seconds; also a test).
    Quick,
    /// Everything, including the ellipsoid loads on every mesh and the MNI152 rows
    /// (minutes, release).
    Full,
}

fn temp_dir() -> PathBuf {
    std::env::temp_dir().join(format!("brainshift-stability-{}", std::process::id()))
}

fn cell(row: &str, value: String, r: &Result<Outcome, Failure>, tol: f64, note: String) -> Cell {
    let verdict = classify(r, tol);
    let steps = r.as_ref().map_or(0, |o| o.steps);
    let note = match (r, note.is_empty()) {
        (Err(Failure::Solve(e)), _) => e.step().map_or(note.clone(), |s| format!("at step {s}")),
        _ => note,
    };
    let c = Cell { row: row.into(), value, verdict, steps, note, ablation: false, metrics: None };
    println!(
        "{:<34} {:<10} {:<28} {:>7} steps  {}",
        c.row,
        c.value,
        Verdict::text(&c.verdict),
        c.steps,
        c.note
    );
    c
}

/// Runs the map's rows.
pub fn run(scope: Scope) -> Result<Vec<Cell>, String> {
    let dir = temp_dir();
    let result = rows(scope, &dir);
    let _ = std::fs::remove_dir_all(&dir);
    result
}

const DR: Option<SolverKind> = Some(SolverKind::Dr);
const NK: Option<SolverKind> = Some(SolverKind::NewtonKrylov);

/// The label of a solver in row names.
fn label(solver: Option<SolverKind>) -> &'static str {
    if solver == NK { "Newton-Krylov" } else { "DR" }
}

/// Every row of the map, in the order the table lists them; the quick scope stops after the
/// block rows.
fn rows(scope: Scope, dir: &Path) -> Result<Vec<Cell>, String> {
    let mut cells = Vec::new();
    let t4 = indentation(dir, true, 8.0, as_built)?;
    time_step_rows(&mut cells, &t4);
    indentation_rows(&mut cells, dir);
    sharp_corner_rows(&mut cells, dir)?;
    poisson_rows(&mut cells, &t4);
    if scope == Scope::Quick {
        return Ok(cells);
    }
    hourglass_rows(&mut cells, dir, &t4)?;
    ellipsoid_rows(&mut cells)?;
    // The real brain: the clinical range of craniotomy pushes, and near incompressibility.
    clinical::craniotomy(&mut cells)?;
    clinical::poisson(&mut cells)?;
    Ok(cells)
}

/// The tolerance every cell is solved to (mm).
const TOL: f64 = 1e-3;

/// DR's time step as a multiple of the element bound, and Newton–Krylov's forcing.
fn time_step_rows(cells: &mut Vec<Cell>, t4: &Prepared) {
    let tol = TOL;
    // Time step (DR): the element bound is a lower bound of the critical step (on this mesh
    // the true one is ≈1.6× it), so 0.5–1.25 must converge and ≥ 2 must be stopped.
    let row = "DR time step / element-bound critical";
    for f in [0.5, 0.8, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0] {
        let v = Variant {
            element: Some(ElementChoice::T4anp),
            step_fraction: Some(f),
            solver: DR,
            ..Variant::default()
        };
        cells.push(cell(row, format!("{f}x"), &v.solve(t4), tol, String::new()));
    }
    // Newton–Krylov has no time step; its counterpart is how loosely the inner linear
    // systems may be solved: from accurate to barely solved, it must converge or stop.
    for s in forcing_specs(t4) {
        cells.push(cell(&s.row, s.value.clone(), &s.solve(), tol, String::new()));
    }
}

/// A 40 mm block indented until an element inverts, by both solvers.
fn indentation_rows(cells: &mut Vec<Cell>, dir: &Path) {
    let tol = TOL;
    // Growing indentation of a 40 mm block until an element inverts (a scene `check`
    // refuses is a guard too).
    for solver in [DR, NK] {
        for s in indentation_specs(dir, solver, as_built) {
            let r = s.solve();
            let note =
                r.as_ref().map_or(String::new(), |o| format!("min J {:.2e}", o.min_volume_ratio));
            cells.push(cell(&s.row, s.value.clone(), &r, tol, note));
        }
    }
}

/// The paper's handler at sharp skull corners, with and without the §3.2 lists.
fn sharp_corner_rows(cells: &mut Vec<Cell>, dir: &Path) -> Result<(), String> {
    let tol = TOL;
    // Sharp skull corners: the paper's handler with and without the §3.2 lists, brute
    // force as the reference of each solver. (The block is squeezed 20 % into a tight box
    // with sharp edges; the two solvers may land in different equilibria of this folded
    // state, so each is judged against its own brute-force run.)
    let boxed = boxed(dir)?;
    let in_contact = |r: &Result<Outcome, Failure>| {
        r.as_ref().map_or(String::new(), |o| format!("{} in contact", o.nodes_in_contact))
    };
    for solver in [DR, NK] {
        let row = format!("sharp corners (box skull), {}", label(solver));
        let brute = Variant {
            contact: Some(ContactChoice::Handler(Algorithm::BruteForce)),
            solver,
            ..Variant::default()
        }
        .solve(&boxed);
        let brute_u = brute.as_ref().ok().map(|o| o.displacements.clone());
        cells.push(cell(&row, "brute force".into(), &brute, tol, in_contact(&brute)));
        for (name, lists) in [("lists on", true), ("lists off", false)] {
            let v = Variant { additional_lists: Some(lists), solver, ..Variant::default() };
            let r = v.solve(&boxed);
            let note = match (&r, &brute_u) {
                (Ok(o), Some(b)) => {
                    format!("max |u - brute| {:.1e} mm", difference(&o.displacements, b, None).1)
                }
                _ => String::new(),
            };
            let mut c = cell(&row, name.into(), &r, tol, note);
            c.ablation = !lists;
            // A handler solves the same discrete problem as brute force: a result farther
            // than 10× the tolerance from brute force's is a missed penetration corrected to
            // the wrong place, returned as if right.
            if let (Ok(o), Some(b), Verdict::Converged) = (&r, &brute_u, &c.verdict) {
                let dev = difference(&o.displacements, b, None).1;
                if dev > 10.0 * tol {
                    c.verdict = Verdict::Silent(format!("differs from brute force by {dev:.2e}"));
                    println!("  -> {}", Verdict::text(&c.verdict));
                }
            }
            cells.push(c);
        }
    }
    Ok(())
}

/// Poisson's ratio towards incompressibility, T4 against T4ANP, by both solvers.
fn poisson_rows(cells: &mut Vec<Cell>, t4: &Prepared) {
    let tol = TOL;
    // Poisson's ratio: T4 locks, T4ANP does not; deviation of T4 from T4ANP recorded.
    for solver in [DR, NK] {
        for element in [ElementChoice::T4, ElementChoice::T4anp] {
            for s in poisson_specs(t4, solver, element) {
                let r = s.solve();
                let note = if element == ElementChoice::T4 {
                    let v = Variant { element: Some(ElementChoice::T4anp), ..s.variant.clone() };
                    match (&r, &v.solve(t4)) {
                        (Ok(a), Ok(b)) => format!(
                            "mean |u - T4ANP| {:.2} mm",
                            difference(&a.displacements, &b.displacements, None).0
                        ),
                        _ => String::new(),
                    }
                } else {
                    String::new()
                };
                cells.push(cell(&s.row, s.value.clone(), &r, tol, note));
            }
        }
    }
}

/// H8's hourglass coefficient: the default, a tenth and none, judged against T4ANP.
fn hourglass_rows(cells: &mut Vec<Cell>, dir: &Path, t4: &Prepared) -> Result<(), String> {
    let tol = TOL;
    // H8 hourglass control: the default coefficient, a tenth of it and none. Judged against
    // T4ANP on the same nodes (the tetrahedral block splits the same grid), an independent
    // locking-free element: a coefficient whose result is more than 3× farther from T4ANP
    // than the default's has let hourglass modes in, a wrong field returned as converged.
    // Neither reduced setting is reachable from a scene (they are ablations).
    let h8 = indentation(dir, false, 8.0, as_built)?;
    let row = "H8 hourglass coefficient, DR";
    let default = bs_dr::ModelOptions::default().hourglass;
    let anp = Variant { element: Some(ElementChoice::T4anp), solver: DR, ..Variant::default() }
        .solve(t4)
        .map_err(|e| format!("T4ANP block: {e}"))?;
    let off_t4anp = |r: &Result<Outcome, Failure>| {
        r.as_ref().ok().map(|o| difference(&o.displacements, &anp.displacements, None).1)
    };
    let controlled = off_t4anp(&Variant { solver: DR, ..Variant::default() }.solve(&h8));
    for (name, k) in [("default", default), ("default/10", default / 10.0), ("0 (off)", 0.0)] {
        let v = Variant { hourglass: Some(k), solver: DR, ..Variant::default() };
        let r = v.solve(&h8);
        let dev = off_t4anp(&r);
        let note = dev.map_or(String::new(), |d| format!("max |u - T4ANP| {d:.2} mm"));
        let mut c = cell(row, name.into(), &r, tol, note);
        c.ablation = k != default;
        if let (Some(d), Some(base), Verdict::Converged) = (dev, controlled, &c.verdict)
            && d > 3.0 * base
        {
            c.verdict = Verdict::Silent(format!("hourglass modes ({d:.1} vs {base:.1} mm)"));
            println!("  -> {}", Verdict::text(&c.verdict));
        }
        cells.push(c);
    }
    Ok(())
}

/// The paper's ellipsoid pushed 10–40 mm: DR's ramps, every mesh, CalculiX's outcome.
fn ellipsoid_rows(cells: &mut Vec<Cell>) -> Result<(), String> {
    // The paper's ellipsoid, pushed 10–40 mm: DR with three load ramps on the coarse mesh
    // (a run that stops says at which ramp load), Newton–Krylov on every mesh, DR at 40 mm
    // on the rim and hexahedral meshes, and CalculiX's stored outcome.
    let ell =
        Prepared::load(&root().join("fixtures/ellipsoid/scene.toml")).map_err(|e| e.to_string())?;
    for ramp in meshes::RAMPS {
        let row = format!("ellipsoid load, DR ramp {ramp} steps");
        for load in meshes::LOADS {
            let v = Variant {
                load_factor: Some(load / 10.0),
                ramp_steps: Some(ramp),
                solver: DR,
                ..Variant::default()
            };
            let m = measure(&v, &ell);
            let note = m
                .result
                .as_ref()
                .map_or(String::new(), |o| format!("{} in contact", o.nodes_in_contact));
            cells.push(measured_cell(&row, format!("{load} mm"), &m, Some(load), note));
        }
    }
    for (name, scene) in meshes::MESHES {
        meshes::by_mesh(cells, name, scene)?;
    }
    for (name, scene) in meshes::DR_MESHES {
        meshes::dr_at_40mm(cells, name, scene)?;
    }
    let dir = root().join("fixtures/ellipsoid/reference");
    let row = "ellipsoid load, CalculiX K=10";
    for (load, tag) in [("10 mm", "ccx-k10"), ("40 mm", "ccx-40mm-k10")] {
        let Some(r) = read_reference(&dir, tag)? else { continue };
        let done = r.meta["converged"] == serde_json::Value::Bool(true);
        let frac = r.meta["load_fraction_reached"].as_f64().unwrap_or(f64::NAN);
        let text = if done {
            "converged".to_string()
        } else {
            format!("failed at {:.0}% load", 100.0 * frac)
        };
        let c = Cell {
            row: row.into(),
            value: load.into(),
            verdict: Verdict::External(text),
            steps: 0,
            note: r.meta["message"].as_str().unwrap_or("").to_string(),
            ablation: false,
            metrics: None,
        };
        println!("{:<34} {:<10} {}", c.row, c.value, Verdict::text(&c.verdict));
        cells.push(c);
    }
    Ok(())
}

/// The cells as CSV (the metrics columns empty where a row has none).
pub fn csv(cells: &[Cell]) -> String {
    let mut s = String::from(
        "row,value,outcome,steps,note,ablation,iterations,gmres,force_evaluations,\
         solve_seconds,wall_seconds,min_j,in_contact\n",
    );
    for c in cells {
        let _ = write!(
            s,
            "{},{},{},{},{},{}",
            c.row.replace(',', ";"),
            c.value,
            Verdict::text(&c.verdict).replace(',', ";"),
            c.steps,
            c.note.replace(',', ";"),
            c.ablation
        );
        let opt = |x: Option<String>| x.unwrap_or_default();
        let _ = match c.metrics {
            Some(m) => writeln!(
                s,
                ",{},{},{},{},{:.3},{},{}",
                m.steps,
                m.linear,
                m.force_evaluations,
                opt(m.solve_seconds.map(|t| format!("{t:.3}"))),
                m.wall_seconds,
                opt(m.min_j.map(|j| format!("{j:.3e}"))),
                opt(m.in_contact.map(|n| n.to_string())),
            ),
            None => writeln!(s, ",,,,,,,"),
        };
    }
    s
}

/// The measured cells as a Markdown table: iterations, GMRES iterations (and per Newton
/// iteration: the preconditioner's quality), force evaluations, seconds, smallest J, nodes
/// in contact. A run that stopped shows what it had spent when it stopped, and its wall
/// time (setup and preparation included) in parentheses.
pub fn measured_markdown(cells: &[Cell]) -> String {
    let mut s = String::from(
        "| experiment | value | outcome | steps | GMRES | GMRES / step | force evaluations | \
         solve s | min J | in contact | note |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for c in cells {
        let Some(m) = c.metrics else { continue };
        let per_step = if m.linear > 0 && m.steps > 0 {
            format!("{:.1}", m.linear as f64 / m.steps as f64)
        } else {
            String::new()
        };
        let seconds = m
            .solve_seconds
            .map_or_else(|| format!("({:.2})", m.wall_seconds), |t| format!("{t:.2}"));
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            escape_cell(&c.row),
            escape_cell(&c.value),
            escape_cell(&Verdict::text(&c.verdict)),
            m.steps,
            m.linear,
            per_step,
            m.force_evaluations,
            seconds,
            m.min_j.map_or(String::new(), |j| format!("{j:.2e}")),
            m.in_contact.map_or(String::new(), |n| n.to_string()),
            escape_cell(&c.note)
        );
    }
    s
}

/// The cells as a Markdown table.
pub fn markdown(cells: &[Cell]) -> String {
    let mut s =
        String::from("| experiment | value | outcome | steps | note |\n|---|---|---|---:|---|\n");
    for c in cells {
        let _ = writeln!(
            s,
            "| {} | {}{} | {} | {} | {} |",
            escape_cell(&c.row),
            escape_cell(&c.value),
            if c.ablation { " (ablation)" } else { "" },
            escape_cell(&Verdict::text(&c.verdict)),
            c.steps,
            escape_cell(&c.note)
        );
    }
    s
}

/// What `cargo xtask stability` runs.
#[derive(Debug, Clone)]
pub enum Options {
    /// The map (the full one writes docs/stability.md and its chart).
    Map(Scope),
    /// One scene's DR run traced step by step.
    Trace(trace::Options),
}

/// `cargo xtask stability [--quick] | stability trace SCENE …`.
pub fn main(o: &Options) -> Result<(), String> {
    let scope = match o {
        Options::Map(scope) => *scope,
        Options::Trace(t) => return trace::main(t),
    };
    let started = std::time::Instant::now();
    let cells = run(scope)?;
    let silent =
        cells.iter().filter(|c| !c.ablation && matches!(c.verdict, Verdict::Silent(_))).count();
    let ablations =
        cells.iter().filter(|c| c.ablation && matches!(c.verdict, Verdict::Silent(_))).count();
    if scope == Scope::Full {
        let stem = root().join("docs/charts/stability-map");
        std::fs::write(stem.with_extension("csv"), csv(&cells)).map_err(|e| e.to_string())?;
        let rows = cells.iter().map(|c| &c.row).collect::<std::collections::BTreeSet<_>>().len();
        plot::save(&chart::Map { cells: &cells }, &stem, (1500, 90 + 62 * rows as u32))?;
        let doc = root().join("docs/stability.md");
        replace_block(&doc, "map", &markdown(&cells))?;
        replace_block(&doc, "measured", &measured_markdown(&cells))?;
        println!("map written to {}", stem.display());
    }
    println!(
        "{} runs in {:.0} s, {silent} failed silently ({ablations} more in ablations no scene \
         can reach)",
        cells.len(),
        started.elapsed().as_secs_f64()
    );
    if silent > 0 {
        return Err(format!("{silent} run(s) failed silently"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The generated geometry: the block's volume and orientation, and the box skull is a
    /// valid closed outward master surface.
    #[test]
    fn generated_scenes_are_valid() {
        for tets in [true, false] {
            let m = block(4, 2.0, tets);
            assert!(m.validate().first_error().is_none());
            let vol: f64 = (0..m.elements.len()).map(|e| m.element_volume(e)).sum();
            assert!((vol - 8.0).abs() < 1e-12, "{vol}");
            assert_eq!(m.node_sets["PATCH"].len(), 9);
        }
        let s = faceted_box(Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 2.0, 3.0), 12, 0.01, 3);
        assert!(bs_contact::MasterSurface::new(&s).is_ok());
        // It encloses the box (the face points are bumped outward), and not much more:
        // box volume 6 ≤ hull volume ≤ the box grown by the bump on every side.
        let vol: f64 = s
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| s.vertices[i].coords);
                a.dot(&b.cross(&c)) / 6.0
            })
            .sum();
        assert!((6.0 - 1e-12..=1.02 * 2.02 * 3.02).contains(&vol), "{vol}");
        assert!(s.vertices.len() > 8 + 6 * 4, "{}", s.vertices.len());
    }
}
