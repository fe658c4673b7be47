//! End-to-end: `brainshift sweep plan|run|collect|emit-slurm` on the cube, and each Slurm
//! array task run by hand the way the emitted script runs it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn brainshift(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_brainshift")).args(args).output().expect("run brainshift")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

#[test]
fn plan_run_collect_and_the_slurm_tasks_by_hand() {
    let d = std::env::temp_dir().join(format!("bs-cli-sweep-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let base = root().join("fixtures/cube/uniaxial-t4.toml");
    let sweep_file = d.join("sweep.toml");
    std::fs::write(
        &sweep_file,
        format!(
            "base = {:?}\n[[axis]]\nkey = \"boundary.3.displacement.z\"\n\
             values = [-0.1, -0.9, -0.05]\n",
            base.to_str().unwrap()
        ),
    )
    .unwrap();
    let dir = d.join("sweep");
    let ds = dir.to_str().unwrap();
    let o = brainshift(&["sweep", "plan", sweep_file.to_str().unwrap(), "--out", ds]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("planned 3 rows (grid)"), "{}", text(&o));

    let o = brainshift(&["sweep", "emit-slurm", ds, "--max-parallel", "2", "--time", "00:05:00"]);
    assert!(o.status.success(), "{}", text(&o));
    let script = std::fs::read_to_string(dir.join("sweep.slurm")).unwrap();
    assert!(script.contains("#SBATCH --array=0-2%2\n"), "{script}");
    // The task line, run by hand for each array index as Slurm would run it.
    let task = script.lines().find(|l| l.starts_with("exec ")).unwrap();
    for i in 0..3 {
        let o = Command::new("bash")
            .args(["-c", task])
            .env("SLURM_ARRAY_TASK_ID", i.to_string())
            .env("SLURM_CPUS_PER_TASK", "1")
            .output()
            .unwrap();
        // Row 1 pushes the top face through the bottom: it fails, naming why.
        assert_eq!(o.status.success(), i != 1, "row {i}: {}", text(&o));
        if i == 1 {
            assert!(text(&o).contains("row 1: "), "{}", text(&o));
            assert!(dir.join("runs/1/error.json").exists());
        }
    }
    let o = brainshift(&["sweep", "run", ds, "--index", "0"]);
    assert!(o.status.success() && text(&o).contains("skipped"), "{}", text(&o));
    let o = brainshift(&["sweep", "run", ds, "--index", "7"]);
    assert!(!o.status.success() && text(&o).contains("there is no row 7"), "{}", text(&o));

    let o = brainshift(&["sweep", "collect", ds]);
    assert!(o.status.success(), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("3 rows: 2 ok, 1 failed, 0 missing"), "{t}");
    assert!(t.contains("row 1 failed: ") && t.contains("exceeds half the mesh size"), "{t}");
    let summary = std::fs::read_to_string(dir.join("summary.csv")).unwrap();
    assert_eq!(summary.lines().count(), 4, "{summary}");

    let o = brainshift(&["sweep", "plan", d.join("none.toml").to_str().unwrap(), "--out", ds]);
    assert!(!o.status.success() && text(&o).contains("none.toml: cannot read"), "{}", text(&o));
    let _ = std::fs::remove_dir_all(&d);
}
