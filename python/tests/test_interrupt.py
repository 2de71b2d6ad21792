"""Ctrl-C stops a long call promptly with KeyboardInterrupt and leaves things usable."""

import os
import signal
import threading
import time

import numpy as np
import pytest

import sparse_levelset as sl
from conftest import torus_fields


@pytest.fixture(autouse=True)
def python_handles_ctrl_c():
    # A process started with SIGINT ignored (a shell's background job, some CI runners)
    # gets no KeyboardInterrupt from Python: these tests install Python's own handler.
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)


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


def test_long_calls_release_the_gil():
    # Python code keeps running on another thread while a march runs.
    phi, _ = torus_fields(n=128, R=40.0, r=12.0)
    phi = phi.astype(np.float32)
    done = threading.Event()
    ticks = 0

    def work():
        sl.distance(phi)
        done.set()

    t = threading.Thread(target=work)
    start = time.perf_counter()
    t.start()
    time.sleep(0.01)
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    t.join()
    elapsed = time.perf_counter() - start
    # Were the GIL held through the march, this loop could not run until it ended; released
    # (but for the brief looks for Ctrl-C every 50 ms), it ticks about once a millisecond.
    # The bound leaves room for a loaded machine.
    assert elapsed > 0.2
    assert ticks > 20 * elapsed


def test_progress_reports_done_and_total_in_order():
    phi, _ = torus_fields(n=160, R=50.0, r=16.0)
    calls = []
    sl.distance(phi.astype(np.float32), progress=calls.append)
    assert calls, "a march of seconds reports at least once"
    done = [c["done"] for c in calls]
    assert all(0 <= c["done"] <= c["total"] for c in calls)
    assert done == sorted(done)
