"""`Simulation`: exact solutions, determinism across threads and grids, callbacks."""

import numpy as np
import pytest

import sparse_levelset as sl


def radius_of(ls):
    return (3 * ls.volume / (4 * np.pi)) ** (1 / 3)


def test_mean_curvature_flow_of_a_sphere():
    # r(t)² = r₀² − 2εt with κ = 1/r (the library's ½∇·n).
    ls = sl.LevelSet.sphere(20.0)
    sim = sl.Simulation(ls, curvature=1.0, scheme="upwind1", integrator="euler",
                        renormalization_sweeps=2)
    t = 100.0
    steps = sim.run_until(t)
    assert sim.time == t and steps == sim.steps > 10
    assert radius_of(sim.levelset) == pytest.approx(np.sqrt(20.0**2 - 2 * t), abs=0.05)


def test_constant_speed_and_advection():
    ls = sl.LevelSet.sphere(10.0)
    grow = sl.Simulation(ls, speed=1.0)
    grow.run_until(5.0)
    assert radius_of(grow.levelset) == pytest.approx(15.0, abs=0.05)
    move = sl.Simulation(ls, velocity=(1.0, 0.5, 0.0))
    move.run_until(4.0)
    np.testing.assert_allclose(move.levelset.value([[4.0 + 10.0, 2.0, 0.0]]), [0.0], atol=0.05)


def test_speed_field_from_an_array():
    ls = sl.LevelSet.sphere(8.0)
    lo, hi = ls.bbox
    shape = tuple(hi[i] - lo[i] + 1 + 20 for i in (2, 1, 0))
    speed = np.full(shape, 0.5, dtype=np.float32)
    sim = sl.Simulation(ls, speed=speed, field_origin=tuple(c - 10 for c in lo))
    sim.run_until(4.0)
    assert radius_of(sim.levelset) == pytest.approx(10.0, abs=0.05)


def test_bitwise_identical_for_any_thread_count_and_grid():
    ls = sl.LevelSet.shape("torus", radius=14.0, minor_radius=5.0)
    sums = set()
    for threads, grid in [(1, "tiles"), (2, "tiles"), (2, "tiles-scalar"), (1, "dtgrid")]:
        sim = sl.Simulation(ls, curvature=0.5, speed=0.3, threads=threads, grid=grid)
        sim.run_until(3.0)
        sums.add(sim.levelset.checksum)
    assert len(sums) == 1


def test_callback_sees_every_step_and_can_stop():
    sim = sl.Simulation(sl.LevelSet.sphere(10.0), speed=1.0)
    seen = []

    def cb(s, report):
        assert s is sim
        seen.append(report["step"])
        return report["step"] < 3

    assert sim.run_until(100.0, cb) == 3
    assert seen == [1, 2, 3] and sim.steps == 3
    with pytest.raises(ZeroDivisionError):
        sim.run_until(100.0, lambda s, r: 1 / 0)
    assert sim.steps == 4  # the step before the failing callback is kept


def test_bad_parameters():
    ls = sl.LevelSet.sphere(10.0)
    for kw, msg in [
        (dict(scheme="weno7"), "scheme"),
        (dict(integrator="rk4"), "integrator"),
        (dict(cfl=2.0), "CFL"),
        (dict(curvature=-1.0), "curvature"),
        (dict(renormalization="magic"), "renormalization"),
        (dict(threads=0), "threads"),
        (dict(velocity=(1.0, 2.0)), "velocity"),
        (dict(grid="octree"), "grid"),
    ]:
        with pytest.raises(ValueError, match=msg):
            sl.Simulation(ls, **kw).step()
    sim = sl.Simulation(ls, speed=1.0)
    with pytest.raises(ValueError, match="finite"):
        sim.run_until(float("nan"))
