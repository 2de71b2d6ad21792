"""Ctrl-C stops a long call promptly with KeyboardInterrupt and leaves things usable."""

import os
import signal
import threading
import time

import numpy as np
import pytest

import sparse_levelset as sl
from conftest import torus_fields


def interrupt_after(seconds):
    timer = threading.Timer(seconds, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    return timer


def test_ctrl_c_stops_fast_marching():
    phi, _ = torus_fields(n=200, R=60.0, r=20.0)
    phi = phi.astype(np.float32)
    start = time.perf_counter()
    full = None
    timer = interrupt_after(0.3)
    with pytest.raises(KeyboardInterrupt):
        full = sl.distance(phi)
    elapsed = time.perf_counter() - start
    timer.join()
    assert full is None
    # The march of 8 million voxels takes seconds; the interrupt lands within a tick.
    assert elapsed < 1.5
    small, _ = torus_fields(n=32, R=9.0, r=3.0)
    assert np.isfinite(sl.distance(small)).all()


def test_ctrl_c_stops_a_simulation_between_steps():
    sim = sl.Simulation(sl.LevelSet.sphere(30.0), speed=1.0, curvature=0.5)
    timer = interrupt_after(0.3)
    with pytest.raises(KeyboardInterrupt):
        sim.run_until(1e9)
    timer.join()
    steps = sim.steps
    assert steps > 0
    # The state is the last completed step: stepping goes on from there.
    sim.step()
    assert sim.steps == steps + 1
