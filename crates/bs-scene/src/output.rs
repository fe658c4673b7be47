//! Writing a verified result: result.vtu (displacement, in_contact; von Mises stress and J
//! per element; the frame as `SPACE` String field data, which 3D Slicer reads) and the same
//! as legacy result.vtk (the frame as `SPACE=` in its title line, for meshio and every VTK
//! reader), displacements.csv, report.json and, with a skull, skull.off (the cavity the
//! registration outputs extend the displacement to), and for each element set named in
//! `[output] surfaces` its deformed boundary surface (`surface-NAME.vtk`, `surface-NAME.stl`),
//! each written atomically (a temporary file renamed into place), so an interrupted or failed
//! run leaves no partial file.

use std::path::{Path, PathBuf};

use bs_dr::DrParams;
use bs_mesh::io::{Field, Fields, write_atomic};
use bs_mesh::{BoundarySurface, Mesh, TriSurface, Vector3};
use serde::Serialize;

use bs_image::Space;

use crate::SceneError;
use crate::prepare::Prepared;
use crate::run::{Run, Solved};
use crate::scene::{Algorithm, ElementChoice, SolverKind, Units};
use crate::uncertainty::UncertaintyReport;

/// The machine-readable summary written to report.json, and read back typed
/// ([`RunReport::read`]: registration and sweeps). A key an older report lacks reads as its
/// default (0, empty, absent).
#[derive(Debug, Clone, Default, PartialEq, Serialize, serde::Deserialize)]
#[serde(default)]
pub struct RunReport {
    /// Always true in a written report: a failed run writes no report.
    pub converged: bool,
    /// DR steps or Newton iterations.
    pub steps: usize,
    /// Wall time of the solver alone (part of `solve_seconds`).
    pub solver_seconds: f64,
    /// Wall time of the independent verification of the result (contact state, J,
    /// equilibrium): `solve_seconds` − `solver_seconds`.
    pub verify_seconds: f64,
    /// Wall time of everything that depends only on mesh, materials and skull (the model's
    /// precomputation, the contact search structures, the solver's preconditioner): what can
    /// be computed before surgery.
    pub prepare_seconds: f64,
    /// Wall time from known displacements to a converged, verified result (the solver and
    /// the verification).
    pub solve_seconds: f64,
    /// Evaluations of the internal forces.
    pub force_evaluations: usize,
    /// Inner linear-solver iterations (newton-krylov: GMRES; otherwise 0).
    pub linear_iterations: usize,
    /// Load levels of newton-krylov's continuation (1: the whole load at once; 0 for the
    /// other solvers).
    pub load_levels: usize,
    /// Failed load levels retried with a smaller increment (newton-krylov).
    pub cutbacks: usize,
    /// Dynamic Relaxation steps of newton-krylov's fallback (0: not needed).
    pub fallback_steps: usize,
    /// Part of `solver_seconds` spent in contact enforcement and queries.
    pub contact_seconds: f64,
    /// Part of `solver_seconds` spent evaluating internal forces (newton-krylov; 0 for the
    /// others, which do not time it).
    pub force_seconds: f64,
    /// Part of `solver_seconds` spent in the preconditioner (newton-krylov), its rebuilds
    /// included.
    pub preconditioner_seconds: f64,
    /// Rebuilds of newton-krylov's preconditioner on the deformed configuration (after a
    /// slow linear solve with elements compressed or stretched by more than 40 %; 0 for
    /// the other solvers).
    pub preconditioner_refreshes: usize,
    /// Wall time of the whole run in this process: reading the scene, preparing, solving,
    /// verifying and writing.
    pub total_seconds: f64,
    /// Final error estimate (mesh length units).
    pub error_estimate: f64,
    /// Tolerance it met (mesh length units).
    pub tolerance: f64,
    /// Physical critical time step of the mesh times the step fraction, in seconds. DR uses
    /// fictitious masses, so this is the step the explicit dynamics would need.
    pub time_step: f64,
    /// Slave nodes lying on the skull at the end (within the tolerance).
    pub nodes_in_contact: usize,
    /// Largest distance by which any slave was found outside the skull in any step, before
    /// it was moved back (mesh length units).
    pub max_penetration_before_correction: f64,
    /// Largest distance of any slave outside the skull in the written result.
    pub max_penetration_after: f64,
    /// Smallest element volume ratio J of the result (verified > 0).
    pub min_jacobian: f64,
    /// Largest out-of-balance force at a free node out of contact, relative to the largest
    /// reaction force (verified below `equilibrium_bound`).
    pub equilibrium_residual: f64,
    /// The bound the equilibrium residual met (from the tolerance and the load size).
    pub equilibrium_bound: f64,
    /// Largest nodal displacement magnitude.
    pub max_displacement: f64,
    /// The solver, by its scene name (`"newton-krylov"`, `"dr"` or `"newton"`).
    pub solver: SolverKind,
    /// The element, by its scene name (`"t4"`, `"t4anp"` or `"h8"`).
    pub element: ElementChoice,
    /// The contact handler, by its scene name, or `"none"`.
    #[serde(default = "no_contact")]
    pub algorithm: Algorithm,
    /// Counts.
    pub nodes: usize,
    /// Counts.
    pub elements: usize,
    /// Slave (contact candidate) nodes.
    pub slave_nodes: usize,
    /// Threads used.
    pub threads: usize,
    /// Length unit of all lengths in this report (`"mm"` or `"m"`; `None` only when read
    /// from a report that lacks the key).
    pub units: Option<Units>,
    /// Anatomical frame of the mesh, the displacements and every output (`"RAS"`/`"LPS"`;
    /// `None` only when read from a report that lacks the key).
    pub space: Option<Space>,
    /// Per `[[measurement]]`: what the fit did (points, inliers, residuals after the fit,
    /// the rigid correction, how far the data moved the model). Empty without measurements.
    pub measurements: Vec<crate::measure::MeasurementReport>,
    /// The gravity solved with (unit direction in the scene's frame, acceleration, fluid
    /// level) and what `[gravity] estimate` estimated, each with its standard error (absent
    /// without `[gravity]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity: Option<crate::estimate::GravityReport>,
    /// Why the measurements could not be used, when they could not (absent otherwise): the
    /// answer is then the prior's, the scene without its data (or at gravity's estimate),
    /// and `measurements` is empty.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data_unused: Option<String>,
    /// What a resection removed (absent without one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub resected: Option<ResectedReport>,
    /// σ of the fitted displacement (`run --uncertainty N`; absent without).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<crate::uncertainty::UncertaintyReport>,
}

