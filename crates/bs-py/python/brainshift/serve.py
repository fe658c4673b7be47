"""``python -m brainshift.serve``: brain shift over OpenIGTLink, for 3D Slicer and
navigation systems — the native server of ``brainshift serve`` (Rust, in the extension
module: one server, the same options and messages), started from Python.

>>> import brainshift.serve
>>> brainshift.serve.main(["fixtures/mni152/scene.toml", "--image", "fixtures/mni152/t1.nii.gz"])

serves until Ctrl-C (SIGINT) or SIGTERM and returns the exit code. The messages, frames and
options are docs/operating-room.md's; ``main(["--help"])`` lists the options. To script
the updates themselves without a network, use :class:`brainshift.Session`; to read the
server's POLYDATA with pyigtl, :func:`brainshift.igtl.let_pyigtl_read_polydata`.
"""

from __future__ import annotations

import sys
from typing import List, Optional

from ._native import serve as _serve


def main(argv: Optional[List[str]] = None) -> int:
    """Runs the server with command-line arguments ``argv`` (default ``sys.argv[1:]``);
    the exit code."""
    return _serve(list(sys.argv[1:] if argv is None else argv))


if __name__ == "__main__":
    sys.exit(main())
