"""scikit-fmm's functions (`distance`, `travel_time`, `extension_velocities`) against the
exact answers and against scikit-fmm itself, run side by side on the same inputs.

Where an exact answer exists, our error must be no larger than scikit-fmm's, up to a slack
of ``SLACK_ABS + SLACK_REL * (scikit-fmm's error)``; run with ``-s`` to see the errors."""

import inspect

import numpy as np
import pytest
import skfmm

import sparse_levelset as sl
from conftest import torus_fields


@pytest.mark.parametrize("order", [1, 2])
def test_distorted_torus_more_accurate_than_scikit_fmm(torus, order):
    phi, exact = torus
    ours = sl.distance(phi, dx=1.0, order=order)
    theirs = skfmm.distance(phi, dx=1.0, order=order)
    near = np.abs(exact) < 4.0
    for band in (near, np.ones_like(near)):
        e_ours = np.abs(ours - exact)[band]
        e_theirs = np.abs(theirs - exact)[band]
        assert e_ours.max() < e_theirs.max()
        assert e_ours.mean() < e_theirs.mean()
    # Second order near the interface: a tenth of a voxel at most, on a field whose
    # gradient varies between about 0.4 and 2.
    if order == 2:
        assert np.abs(ours - exact)[near].max() < 0.1
        assert np.abs(ours - exact)[near].mean() < 0.02


def test_spacing_scales_distances():
    phi, exact = torus_fields(n=48, h=0.5, R=8.0, r=3.0)
    d = sl.distance(phi, dx=0.5)
    near = np.abs(exact) < 2.0
    assert np.abs(d - exact)[near].max() < 0.05
    # The same march in voxel units, scaled.
    np.testing.assert_allclose(d, sl.distance(phi, dx=1.0) * 0.5, rtol=1e-6, atol=1e-6)


def test_narrow_band_masks_like_scikit_fmm(torus):
    phi, exact = torus
    d = sl.distance(phi, narrow=3.0)
    assert isinstance(d, np.ma.MaskedArray)
    inside = np.abs(exact) < 2.5
    assert not d.mask[inside].any()
    assert d.mask[np.abs(exact) > 3.5].all()
    full = sl.distance(phi)
    np.testing.assert_array_equal(d.data[~d.mask], full[~d.mask])


def test_one_and_two_dimensions_match_scikit_fmm_examples():
    np.testing.assert_allclose(
        sl.distance([-1, -1, -1, 1, 1, 1]), [-2.5, -1.5, -0.5, 0.5, 1.5, 2.5], atol=1e-6
    )
    # A distorted circle in 2-D: closer to the exact distance than scikit-fmm.
    y, x = np.mgrid[:80, :80].astype(np.float64) - 39.5
    exact = np.hypot(x, y) - 20.0
    phi = exact * (1.5 + np.sin(x / 9) * np.cos(y / 13))
    near = np.abs(exact) < 4
    e_ours = np.abs(sl.distance(phi) - exact)[near]
    e_theirs = np.abs(skfmm.distance(phi) - exact)[near]
    assert e_ours.max() < e_theirs.max() and e_ours.mean() < e_theirs.mean()
    assert e_ours.max() < 0.1


def test_dtypes_and_orders_give_the_same_result(torus):
    phi, _ = torus
    ref = sl.distance(phi.astype(np.float32))
    assert ref.dtype == np.float32
    d64 = sl.distance(phi)
    assert d64.dtype == np.float64
    np.testing.assert_array_equal(d64, ref.astype(np.float64))
    fortran = sl.distance(np.asfortranarray(phi.astype(np.float32)))
    np.testing.assert_array_equal(fortran, ref)
    strided = sl.distance(phi[::2, ::2, ::2].astype(np.float32))
    np.testing.assert_array_equal(
        strided, sl.distance(np.ascontiguousarray(phi[::2, ::2, ::2], dtype=np.float32))
    )


