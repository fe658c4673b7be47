//! `brainshift serve` starts the Python package's OpenIGTLink server; the server itself is
//! tested from Python (crates/bs-py/tests/test_serve.py, driven by pyigtl). Here: the
//! arguments it forwards, and the errors when no interpreter can run it.

use std::process::Command;

use bs_cli::serve::ServeOptions;

fn options() -> ServeOptions {
    ServeOptions {
        scene: "fixtures/mni152/scene.toml".into(),
        image: "fixtures/mni152/t1.nii.gz".into(),
        host: "127.0.0.1".into(),
        port: 18944,
        set: Some("CRANIOTOMY".into()),
        threads: Some(2),
        no_field: true,
        no_surface: true,
        max_message_mb: 64.0,
        stall_seconds: 30.0,
        max_clients: 16,
        verbose: true,
    }
}

#[test]
fn the_options_are_forwarded_to_the_python_server() {
    let a = options().args();
    let expected = "-m brainshift.serve fixtures/mni152/scene.toml --image fixtures/mni152/t1.nii.gz \
                    --host 127.0.0.1 --port 18944 --max-message-mb 64 --stall-seconds 30 \
                    --max-clients 16 --set CRANIOTOMY --threads 2 --no-field --no-surface --verbose";
    assert_eq!(a.join(" "), expected);
}

fn serve_with(python: &str) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_brainshift"))
        .args(["serve", "scene.toml", "--image", "t1.nii.gz"])
        .env("BRAINSHIFT_PYTHON", python)
        .output()
        .expect("run brainshift")
}

#[test]
fn a_missing_interpreter_is_named_with_the_fix() {
    let o = serve_with("/nonexistent/python3");
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("'/nonexistent/python3' cannot be started"), "{e}");
    assert!(e.contains("BRAINSHIFT_PYTHON"), "{e}");
}

#[test]
fn an_interpreter_without_the_package_says_how_to_install_it() {
    // `false` runs and fails like an interpreter that cannot import brainshift.serve.
    let o = serve_with("false");
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("cannot import it") && e.contains("pip install ./crates/bs-py pyigtl"),
        "{e}"
    );
}