fn no_contact() -> Algorithm {
    Algorithm::None
}

impl RunReport {
    /// Reads a report.json (as `brainshift run` writes it).
    pub fn read(path: &Path) -> Result<RunReport, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
        serde_json::from_str(&text)
            .map_err(|e| format!("{}: not a brainshift report: {e}", path.display()))
    }
}

/// The report's account of a resection.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ResectedReport {
    /// The resected regions' element sets.
    pub regions: Vec<String>,
    /// Elements removed.
    pub elements: usize,
    /// Nodes left without an element, held where they were (in result.vtu, in no cell, with
    /// zero displacement).
    pub nodes_held: usize,
    /// Cavity wall triangles (free surfaces now).
    pub wall_triangles: usize,
}

/// Where the files of a run went.
#[derive(Debug, Clone)]
pub struct Written {
    /// result.vtu.
    pub vtu: PathBuf,
    /// result.vtk (the same, legacy VTK: meshio reads it).
    pub vtk: PathBuf,
    /// skull.off (the scene's skull, mesh frame and unit), when the scene has one.
    pub skull: Option<PathBuf>,
    /// displacements.csv.
    pub csv: PathBuf,
    /// report.json.
    pub report: PathBuf,
    /// Per `[output] surfaces` entry: the set's name and its `.vtk` and `.stl` files.
    pub surfaces: Vec<(String, PathBuf, PathBuf)>,
    /// residuals.csv (one row per measured point), when the scene has measurements.
    pub residuals: Option<PathBuf>,
    /// uncertainty.csv (σ per node), when the run sampled it.
    pub uncertainty: Option<PathBuf>,
}

