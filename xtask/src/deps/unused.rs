//! Dependencies no file of their package names: each package's `[dependencies]`,
//! `[dev-dependencies]` and `[build-dependencies]` (from `cargo metadata`) against the
//! Rust files of the package (`src/`, `tests/`, `benches/`, `examples/`, `build.rs`). A
//! dependency counts as used where its library name appears as a path (`name::`), in a
//! `use` or `extern crate`, or in an attribute (`#[name(`, e.g. a derive's helper).

use std::path::{Path, PathBuf};

use serde_json::Value;

/// Every unused dependency of the workspace's packages in `metadata`, as a problem naming
/// the package, the dependency and the manifest to drop it from.
pub fn unused(metadata: &Value) -> Result<Vec<String>, String> {
    let members: Vec<&str> = metadata["workspace_members"]
        .as_array()
        .ok_or("cargo metadata: no workspace_members")?
        .iter()
        .filter_map(Value::as_str)
        .collect();
    let packages = metadata["packages"].as_array().ok_or("cargo metadata: no packages array")?;
    let mut problems = Vec::new();
    for p in packages.iter().filter(|p| p["id"].as_str().is_some_and(|id| members.contains(&id))) {
        let name = p["name"].as_str().unwrap_or("?");
        let manifest = PathBuf::from(p["manifest_path"].as_str().unwrap_or("Cargo.toml"));
        let dir = manifest.parent().unwrap_or(Path::new(".")).to_path_buf();
        let text = sources(&dir)?;
        for d in p["dependencies"].as_array().into_iter().flatten() {
            let dep = d["rename"].as_str().or(d["name"].as_str()).unwrap_or("?");
            let lib = dep.replace('-', "_");
            if !names(&text, &lib) {
                problems.push(format!(
                    "{name}: the dependency `{dep}` is named by no Rust file of the package; \
                     drop it from {}",
                    manifest.display()
                ));
            }
        }
    }
    Ok(problems)
}

/// Whether `text` names the crate `lib` as code does.
fn names(text: &str, lib: &str) -> bool {
    [format!("{lib}::"), format!("use {lib}"), format!("extern crate {lib}"), format!("#[{lib}(")]
        .iter()
        .any(|pattern| {
            text.match_indices(pattern.as_str()).any(|(at, _)| {
                // Not the tail of a longer name (`my_serde::`).
                at == 0 || !text[..at].ends_with(|c: char| c.is_alphanumeric() || c == '_')
            })
        })
}

/// The Rust files of the package in `dir`, concatenated.
fn sources(dir: &Path) -> Result<String, String> {
    let mut files = Vec::new();
    let build = dir.join("build.rs");
    if build.is_file() {
        files.push(build);
    }
    for sub in ["src", "tests", "benches", "examples"] {
        let d = dir.join(sub);
        if d.is_dir() {
            super::modules::rust_files(&d, &mut files)?;
        }
    }
    let mut text = String::new();
    for f in files {
        text += &std::fs::read_to_string(&f).map_err(|e| format!("{}: {e}", f.display()))?;
        text.push('\n');
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_name_counts_as_a_path_a_use_or_an_attribute_and_not_inside_another() {
        assert!(names("let x = serde_json::json!(1);", "serde_json"));
        assert!(names("use rayon::prelude::*;", "rayon"));
        assert!(names("#[pyo3(signature = ())]", "pyo3"));
        assert!(!names("use my_rayon::prelude::*;", "rayon"));
        assert!(!names("// rayon is fast", "rayon"));
    }
}