def test_bad_input_raises_value_error():
    with pytest.raises(ValueError, match="no zero crossing|empty"):
        sl.distance(np.ones((8, 8, 8)))
    bad = np.ones((8, 8, 8))
    bad[0, 0, 0] = -1
    bad[4, 4, 4] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        sl.distance(bad)
    with pytest.raises(ValueError, match="order"):
        sl.distance(bad[:, :, :], order=3)
    with pytest.raises(ValueError, match="dx"):
        sl.distance(np.ones((4, 4)), dx=-1.0)
    with pytest.raises(ValueError, match="dtype"):
        sl.distance(np.ones(4, dtype=complex))
    with pytest.raises(ValueError, match="4-D|1-D"):
        sl.distance(np.ones((2, 2, 2, 2)))
    with pytest.raises(ValueError, match="empty"):
        sl.distance(np.ones((0, 3, 3)))


def test_progress_reaches_its_total():
    x, y = np.mgrid[-1:1:101j, -1:1:101j]
    seen = []
    sl.distance(x**2 + y**2 - 0.25, dx=0.02, progress=lambda p: seen.append(p))
    assert seen and seen[-1]["done"] == seen[-1]["total"] > 0


# ---------------------------------------------------------------------------------------
# Every scikit-fmm function, side by side with scikit-fmm.

# Slack of "our error is no larger than scikit-fmm's": a thousandth of the spacing plus
# 5 % of scikit-fmm's error (the results are float32, scikit-fmm's float64).
SLACK_ABS = 1e-3
SLACK_REL = 0.05


def _errors(name, ours, theirs, exact, region, h):
    """Max and mean errors of both in `region`, printed, and ours checked against theirs."""
    eo = np.abs(np.asarray(ours, dtype=np.float64) - exact)[region]
    et = np.abs(np.asarray(theirs, dtype=np.float64) - exact)[region]
    print(
        f"\n{name}: max error ours {eo.max():.5f} skfmm {et.max():.5f}; "
        f"mean ours {eo.mean():.5f} skfmm {et.mean():.5f}"
    )
    for o, t in ((eo.max(), et.max()), (eo.mean(), et.mean())):
        assert o <= t * (1 + SLACK_REL) + SLACK_ABS * h, (name, o, t)
    return eo, et


def test_every_skfmm_function_is_here_with_its_arguments():
    for name in ("distance", "travel_time", "extension_velocities"):
        theirs = inspect.signature(getattr(skfmm, name)).parameters
        ours = inspect.signature(getattr(sl, name)).parameters
        positional = [p for p in ours.values() if p.kind != p.KEYWORD_ONLY]
        assert [p.name for p in positional] == list(theirs), name
        for p in theirs.values():
            assert ours[p.name].default == p.default, (name, p.name)


def _grid2(n, m, dx):
    """Coordinates of an (n, m) array with spacing dx = (d0, d1), centred."""
    i, j = np.mgrid[:n, :m].astype(np.float64)
    return (i - (n - 1) / 2) * dx[0], (j - (m - 1) / 2) * dx[1]


@pytest.mark.parametrize("order", [1, 2])
def test_analytic_distance_to_a_circle_with_per_axis_dx(order):
    dx = (0.04, 0.025)
    a, b = _grid2(60, 96, dx)
    r = np.hypot(a + 0.013, b - 0.021)
    phi = r**2 - 0.5**2  # the zero contour of a circle, not a distance
    exact = r - 0.5
    ours = sl.distance(phi, dx=dx, order=order)
    theirs = skfmm.distance(phi, dx=dx, order=order)
    _errors(f"circle, dx {dx}, order {order}", ours, theirs, exact, np.abs(exact) < 0.15, 0.04)
    _errors(f"circle everywhere, order {order}", ours, theirs, exact, r > 0.15, 0.04)


@pytest.mark.parametrize("order", [1, 2])
def test_analytic_distance_to_a_sphere_with_per_axis_dx(order):
    dx = (0.09, 0.07, 0.06)
    i, j, k = np.mgrid[:26, :34, :40].astype(np.float64)
    x, y, z = (i - 12.3) * dx[0], (j - 16.6) * dx[1], (k - 19.2) * dx[2]
    r = np.sqrt(x**2 + y**2 + z**2)
    phi = np.tanh(r - 0.8)  # a smooth field with the sphere of radius 0.8 as zero set
    exact = r - 0.8
    ours = sl.distance(phi, dx=dx, order=order)
    theirs = skfmm.distance(phi, dx=dx, order=order)
    assert ours.shape == phi.shape and ours.dtype == np.float64
    _errors(f"sphere, dx {dx}, order {order}", ours, theirs, exact, np.abs(exact) < 0.25, 0.09)