/// Timing and threading of a run that only the front end knows.
#[derive(Debug, Clone, Copy)]
pub struct RunContext {
    /// Wall time from the start of the command to now (seconds).
    pub total_seconds: f64,
    /// Worker threads of the run.
    pub threads: usize,
}

/// The report of a verified run.
pub fn report(run: &Run, s: &Solved, ctx: RunContext) -> RunReport {
    let (p, c) = (&run.prepared, &run.composed);
    let u = &s.solution.displacements;
    let r = &s.solution.report;
    let (dt, _) = c.model.critical_time_step();
    let v = &s.verification;
    RunReport {
        converged: true,
        steps: r.steps,
        solver_seconds: r.elapsed.as_secs_f64(),
        verify_seconds: (s.solve_seconds - r.elapsed.as_secs_f64()).max(0.0),
        prepare_seconds: run.prepare_seconds,
        solve_seconds: s.solve_seconds,
        force_evaluations: r.force_evaluations,
        linear_iterations: r.linear_iterations,
        load_levels: r.continuation.map_or(0, |c| c.load_levels),
        cutbacks: r.continuation.map_or(0, |c| c.cutbacks),
        fallback_steps: r.continuation.map_or(0, |c| c.fallback_steps),
        contact_seconds: c.contact.as_ref().map_or(0.0, |sc| sc.elapsed.as_secs_f64()),
        force_seconds: r.breakdown.forces.as_secs_f64(),
        preconditioner_seconds: r.breakdown.preconditioner.as_secs_f64(),
        preconditioner_refreshes: r.continuation.map_or(0, |c| c.refreshes),
        total_seconds: ctx.total_seconds,
        error_estimate: r.err,
        tolerance: run.settings.tolerance,
        time_step: dt * DrParams::default().step_fraction * p.scene.units.metres(),
        nodes_in_contact: v.in_contact.iter().filter(|&&x| x > 0.0).count(),
        max_penetration_before_correction: s.max_penetration_before,
        max_penetration_after: v.max_penetration_after,
        min_jacobian: v.min_jacobian,
        equilibrium_residual: v.equilibrium_residual,
        equilibrium_bound: v.equilibrium_bound,
        max_displacement: u.iter().map(|d| d.norm()).fold(0.0, f64::max),
        solver: p.scene.solver.kind,
        element: p.element,
        algorithm: p.scene.contact.as_ref().map_or(Algorithm::None, |c| c.algorithm),
        nodes: p.mesh.nodes.len(),
        elements: p.mesh.elements.len(),
        slave_nodes: c.slaves.len(),
        threads: ctx.threads,
        units: Some(p.scene.units),
        space: Some(p.scene.space),
        measurements: s.measurements.clone(),
        gravity: s.gravity.clone(),
        data_unused: s.data_unused.clone(),
        resected: p.resection.as_ref().map(|r| ResectedReport {
            regions: r.regions.clone(),
            elements: r.elements,
            nodes_held: r.orphans.len(),
            wall_triangles: r.walls.len(),
        }),
        uncertainty: s.uncertainty.as_ref().map(|u| UncertaintyReport::of(run, u)),
    }
}

