"""Sweeps from Python: a Dask LocalCluster runs a planned sweep, an interrupted sweep resumes
without rerunning finished rows, and the Slurm array tasks run by hand."""

import os
import subprocess
from pathlib import Path

import pytest

import brainshift
from brainshift import sweep


def write_sweep(tmp_path, fixtures, body):
    base = fixtures / "cube/uniaxial-t4.toml"
    f = tmp_path / "sweep.toml"
    f.write_text(f'base = "{base}"\n{body}')
    return f


EIGHT_ROWS = """
[[axis]]
key = "region.material.youngs_modulus"
range = [1500.0, 6000.0]
samples = 4
[[axis]]
key = "boundary.3.displacement.z"
values = [-0.05, -0.1]
"""


@pytest.fixture(scope="module")
def client():
    distributed = pytest.importorskip("dask.distributed")
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def test_a_two_worker_cluster_runs_an_eight_row_sweep(tmp_path, fixtures, client):
    manifest = sweep.plan(write_sweep(tmp_path, fixtures, EIGHT_ROWS), tmp_path / "s")
    assert len(manifest["rows"]) == 8
    rows = sweep.run_dask(tmp_path / "s", client, threads=1,
                          points={"top": (0.5, 0.5, 1.0)})
    assert len(rows) == 8
    assert [r["status"] for r in rows] == ["ok"] * 8, rows
    for r in rows:
        assert abs(r["top_uz"] - r["boundary.3.displacement.z"]) < 1e-6
        assert r["max_displacement"] > 0
    summary = (tmp_path / "s" / "summary.csv").read_text().splitlines()
    assert len(summary) == 9 and summary[0].startswith(
        "index,region.material.youngs_modulus,boundary.3.displacement.z,status,error,")
    # Every row ran on a worker into its own folder, with the report the CLI writes.
    for i in range(8):
        assert (tmp_path / "s" / "runs" / str(i) / "report.json").exists()


def test_an_interrupted_sweep_resumes_without_rerunning_finished_rows(tmp_path, fixtures, client):
    d = tmp_path / "s"
    sweep.plan(write_sweep(tmp_path, fixtures, EIGHT_ROWS), d)
    assert sweep.run_row(d, 0) == "ran"
    assert sweep.run_row(d, 1) == "ran"
    done = {i: (d / "runs" / str(i) / "report.json") for i in (0, 1)}
    before = {i: (p.stat().st_mtime_ns, p.read_bytes()) for i, p in done.items()}
    # Row 2 was interrupted mid-run: its temporary folder is still there.
    stale = d / "runs" / ".2.424242.tmp"
    stale.mkdir()
    (stale / "result.vtu").write_text("partial")
    assert sweep.collect(d)[2]["status"] == "missing"
    rows = sweep.run_dask(d, client)
    assert [r["status"] for r in rows] == ["ok"] * 8
    after = {i: (p.stat().st_mtime_ns, p.read_bytes()) for i, p in done.items()}
    assert after == before, "finished rows were not rerun"
    assert not stale.exists()
    assert sorted(os.listdir(d / "runs")) == sorted(str(i) for i in range(8))
    assert sweep.run_row(d, 3) == "skipped"


def test_a_failed_row_is_reported_not_raised_by_the_dask_runner(tmp_path, fixtures, client):
    body = '[[axis]]\nkey = "boundary.3.displacement.z"\nvalues = [-0.1, -0.9]\n'
    d = tmp_path / "s"
    sweep.plan(write_sweep(tmp_path, fixtures, body), d)
    rows = sweep.run_dask(d, client)
    assert [r["status"] for r in rows] == ["ok", "failed"]
    assert "exceeds half the mesh size" in rows[1]["error"]
    with pytest.raises(brainshift.BrainshiftError, match="row 1: "):
        sweep.run_row(d, 1)


def test_plan_errors_name_the_key(tmp_path, fixtures):
    f = write_sweep(tmp_path, fixtures, '[[axis]]\nkey = "region.material.E"\nvalues = [1.0]\n')
    with pytest.raises(brainshift.BrainshiftError, match='key = "region.material.E" names nothing'):
        sweep.plan(f, tmp_path / "s")


def test_slurm_array_tasks_run_by_hand(tmp_path, fixtures, cli):
    """The emitted script's task line, run once per array index with SLURM_ARRAY_TASK_ID
    set, as Slurm would (a real Slurm submission: .ci/slurm.sh, where slurmd can run)."""
    d = tmp_path / "s"
    sweep.plan(write_sweep(tmp_path, fixtures, EIGHT_ROWS), d)
    script = Path(sweep.emit_slurm(d, max_parallel=2, time="00:05:00", program=cli.path))
    text = script.read_text()
    assert "#SBATCH --array=0-7%2" in text
    assert "#SBATCH --cpus-per-task=2" in text
    assert "#SBATCH --mem=" in text
    for i in range(8):
        env = dict(os.environ, SLURM_ARRAY_TASK_ID=str(i), SLURM_CPUS_PER_TASK="1")
        o = subprocess.run(["bash", str(script)], env=env, capture_output=True, text=True)
        assert o.returncode == 0, o.stderr
    rows = sweep.collect(d)
    assert [r["status"] for r in rows] == ["ok"] * 8
