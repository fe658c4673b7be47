//! Why a scene cannot run, or why its result is refused: one typed error for the whole
//! crate, each variant naming the file and the key, set, node or element at fault, and its
//! message saying how to fix it.

use std::path::PathBuf;

use bs_dr::SolveError;

/// Why a scene cannot run or its result cannot be written.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file cannot be read or parsed, or a key holds a value out of range.
    #[error("{}: {message}", file.display())]
    Scene {
        /// The scene file.
        file: PathBuf,
        /// What is wrong with which key, and how to fix it.
        message: String,
    },
    /// A file the scene names (mesh, skull, displacement file) cannot be read.
    #[error("{}: {key}: {message}", scene.display())]
    Read {
        /// The scene file.
        scene: PathBuf,
        /// The key that names the file (`[mesh] file`, `[contact] skull`, …).
        key: String,
        /// The reader's message (it names the file and line).
        message: String,
    },
    /// The mesh is unusable (inverted or degenerate elements, dangling references).
    #[error("{}: the mesh is not usable ({count} problem{}); first: {first}",
            file.display(), if *count == 1 { "" } else { "s" })]
    Mesh {
        /// The mesh file.
        file: PathBuf,
        /// How many problems validation found.
        count: usize,
        /// The first problem.
        first: String,
    },
    /// A set named by the scene is missing from the mesh or selects nothing.
    #[error("{}: {key} = \"{set}\": {message}", scene.display())]
    Set {
        /// The scene file.
        scene: PathBuf,
        /// The key (`[[region]] elset`, `[[boundary]] #2 nset`, …).
        key: String,
        /// The set's name.
        set: String,
        /// What is wrong (missing, empty) and what the mesh has.
        message: String,
    },
    /// A node is constrained inconsistently or a prescribed displacement is refused.
    #[error("{}: node {node_id}: {message}", scene.display())]
    Node {
        /// The scene file.
        scene: PathBuf,
        /// The node's id in the mesh file.
        node_id: u64,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// An element does not fit the scene (wrong kind, two regions, no material).
    #[error("{}: element {element_id}: {message}", scene.display())]
    Element {
        /// The scene file.
        scene: PathBuf,
        /// The element's id in the mesh file.
        element_id: u64,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// The skull surface is not a closed outward surface, or cannot be searched.
    #[error("{}: [contact] skull {}: {message}", scene.display(), skull.display())]
    Skull {
        /// The scene file.
        scene: PathBuf,
        /// The skull file.
        skull: PathBuf,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// Brain surface nodes lie outside the skull before any load.
    #[error(
        "{}: {} brain surface nodes are outside the skull before any load: {}{}; the brain \
         must start inside the skull cavity (check the skull file, its units and its \
         registration to the mesh)",
        scene.display(), nodes.len(), list(nodes), if nodes.len() > 10 { ", ..." } else { "" }
    )]
    OutsideSkull {
        /// The scene file.
        scene: PathBuf,
        /// Node ids and how far outside (mesh length units), worst first.
        nodes: Vec<(u64, f64)>,
    },
    /// The scene has nothing to compute, or asks for a combination that cannot run.
    #[error("{}: {message}", scene.display())]
    Unsupported {
        /// The scene file.
        scene: PathBuf,
        /// What cannot run and what to do instead.
        message: String,
    },
    /// The run would need more memory than the machine has.
    #[error(
        "{}: the run needs about {} MB but only {} MB are available; use a coarser mesh, \
         the dr solver (less memory) or a machine with more memory",
        scene.display(), (*estimate_bytes / 1e6).round(), (*available_bytes / 1e6).round()
    )]
    Memory {
        /// The scene file.
        scene: PathBuf,
        /// The run's estimated peak memory (bytes).
        estimate_bytes: f64,
        /// Memory available on this machine (bytes).
        available_bytes: f64,
    },
    /// The solver stopped with a typed error.
    #[error("the solver stopped: {0}")]
    Solve(#[from] SolveError),
    /// The solver converged but the result failed a check independent of it.
    #[error("{0}")]
    Verify(#[from] VerifyError),
    /// A labelmap cannot be read or meshed (`brainshift mesh`); the message says why and
    /// the fix.
    #[error("{}: {message}", file.display())]
    Labelmap {
        /// The labelmap file.
        file: PathBuf,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// An image cannot be read or does not fit the result (wrong dimension, a mesh outside
    /// its extent: wrong frame).
    #[error("{}: {message}", file.display())]
    Image {
        /// The image file.
        file: PathBuf,
        /// What is wrong, with both frames and extents when they disagree, and the fix.
        message: String,
    },
    /// A result directory cannot be read back (missing files, no displacement field).
    #[error("{}: {message}", dir.display())]
    Result {
        /// The result directory.
        dir: PathBuf,
        /// What is missing or wrong and how to fix it.
        message: String,
    },
    /// An output file could not be written.
    #[error("{}: {message}", path.display())]
    Write {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's message.
        message: String,
    },
}

fn list(nodes: &[(u64, f64)]) -> String {
    let v: Vec<String> =
        nodes.iter().take(10).map(|&(n, d)| format!("node {n} ({d:.4} outside)")).collect();
    v.join(", ")
}

impl SceneError {
    /// A short stable name of the error kind, for tables and scripts (the solver's own kind
    /// for solver errors).
    pub fn kind(&self) -> &'static str {
        match self {
            SceneError::Scene { .. } => "Scene",
            SceneError::Read { .. } => "Read",
            SceneError::Mesh { .. } => "Mesh",
            SceneError::Set { .. } => "Set",
            SceneError::Node { .. } => "Node",
            SceneError::Element { .. } => "Element",
            SceneError::Skull { .. } => "Skull",
            SceneError::OutsideSkull { .. } => "OutsideSkull",
            SceneError::Unsupported { .. } => "Unsupported",
            SceneError::Memory { .. } => "Memory",
            SceneError::Solve(e) => e.kind(),
            SceneError::Verify(e) => e.kind(),
            SceneError::Labelmap { .. } => "Labelmap",
            SceneError::Image { .. } => "Image",
            SceneError::Result { .. } => "Result",
            SceneError::Write { .. } => "Write",
        }
    }
}

/// Why a converged result is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum VerifyError {
    /// Brain surface nodes ended outside the skull.
    #[error(
        "contact check failed: {count} brain surface node{} ended outside the skull by more \
         than the tolerance {tolerance:e}; worst: node {node_id} by {distance:.3e}. The contact \
         handler missed penetrations; run the scene with algorithm = \"brute-force\" to confirm",
        if *count == 1 { "" } else { "s" }
    )]
    OutsideSkull {
        /// How many slaves are outside beyond the tolerance.
        count: usize,
        /// The worst one's id.
        node_id: u64,
        /// How far outside it is (mesh length units).
        distance: f64,
        /// The tolerance (mesh length units).
        tolerance: f64,
    },
    /// An element of the result is inverted or flat.
    #[error(
        "result check failed: element {element_id} has J = {jacobian:.3e} <= 0 (inverted) in \
         the converged result; the load is too large for this mesh: refine it under the load \
         or reduce the displacement"
    )]
    Inverted {
        /// The element's id.
        element_id: u64,
        /// Its volume ratio.
        jacobian: f64,
    },
    /// The result is not in equilibrium.
    #[error(
        "result check failed: the out-of-balance force at node {node_id} is {residual:.3e} of \
         the largest reaction force (bound {bound:.1e} for the tolerance); the solver stopped \
         before equilibrium: tighten [solver] tolerance or use kind = \"dr\""
    )]
    Equilibrium {
        /// The worst free node's id.
        node_id: u64,
        /// Its out-of-balance force relative to the largest reaction.
        residual: f64,
        /// The bound it exceeded.
        bound: f64,
    },
}

impl VerifyError {
    /// A short stable name of the error kind.
    pub fn kind(&self) -> &'static str {
        match self {
            VerifyError::OutsideSkull { .. } => "ContactCheck",
            VerifyError::Inverted { .. } => "InvertedResult",
            VerifyError::Equilibrium { .. } => "Equilibrium",
        }
    }
}