/// Writes the three result files of a verified run into `out` (created if missing).
pub fn write_outputs(
    out: &Path,
    p: &Prepared,
    s: &Solved,
    report: &RunReport,
) -> Result<Written, SceneError> {
    let u = &s.solution.displacements;
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |e: &dyn std::fmt::Display| SceneError::Write { path, message: e.to_string() }
    };
    std::fs::create_dir_all(out).map_err(|e| io(out)(&format!("cannot create the folder: {e}")))?;
    let mut point = vec![
        Field::new("displacement", 3, u.iter().flat_map(|d| [d.x, d.y, d.z]).collect()),
        Field::new("in_contact", 1, s.verification.in_contact.clone()),
    ];
    if let Some(un) = &s.uncertainty {
        point.push(Field::new("sigma", 1, (0..u.len()).map(|a| un.total(a)).collect()));
    }
    let fields = Fields {
        point,
        cell: vec![
            Field::new("von_mises", 1, s.verification.measures.von_mises.clone()),
            Field::new("J", 1, s.verification.measures.volume_ratio.clone()),
        ],
        // The frame of the coordinates and displacements (read back by `warp` and `field`).
        field_data: vec![("SPACE".into(), p.scene.space.name().into())],
    };
    let mut written = Written {
        vtu: out.join("result.vtu"),
        vtk: out.join("result.vtk"),
        skull: p.skull.as_ref().map(|_| out.join("skull.off")),
        csv: out.join("displacements.csv"),
        report: out.join("report.json"),
        surfaces: Vec::new(),
        residuals: (!s.residuals.is_empty()).then(|| out.join("residuals.csv")),
        uncertainty: s.uncertainty.as_ref().map(|_| out.join(UNCERTAINTY_CSV)),
    };
    for name in &p.scene.output.surfaces {
        let set = p.mesh.element_set(name).ok_or_else(|| SceneError::Write {
            path: out.to_path_buf(),
            message: format!("[output] surfaces: no element set '{name}' (checked when loaded)"),
        })?;
        let b = deformed_set_surface(&p.mesh, set, u);
        let (vtk, stl) =
            (out.join(format!("surface-{name}.vtk")), out.join(format!("surface-{name}.stl")));
        let title = format!(
            "brainshift deformed surface of element set {name}, units {}. SPACE={}",
            p.scene.units.symbol(),
            p.scene.space.name()
        );
        write_atomic(&vtk, |w| write_surface_vtk(w, &title, &b, &p.mesh, u))
            .map_err(|e| io(&vtk)(&e))?;
        bs_mesh::io::write_surface(&stl, &b.surface).map_err(|e| io(&stl)(&e))?;
        written.surfaces.push((name.clone(), vtk, stl));
    }
    bs_mesh::io::write_mesh(&written.vtu, &p.mesh, &fields).map_err(|e| io(&written.vtu)(&e))?;
    bs_mesh::io::write_mesh(&written.vtk, &p.mesh, &fields).map_err(|e| io(&written.vtk)(&e))?;
    if let (Some(path), Some(skull)) = (&written.skull, &p.skull) {
        bs_mesh::io::write_surface(path, skull).map_err(|e| io(path)(&e))?;
    } else {
        // A skull from an earlier run into the same folder would be taken for this one's.
        let stale = out.join("skull.off");
        if stale.is_file() {
            std::fs::remove_file(&stale).map_err(|e| io(&stale)(&e))?;
        }
    }
    write_atomic(&written.csv, |w| {
        writeln!(w, "node_id,ux,uy,uz")?;
        for (id, d) in p.mesh.node_ids.iter().zip(u) {
            writeln!(w, "{id},{:?},{:?},{:?}", d.x, d.y, d.z)?;
        }
        Ok(())
    })
    .map_err(|e| io(&written.csv)(&e))?;
    let residuals = out.join("residuals.csv");
    if written.residuals.is_some() {
        let text = crate::measure::outcome::residuals_csv(&s.residuals);
        write_atomic(&residuals, |w| w.write_all(text.as_bytes()))
            .map_err(|e| io(&residuals)(&e))?;
    } else if residuals.is_file() {
        // An earlier fit's residuals would be taken for this run's.
        std::fs::remove_file(&residuals).map_err(|e| io(&residuals)(&e))?;
    }
    write_uncertainty(out, p, s.uncertainty.as_ref())?;
    let json = serde_json::to_string_pretty(report).map_err(|e| io(&written.report)(&e))?;
    write_atomic(&written.report, |w| writeln!(w, "{json}"))
        .map_err(|e| io(&written.report)(&e))?;
    Ok(written)
}

/// The file of σ per node in a result folder.
pub const UNCERTAINTY_CSV: &str = "uncertainty.csv";

