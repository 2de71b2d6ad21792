"""`evolve2d`: a 2-D contour moved on the planar lattice, against exact solutions."""

import subprocess
import sys

import numpy as np
import pytest

import sparse_levelset as sl


def circle(n, centre, radius, dx=1.0):
    """The signed distance to a circle on an n × n array of spacing dx (world units)."""
    y, x = np.mgrid[:n, :n] * dx
    return (np.hypot(x - centre[0], y - centre[1]) - radius).astype(np.float32)


def area(phi, dx=1.0):
    """The inside's area from each pixel's share, clamp(1/2 − φ/dx, 0, 1)."""
    return np.clip(0.5 - phi / dx, 0.0, 1.0).sum() * dx * dx


def centroid(phi, dx=1.0):
    w = np.clip(0.5 - phi / dx, 0.0, 1.0)
    y, x = np.mgrid[: phi.shape[0], : phi.shape[1]] * dx
    return np.array([(w * x).sum(), (w * y).sum()]) / w.sum()


def test_a_circle_shrinks_by_its_curvature():
    # κ = 1/r, so r² = r₀² − 2εt.
    phi = circle(64, (31.5, 31.5), 20.0)
    r0 = np.sqrt(area(phi) / np.pi)
    out, info = sl.evolve2d(phi, 100.0, curvature=1.0, full_output=True)
    assert info["time"] == 100.0 and info["steps"] > 10 and not info["collapsed"]
    r = np.sqrt(area(out) / np.pi)
    assert r == pytest.approx(np.sqrt(r0**2 - 200.0), abs=0.1)
    # One tile layer: the band is counted once, as the image's pixels.
    assert 0 < info["band_voxels"] < 2 * 7 * 2 * np.pi * r


def test_speed_and_advection_in_world_units():
    dx = 0.5
    phi = circle(96, (20.0, 24.0), 8.0, dx)
    r0 = np.sqrt(area(phi, dx) / np.pi)
    grown = sl.evolve2d(phi, 5.0, dx=dx, speed=1.0)
    assert np.sqrt(area(grown, dx) / np.pi) == pytest.approx(r0 + 5.0, abs=0.05)
    moved = sl.evolve2d(phi, 4.0, dx=dx, velocity=(1.0, -0.5))
    np.testing.assert_allclose(centroid(moved, dx), [24.0, 22.0], atol=0.05)
    assert area(moved, dx) == pytest.approx(area(phi, dx), rel=0.01)


def test_fields_as_arrays_give_the_constants_bits():
    phi = circle(48, (20.0, 22.0), 9.0)
    speed = np.full(phi.shape, 0.5, np.float32)
    velocity = np.zeros(phi.shape + (2,), np.float32)
    velocity[..., 0] = 0.3
    a = sl.evolve2d(phi, 3.0, speed=0.5, velocity=(0.3, 0.0), curvature=0.2)
    b = sl.evolve2d(phi, 3.0, speed=speed, velocity=velocity, curvature=0.2)
    assert a.tobytes() == b.tobytes()


def test_bitwise_identical_for_any_thread_count():
    phi = circle(80, (40.0, 38.0), 25.0) + 2.0 * np.sin(np.arange(80) / 5.0)[:, None]
    results = {
        sl.evolve2d(phi, 4.0, curvature=0.5, speed=-0.3, threads=t).tobytes() for t in (1, 2, 3)
    }
    assert len(results) == 1


def test_the_contour_may_leave_the_array():
    phi = circle(32, (16.0, 16.0), 6.0)
    out, info = sl.evolve2d(phi, 20.0, speed=1.0, full_output=True)
    assert not info["collapsed"] and out.shape == phi.shape
    # r = 26 covers the whole 32 × 32 array but its corners (at 22.6 from the centre).
    assert (out < 0).all()


def test_a_vanishing_contour_is_reported():
    out, info = sl.evolve2d(circle(32, (16.0, 16.0), 3.0), 50.0, curvature=1.0, full_output=True)
    assert info["collapsed"] and info["time"] < 50.0
    # Nothing inside (φ < 0) is left.
    assert (out >= 0).all()


def test_bad_input_is_refused_before_any_work():
    phi = circle(32, (16.0, 16.0), 6.0)
    nan = phi.copy()
    nan[3, 4] = np.nan
    for args, kw, msg in [
        ((nan, 1.0), {}, "NaN at index \\[3, 4\\]"),
        ((np.ones((8, 8), np.float32), 1.0), {}, "no value is < 0"),
        ((-np.ones((8, 8), np.float32), 1.0), {}, "no value is > 0"),
        ((phi[None], 1.0), {}, "2-D"),
        ((phi, -1.0), {}, "t must be"),
        ((phi, 1.0), dict(curvature=-1.0), "curvature"),
        ((phi, 1.0), dict(velocity=(1.0, 0.0, 0.0)), "velocity"),
        ((phi, 1.0), dict(velocity=np.zeros((32, 32, 3), np.float32)), "velocity_field"),
        ((phi, 1.0), dict(speed=np.zeros((16, 32), np.float32)), "speed_field"),
        ((phi, 1.0), dict(dx=0.0), "dx must be"),
        ((phi, 1.0), dict(scheme="weno7"), "scheme"),
        ((phi, 1.0), dict(cfl=2.0), "CFL"),
        ((phi, 1.0), dict(max_steps=-1), "max_steps"),
    ]:
        with pytest.raises(ValueError, match=msg):
            sl.evolve2d(*args, **kw)


def test_progress_sees_every_step_and_its_exception_stops_the_call():
    phi = circle(40, (20.0, 20.0), 8.0)
    seen = []
    out, info = sl.evolve2d(phi, 2.0, speed=1.0, full_output=True, progress=seen.append)
    assert [r["step"] for r in seen] == list(range(1, info["steps"] + 1))
    assert seen[-1]["done"] == seen[-1]["total"] == 2.0

    def stop(report):
        raise ZeroDivisionError

    with pytest.raises(ZeroDivisionError):
        sl.evolve2d(phi, 2.0, speed=1.0, progress=stop)


def test_only_the_contour_is_read():
    # A steep, a shallow, a huge and a binary field with the same zero contour (a steep
    # one once left a few band voxels and the front vanished).
    d = circle(128, (63.5, 63.5), 30.0)
    exact = np.sqrt(np.sqrt(area(d) / np.pi) ** 2 - 200.0)
    for phi, tol in [
        (d, 0.02),
        (d * 50.0, 0.02),
        (d * 0.2, 0.02),
        (np.where(d < 0, -1e30, 1e30).astype(np.float32), 0.1),
        (np.where(d < 0, -1.0, 1.0).astype(np.float32), 0.1),
    ]:
        out, info = sl.evolve2d(phi, 100.0, curvature=1.0, full_output=True)
        assert not info["collapsed"]
        assert np.sqrt(area(out) / np.pi) == pytest.approx(exact, abs=tol)


def test_arrays_that_cannot_fit_are_refused_before_any_work():
    # Under a 2 GiB address-space limit, a 8000² phi needs about 1.5 GB of working arrays.
    code = """
import resource
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
import numpy as np
import sparse_levelset as sl
phi = np.ones((8000, 8000), np.float32)
phi[:4000] = -1.0
try:
    sl.evolve2d(phi, 1.0, threads=1)
except MemoryError as e:
    print("refused:", e)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert "refused:" in out.stdout and "evolve2d" in out.stdout, out.stdout + out.stderr
