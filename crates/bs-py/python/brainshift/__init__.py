"""brainshift: brain shift for image-guided neurosurgery, from Python.

The native extension (``brainshift._native``, Rust) does the work through the same
library calls as the ``brainshift`` command, so a scene run here gives bit-identical
displacements and the same error messages.

>>> import brainshift
>>> scene = brainshift.Scene.from_toml("fixtures/cube/uniaxial-t4.toml")
>>> result = scene.run()
>>> result.displacements.shape            # (n, 3) float64, rows in result.node_ids order
>>> result.report["max_displacement"]     # the keys of report.json
>>> result.write("out")                   # result.vtu, displacements.csv, report.json

Intra-operative updates: a live session prepares the scene once and solves each new
measurement warm from the last one (same Result type):

>>> session = brainshift.Session(brainshift.Scene.from_toml("fixtures/mni152/scene.toml"))
>>> r = session.update(displacements={"CRANIOTOMY": [0.0, 0.0, -4.0]})
>>> session.reset()                       # back to the reference state

Sweeps: :mod:`brainshift.sweep` (plan, run on Dask, collect, Slurm script).
"""

from ._native import (
    BrainshiftError,
    Result,
    Scene,
    Session,
    __version__,
    gap,
    read_mesh,
)
from . import sweep

__all__ = [
    "BrainshiftError",
    "Result",
    "Scene",
    "Session",
    "__version__",
    "gap",
    "read_mesh",
    "sweep",
]
