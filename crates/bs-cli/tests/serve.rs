//! `brainshift serve` is the native server of bs-serve: nothing but the binary. Here: what
//! it refuses before listening, each error naming the fix. The server itself is tested by
//! bs-serve's tests (its own clients) and crates/bs-py/tests/test_serve.py (pyigtl and the
//! C++ library's client driving this binary).

use std::path::Path;
use std::process::Command;

fn fixtures() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures"))
}

fn serve(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_brainshift"))
        .arg("serve")
        .args(args)
        .args(["--port", "0"])
        .output()
        .expect("run brainshift")
}

#[test]
fn a_missing_image_or_a_set_the_scene_does_not_prescribe_is_refused_before_listening() {
    let scene = fixtures().join("ellipsoid/scene.toml");
    let image = fixtures().join("registration/preop.nii.gz");
    let o = serve(&[scene.to_str().unwrap(), "--image", "/nonexistent/none.nii.gz"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("none.nii.gz"), "{e}");
    let o = serve(&[scene.to_str().unwrap(), "--image", image.to_str().unwrap(), "--set", "FIXED"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("--set FIXED") && e.contains("CRANIOTOMY"), "{e}");
    assert!(!String::from_utf8_lossy(&o.stdout).contains("listening on"));
}
