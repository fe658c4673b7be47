//! The server's options, declared once: `brainshift serve` flattens them into its command
//! line, the Python package's `python -m brainshift.serve` parses its arguments with them
//! (through the bindings), and docs/operating-room.md's option list is checked against
//! them (`tests/options_doc.rs`).

use std::path::PathBuf;

/// How to serve: the scene, the image, the address and the limits.
#[derive(Debug, Clone, clap::Args)]
pub struct Options {
    /// The scene file (TOML), e.g. fixtures/mni152/scene.toml.
    pub scene: PathBuf,
    /// The pre-operative image to warp (.nii, .nii.gz, .nrrd), in the scene's world.
    #[arg(long)]
    pub image: PathBuf,
    /// Address to listen on (127.0.0.1: this machine only; 0.0.0.0 for the network).
    #[arg(long, default_value = "127.0.0.1")]
    pub host: String,
    /// TCP port (18944: OpenIGTLink's; 0: any free port, printed).
    #[arg(long, default_value_t = 18944)]
    pub port: u16,
    /// The prescribed node set the measurements move (default: the scene's only one).
    #[arg(long)]
    pub set: Option<String>,
    /// Solver threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Do not send the DisplacementField image.
    #[arg(long)]
    pub no_field: bool,
    /// Do not send the DeformedBrain surface.
    #[arg(long)]
    pub no_surface: bool,
    /// After each update, sample σ of the fitted answer with N samples and send IMAGE
    /// Uncertainty (total σ in mm, float32 on the image's grid) after the WarpedImage; the
    /// scene must fit something (docs/uncertainty.md).
    #[arg(long, value_name = "N")]
    pub uncertainty: Option<usize>,
    /// Largest message accepted, MB.
    #[arg(long, default_value_t = 64.0)]
    pub max_message_mb: f64,
    /// Close a connection silent this long in the middle of a message, seconds.
    #[arg(long, default_value_t = 30.0)]
    pub stall_seconds: f64,
    /// Clients served at once (more are answered with an error and closed).
    #[arg(long, default_value_t = 16)]
    pub max_clients: usize,
    /// Print every solver iteration.
    #[arg(long)]
    pub verbose: bool,
}

/// [`Options`] as a command of its own (the Python package's `python -m brainshift.serve`).
#[derive(Debug, clap::Parser)]
#[command(
    name = "brainshift serve",
    about = "Serve brain-shift updates over OpenIGTLink (3D Slicer's OpenIGTLinkIF, PLUS, \
             navigation systems): each intra-operative measurement is solved warm from the last \
             and answered with the warped image, the displacement field, the deformed brain \
             surface and the report. Geometry on the wire is RAS, mm."
)]
pub struct Command {
    /// The options.
    #[command(flatten)]
    pub options: Options,
}

impl Options {
    /// The largest body accepted, bytes.
    pub fn max_body(&self) -> u64 {
        (self.max_message_mb.max(0.0) * (1u64 << 20) as f64) as u64
    }

    /// The stall limit (`None` for a non-positive or non-finite one: no limit).
    pub fn stall(&self) -> Option<std::time::Duration> {
        (self.stall_seconds.is_finite() && self.stall_seconds > 0.0)
            .then(|| std::time::Duration::from_secs_f64(self.stall_seconds))
    }
}