def test_analytic_distance_with_periodic_boundaries():
    # A circle crossing the array's faces: with periodic axes the distance is to the nearest
    # periodic copy of the circle.
    dx = (0.05, 0.04)
    n, m = 60, 80
    i, j = np.mgrid[:n, :m].astype(np.float64)
    lx, ly = n * dx[0], m * dx[1]
    cx, cy = 0.3, 2.9
    du = np.abs(i * dx[0] - cx)
    dv = np.abs(j * dx[1] - cy)
    r = np.hypot(np.minimum(du, lx - du), np.minimum(dv, ly - dv))
    phi = r - 0.6
    for periodic in (True, (True, True), [1, 1]):
        ours = sl.distance(phi, dx=dx, periodic=periodic)
        theirs = skfmm.distance(phi, dx=dx, periodic=periodic)
        _errors(f"periodic circle {periodic!r}", ours, theirs, phi, np.ones_like(phi, bool), 0.05)
    # Periodic along one axis only: the other axis stops at the faces.
    ours = sl.distance(phi, dx=dx, periodic=(True, False))
    theirs = skfmm.distance(phi, dx=dx, periodic=(True, False))
    np.testing.assert_allclose(ours, theirs, atol=0.02)
    assert np.abs(ours - phi).max() > 0.1  # not the doubly periodic answer
    # Rolling along a periodic axis rolls the result (scikit-fmm's own check).
    rolled = sl.distance(np.roll(phi, 17, axis=0), dx=dx, periodic=True)
    unrolled = sl.distance(phi, dx=dx, periodic=True)
    np.testing.assert_allclose(rolled, np.roll(unrolled, 17, axis=0), atol=1e-5)


@pytest.mark.parametrize("order", [1, 2])
def test_analytic_travel_time_constant_speed(order):
    dx = (0.05, 0.04)
    a, b = _grid2(50, 64, dx)
    r = np.hypot(a, b)
    phi = r - 0.45
    speed = np.full_like(phi, 2.5)
    ours = sl.travel_time(phi, speed, dx=dx, order=order)
    theirs = skfmm.travel_time(phi, speed, dx=dx, order=order)
    assert not isinstance(ours, np.ma.MaskedArray) and (ours >= 0).all()
    exact = np.abs(r - 0.45) / 2.5
    _errors(f"travel time, speed 2.5, order {order}", ours, theirs, exact, r > 0.1, 0.02)
    # The same march as the distance, over the speed, up to rounding — which can flip a
    # choice between the nearly equal neighbours of a symmetric front (a hundredth of a
    # voxel at most here).
    d = np.abs(sl.distance(phi, dx=dx, order=order))
    np.testing.assert_allclose(ours, d / 2.5, rtol=1e-5, atol=0.01 * 0.04 / 2.5)


@pytest.mark.parametrize("order", [1, 2])
def test_analytic_travel_time_in_a_two_speed_medium(order):
    # A plane front at x = 0.1 moving along x through speed 1 (x < 1) then 3: the travel
    # time is (x - 0.1) before the jump and 0.9 + (x - 1) / 3 after it.
    dx = (0.04, 0.05)
    i, j = np.mgrid[:60, :20].astype(np.float64)
    x = i * dx[0]
    phi = x - 0.1
    speed = np.where(x < 1.0, 1.0, 3.0)
    exact = np.where(x < 1.0, x - 0.1, 0.9 + (x - 1.0) / 3.0)
    ours = sl.travel_time(phi, speed, dx=dx, order=order)
    theirs = skfmm.travel_time(phi, speed, dx=dx, order=order)
    _errors(f"two-speed medium, order {order}", ours, theirs, np.abs(exact), x >= 0, 0.04)


