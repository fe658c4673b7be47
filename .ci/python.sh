#!/usr/bin/env bash
# CI for the Python bindings (crates/bs-py): a venv with maturin, pytest, numpy,
# dask[distributed], meshio 5.3.5 and nibabel 5.3.2 (the mesh and image outputs read as users read them), pyigtl 0.3.4 (an OpenIGTLink client that drives the native server; the C++ library's is built here too); the `brainshift` wheel built (release) and installed with the README's
# one command (`pip install ./crates/bs-py`); the CLI for the comparisons; the
# pytest suite (bit-identity with the CLI, errors, Dask sweeps, Slurm tasks by hand); and,
# where the Slurm daemons can run (root, Debian's slurm-wlm), a real one-node Slurm
# submission of an emitted sweep script (.ci/slurm.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
started=$SECONDS

PYTHON=${PYTHON:-python3}
target=$(cargo metadata --format-version 1 --no-deps | "$PYTHON" -c 'import json,sys; print(json.load(sys.stdin)["target_directory"])')
venv=$target/py-venv
echo "== python venv ($venv)"
"$PYTHON" -m venv "$venv"
# shellcheck disable=SC1091
. "$venv/bin/activate"
python -m pip install -q --upgrade pip
python -m pip install -q maturin pytest numpy "dask[distributed]" "meshio==5.3.5" "nibabel==5.3.2" "pyigtl==0.3.4"

# The CLI to compare with: the debug build `cargo test --workspace` has just made in .ci/run
# (a no-op here then; a release build would compile every dependency a second time for
# nothing: the displacements are bit-identical across profiles, which the tests check,
# since the wheel is a release build). BRAINSHIFT_BIN overrides it.
if [ -z "${BRAINSHIFT_BIN:-}" ]; then
  echo "== brainshift CLI"
  cargo build -p bs-cli
  export BRAINSHIFT_BIN=$target/debug/brainshift
fi

# The reference C++ OpenIGTLink client of test_cpp_client.py (Debian's libopenigtlink-dev,
# installed by .ci/run); required under CI, skipped by the tests elsewhere without it.
if [ -f /usr/include/openigtlink/igtlClientSocket.h ]; then
  echo "== OpenIGTLink C++ client (crates/bs-py/tests/cpp)"
  g++ -O1 -o "$target/igtl_client" crates/bs-py/tests/cpp/igtl_client.cpp \
    -I/usr/include/openigtlink -lOpenIGTLink
  export BRAINSHIFT_IGTL_CLIENT=$target/igtl_client
elif [ "${CI:-}" = true ]; then
  echo "libopenigtlink-dev is not installed (.ci/run installs it)" >&2
  exit 1
fi

echo "== pip install ./crates/bs-py"
python -m pip install -q ./crates/bs-py

echo "== pytest crates/bs-py/tests"
# Run from outside the source tree so that the installed package is the one imported.
(cd "$target" && python -m pytest -q -p no:cacheprovider "$OLDPWD/crates/bs-py/tests")

if [ "$(id -u)" = 0 ] && [ "${BRAINSHIFT_SKIP_SLURM:-0}" != 1 ]; then
  echo "== slurm (one-node cluster on localhost)"
  .ci/slurm.sh "$BRAINSHIFT_BIN"
fi
echo "python CI took $((SECONDS - started)) s"
