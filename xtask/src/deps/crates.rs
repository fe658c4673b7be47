//! The layering rules between the crates of the workspace, checked against `cargo metadata`.
//!
//! The table below is the single source of truth for which workspace crate may depend on
//! which (normal, dev and build dependencies alike). A crate missing from the table, or an
//! edge not allowed by it, fails the check with a message naming the edge and the rule.

use std::process::Command;

use serde_json::Value;

/// Workspace crates and the workspace crates each may depend on.
pub const ALLOWED: &[(&str, &[&str])] = &[
    ("bs-atomic", &[]),
    ("bs-igtl", &[]),
    ("bs-mesh", &["bs-atomic"]),
    ("bs-material", &[]),
    ("bs-image", &["bs-atomic"]),
    ("bs-preview", &["bs-atomic", "bs-image"]),
    ("bs-meshgen", &["bs-mesh", "bs-image"]),
    ("bs-contact", &["bs-mesh"]),
    ("bs-dr", &["bs-mesh", "bs-material"]),
    ("bs-fit", &["bs-mesh", "bs-contact", "bs-dr"]),
    (
        "bs-scene",
        &["bs-mesh", "bs-material", "bs-dr", "bs-contact", "bs-fit", "bs-image", "bs-meshgen"],
    ),
    ("bs-register", &["bs-mesh", "bs-image", "bs-meshgen", "bs-scene"]),
    ("bs-sweep", &["bs-atomic", "bs-mesh", "bs-dr", "bs-scene"]),
    ("bs-serve", &["bs-igtl", "bs-mesh", "bs-image", "bs-scene", "bs-register"]),
    (
        "bs-study",
        &[
            "bs-mesh",
            "bs-material",
            "bs-dr",
            "bs-contact",
            "bs-fit",
            "bs-scene",
            "bs-register",
            "bs-image",
            "bs-meshgen",
            "bs-igtl",
            "bs-serve",
        ],
    ),
    ("bs-fuzz", &["bs-mesh", "bs-scene"]),
    (
        "bs-cli",
        &[
            "bs-mesh",
            "bs-dr",
            "bs-contact",
            "bs-scene",
            "bs-register",
            "bs-sweep",
            "bs-preview",
            "bs-serve",
        ],
    ),
    (
        "bs-py",
        &[
            "bs-mesh",
            "bs-contact",
            "bs-scene",
            "bs-register",
            "bs-sweep",
            "bs-image",
            "bs-igtl",
            "bs-serve",
        ],
    ),
    ("xtask", &["bs-study"]),
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
             with bs-mesh and bs-contact, images with bs-image), so Python results are the \
             command's"
        }
        (_, "bs-study") => {
            "bs-study is evidence, not product: only xtask drives it, so no front end or library \
             carries the studies, benchmarks, charts and CalculiX runners"
        }
        ("xtask", _) => {
            "xtask is thin: it parses the arguments and calls bs-study (benchmarks, studies, \
             validation) or runs bs-fuzz; the work lives there"
        }
        ("bs-material", _) => "materials know no meshes, elements or solvers",
        ("bs-igtl", _) => {
            "bs-igtl is the wire protocol: it knows bytes, never the model (bs-serve maps \
             messages to session updates)"
        }
        ("bs-mesh", _) => {
            "bs-mesh is the bottom layer of the model: it depends on no brainshift crate but \
             bs-atomic (whole files written)"
        }
        _ => "only bs-scene composes the layers; front ends (bs-cli, bs-py, xtask) build on it",
    }
}

/// `cargo metadata --no-deps` of the workspace.
pub fn metadata() -> Result<Value, String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--no-deps", "--offline"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .map_err(|e| format!("could not run cargo metadata: {e}"))?;
    if !out.status.success() {
        return Err(format!("cargo metadata failed:\n{}", String::from_utf8_lossy(&out.stderr)));
    }
    serde_json::from_slice(&out.stdout).map_err(|e| format!("cargo metadata output: {e}"))
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
                "crate '{name}' is not in the layering table of xtask/src/deps/crates.rs: add it with the \
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

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn workspace_graph_follows_the_layering_rules() {
        let edges = metadata().and_then(|m| check(&m)).unwrap_or_else(|e| panic!("{e}"));
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
    fn a_front_end_depending_on_the_studies_is_rejected() {
        let err = check(&workspace_with(("bs-cli", "bs-study"))).unwrap_err();
        assert!(
            err.contains("bs-cli -> bs-study") && err.contains("only xtask drives it"),
            "{err}"
        );
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
}
