//! `cargo xtask deps`: the dependency rules of the workspace, also run as tests.
//!
//! * [`crates`]: which workspace crate may depend on which (`cargo metadata`);
//! * [`modules`]: the module graph of every crate of the workspace, read from every `.rs`
//!   file under its `src/` (folders walked recursively, `crate::`, `super::` and `self::`
//!   paths resolved, intra-doc links counted);
//! * [`cycles`]: every circle of modules in any crate, with its path and its imports;
//! * [`layers`]: the folder order of bs-dr (a lower folder importing a higher one fails,
//!   naming both files);
//! * [`unused`]: dependencies no file of their package names.

pub mod crates;
pub mod cycles;
pub mod layers;
pub mod modules;
pub mod source;
pub mod unused;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde_json::Value;

/// The workspace members and their `src/` folders, from `cargo metadata`.
fn members(metadata: &Value) -> Result<Vec<(String, PathBuf)>, String> {
    let packages = metadata["packages"].as_array().ok_or("cargo metadata: no packages array")?;
    let mut out = Vec::new();
    for p in packages {
        let name = p["name"].as_str().ok_or("cargo metadata: a package without a name")?;
        let manifest = p["manifest_path"].as_str().ok_or("cargo metadata: no manifest_path")?;
        let dir = Path::new(manifest).parent().ok_or("cargo metadata: manifest at /")?;
        out.push((name.to_string(), dir.join("src")));
    }
    out.sort();
    Ok(out)
}

/// What the module check found in one crate.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CrateModules {
    /// Crate name.
    pub name: String,
    /// Modules read (the root included).
    pub modules: usize,
    /// Edges between them.
    pub edges: usize,
    /// Its layer order's rows, if it has one.
    pub order: Option<String>,
}

/// Checks the module graph of crate `name` in `src`: circles, and its layer order if it has
/// one. Problems are appended to `problems`.
pub fn check_crate(
    name: &str,
    src: &Path,
    problems: &mut Vec<String>,
) -> Result<CrateModules, String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap_or(Path::new("."));
    let g = modules::read(src)?.relative_to(root);
    problems.extend(cycles::circles(name, &g));
    let order = layers::ORDERS.iter().find(|(n, _)| *n == name).map(|(_, o)| *o);
    if let Some(order) = order {
        problems.extend(layers::breaches(name, order, &g));
    }
    Ok(CrateModules {
        name: name.to_string(),
        modules: g.modules.len(),
        edges: g.edges.len(),
        order: order.map(|o| o.iter().map(|r| r.join(", ")).collect::<Vec<_>>().join(" < ")),
    })
}

/// Runs every check; the summary to print, or every problem found.
pub fn run() -> Result<String, String> {
    let metadata = crates::metadata()?;
    let mut problems = Vec::new();
    let edges = crates::check(&metadata).unwrap_or_else(|e| {
        problems.push(e);
        0
    });
    problems.extend(unused::unused(&metadata)?);
    let mut summary = format!("crate graph OK ({edges} workspace edges checked)\n");
    for (name, src) in members(&metadata)? {
        let c = check_crate(&name, &src, &mut problems)?;
        let _ = write!(summary, "{:<12} {:>3} modules {:>4} imports", c.name, c.modules, c.edges);
        if let Some(order) = &c.order {
            let _ = write!(summary, "  layers {order}");
        }
        summary.push('\n');
    }
    if problems.is_empty() {
        summary.push_str(
            "no module cycle in any crate; every layer order holds; every dependency is used",
        );
        Ok(summary)
    } else {
        Err(problems.join("\n"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_crate_is_free_of_circles_and_bs_dr_keeps_its_layers() {
        let summary = run().unwrap_or_else(|e| panic!("{e}"));
        for krate in ["bs-mesh", "bs-dr", "bs-scene", "bs-image", "bs-meshgen", "bs-py", "xtask"] {
            assert!(summary.contains(krate), "{krate} not checked:\n{summary}");
        }
        assert!(summary.contains("layers element < kernels"), "{summary}");
    }
}