/// uncertainty.csv (`node_id,sx,sy,sz,s`: σ per axis and in total, mesh units) into `out`,
/// or an earlier run's removed (it would be taken for this one's).
fn write_uncertainty(
    out: &Path,
    p: &Prepared,
    u: Option<&crate::uncertainty::Uncertainty>,
) -> Result<(), SceneError> {
    let path = out.join(UNCERTAINTY_CSV);
    let err = |e: &dyn std::fmt::Display| SceneError::Write {
        path: path.clone(),
        message: e.to_string(),
    };
    let Some(u) = u else {
        if path.is_file() {
            std::fs::remove_file(&path).map_err(|e| err(&e))?;
        }
        return Ok(());
    };
    write_atomic(&path, |w| {
        writeln!(w, "node_id,sx,sy,sz,s")?;
        for (a, (id, s)) in p.mesh.node_ids.iter().zip(&u.sigma).enumerate() {
            writeln!(w, "{id},{:?},{:?},{:?},{:?}", s[0], s[1], s[2], u.total(a))?;
        }
        Ok(())
    })
    .map_err(|e| err(&e))
}

/// The deformed boundary surface of the element set `set` of `mesh` under the nodal
/// displacements `u`: the faces of the set's elements that no other element of the set
/// shares (so a region's surface includes its interfaces with other regions), oriented out
/// of the set, at `X + u`. `volume_node` maps each vertex to its node, `element` each
/// triangle to its element in `mesh`.
pub fn deformed_set_surface(mesh: &Mesh, set: &[usize], u: &[Vector3<f64>]) -> BoundarySurface {
    let part = Mesh {
        nodes: mesh.nodes.clone(),
        node_ids: mesh.node_ids.clone(),
        elements: set.iter().map(|&e| mesh.elements[e]).collect(),
        element_ids: set.iter().map(|&e| mesh.element_ids[e]).collect(),
        ..Mesh::default()
    };
    let b = part.boundary();
    let vertices = b.volume_node.iter().map(|&n| mesh.nodes[n] + u[n]).collect();
    BoundarySurface {
        surface: TriSurface::new(vertices, b.surface.triangles),
        element: b.element.iter().map(|&e| set[e]).collect(),
        volume_node: b.volume_node,
    }
}

/// The deformed boundary surface of the whole mesh ([`deformed_set_surface`] of every
/// element): what a surgeon's view shows as the brain.
pub fn deformed_boundary(mesh: &Mesh, u: &[Vector3<f64>]) -> BoundarySurface {
    let all: Vec<usize> = (0..mesh.elements.len()).collect();
    deformed_set_surface(mesh, &all, u)
}

/// Legacy VTK polydata of a deformed surface: points at `X + u`, triangles, and per point
/// the node id (`node_id`, as in result.vtk) and the displacement. The title line carries
/// `SPACE=` (3D Slicer's convention for legacy files).
fn write_surface_vtk(
    w: &mut dyn std::io::Write,
    title: &str,
    b: &BoundarySurface,
    mesh: &Mesh,
    u: &[Vector3<f64>],
) -> std::io::Result<()> {
    let (n, t) = (b.surface.vertices.len(), b.surface.triangles.len());
    writeln!(w, "# vtk DataFile Version 4.2\n{title}\nASCII\nDATASET POLYDATA")?;
    writeln!(w, "POINTS {n} double")?;
    for p in &b.surface.vertices {
        writeln!(w, "{:?} {:?} {:?}", p.x, p.y, p.z)?;
    }
    writeln!(w, "POLYGONS {t} {}", 4 * t)?;
    for [i, j, k] in &b.surface.triangles {
        writeln!(w, "3 {i} {j} {k}")?;
    }
    writeln!(w, "POINT_DATA {n}\nFIELD FieldData 2\nnode_id 1 {n} unsigned_long")?;
    for &v in &b.volume_node {
        writeln!(w, "{}", mesh.node_ids[v])?;
    }
    writeln!(w, "displacement 3 {n} double")?;
    for &v in &b.volume_node {
        writeln!(w, "{:?} {:?} {:?}", u[v].x, u[v].y, u[v].z)?;
    }
    Ok(())
}
