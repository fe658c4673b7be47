//! `brainshift`: brain shift computation for image-guided neurosurgery.

use bs_cli::{check, demo, field, gap, inspect, mesh, run, serve, sweep, warp};
use bs_scene::scene;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Computes brain shift with a Total Lagrangian finite-element model (Newton–Krylov by
/// default, or the paper's Dynamic Relaxation) and kinematic brain–skull contact. Each
/// command's one-line summary is its first doc paragraph (`brainshift --help`); the rest
/// is its `brainshift CMD --help`.
#[derive(Debug, Parser)]
#[command(name = "brainshift", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print what a mesh file holds: counts, sets, quality, surface.
    ///
    /// Reads a mesh file and prints what it holds: counts, sets, bounding box, element
    /// quality, surface closedness and orientation. Exits non-zero if the mesh is unusable.
    ///
    /// Formats: .inp (Abaqus), .msh (Gmsh 2.2/4.1 ASCII), .vtk, .vtu (volume);
    /// .stl, .obj, .off (surface).
    Inspect {
        /// The mesh file.
        file: PathBuf,
        /// Print the report as JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Validate a scene and the files it names, without solving.
    ///
    /// Validates a scene file and everything it refers to without running it: mesh validity,
    /// element and node sets, materials, boundary conditions, unit sanity and the skull
    /// surface (closed, manifold, outward). Exits non-zero naming the first problem.
    Check {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Also measure what each region with its own material changes: solve the scene,
        /// then once per region other than the largest with its elements made part of the
        /// largest, and print the largest and mean displacement differences.
        #[arg(long)]
        region_effect: bool,
        /// Print the report as JSON (the keys of the Python `Scene.check()` dict) instead of
        /// text.
        #[arg(long, conflicts_with = "region_effect")]
        json: bool,
    },
    /// Solve a scene and write its result (VTU, VTK, CSV, JSON).
    ///
    /// Computes the brain shift of a scene and writes DIR/result.vtu (displacement,
    /// in_contact; von Mises stress and J per element), DIR/displacements.csv and
    /// DIR/report.json. Without SCENE it runs the bundled real-anatomy demo.
    Run {
        /// The scene file (TOML); default: the bundled MNI152 demo scene.
        scene: Option<PathBuf>,
        /// Output folder (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// No progress or summary output.
        #[arg(long)]
        quiet: bool,
        /// Also sample how far to trust the fitted answer: N draws of the scan's noise (and
        /// of gravity's estimated parameters) pushed through the converged tangent. Writes
        /// DIR/uncertainty.csv (node_id,sx,sy,sz,s: σ per axis and in total, the scene's
        /// unit and frame), DIR/uncertainty.nii.gz (total σ in mm, float32, RAS, zero
        /// outside the brain) and report.json's `uncertainty`. 32 samples give σ to about
        /// 13 %. Needs a scene with something fitted (a scan `[[measurement]]`).
        #[arg(long, value_name = "N", value_parser = run::parse_samples)]
        uncertainty: Option<usize>,
        /// With --uncertainty: the grid of uncertainty.nii.gz, an image's (the pre-operative
        /// image: its warp shares the grid); default a 1 mm RAS grid around the deformed
        /// brain.
        #[arg(long, value_name = "IMAGE", requires = "uncertainty")]
        uncertainty_grid: Option<PathBuf>,
        /// With --uncertainty: GMRES's relative residual per sample (default 1e-2). A loose
        /// solve makes σ smaller than it is (at 1e-2 by 3 % on fixtures/fit and 17 % on
        /// fixtures/fit-gravity), so above 1e-3 four samples are refined to 1e-3 and σ is
        /// scaled by what that adds (at the default, then within 2 % on both); at 1e-3 σ
        /// is within 1.2 % unscaled, at 1.7–1.9× the time.
        #[arg(long, value_name = "R", requires = "uncertainty", value_parser = run::parse_tolerance)]
        uncertainty_tolerance: Option<f64>,
    },
    /// Solve the bundled MNI152 brain and warp its T1 image.
    ///
    /// Runs the bundled real-anatomy scene (MNI152 brain in its skull, craniotomy pushed in)
    /// and applies the result to the MNI152 T1 template: DIR/warped_t1.nii.gz (the template
    /// in the intra-operative configuration), DIR/field.nii.gz (the displacement field) and
    /// DIR/preview.png (slices before and after, and the displacement).
    Demo {
        /// Output folder (created if missing).
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Start from the image: mesh the bundled MNI152 brain mask (NIfTI) into OUT/mesh/
        /// with `brainshift mesh`, then solve that scene.
        #[arg(long)]
        from_image: bool,
    },
    /// Mesh a labelmap into a brain model, a skull cavity and a scene.
    ///
    /// Builds a model from a segmentation: a quality tetrahedral (or hexahedral) brain
    /// mesh of a labelmap with an element set per region, a skull cavity around it and a
    /// scene. Writes DIR/brain.vtu, DIR/brain.inp, DIR/skull.off and DIR/scene.toml and
    /// prints a quality report. Coordinates: the image's world frame (RAS), mm.
    Mesh {
        /// The labelmap (.nii or .nii.gz).
        labels: PathBuf,
        /// Output folder (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Label values that make up the brain, e.g. 1,2,3 (default: every non-zero label).
        #[arg(long)]
        brain: Option<String>,
        /// A region with its own material as NAME=LABELS, e.g. ventricles=4 (repeatable);
        /// the rest of the brain is the element set BRAIN.
        #[arg(long = "region")]
        regions: Vec<String>,
        /// Target element edge length, mm.
        #[arg(long, default_value_t = 4.0)]
        size: f64,
        /// Element type: t4 (isosurface stuffing, dihedral angles in [10.8°, 164.8°]) or h8
        /// (grid hexahedra).
        #[arg(long, default_value = "t4")]
        element: String,
        /// Distance of the skull cavity outside the brain, mm.
        #[arg(long, default_value_t = 3.0)]
        skull_offset: f64,
        /// Use the inner boundary of these (skull) labels as the cavity instead of an offset.
        #[arg(long)]
        cavity: Option<String>,
        /// Write scene.toml with its craniotomy load active (the CRANIOTOMY surface nodes
        /// moved 8 mm along -z) instead of as a comment to edit, so it runs as written.
        #[arg(long)]
        craniotomy: bool,
    },
    /// Warp a pre-operative image into a result's intra-operative state.
    ///
    /// Resamples the pre-operative image into the intra-operative configuration of a run's
    /// result: each voxel centre y inside the deformed brain gets the pre-operative value at
    /// the reference point X(y) (exact inverse of the piecewise-linear FE map; trilinear, or
    /// nearest voxel with --labels); between the brain and the skull the displacement is
    /// extended harmonically to zero at the skull, so the space the brain left samples the
    /// fluid that was there; voxels beyond the skull keep their value. Same grid (and, NIfTI
    /// to NIfTI, header) as the input. Images: .nii, .nii.gz, .nrrd, .nhdr.
    Warp {
        /// The pre-operative image (.nii, .nii.gz, .nrrd or .nhdr), in the mesh's world (mm).
        #[arg(long)]
        image: PathBuf,
        /// The result directory written by `brainshift run` (result.vtu, report.json).
        #[arg(long)]
        result: PathBuf,
        /// The warped image (.nii, .nii.gz or .nrrd).
        #[arg(long)]
        out: PathBuf,
        /// The image is a labelmap: nearest-voxel sampling, written as labels.
        #[arg(long)]
        labels: bool,
        /// With --labels: the label a resection's cavity (fluid) takes in the warped
        /// labelmap (default 0, background).
        #[arg(long, value_name = "LABEL", requires = "labels")]
        cavity_label: Option<u32>,
        /// Also draw a PNG: three orthogonal slices through the largest displacement
        /// (pre-operative, warped, and |displacement| in mm with the deformed brain's
        /// outline and a colour bar; a fourth column of σ in mm when the result was run
        /// with --uncertainty).
        #[arg(long, value_name = "PNG")]
        preview: Option<PathBuf>,
        /// The preview's slices through this point instead (RAS mm), e.g. a tumour's
        /// centre: `--preview-at -12,-37,50`.
        #[arg(
            long,
            value_name = "X,Y,Z",
            value_delimiter = ',',
            allow_hyphen_values = true,
            requires = "preview"
        )]
        preview_at: Option<Vec<f64>>,
    },
    /// Write a result as an ITK displacement field on an image's grid.
    ///
    /// Writes a run's result as an ITK displacement field on an image's grid:
    /// d(y) = X(y) - y inside the deformed brain, extended harmonically to zero at the skull,
    /// zero beyond. Loaded into 3D Slicer or ITK as a transform and applied to the
    /// pre-operative image, it gives what `warp` gives.
    Field {
        /// The image whose grid the field is sampled on (.nii, .nii.gz, .nrrd or .nhdr).
        #[arg(long)]
        reference: PathBuf,
        /// The result directory written by `brainshift run`.
        #[arg(long)]
        result: PathBuf,
        /// The field: .nii/.nii.gz (5-D float32, intent DISPVECT, RAS vectors), .mha or .nrrd
        /// (vector NRRD; both LPS, ITK's frame).
        #[arg(long)]
        out: PathBuf,
    },
    /// Brain–skull gap of a mesh's boundary nodes or of points, as CSV.
    ///
    /// Brain–skull gap of every boundary node of a mesh (or of points): one CSV row per node
    /// `id,signed_distance,closest_x,closest_y,closest_z,outside` (positive = inside the
    /// skull). Exits 1 if any node is outside the skull.
    Gap {
        /// Closed, outward-oriented skull surface (.stl, .obj, .off).
        #[arg(long)]
        skull: PathBuf,
        /// Volume mesh whose boundary nodes are measured.
        #[arg(long, conflicts_with = "points", required_unless_present = "points")]
        mesh: Option<PathBuf>,
        /// CSV of points with a header naming columns x, y, z.
        #[arg(long)]
        points: Option<PathBuf>,
        /// Closest-point algorithm.
        #[arg(long, value_enum, default_value = "paper")]
        algorithm: GapAlgorithm,
        /// Write the CSV here instead of standard output.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Serve live updates over OpenIGTLink (3D Slicer, PLUS).
    ///
    /// Serves brain-shift updates over OpenIGTLink (3D Slicer's OpenIGTLinkIF, PLUS,
    /// navigation systems): prepares a live session of SCENE and reads IMAGE once, then
    /// answers each measurement (POINT/POLYDATA IntraopPoints, POLYDATA IntraopSurface,
    /// POINT PreopLandmarks + IntraopLandmarks, STRING Displacements, Gravity or Resect)
    /// with IMAGE WarpedImage, IMAGE DisplacementField, POLYDATA DeformedBrain and STRING
    /// Report; errors as STRING Error. Geometry on the wire: RAS, mm. docs/operating-room.md
    /// has the messages.
    Serve(bs_serve::Options),
    /// Parameter sweeps: plan, run, collect, emit a Slurm job.
    ///
    /// Parameter sweeps: plan one scene per row from a sweep file, run rows (anywhere, in
    /// any order, idempotently), collect one table, or emit a Slurm array job.
    #[command(subcommand)]
    Sweep(SweepCommand),
}

