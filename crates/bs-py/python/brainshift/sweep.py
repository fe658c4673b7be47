"""Parameter sweeps: a sweep folder planned from a sweep file, its rows run anywhere
(here, on a Dask cluster, as a Slurm array), and one table collected.

A sweep file (TOML)::

    base = "scene.toml"                       # relative to the sweep file
    method = "grid"                           # or "lhs" with seed = S and samples = N
    [[axis]]
    key = "region.material.youngs_modulus"    # dotted path into the scene; every region
    values = [1500.0, 3000.0, 6000.0]
    [[axis]]
    key = "boundary.1.displacement.z"         # 0-based index into [[boundary]]
    range = [-12.0, -4.0]
    samples = 3

The folder layout is the command line's (``brainshift sweep plan|run|collect|emit-slurm``):
``manifest.csv``, ``manifest.json``, ``scenes/I.toml``, ``runs/I/`` and ``summary.csv``.
"""

from __future__ import annotations

import json
import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

from . import _native

PathLike = Union[str, "os.PathLike[str]"]
Points = Union[PathLike, Mapping[str, Sequence[float]]]

__all__ = ["plan", "run_row", "run_dask", "collect", "emit_slurm", "rows"]


def plan(sweep_file: PathLike, out: PathLike) -> Dict[str, Any]:
    """Plans ``sweep_file`` into the folder ``out``; returns the manifest."""
    return _native.sweep_plan(os.fspath(sweep_file), os.fspath(out))


def rows(sweep_dir: PathLike) -> int:
    """Number of rows of the sweep planned in ``sweep_dir``."""
    with open(os.path.join(os.fspath(sweep_dir), "manifest.json"), encoding="utf-8") as f:
        return len(json.load(f)["rows"])


def run_row(sweep_dir: PathLike, index: int, threads: Optional[int] = None) -> str:
    """Runs row ``index`` into ``sweep_dir/runs/index`` ("ran", or "skipped" when it was
    already done); a failed row raises BrainshiftError after writing its error.json."""
    return _native.sweep_run(os.fspath(sweep_dir), index, threads)


def _task(sweep_dir: str, index: int, threads: int) -> Tuple[int, str, Optional[str]]:
    """One Dask task: a row's outcome as data (a failed row is a result, not a task
    failure, so one bad row does not stop the gather)."""
    try:
        return index, _native.sweep_run(sweep_dir, index, threads), None
    except _native.BrainshiftError as e:
        return index, "failed", str(e)


def run_dask(
    sweep_dir: PathLike,
    client: Any,
    threads: int = 1,
    points: Optional[Points] = None,
) -> List[Dict[str, Any]]:
    """Runs every row of ``sweep_dir`` on a ``dask.distributed`` ``client`` (one task per
    row, each on ``threads`` worker threads), then collects: returns the rows of
    summary.csv as dicts. Rows already done are skipped, so a sweep interrupted part-way
    resumes where it stopped."""
    d = os.path.abspath(os.fspath(sweep_dir))
    n = rows(d)
    futures = client.map(_task, [d] * n, range(n), [threads] * n, pure=False)
    client.gather(futures)
    return collect(d, points)


def collect(sweep_dir: PathLike, points: Optional[Points] = None) -> List[Dict[str, Any]]:
    """Writes ``sweep_dir/summary.csv`` and returns its rows as dicts (index, the swept
    keys, status "ok"/"failed"/"missing", error, max_displacement, NAME_ux/uy/uz/umag per
    point, nodes_in_contact, solve_seconds, units). ``points``: a CSV (name,x,y,z) or a
    dict name -> (x, y, z) in mesh units."""
    if points is not None and not isinstance(points, Mapping):
        points = os.fspath(points)
    return _native.sweep_collect(os.fspath(sweep_dir), points)


def emit_slurm(
    sweep_dir: PathLike,
    max_parallel: Optional[int] = None,
    time: str = "01:00:00",
    cpus_per_task: int = 2,
    program: str = "brainshift",
) -> str:
    """Writes ``sweep_dir/sweep.slurm`` (a Slurm array job, one task per row, calling
    ``program sweep run DIR --index $SLURM_ARRAY_TASK_ID``); returns its path."""
    return os.fspath(
        _native.sweep_emit_slurm(os.fspath(sweep_dir), max_parallel, time, cpus_per_task, program)
    )
