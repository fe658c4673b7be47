//! Every input `cargo xtask fuzz` saved in `fixtures/fuzz/` (a file that once crashed, hung
//! or over-allocated a reader) read again by its reader: it must give `Ok` or `Err`, never
//! a panic. The scene parser's findings (`.toml`) are bs-scene's test.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use bs_mesh::io::{inp, msh, obj, off, stl, vtk, vtu};

/// Reads `bytes` with the reader of `path`'s extension; `None` for another extension.
fn read(path: &Path, bytes: &[u8]) -> Option<bool> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    Some(match ext.as_str() {
        "inp" => inp::read(bytes, path).is_ok(),
        "msh" => msh::read(bytes, path).is_ok(),
        "vtk" => vtk::read(bytes, path).is_ok(),
        "vtu" => vtu::read(bytes, path).is_ok(),
        "stl" => stl::read(bytes, path).is_ok(),
        "obj" => obj::read(bytes, path).is_ok(),
        "off" => off::read(bytes, path).is_ok(),
        _ => return None,
    })
}

#[test]
fn saved_findings_read_without_panic() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/fuzz");
    let mut paths: Vec<PathBuf> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
    paths.sort();
    // The readers' own corpus of bad files goes through the same check, so that the test
    // reads files even while the fuzzer has saved none.
    let bad = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/bad");
    paths.extend(std::fs::read_dir(&bad).unwrap().map(|e| e.unwrap().path()));
    let mut read_any = 0;
    for p in paths {
        let bytes = std::fs::read(&p).unwrap();
        let r = catch_unwind(AssertUnwindSafe(|| read(&p, &bytes)));
        assert!(r.is_ok(), "{} panicked", p.display());
        read_any += usize::from(r.unwrap().is_some());
    }
    assert!(read_any > 0, "no mesh or surface file under fixtures/fuzz or fixtures/bad");
}
