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

In the operating room: ``python -m brainshift.serve SCENE --image PREOP`` (or
``brainshift serve``) answers measurements sent over OpenIGTLink (3D Slicer) with the
warped image; see :mod:`brainshift.serve`.

Sweeps: :mod:`brainshift.sweep` (plan, run on Dask, collect, Slurm script).
"""

from ._native import (
    BrainshiftError,
    Image,
    Result,
    Scene,
    Session,
    __version__,
    gap,
    read_image,
    read_mesh,
)
from . import sweep

__all__ = [
    "BrainshiftError",
    "Image",
    "Result",
    "Scene",
    "Session",
    "__version__",
    "gap",
    "read_image",
    "read_mesh",
    "sweep",
]
