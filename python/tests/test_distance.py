"""`distance` against the exact distance and scikit-fmm on shared cases."""

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
    with pytest.raises(ValueError, match="same along every axis"):
        sl.distance(np.ones((4, 4)), dx=(1.0, 2.0))
    with pytest.raises(ValueError, match="dx"):
        sl.distance(np.ones((4, 4)), dx=-1.0)
    with pytest.raises(ValueError, match="periodic"):
        sl.distance(np.ones((4, 4)), periodic=True)
    with pytest.raises(ValueError, match="masked"):
        sl.distance(np.ma.masked_array(np.ones(4), mask=[0, 1, 0, 0]))
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
