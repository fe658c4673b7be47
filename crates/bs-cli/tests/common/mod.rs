//! Helpers shared by the end-to-end tests of the `brainshift` binary.

use std::path::PathBuf;
use std::process::{Command, Output};

/// Runs the `brainshift` binary of this build with `args`.
pub fn brainshift(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_brainshift")).args(args).output().expect("run brainshift")
}

/// A fresh temporary folder (`bs-{prefix}-{pid}-{name}`), removed on drop.
pub struct TempDir(pub PathBuf);

impl TempDir {
    /// Creates it empty.
    pub fn new_in(prefix: &str, name: &str) -> TempDir {
        let p = std::env::temp_dir().join(format!("bs-{prefix}-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
