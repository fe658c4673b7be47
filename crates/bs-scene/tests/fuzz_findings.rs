//! Every scene file `cargo xtask fuzz` saved in `fixtures/fuzz/` (and the bad-input corpus's
//! scenes) parsed again: `Ok` or `Err`, never a panic. The mesh readers' findings are
//! bs-mesh's test.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

use bs_scene::scene::Scene;

#[test]
fn saved_scene_findings_parse_without_panic() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
    let mut paths: Vec<PathBuf> = Vec::new();
    for dir in ["fuzz", "bad"] {
        paths.extend(std::fs::read_dir(fixtures.join(dir)).unwrap().map(|e| e.unwrap().path()));
    }
    paths.retain(|p| p.extension().is_some_and(|e| e == "toml"));
    paths.sort();
    assert!(!paths.is_empty(), "no scene under fixtures/fuzz or fixtures/bad");
    for p in paths {
        let text = String::from_utf8_lossy(&std::fs::read(&p).unwrap()).into_owned();
        let r = catch_unwind(AssertUnwindSafe(|| Scene::parse(&text).is_ok()));
        assert!(r.is_ok(), "{} panicked", p.display());
    }
}
