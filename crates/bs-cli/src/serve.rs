//! `brainshift serve`: the OpenIGTLink server lives in the Python package (on pyigtl, the
//! OpenIGTLink library used with 3D Slicer and PLUS), next to the live `Session` it drives;
//! this command starts it with the same options (`python3 -m brainshift.serve`, or the
//! interpreter named by BRAINSHIFT_PYTHON).

use std::path::PathBuf;
use std::process::{Command, ExitCode};

/// The options of `python -m brainshift.serve`, forwarded as given.
#[derive(Debug, clap::Args)]
pub struct ServeOptions {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// The pre-operative image to warp (.nii, .nii.gz, .nrrd), in the scene's world.
    #[arg(long)]
    pub image: PathBuf,
    /// Address to listen on (127.0.0.1: this machine only).
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

impl ServeOptions {
    /// The server's command-line arguments.
    pub fn args(&self) -> Vec<String> {
        let mut a = vec![
            "-m".into(),
            "brainshift.serve".into(),
            self.scene.display().to_string(),
            "--image".into(),
            self.image.display().to_string(),
            "--host".into(),
            self.host.clone(),
            "--port".into(),
            self.port.to_string(),
            "--max-message-mb".into(),
            self.max_message_mb.to_string(),
            "--stall-seconds".into(),
            self.stall_seconds.to_string(),
            "--max-clients".into(),
            self.max_clients.to_string(),
        ];
        if let Some(s) = &self.set {
            a.extend(["--set".into(), s.clone()]);
        }
        if let Some(t) = self.threads {
            a.extend(["--threads".into(), t.to_string()]);
        }
        if self.no_field {
            a.push("--no-field".into());
        }
        if self.no_surface {
            a.push("--no-surface".into());
        }
        if self.verbose {
            a.push("--verbose".into());
        }
        a
    }
}

/// Runs the server in the Python interpreter that has the `brainshift` package and pyigtl.
pub fn run(o: &ServeOptions) -> Result<ExitCode, Box<dyn std::error::Error>> {
    let python = std::env::var("BRAINSHIFT_PYTHON").unwrap_or_else(|_| "python3".into());
    let probe = Command::new(&python).args(["-c", "import brainshift.serve, pyigtl"]).output();
    match probe {
        Err(e) => {
            return Err(format!(
                "brainshift serve runs the Python package's server, and '{python}' cannot be \
                 started ({e}); set BRAINSHIFT_PYTHON to a Python 3 interpreter"
            )
            .into());
        }
        Ok(out) if !out.status.success() => {
            return Err(format!(
                "brainshift serve runs the Python package's server, and '{python}' cannot \
                 import it: {}install it with `pip install ./crates/bs-py pyigtl` (or set \
                 BRAINSHIFT_PYTHON to the interpreter that has them)",
                String::from_utf8_lossy(&out.stderr)
                    .lines()
                    .last()
                    .map(|l| format!("{l}; "))
                    .unwrap_or_default()
            )
            .into());
        }
        Ok(_) => {}
    }
    let mut cmd = Command::new(&python);
    cmd.args(o.args());
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        // Replace this process: Ctrl-C and SIGTERM reach the server itself.
        let e = cmd.exec();
        Err(format!("could not start '{python}': {e}").into())
    }
    #[cfg(not(unix))]
    {
        let status = cmd.status()?;
        Ok(if status.success() { ExitCode::SUCCESS } else { ExitCode::FAILURE })
    }
}
