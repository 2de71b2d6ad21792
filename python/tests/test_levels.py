"""The instruction-set level: detected at import, forced by ``LEVELSET_SIMD``, the same
bits at every level with FMA, a level the CPU cannot run refused at import."""

import os
import subprocess
import sys

import pytest

import sparse_levelset as sl

LEVELS = ("baseline", "avx2", "avx512")

SCRIPT = """
import sparse_levelset as sl
ls = sl.LevelSet.shape("torus", radius=14.0, minor_radius=5.0)
sums = set()
for grid in ("tiles", "tiles-scalar", "dtgrid"):
    sim = sl.Simulation(ls, curvature=0.5, speed=0.3, scheme="weno5", integrator="rk3", grid=grid)
    sim.run_until(2.0)
    sums.add(sim.levelset.checksum)
assert len(sums) == 1, sums
print(sl.SIMD_LEVEL, sums.pop())
"""


def run(level, code=SCRIPT):
    env = dict(os.environ)
    env.pop("LEVELSET_SIMD", None)
    if level is not None:
        env["LEVELSET_SIMD"] = level
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)


def test_the_level_is_detected_and_named():
    assert sl.SIMD_LEVEL in LEVELS
    assert "SIMD_LEVEL" in sl.__all__


def test_every_level_with_fma_gives_the_same_bits():
    detected = run(None)
    assert detected.returncode == 0, detected.stderr
    level, checksum = detected.stdout.split()
    results = {}
    for name in LEVELS:
        r = run(name)
        if r.returncode != 0:
            # A level above the CPU's: refused at import, with the reason.
            assert "this CPU cannot run" in r.stderr, r.stderr
            assert LEVELS.index(name) > LEVELS.index(level)
            continue
        got_level, got = r.stdout.split()
        assert got_level == name
        results[name] = got
    assert results[level] == checksum
    fused = [results[n] for n in ("avx2", "avx512") if n in results]
    assert all(c == fused[0] for c in fused)


def test_a_value_that_names_no_level_is_refused_at_import():
    r = run("sse9", "import sparse_levelset")
    assert r.returncode != 0
    assert "LEVELSET_SIMD=sse9: not a level" in r.stderr