#[derive(Debug, Subcommand)]
enum SweepCommand {
    /// Expand a sweep file into one scene per row.
    ///
    /// Expands SWEEP.toml (base scene, [[axis]] keys with values or range + samples, grid or
    /// Latin hypercube) into DIR/manifest.csv, DIR/manifest.json and DIR/scenes/I.toml.
    Plan {
        /// The sweep file (TOML).
        sweep: PathBuf,
        /// The sweep folder (created if missing).
        #[arg(long)]
        out: PathBuf,
    },
    /// Run one row of a sweep.
    ///
    /// Runs row I into DIR/runs/I/ (the files `run` writes). A row already done is skipped;
    /// a failed row writes DIR/runs/I/error.json and exits non-zero.
    Run {
        /// The sweep folder.
        dir: PathBuf,
        /// The row (0-based; the Slurm array index).
        #[arg(long)]
        index: usize,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// No summary output.
        #[arg(long)]
        quiet: bool,
    },
    /// Collect every row's outcome into one table.
    ///
    /// Writes DIR/summary.csv: every row's parameters, status (ok/failed/missing), error,
    /// max displacement, displacement at named points, nodes in contact and solve time.
    Collect {
        /// The sweep folder.
        dir: PathBuf,
        /// CSV of named reference points with a header name,x,y,z (mesh units).
        #[arg(long)]
        points: Option<PathBuf>,
    },
    /// Write a Slurm array job with one task per row.
    ///
    /// Writes DIR/sweep.slurm: a Slurm array job with one task per row, memory from the
    /// scene's estimate (as `check` prints it).
    EmitSlurm {
        /// The sweep folder.
        dir: PathBuf,
        /// Run at most M rows at once.
        #[arg(long)]
        max_parallel: Option<usize>,
        /// Wall-time limit per row (HH:MM:SS).
        #[arg(long, default_value = "01:00:00")]
        time: String,
        /// Cores per row (passed on as --threads).
        #[arg(long, default_value_t = 2)]
        cpus_per_task: usize,
        /// The brainshift program the tasks call (default: this one).
        #[arg(long)]
        program: Option<PathBuf>,
    },
}

