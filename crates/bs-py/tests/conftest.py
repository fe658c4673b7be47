"""Shared fixtures: the repository's scenes and the `brainshift` binary to compare with.

The binary comes from BRAINSHIFT_BIN (set by .ci/python.sh); without it the comparisons
with the command line are skipped, never built here.
"""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
FIXTURES = ROOT / "fixtures"


def brainshift_bin():
    b = os.environ.get("BRAINSHIFT_BIN") or shutil.which("brainshift")
    return b if b and os.path.exists(b) else None


@pytest.fixture
def cli():
    """Runs the `brainshift` binary; returns the completed process."""
    b = brainshift_bin()
    if b is None:
        pytest.skip("set BRAINSHIFT_BIN to the brainshift binary to compare with the CLI")

    def run(*args, **kw):
        return subprocess.run([b, *map(str, args)], capture_output=True, text=True, **kw)

    run.path = b
    return run


@pytest.fixture
def fixtures():
    return FIXTURES
