//! Layer orders inside a crate: rows of top-level modules, lowest first. A module may import
//! its own row and the rows below it; importing a higher row fails with both files named.
//! Every top-level module of a crate with an order must be in one of its rows.

use super::modules::Graph;

/// A crate's rows, lowest first.
pub type Order = &'static [&'static [&'static str]];

/// The crates whose folders have an order (docs/ARCHITECTURE.md, "bs-dr code map").
pub const ORDERS: &[(&str, Order)] = &[(
    "bs-dr",
    &[
        // Element data: Tet, Hex, Solid, shape gradients, hourglass, F, stiffness bounds.
        &["element"],
        // The TLED kernels (SIMD lanes, blocks of four elements, the scalar reference).
        &["kernels"],
        // Nodal vectors, sparse matrices, GMRES, the two-level preconditioner.
        &["linalg"],
        // Internal forces (slots, deterministic gather, workspace), K₀, element tangents.
        &["assembly"],
        // The model (elements + blocks + slot map) and its masses and critical steps.
        &["model", "mass", "body"],
        // The solvers, their seams (contact, loads, data) and post-processing.
        &["contact", "data", "loads", "solver", "dr", "newton", "nk", "post"],
    ],
)];

/// The row of a top-level module name.
fn row(order: Order, top: &str) -> Option<usize> {
    order.iter().position(|r| r.contains(&top))
}

fn top(path: &str) -> &str {
    path.split("::").next().unwrap_or(path)
}

/// Every breach of `order` in `g` (crate `krate`): a module in no row, an import of a higher
/// row.
pub fn breaches(krate: &str, order: Order, g: &Graph) -> Vec<String> {
    let rows = order.iter().map(|r| r.join(", ")).collect::<Vec<_>>().join(" < ");
    let mut out = Vec::new();
    for m in g.modules.iter().filter(|m| !m.path.is_empty() && !m.path.contains("::")) {
        if row(order, &m.path).is_none() {
            out.push(format!(
                "{krate}: module {} ({}) is in no row of the layer order {rows}: add it to \
                 xtask/src/deps/layers.rs and the code map of docs/ARCHITECTURE.md",
                m.path,
                m.file.display()
            ));
        }
    }
    for ((a, b), site) in &g.edges {
        let (from, to) = (&g.modules[*a], &g.modules[*b]);
        let (Some(ra), Some(rb)) = (row(order, top(&from.path)), row(order, top(&to.path))) else {
            continue;
        };
        if ra < rb {
            out.push(format!(
                "{krate}: {}:{} ({}) imports {} from {} ({}), a higher layer: the order is \
                 {rows}; move what both need down, or this code up",
                site.file.display(),
                site.line,
                from.path,
                site.text,
                to.file.display(),
                to.path,
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::modules::{read, tests::Tree};
    use super::*;

    const ORDER: Order = &[&["element"], &["kernels"], &["model", "mass"]];

    #[test]
    fn a_lower_folder_importing_a_higher_one_fails_naming_both_files() {
        let t = Tree::new(
            "layers",
            &[
                ("lib.rs", "mod element;\nmod kernels;\nmod model;\nmod mass;\n"),
                ("element/mod.rs", "pub mod tet;\n"),
                ("element/tet.rs", "pub struct Tet;\n"),
                ("kernels/mod.rs", "mod t4;\n"),
                ("kernels/t4.rs", "use crate::element::tet::Tet;\n\nuse crate::model::Model;\n"),
                ("model.rs", "use crate::kernels;\npub struct Model;\n"),
                ("mass.rs", "use crate::model::Model;\n"),
            ],
        );
        let found = breaches("bs-dr", ORDER, &read(&t.0).unwrap());
        assert_eq!(found.len(), 1, "{found:?}");
        let f = &found[0];
        assert!(f.contains("kernels/t4.rs:3 (kernels::t4) imports crate::model::Model"), "{f}");
        assert!(f.contains("model.rs (model), a higher layer"), "{f}");
        assert!(f.contains("element < kernels < model, mass"), "{f}");
    }

    #[test]
    fn a_module_outside_every_row_fails() {
        let t =
            Tree::new("unplaced", &[("lib.rs", "mod element;\nmod extra;\n"), ("extra.rs", "")]);
        let found = breaches("bs-dr", ORDER, &read(&t.0).unwrap());
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].contains("module extra (") && found[0].contains("in no row"));
    }
}