/// Contact algorithms selectable on the command line.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum GapAlgorithm {
    Paper,
    Coherent,
    Parry,
    BruteForce,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result: Result<ExitCode, Box<dyn std::error::Error>> = match cli.command {
        Command::Inspect { file, json } => inspect::run(&file, json).map_err(Into::into),
        Command::Check { scene, region_effect, json } => {
            check::run(&scene, region_effect, json).map_err(Into::into)
        }
        Command::Run {
            scene,
            out,
            threads,
            quiet,
            uncertainty,
            uncertainty_grid,
            uncertainty_tolerance,
        } => run::run(&run::RunOptions {
            scene: scene.unwrap_or_else(run::default_scene),
            out,
            threads,
            quiet,
            uncertainty,
            uncertainty_grid,
            uncertainty_tolerance,
        }),
        Command::Demo { out, from_image } => demo::run(&out, from_image),
        Command::Mesh {
            labels,
            out,
            brain,
            regions,
            size,
            element,
            skull_offset,
            cavity,
            craniotomy,
        } => mesh::run(&mesh::MeshOptions {
            labels,
            out,
            brain,
            regions,
            size,
            element,
            skull_offset,
            cavity,
            craniotomy,
        }),
        Command::Warp { image, result, out, labels, cavity_label, preview, preview_at } => {
            let labels = labels.then(|| cavity_label.unwrap_or(0));
            warp::run(&image, &result, &out, labels, (preview.as_deref(), preview_at.as_deref()))
        }
        Command::Field { reference, result, out } => {
            field::run(&reference, &result, &out).map_err(Into::into)
        }
        Command::Gap { skull, mesh, points, algorithm, out } => {
            let query = match (mesh, points) {
                (Some(m), _) => Ok(gap::Query::Mesh(m)),
                (None, Some(p)) => Ok(gap::Query::Points(p)),
                (None, None) => Err("give --mesh VOLUME or --points POINTS.csv".into()),
            };
            let algorithm = match algorithm {
                GapAlgorithm::Paper => scene::Algorithm::Paper,
                GapAlgorithm::Coherent => scene::Algorithm::Coherent,
                GapAlgorithm::Parry => scene::Algorithm::Parry,
                GapAlgorithm::BruteForce => scene::Algorithm::BruteForce,
            };
            query.and_then(|q| gap::run(&skull, &q, algorithm, out.as_deref()))
        }
        Command::Serve(o) => serve::run(&o),
        Command::Sweep(c) => match c {
            SweepCommand::Plan { sweep, out } => sweep::plan(&sweep, &out),
            SweepCommand::Run { dir, index, threads, quiet } => {
                sweep::run(&dir, index, threads, quiet)
            }
            SweepCommand::Collect { dir, points } => sweep::collect(&dir, points.as_deref()),
            SweepCommand::EmitSlurm { dir, max_parallel, time, cpus_per_task, program } => {
                sweep::emit_slurm(&dir, max_parallel, &time, cpus_per_task, program)
            }
        },
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