@pytest.mark.parametrize("order", [1, 2])
def test_analytic_extension_of_a_speed_constant_along_normals(order):
    # speed = 2 + cos(angle) around a circle: constant along the normals, so the extension
    # from the circle is the speed itself.
    dx = (0.03, 0.04)
    a, b = _grid2(70, 52, dx)
    r = np.hypot(a, b)
    phi = r - 0.6
    speed = 2.0 + np.cos(np.arctan2(b, a))
    d, f = sl.extension_velocities(phi, speed, dx=dx, order=order)
    dt, ft = skfmm.extension_velocities(phi, speed, dx=dx, order=order)
    _errors(f"extension 2 + cos, order {order}", f, ft, speed, r > 0.3, 0.04)
    _errors(f"extension's distance, order {order}", d, dt, r - 0.6, r > 0.3, 0.04)
    np.testing.assert_array_equal(d, sl.distance(phi, dx=dx, order=order))


def test_extension_velocities_3d_agrees_with_scikit_fmm():
    i, j, k = np.mgrid[:24, :28, :30].astype(np.float64)
    x, y, z = (i - 11.5) * 0.1, (j - 13.2) * 0.09, (k - 14.7) * 0.08
    r = np.sqrt(x**2 + y**2 + z**2)
    phi = r - 0.7
    speed = 1.0 + x + 0.5 * y * z
    d, f = sl.extension_velocities(phi, speed, dx=(0.1, 0.09, 0.08))
    dt, ft = skfmm.extension_velocities(phi, speed, dx=(0.1, 0.09, 0.08))
    # No exact answer: agreement within 0.05 (the speed varies by 1.4 on the sphere) near
    # the sphere, 0.15 everywhere away from the centre.
    near = np.abs(phi) < 0.3
    print(f"\n3-D extension: max |ours - skfmm| {np.abs(f - ft)[near].max():.4f} near")
    assert np.abs(f - ft)[near].max() < 0.05
    assert np.abs(f - ft)[r > 0.3].max() < 0.15
    assert np.abs(d - dt)[r > 0.3].max() < 0.05


def test_masked_obstacles_like_scikit_fmm():
    # A source in a corner, a masked wall with a gap: the front goes through the gap.
    n = 64
    phi = np.ones((n, n))
    phi[:3, :3] = -1
    mask = np.zeros((n, n), bool)
    mask[30, :50] = True
    mphi = np.ma.MaskedArray(phi, mask)
    for func, args in (
        (sl.distance, ()),
        (sl.travel_time, (np.full((n, n), 2.0),)),
    ):
        theirs = getattr(skfmm, func.__name__)(mphi, *args, dx=0.1)
        ours = func(mphi, *args, dx=0.1)
        assert isinstance(ours, np.ma.MaskedArray)
        np.testing.assert_array_equal(ours.mask, mask)
        np.testing.assert_array_equal(theirs.mask, mask)
        assert (ours.data[mask] == 0).all()
        # Behind the wall, the path goes round its end at (30, 50): far longer than the
        # straight line.
        straight = sl.distance(phi, dx=0.1)
        scale = 1 if func is sl.distance else 2
        assert (np.abs(ours[40:, :20]) > 1.5 * np.abs(straight[40:, :20]) / scale).all()
        # No exact answer: agreement with scikit-fmm within 2 % + half a voxel.
        diff = np.abs(ours - theirs)
        print(f"\nmasked wall, {func.__name__}: max |ours - skfmm| {diff.max():.4f}")
        np.testing.assert_allclose(ours.data[~mask], theirs.data[~mask], rtol=0.02, atol=0.05)
    # A region cut off by the mask is masked too (scikit-fmm's doctest).
    d = sl.distance(np.ma.MaskedArray([1, 1, 1, 0], [False, True, False, False]))
    np.testing.assert_array_equal(d.mask, [True, True, False, False])
    np.testing.assert_array_equal(d.data, [0, 0, 1, 0])
    # Masked speeds are obstacles too; speed 0 (or below the double epsilon) as well.
    t = sl.travel_time([-1, -1, 0, 1, 1], [1, 1, 1, 1, 0])
    np.testing.assert_array_equal(t.mask, [False, False, False, False, True])
    np.testing.assert_array_equal(t.data[:-1], [2, 1, 0, 1])
    t2 = sl.travel_time([-1, -1, 0, 1, 1], [1, 1, 1, 1, 1e-300])
    np.testing.assert_array_equal(t2.mask, t.mask)
    t3 = sl.travel_time([-1, -1, 0, 1, 1], np.ma.MaskedArray([1, 1, 1, 1, 5], [0, 0, 0, 0, 1]))
    np.testing.assert_array_equal(t3.mask, t.mask)


