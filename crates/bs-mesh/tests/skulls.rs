//! Every skull and shell surface shipped in `fixtures/` is free of self-intersections and
//! degenerate triangles (the new skull checks must not refuse a surface the solver accepts),
//! and the valid ones pass the whole skull check.

use std::path::{Path, PathBuf};

use bs_mesh::io;

/// Surface files under `fixtures/*/` named skull* or shell*.
fn skull_files() -> Vec<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
    let mut files = Vec::new();
    for dir in std::fs::read_dir(&root).expect("fixtures readable").flatten() {
        let Ok(entries) = std::fs::read_dir(dir.path()) else { continue };
        for f in entries.flatten() {
            let path = f.path();
            let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("").to_owned();
            let surface = io::Format::from_path(&path).is_some_and(|f| !f.is_volume());
            if surface
                && (name.starts_with("skull")
                    || name.contains("-skull")
                    || name.starts_with("shell"))
            {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

#[test]
fn fixture_skulls_do_not_intersect_themselves() {
    let files = skull_files();
    // sphere-shell, ellipsoid, mni152 skulls; bad/{open,small,inward}-skull; basic/shell.*
    assert!(files.len() >= 10, "{files:?}");
    for path in &files {
        let s = io::read_surface(path).unwrap_or_else(|e| panic!("{e}"));
        assert!(s.degenerate_triangles().is_empty(), "{}", path.display());
        let crossing = s.self_intersections();
        assert!(
            crossing.is_empty(),
            "{}: {:?}",
            path.display(),
            &crossing[..crossing.len().min(5)]
        );
        let bad = path.parent().and_then(|d| d.file_name()).is_some_and(|d| d == "bad");
        if !bad {
            s.require_closed_outward().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
    }
}
