//! The layering rules of the workspace, checked against `cargo metadata`.
//!
//! The table below is the single source of truth for which workspace crate may depend on
//! which (normal, dev and build dependencies alike). A crate missing from the table, or an
//! edge not allowed by it, fails the check with a message naming the edge and the rule.

use std::process::Command;

use serde_json::Value;

/// Workspace crates and the workspace crates each may depend on.
pub const ALLOWED: &[(&str, &[&str])] = &[
    ("bs-mesh", &[]),
    ("bs-material", &[]),
    ("bs-image", &[]),
    ("bs-meshgen", &["bs-mesh", "bs-image"]),
    ("bs-contact", &["bs-mesh"]),
    ("bs-dr", &["bs-mesh", "bs-material"]),
    ("bs-scene", &["bs-mesh", "bs-material", "bs-dr", "bs-contact", "bs-image", "bs-meshgen"]),
    ("bs-cli", &["bs-mesh", "bs-dr", "bs-contact", "bs-scene"]),
    ("bs-py", &["bs-mesh", "bs-contact", "bs-scene"]),
    (
        "xtask",
        &["bs-mesh", "bs-material", "bs-dr", "bs-contact", "bs-scene", "bs-image", "bs-meshgen"],
    ),
];

/// Extra edges allowed for dev-dependencies only (tests checking a front end against a
/// lower crate's closed forms).
pub const ALLOWED_DEV: &[(&str, &[&str])] = &[("bs-cli", &["bs-material"])];

/// Why an edge is forbidden, for the error message.
fn rule_for(from: &str, to: &str) -> &'static str {
    match (from, to) {
        ("bs-dr", "bs-contact") | ("bs-contact", "bs-dr") => {
            "the solver and the contact handlers must stay swappable: bs-dr owns the contact \
             trait and bs-scene adapts bs-contact to it"
        }
        ("bs-cli", "bs-material") => {
            "bs-cli is a front end: materials are built by bs-scene from the scene's moduli"
        }
        ("bs-py", _) => {
            "bs-py is a front end like bs-cli: it calls bs-scene (and reads meshes and skulls \
             with bs-mesh and bs-contact), so Python results are the command's"
        }
        ("xtask", "bs-cli") => {
            "xtask drives bs-scene, as every front end does, not the binary's code"
        }
        ("bs-material", _) => "materials know no meshes, elements or solvers",
        ("bs-mesh", _) => "bs-mesh is the bottom layer and depends on no other brainshift crate",
        _ => "only bs-scene composes the layers; front ends (bs-cli, bs-py, xtask) build on it",
    }
}

/// Runs `cargo metadata` on the workspace and checks it. Returns the number of
/// workspace-internal edges.
pub fn check_workspace() -> Result<usize, String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--no-deps", "--offline"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .map_err(|e| format!("could not run cargo metadata: {e}"))?;
    if !out.status.success() {
        return Err(format!("cargo metadata failed:\n{}", String::from_utf8_lossy(&out.stderr)));
    }
    let metadata: Value =
        serde_json::from_slice(&out.stdout).map_err(|e| format!("cargo metadata output: {e}"))?;
    check(&metadata)
}

/// Checks parsed `cargo metadata --no-deps` output against [`ALLOWED`].
pub fn check(metadata: &Value) -> Result<usize, String> {
    let packages = metadata["packages"].as_array().ok_or("cargo metadata: no packages array")?;
    let members: Vec<&str> = packages.iter().filter_map(|p| p["name"].as_str()).collect();
    let mut problems = Vec::new();
    let mut edges = 0;
    for p in packages {
        let name = p["name"].as_str().unwrap_or("?");
        let Some((_, allowed)) = ALLOWED.iter().find(|(n, _)| *n == name) else {
            problems.push(format!(
                "crate '{name}' is not in the layering table of xtask/src/deps.rs: add it with the \
                 crates it may depend on, and a paragraph in docs/ARCHITECTURE.md"
            ));
            continue;
        };
        for d in p["dependencies"].as_array().into_iter().flatten() {
            let Some(dep) = d["name"].as_str() else { continue };
            // A crate's dev-dependency on itself (to switch on its own test features) is no
            // edge between layers.
            if !members.contains(&dep) || dep == name {
                continue;
            }
            edges += 1;
            let kind = d["kind"].as_str().unwrap_or("normal");
            let dev_ok =
                kind == "dev" && ALLOWED_DEV.iter().any(|(n, a)| *n == name && a.contains(&dep));
            if !allowed.contains(&dep) && !dev_ok {
                problems.push(format!(
                    "forbidden dependency {name} -> {dep} ({kind}): {}",
                    rule_for(name, dep)
                ));
            }
        }
    }
    if problems.is_empty() { Ok(edges) } else { Err(problems.join("\n")) }
}

/// Crates whose top-level modules must not import each other in a circle (every crate).
pub const ACYCLIC: &[&str] =
    &["bs-mesh", "bs-material", "bs-contact", "bs-dr", "bs-scene", "bs-cli"];