def test_narrow_band_like_scikit_fmm():
    dx = 2.0 / 49
    x, y = np.meshgrid(np.linspace(-1, 1, 50), np.linspace(-1, 1, 50))
    phi = x**2 + y**2 - 0.25
    band = 5 * dx
    speed = np.where(x > 0, 1.8, 1.0)
    ext, ext_t = (m.extension_velocities(phi, x + y, dx, narrow=band) for m in (sl, skfmm))
    assert isinstance(ext[1], np.ma.MaskedArray)
    np.testing.assert_array_equal(ext[1].mask, ext[0].mask)
    for ours, theirs in (
        (sl.distance(phi, dx, narrow=band), skfmm.distance(phi, dx, narrow=band)),
        (
            sl.travel_time(phi, speed, dx, narrow=band),
            skfmm.travel_time(phi, speed, dx, narrow=band),
        ),
        (ext[0], ext_t[0]),
    ):
        assert isinstance(ours, np.ma.MaskedArray)
        assert (np.abs(ours) <= band + 1e-6).all()
        # The same elements are masked, but for a few within a few hundredths of a voxel of
        # the band's edge (the two marches differ by that much there).
        diff = ours.mask != theirs.mask
        edge = np.where(ours.mask, np.abs(theirs.data), np.abs(ours.data))[diff]
        print(f"\nnarrow band: {diff.sum()} of {diff.size} masked differently")
        assert (np.abs(edge - band) < 0.1 * dx).all(), edge
    # A narrow band wider than the array: a plain array, as scikit-fmm.
    assert not isinstance(sl.distance(phi, dx, narrow=1000 * dx), np.ma.MaskedArray)
    with pytest.raises(ValueError, match="narrow"):
        sl.distance(phi, dx, narrow=-1)
    # With an existing mask, the band adds to it.
    mask = np.abs(x) < 0.25
    d3 = sl.distance(np.ma.masked_array(phi, mask), dx, narrow=band)
    assert d3.mask[mask].all() and d3.mask.sum() > mask.sum()


def test_scikit_fmm_examples_give_scikit_fmm_results():
    # Doctests of scikit-fmm whose answers do not depend on how the interface starts.
    for phi, speed, periodic, ext in (
        ([1, -1, 1, 1, 1, 1], [4, 1, 2, 2, 2, 2], False, (2.5, 2.5, 1.5, 1.5, 1.5, 1.5)),
        ([1, -1, 1, 1, 1, 1], [4, 1, 2, 2, 2, 2], True, (2.5, 2.5, 1.5, 1.5, 1.5, 2.5)),
    ):
        np.testing.assert_allclose(sl.extension_velocities(phi, speed, periodic=periodic)[1], ext)
        theirs = skfmm.extension_velocities(phi, speed, periodic=periodic)[1]
        np.testing.assert_allclose(theirs, ext)
    phi = np.ones(10)
    phi[0] = -1
    speed = np.ones(10)
    speed[0:3] = 5
    np.testing.assert_allclose(sl.extension_velocities(phi, speed)[1], 5)
    np.testing.assert_array_equal(sl.distance([-1, 0, 1], dx=2), [-2, 0, 2])
    np.testing.assert_array_equal(sl.travel_time([1, 0, -1], [1, 1, 1], dx=[2]), [2, 0, 2])
    np.testing.assert_allclose(sl.travel_time([0, 1, 1, 1, 1], [2] * 5), [0, 0.5, 1.0, 1.5, 2.0])
    np.testing.assert_array_equal(sl.distance([0, 0]), [0, 0])
    np.testing.assert_allclose(
        sl.distance((-1.0, -1, -1, -1, 1, 1, 1, 1), dx=0.5),
        (-1.75, -1.25, -0.75, -0.25, 0.25, 0.75, 1.25, 1.75),
    )
    # ext_mask: the masked elements' own speed is not used at the interface.
    phi = np.array([[-1.0, 1.0], [1.0, 1.0]])
    sp = [[-1, 0.5], [2.0, -1.0]]
    ours = sl.extension_velocities(phi, sp, ext_mask=phi < 0, order=1)[1]
    theirs = skfmm.extension_velocities(phi, sp, ext_mask=phi < 0, order=1)[1]
    np.testing.assert_allclose(ours[phi < 0], theirs[phi < 0])
    np.testing.assert_allclose(theirs[phi < 0], 1.25)


