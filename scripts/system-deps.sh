#!/usr/bin/env bash
# The Debian packages the tests need, installed with apt-get when missing (sudo when not
# root): OpenVDB for the `.vdb` cross-checks (python3-openvdb for /usr/bin/python3,
# vdb_print from libopenvdb-tools), OpenMPI and libclang for the distributed runs' tests
# (the crate sparse-levelset-mpi builds against OpenMPI with bindgen). Run by
# scripts/test.sh, and by .ci/run before the lints that build the MPI crate.
set -euo pipefail

sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi

if ! { /usr/bin/python3 -c "import pyopenvdb" && command -v vdb_print; } >/dev/null 2>&1; then
  echo "== installing Debian's OpenVDB (python3-openvdb, libopenvdb-tools)"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq python3-openvdb libopenvdb-tools >/dev/null
fi

if ! { command -v mpirun && dpkg -s libopenmpi-dev libclang-dev; } >/dev/null 2>&1; then
  echo "== installing OpenMPI and libclang (libopenmpi-dev, openmpi-bin, libclang-dev)"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq libopenmpi-dev openmpi-bin \
    libclang-dev >/dev/null
fi
