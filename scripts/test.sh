#!/usr/bin/env bash
# Every test of the workspace on a fresh machine: the Rust tests (`cargo test --workspace`),
# then the Python package built from `python/` and its pytest suite, in a virtual
# environment of its own (target/py-venv) with the reference libraries the tests compare
# against (python/requirements-test.txt). The `.vdb` cross-checks run Debian's OpenVDB
# (python3-openvdb for /usr/bin/python3, vdb_print from libopenvdb-tools), installed with
# apt-get when missing, as are OpenMPI and libclang for the distributed runs' tests
# (`cargo test --features mpi`, which start `mpirun -n 2` and `-n 3`). Extra arguments go
# to `cargo test` (e.g. --no-default-features).
set -euo pipefail
cd "$(dirname "$0")/.."

if ! { /usr/bin/python3 -c "import pyopenvdb" && command -v vdb_print; } >/dev/null 2>&1; then
  echo "== [${SECONDS}s] installing Debian's OpenVDB (python3-openvdb, libopenvdb-tools)"
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq python3-openvdb libopenvdb-tools >/dev/null
fi

if ! { command -v mpirun && dpkg -s libopenmpi-dev libclang-dev; } >/dev/null 2>&1; then
  echo "== [${SECONDS}s] installing OpenMPI and libclang (libopenmpi-dev, openmpi-bin, libclang-dev)"
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq libopenmpi-dev openmpi-bin \
    libclang-dev >/dev/null
fi

venv=target/py-venv
if [ ! -x "$venv/bin/python" ]; then
  echo "== [${SECONDS}s] creating $venv"
  "${PYTHON:-python3}" -m venv "$venv"
fi
"$venv/bin/python" -m pip install -q --upgrade pip
"$venv/bin/python" -m pip install -q -r python/requirements-test.txt

echo "== [${SECONDS}s] Rust tests"
cargo test --workspace --locked "$@"

echo "== [${SECONDS}s] under mpirun (feature mpi): distributed runs on 2 and 3 ranks, batches on 2"
cargo test -p levelset-cli --features mpi --locked --test distributed "$@"

echo "== [${SECONDS}s] the Python package (pip install ./python) and its tests"
"$venv/bin/python" -m pip install -q --force-reinstall --no-deps ./python
# Run from python/tests so that the installed package, not the source folder, is imported.
(cd python/tests && "../../$venv/bin/python" -m pytest -q -p no:cacheprovider .)