def test_dtypes_of_the_new_functions():
    phi = np.array([[-1.0, 1.0, 2.0], [1.0, 2.0, 3.0]])
    for dt, want in ((np.float64, np.float64), (np.float32, np.float32), (np.int64, np.float32)):
        p = phi.astype(dt)
        assert sl.distance(p).dtype == want
        assert sl.travel_time(p, np.ones_like(phi)).dtype == want
        d, f = sl.extension_velocities(p, np.ones_like(phi))
        assert d.dtype == want and f.dtype == want
    # Fortran order gives the same result as C order.
    x, y = np.mgrid[:20, :30] * 0.1
    phi = np.hypot(x - 1, y - 1.4) - 0.5
    sp = 1 + x
    np.testing.assert_array_equal(
        sl.travel_time(np.asfortranarray(phi), np.asfortranarray(sp), dx=(0.1, 0.2)),
        sl.travel_time(phi, sp, dx=(0.1, 0.2)),
    )


@pytest.mark.parametrize(
    "call",
    [
        lambda m: m.distance([[-1, 1], [1, 1]], dx=(1, 2, 3)),
        lambda m: m.distance([1, 0, 1, 1], 0),
        lambda m: m.distance([1, 1]),
        lambda m: m.distance([-1, 1], order=0),
        lambda m: m.distance([-1, 1], order=3),
        lambda m: m.distance([-1, 1], self_test=44),
        lambda m: m.distance(np.array(["a", "b"])),
        lambda m: m.distance([-1, 1], narrow=-1),
        lambda m: m.distance([-1, 1], periodic=(True, False)),
        lambda m: m.travel_time([-1, 1], [2]),
        lambda m: m.travel_time([0, 0, 1, 1], 2),
        lambda m: m.travel_time([-1, 1], [2, 2], [2, 2, 2, 2]),
        lambda m: m.extension_velocities([[-1, 1], [1, 1]], speed=[1, 1]),
    ],
)
def test_bad_input_raises_value_error_like_scikit_fmm(call):
    with pytest.raises(ValueError):
        call(skfmm)
    with pytest.raises(ValueError):
        call(sl)


def test_bad_input_scikit_fmm_accepts_is_an_error_here():
    # A negative speed is a mistake (scikit-fmm masks it silently); NaN in phi or speed.
    with pytest.raises(ValueError, match="speed"):
        sl.travel_time([-1, 1, 1], [1, -1, 1])
    with pytest.raises(ValueError, match="speed"):
        sl.travel_time([-1, 1, 1], [1, np.nan, 1])
    with pytest.raises(ValueError, match="NaN"):
        sl.travel_time([-1, np.nan, 1], [1, 1, 1])
    with pytest.raises(ValueError, match="speed"):
        sl.extension_velocities([-1, 1, 1], [1, np.inf, 1])
    with pytest.raises(ValueError, match="ext_mask"):
        sl.extension_velocities([-1, 1, 1], [1, 1, 1], ext_mask=[True, False])
    with pytest.raises(ValueError, match="shape"):
        sl.travel_time(np.ma.MaskedArray([-1, 1, 1], [0, 0, 0]), np.ma.MaskedArray([1, 1], [0, 1]))
    # NaN under the mask is not read.
    d = sl.distance(np.ma.MaskedArray([-1, 1, np.nan, 1], [0, 0, 1, 0]))
    np.testing.assert_array_equal(d.mask, [False, False, True, True])


