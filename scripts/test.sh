#!/usr/bin/env bash
# Every test of the workspace on a fresh machine: the Rust tests (`cargo test --workspace`),
# then the Python package built from `python/` as an abi3 manylinux wheel (maturin, from
# the virtual environment target/py-venv, which holds the reference libraries the tests
# compare against: python/requirements-test.txt), built in the same `suite` profile as the
# Rust tests so that it reuses their compiled library, and its pytest suite, run on that wheel
# installed in the same environment with no Rust toolchain on PATH. Both are built before
# either runs. The `.vdb`
# cross-checks run Debian's OpenVDB, installed with apt-get when missing
# (scripts/system-deps.sh), as are OpenMPI and libclang for the distributed runs' tests:
# the Rust tests are built once, with the CLI's `mpi` feature
# (the crate sparse-levelset-mpi; the tests in cli/tests/distributed start `mpirun -n 2` and
# `-n 3`; without the feature that binary holds no test, and the only other difference is
# the refusal of `mpirun` by a build without it). Extra arguments go to `cargo test` (e.g.
# --no-default-features).
set -euo pipefail
cd "$(dirname "$0")/.."

bash scripts/system-deps.sh

venv=target/py-venv
if [ ! -x "$venv/bin/python" ]; then
  echo "== [${SECONDS}s] creating $venv"
  "${PYTHON:-python3}" -m venv "$venv"
fi
# The Python libraries download and install while the Rust tests compile.
echo "== [${SECONDS}s] installing the Python test requirements (in the background: target/py-venv-install.log)"
("$venv/bin/python" -m pip install -q --upgrade pip &&
  "$venv/bin/python" -m pip install -q -r python/requirements-test.txt) \
  >target/py-venv-install.log 2>&1 &
pip_pid=$!
trap 'kill "$pip_pid" 2>/dev/null || true' EXIT

echo "== [${SECONDS}s] Rust tests, with MPI (distributed runs under mpirun on 2 and 3 ranks): the build"
# The `suite` profile (the test profile's settings) is the wheel's too: the wheel's build
# below reuses the library and the dependencies this build compiled. The Python crate holds
# no Rust test; selected here, it makes the features resolve as for the wheel's build.
# Everything is built before anything runs: the Rust tests, then the wheel.
cargo test --profile suite --workspace --locked --features levelset-cli/mpi --no-run "$@"

if ! wait "$pip_pid"; then
  cat target/py-venv-install.log >&2
  echo "installing python/requirements-test.txt into $venv failed" >&2
  exit 1
fi

echo "== [${SECONDS}s] the Python package as a wheel (maturin: abi3, manylinux)"
rm -rf target/wheels
# Its build's output is kept (target/wheels/build.log): CI checks from it that the library
# was not compiled a second time.
mkdir -p target/wheels
"$venv/bin/maturin" build --profile suite --locked --manifest-path python/Cargo.toml \
  --out target/wheels 2>&1 | tee target/wheels/build.log
wheel=$(ls target/wheels/sparse_levelset-*-abi3-manylinux*.whl)

echo "== [${SECONDS}s] Rust tests: the run"
cargo test --profile suite --workspace --locked --features levelset-cli/mpi "$@"

echo "== [${SECONDS}s] the wheel, tested where no Rust is"
# The wheel replaces whatever the environment held of the package (the docs' scripts run
# there too); `pip check` then verifies that what the wheel declares it needs is installed.
"$venv/bin/python" -m pip install -q --force-reinstall --no-deps "$wheel"
"$venv/bin/python" -m pip check
# The tests see the environment and the system's programs only (OpenVDB's tools, mpirun):
# nothing of Rust, so they show that the wheel needs none.
bare_path="$PWD/$venv/bin:/usr/local/bin:/usr/bin:/bin"
if PATH="$bare_path" command -v cargo >/dev/null || PATH="$bare_path" command -v rustc >/dev/null; then
  echo "cargo or rustc is on $bare_path: the wheel's test would not show that it needs no Rust" >&2
  exit 1
fi
echo "== [${SECONDS}s] pytest on the wheel"
# Run from python/tests so that the installed package, not the source folder, is imported.
(cd python/tests && env -u CARGO_HOME -u RUSTUP_HOME PATH="$bare_path" \
  "../../$venv/bin/python" -m pytest -q -p no:cacheprovider .)