/// The top-level modules of a crate's `src` and the modules each names through `crate::`
/// (a `use crate::m` or a `crate::m::` path anywhere in the file).
pub fn module_graph(src: &std::path::Path) -> Result<Vec<(String, Vec<String>)>, String> {
    let mut graph = Vec::new();
    let entries = std::fs::read_dir(src).map_err(|e| format!("{}: {e}", src.display()))?;
    let mut files: Vec<std::path::PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "rs"))
        .collect();
    files.sort();
    let names: Vec<String> =
        files.iter().filter_map(|f| Some(f.file_stem()?.to_str()?.to_string())).collect();
    for (file, name) in files.iter().zip(&names) {
        if name == "lib" || name == "main" {
            continue;
        }
        let text = std::fs::read_to_string(file).map_err(|e| format!("{}: {e}", file.display()))?;
        let code: String = text
            .lines()
            .filter(|l| !l.trim_start().starts_with("//"))
            .collect::<Vec<_>>()
            .join("\n");
        let mut uses: Vec<String> = names
            .iter()
            .filter(|m| *m != name && *m != "lib" && *m != "main")
            .filter(|m| {
                code.contains(&format!("crate::{m}::"))
                    || code.contains(&format!("crate::{m};"))
                    || code.contains(&format!("crate::{m}}}"))
                    || code.contains(&format!("crate::{m},"))
            })
            .cloned()
            .collect();
        uses.sort();
        graph.push((name.clone(), uses));
    }
    Ok(graph)
}

/// Checks every crate of [`ACYCLIC`] for module cycles; returns how many were checked.
pub fn check_modules() -> Result<usize, String> {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for krate in ACYCLIC {
        let graph = module_graph(&root.join("crates").join(krate).join("src"))?;
        if let Some(c) = find_cycle(&graph) {
            return Err(format!(
                "{krate}: module cycle {}; move what both need into a module of its own",
                c.join(" -> ")
            ));
        }
    }
    Ok(ACYCLIC.len())
}

/// A cycle of `graph` as a path `a -> b -> ... -> a`, if any.
pub fn find_cycle(graph: &[(String, Vec<String>)]) -> Option<Vec<String>> {
    fn visit(
        n: &str,
        graph: &[(String, Vec<String>)],
        state: &mut std::collections::HashMap<String, u8>,
        path: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        match state.get(n) {
            Some(2) => return None,
            Some(1) => {
                let at = path.iter().position(|p| p == n).unwrap_or(0);
                let mut cycle = path[at..].to_vec();
                cycle.push(n.to_string());
                return Some(cycle);
            }
            _ => {}
        }
        state.insert(n.to_string(), 1);
        path.push(n.to_string());
        let edges = graph.iter().find(|(m, _)| m == n).map(|(_, e)| e.as_slice()).unwrap_or(&[]);
        for e in edges {
            if let Some(c) = visit(e, graph, state, path) {
                return Some(c);
            }
        }
        path.pop();
        state.insert(n.to_string(), 2);
        None
    }
    let mut state = std::collections::HashMap::new();
    graph.iter().find_map(|(n, _)| visit(n, graph, &mut state, &mut Vec::new()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn workspace_graph_follows_the_layering_rules() {
        let edges = check_workspace().unwrap_or_else(|e| panic!("{e}"));
        // bs-contact -> bs-mesh, bs-dr -> {bs-mesh, bs-material}, bs-scene -> 4 crates,
        // bs-cli -> bs-scene.
        assert!(edges >= 8, "expected at least the 8 layering edges, found {edges}");
    }

    fn package(name: &str, deps: &[&str]) -> Value {
        json!({
            "name": name,
            "dependencies": deps.iter().map(|d| json!({"name": d, "kind": null})).collect::<Vec<_>>(),
        })
    }

    fn workspace_with(extra: (&str, &str)) -> Value {
        let mut pkgs = Vec::new();
        for (name, allowed) in ALLOWED {
            let mut deps: Vec<&str> = allowed.to_vec();
            if *name == extra.0 {
                deps.push(extra.1);
            }
            pkgs.push(package(name, &deps));
        }
        json!({ "packages": pkgs })
    }

    #[test]
    fn solver_depending_on_contact_is_rejected() {
        let err = check(&workspace_with(("bs-dr", "bs-contact"))).unwrap_err();
        assert!(err.contains("forbidden dependency bs-dr -> bs-contact"), "{err}");
    }

    #[test]
    fn material_depending_on_mesh_is_rejected() {
        let err = check(&workspace_with(("bs-material", "bs-mesh"))).unwrap_err();
        assert!(err.contains("bs-material -> bs-mesh"), "{err}");
    }

    #[test]
    fn unknown_crate_must_be_added_to_the_table() {
        let mut ws = workspace_with(("bs-mesh", "serde"));
        ws["packages"].as_array_mut().unwrap().push(package("bs-new", &["bs-mesh"]));
        let err = check(&ws).unwrap_err();
        assert!(err.contains("'bs-new' is not in the layering table"), "{err}");
    }

    #[test]
    fn allowed_table_passes() {
        // Every allowed edge present, nothing else: 0 problems, edge count = table size.
        let expected: usize = ALLOWED.iter().map(|(_, a)| a.len()).sum();
        assert_eq!(check(&workspace_with(("bs-mesh", "serde"))), Ok(expected));
    }

    #[test]
    fn composing_crates_have_no_module_cycles() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        for krate in ACYCLIC {
            let graph = module_graph(&root.join("crates").join(krate).join("src")).unwrap();
            assert!(graph.len() >= 4, "{krate}: expected its modules, found {graph:?}");
        }
        assert_eq!(check_modules(), Ok(ACYCLIC.len()));
    }

    #[test]
    fn a_module_cycle_is_found() {
        let g = |e: &[(&str, &[&str])]| -> Vec<(String, Vec<String>)> {
            e.iter()
                .map(|(n, d)| (n.to_string(), d.iter().map(|x| x.to_string()).collect()))
                .collect()
        };
        let cyclic =
            g(&[("advice", &["check"]), ("check", &["compose"]), ("compose", &["advice"])]);
        assert_eq!(
            find_cycle(&cyclic).map(|c| c.join(" -> ")),
            Some("advice -> check -> compose -> advice".to_string())
        );
        let acyclic =
            g(&[("advice", &["prepare"]), ("check", &["advice", "prepare"]), ("prepare", &[])]);
        assert_eq!(find_cycle(&acyclic), None);
    }
}