def _scene(ndim):
    """A sphere (circle) crossing a periodic face, an obstacle plate away from the faces,
    per-axis dx, a smooth speed."""
    if ndim == 2:
        shape, dx, c = (40, 56), (0.05, 0.04), (0.3, 1.1)
    else:
        shape, dx, c = (22, 26, 30), (0.09, 0.08, 0.07), (0.15, 1.0, 1.05)
    idx = np.indices(shape).astype(np.float64)
    x = [idx[a] * dx[a] for a in range(ndim)]
    length = [shape[a] * dx[a] for a in range(ndim)]
    # Axis 0 periodic: the distance to the nearest copy of the sphere along it.
    d0 = np.abs(x[0] - c[0])
    d = [np.minimum(d0, length[0] - d0)] + [x[a] - c[a] for a in range(1, ndim)]
    r = np.sqrt(sum(v**2 for v in d))
    phi = r - 0.45
    mask = np.zeros(shape, bool)
    rest = (slice(None),) * (ndim - 2)
    plate = (slice(shape[0] // 2 - 4, shape[0] // 2 + 4), shape[1] - 12) + rest
    mask[plate] = True
    speed = 1.0 + 0.5 * x[1] + 0.3 * np.sin(3 * x[-1])
    periodic = (True,) + (False,) * (ndim - 1)
    return np.ma.MaskedArray(phi, mask), speed, dx, periodic, min(dx)


@pytest.mark.parametrize("ndim", [2, 3])
@pytest.mark.parametrize("name", ["distance", "travel_time", "extension_velocities"])
def test_side_by_side_with_masks_periodic_and_per_axis_dx(name, ndim):
    # No exact answer (an obstacle, a speed that varies): the same elements masked, and
    # agreement with scikit-fmm within 1 % of the value plus 0.2 (2-D) or 0.6 (3-D) of the
    # smallest spacing — the size of scikit-fmm's own error next to the sphere, where its
    # start from the edge crossings alone is off (checked below without the obstacle,
    # where the exact distance is known).
    phi, speed, dx, periodic, h = _scene(ndim)
    if name == "distance":
        plain = phi.data
        ours = sl.distance(plain, dx=dx, periodic=periodic)
        theirs = skfmm.distance(plain, dx=dx, periodic=periodic)
        _errors(f"periodic {ndim}-D, dx {dx}", ours, theirs, plain, np.ones(plain.shape, bool), h)
    args = () if name == "distance" else (speed,)
    ours = getattr(sl, name)(phi, *args, dx=dx, periodic=periodic)
    theirs = getattr(skfmm, name)(phi, *args, dx=dx, periodic=periodic)
    if name != "extension_velocities":
        ours, theirs = (ours,), (theirs,)
    # The extended speed (the second result of extension_velocities) has no one right
    # value where characteristics meet: in the sphere's core and where the fronts from two
    # periodic copies collide. It must agree at 99 % of the elements, and within 0.15
    # (a tenth of the speed's range) everywhere outside the core (r > 0.2).
    tol = (0.2 if ndim == 2 else 0.6) * h
    for n, (o, t) in enumerate(zip(ours, theirs)):
        assert isinstance(o, np.ma.MaskedArray) and o.shape == phi.shape
        np.testing.assert_array_equal(o.mask, t.mask)
        np.testing.assert_array_equal(o.mask, phi.mask)
        open_ = ~phi.mask
        diff = np.abs(o.data - t.data)[open_]
        print(f"\n{name} {ndim}-D, result {n}: max |ours - skfmm| {diff.max():.4f} (dx {h})")
        close = diff <= tol + 0.01 * np.abs(t.data[open_])
        if n == 0:
            assert close.all(), diff.max()
        else:
            assert close.mean() >= 0.99, close.mean()
            assert np.abs(o - t)[open_ & (phi.data > -0.25)].max() < 0.15
