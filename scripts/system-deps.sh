#!/usr/bin/env bash
# The Debian packages the tests need, installed with apt-get when missing (sudo when not
# root): OpenVDB for the `.vdb` cross-checks (python3-openvdb for /usr/bin/python3,
# vdb_print from libopenvdb-tools), OpenMPI and libclang for the distributed runs' tests
# (the crate sparse-levelset-mpi builds against OpenMPI with bindgen). Run by
# scripts/test.sh, and by .ci/run before the lints that build the MPI crate.
set -euo pipefail

sudo=""
if [ "$(id -u)" -ne 0 ]; then sudo="sudo"; fi

# What is missing, then one `apt-get update` and one install for all of it.
missing=()
if ! { /usr/bin/python3 -c "import pyopenvdb" && command -v vdb_print; } >/dev/null 2>&1; then
  missing+=(python3-openvdb libopenvdb-tools)
fi
if ! { command -v mpirun && dpkg -s libopenmpi-dev libclang-dev; } >/dev/null 2>&1; then
  missing+=(libopenmpi-dev openmpi-bin libclang-dev)
fi
if [ "${#missing[@]}" -gt 0 ]; then
  echo "== installing Debian packages: ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
fi
