"""`isosurface` against the exact sphere, scikit-image's `marching_cubes` and trimesh."""

import inspect

import numpy as np
import pytest
import trimesh
from scipy import ndimage
from scipy.spatial import cKDTree
from skimage import measure

import sparse_levelset as sl
from conftest import sphere_field


@pytest.mark.parametrize("radius", [10.3, 31.7])
def test_sphere_is_watertight_with_area_within_half_a_percent(radius):
    n = int(2 * radius) + 12
    phi = sphere_field(n, radius)
    verts, faces, normals, _ = sl.isosurface(phi, 0.0, inside="below")
    mesh = trimesh.Trimesh(verts, faces, process=False)
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.euler_number == 2
    exact_area = 4 * np.pi * radius**2
    assert abs(mesh.area - exact_area) < 0.005 * exact_area
    exact_volume = 4 / 3 * np.pi * radius**3
    assert abs(mesh.volume - exact_volume) < 0.005 * exact_volume
    # Counter-clockwise seen from outside: positive volume, normals outward.
    assert mesh.volume > 0
    centre = (n - 1) / 2
    outward = np.einsum("ij,ij->i", normals, verts - centre)
    assert (outward > 0).all()
    # Vertices on the sphere to a small fraction of a voxel.
    r = np.linalg.norm(verts - centre, axis=1)
    assert np.abs(r - radius).max() < 0.05


def test_agrees_with_marching_cubes_in_array_axis_order():
    # An ellipsoid off-centre, anisotropic spacing: both meshes in the same coordinates.
    z, y, x = np.mgrid[:40, :50, :60].astype(np.float64)
    vol = np.sqrt(((x - 33) / 20) ** 2 + ((y - 22) / 14) ** 2 + ((z - 19) / 9) ** 2) - 1
    spacing = (2.0, 1.0, 0.5)
    ours = trimesh.Trimesh(*sl.isosurface(vol, 0.0, spacing=spacing)[:2], process=False)
    v, f, _, _ = measure.marching_cubes(vol, 0.0, spacing=spacing)
    theirs = trimesh.Trimesh(v, f, process=False)
    np.testing.assert_allclose(ours.bounds, theirs.bounds, atol=0.05)
    np.testing.assert_allclose(ours.centroid, theirs.centroid, atol=0.02)
    assert abs(ours.area - theirs.area) < 0.01 * theirs.area
    assert abs(abs(ours.volume) - abs(theirs.volume)) < 0.01 * abs(theirs.volume)
    # The same surface: the trilinear interpolant of the volume nearly vanishes at our
    # vertices (they are interpolated along the tetrahedra's edges, some of them cell
    # diagonals). |∇vol| ≥ 1/20 per voxel here, so 0.005 is a tenth of a voxel.
    def residual(verts):
        idx = (verts / np.array(spacing)).T
        return np.abs(ndimage.map_coordinates(vol, idx, order=1))

    assert residual(theirs.vertices).max() < 1e-6
    assert residual(ours.vertices).max() < 0.005


def test_fortran_order_and_dtypes_give_the_same_surface():
    phi = sphere_field(30, 9.2)
    v, f, n, _ = sl.isosurface(phi, 0.0, inside="below")
    vf, ff, nf, _ = sl.isosurface(np.asfortranarray(phi.astype(np.float32)), 0.0, inside="below")
    a = trimesh.Trimesh(v, f, process=False)
    b = trimesh.Trimesh(vf, ff, process=False)
    assert b.is_watertight and b.volume > 0
    assert abs(a.area - b.area) < 1e-3 * a.area
    np.testing.assert_allclose(np.sort(v, axis=0), np.sort(vf, axis=0), atol=1e-5)


def test_bright_object_and_closed_at_the_border():
    # An intensity image: a bright ball cut by the array's border is closed on request.
    phi = sphere_field(32, 12.0, center=4.0)
    image = 100.0 - 10.0 * phi
    verts, faces, normals, _ = sl.isosurface(image, 100.0, inside="above", closed=True)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    assert mesh.is_watertight and mesh.volume > 0
    with pytest.raises(ValueError, match="inside"):
        sl.isosurface(image, 100.0, inside="left")


def test_bad_input():
    phi = sphere_field(16, 5.0)
    with pytest.raises(ValueError, match="data range"):
        sl.isosurface(phi, 1e6)
    with pytest.raises(ValueError, match="spacing"):
        sl.isosurface(phi, 0.0, spacing=(1, 0, 1))
    bad = phi.copy()
    bad[3, 3, 3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        sl.isosurface(bad, 0.0)
    with pytest.raises(ValueError, match="3-D"):
        sl.isosurface(phi[0], 0.0)
    with pytest.raises(ValueError, match="step_size"):
        sl.isosurface(phi, 0.0, step_size=0)
    with pytest.raises(ValueError, match="method"):
        sl.isosurface(phi, 0.0, method="dual")
    with pytest.raises(ValueError, match="gradient_direction"):
        sl.isosurface(phi, 0.0, gradient_direction="up")
    with pytest.raises(ValueError, match="gradient_direction"):
        sl.isosurface(phi, 0.0, inside="below", gradient_direction="ascent")
    with pytest.raises(ValueError, match="shape"):
        sl.isosurface(phi, 0.0, mask=np.ones((16, 16, 15), bool))


# --- scikit-image's marching_cubes, argument for argument --------------------------------
#
# Our vertices on a cube's edges are scikit-image's (both interpolate linearly along the
# edge); the simplicial surface adds vertices on cell diagonals. So, on the same cells:
# every scikit-image vertex has one of ours within SAME (abs, voxels: our vertices keep
# 32 ulp off the voxels), and every one of ours lies within NEAR voxels of one of theirs
# (a vertex on a cube's diagonal is up to half the diagonal, √3/2 = 0.87, from the cube's
# edges; measured up to 0.82). Areas agree within AREA (relative; measured ≤ 0.15 %). The
# tetrahedra cut the surface into TRIANGLES times as many triangles (measured 2.93-3.01).
SAME = 1e-3
NEAR = 0.9
AREA = 0.01
TRIANGLES = (2.5, 3.5)


def bright_ball(n, centre, radius):
    """A bright object: 100 inside a ball, falling off linearly (10 per voxel)."""
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float64)
    r = np.sqrt((z - centre[0]) ** 2 + (y - centre[1]) ** 2 + (x - centre[2]) ** 2)
    return (100.0 - 10.0 * (r - radius)).astype(np.float32)


def compare(ours, theirs, what, scale=1.0):
    """Checks both meshes describe one surface on the same cells; returns the matched
    vertex pairs (ours, theirs) with their distance below SAME * scale, and prints the
    figures."""
    (v, f, n, val), (V, F, N, VAL) = ours, theirs
    d_theirs, i_ours = cKDTree(v).query(V)  # theirs -> nearest of ours
    d_ours, _ = cKDTree(V).query(v)  # ours -> nearest of theirs
    a, A = measure.mesh_surface_area(v, f), measure.mesh_surface_area(V, F)
    print(
        f"{what}: ours {len(f)} triangles, area {a:.2f}; marching_cubes {len(F)} triangles, "
        f"area {A:.2f} ({a / A - 1:+.2%}); max distance theirs->ours {d_theirs.max():.2e}, "
        f"ours->theirs {d_ours.max():.3f}"
    )
    assert TRIANGLES[0] <= len(f) / len(F) <= TRIANGLES[1], (len(f), len(F))
    assert abs(a - A) <= 1e-6 + AREA * A
    assert d_theirs.max() <= SAME * scale
    assert d_ours.max() <= NEAR * scale
    return i_ours


def test_every_marching_cubes_keyword_is_accepted():
    theirs = set(inspect.signature(measure.marching_cubes).parameters)
    ours = set(inspect.signature(sl.isosurface).parameters)
    assert theirs <= ours, theirs - ours
    vol = bright_ball(24, (11.2, 12.4, 10.7), 6.3)
    mask = np.ones(vol.shape, bool)
    kw = dict(
        spacing=(1.0, 1.0, 1.0),
        gradient_direction="descent",
        step_size=1,
        allow_degenerate=True,
        method="lewiner",
        mask=mask,
    )
    out = sl.isosurface(vol, 100.0, **kw)
    assert len(out) == 4
    v, f, n, val = out
    assert v.dtype == np.float32 and f.dtype == np.int32 and n.dtype == np.float32
    assert val.shape == (len(v),) and val.dtype == np.float32
    compare(out, measure.marching_cubes(vol, 100.0, **kw), "all keywords")
    # 'lorensen' is the same simplicial surface; allow_degenerate=False removes nothing
    # (no zero-area triangle exists).
    for other in (dict(method="lorensen"), dict(allow_degenerate=False)):
        again = sl.isosurface(vol, 100.0, **{**kw, **other})
        for x, y in zip(out, again):
            np.testing.assert_array_equal(x, y)
    tri = v[f]
    areas = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    assert areas.min() > 0
    # Progress counts tiles, and the last report is the end.
    reports = []
    sl.isosurface(vol, 100.0, progress=reports.append, **kw)
    assert reports and reports[-1]["done"] == reports[-1]["total"] > 0


def test_masked_ball_matches_marching_cubes():
    vol = bright_ball(40, (19.3, 20.6, 18.8), 11.4)
    mask = np.zeros(vol.shape, bool)
    mask[:, :, 20:] = True  # the half x >= 20 (last axis): cells from x = 19
    ours = sl.isosurface(vol, 100.0, mask=mask)
    theirs = measure.marching_cubes(vol, 100.0, mask=mask)
    compare(ours, theirs, "masked ball")
    for v in (ours[0], theirs[0]):
        assert abs(v[:, 2].min() - 19.0) < SAME
    full = sl.isosurface(vol, 100.0)
    assert len(ours[1]) < 0.6 * len(full[1])


def test_bright_object_at_the_border_is_open_like_marching_cubes():
    n = 48
    vol = bright_ball(n, (3.4, 40.2, 22.7), 14.6)  # cut by the faces z = 0 and y = 47
    spacing = (1.0, 0.8, 1.25)
    ours = sl.isosurface(vol, 100.0, spacing=spacing)
    theirs = measure.marching_cubes(vol, 100.0, spacing=spacing)
    compare(ours, theirs, "bright ball at the border", scale=1.25)
    v, f = ours[0], ours[1]
    top = (np.array(vol.shape) - 1) * spacing
    # Normals on the cut faces (one-sided differences) agree with scikit-image's: mean dot
    # product > 0.999 at the matched vertices there (measured 0.99986). Unit spacing:
    # with anisotropic spacing scikit-image's normals are in index units, ours in world
    # units (mean dot 0.987 on the cut faces, 0.990 elsewhere, for the spacing above).
    w, _, n1, _ = sl.isosurface(vol, 100.0)
    V, _, N, _ = measure.marching_cubes(vol, 100.0)
    _, i = cKDTree(w).query(V)
    cut = (np.abs(V[:, 0]) < 1e-4) | (np.abs(V[:, 1] - (n - 1)) < 1e-4)
    dots = np.einsum("ij,ij->i", n1[i[cut]], N[cut])
    print(f"normals on the cut faces: {cut.sum()} vertices, mean dot {dots.mean():.4f}")
    assert cut.sum() > 50 and dots.mean() > 0.999
    assert (v >= 0).all() and (v <= top + 1e-4).all()
    # No box faces: no triangle lies in one of the array's outer faces.
    tri = v[f]
    for axis in range(3):
        for plane in (0.0, top[axis]):
            assert not (np.abs(tri[:, :, axis] - plane) < 1e-4).all(axis=1).any()
    # The boundary (edges of one triangle) lies on the two cut faces only.
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    ends = v[uniq[count == 1]]
    # (1e-4: the f32 rounding of 47 × 0.8.)
    on = (np.abs(ends[:, :, 0]) < 1e-4).all(axis=1) | (
        np.abs(ends[:, :, 1] - top[1]) < 1e-4
    ).all(axis=1)
    assert len(ends) > 0 and on.all()
    # closed=True: the watertight mesh, larger by the caps on the array's faces.
    vc, fc, _, _ = sl.isosurface(vol, 100.0, spacing=spacing, closed=True)
    closed = trimesh.Trimesh(vc, fc, process=False)
    assert closed.is_watertight
    assert closed.area > 1.2 * measure.mesh_surface_area(v, f)


def test_step_size_2_matches_marching_cubes():
    vol = bright_ball(41, (20.2, 19.7, 21.1), 13.3)
    ours = sl.isosurface(vol, 100.0, step_size=2)
    theirs = measure.marching_cubes(vol, 100.0, step_size=2)
    compare(ours, theirs, "step_size=2", scale=2.0)
    full = sl.isosurface(vol, 100.0)
    assert 3.0 < len(full[1]) / len(ours[1]) < 5.0


@pytest.mark.parametrize("direction", ["descent", "ascent"])
@pytest.mark.parametrize("kind", ["bright ball", "signed distance"])
def test_normals_faces_and_values_agree_with_marching_cubes(direction, kind):
    if kind == "bright ball":
        vol, level = bright_ball(36, (17.3, 18.1, 16.6), 10.2), 100.0
    else:
        vol, level = sphere_field(36, 10.2).astype(np.float32), 0.0
    ours = sl.isosurface(vol, level, gradient_direction=direction)
    theirs = measure.marching_cubes(vol, level, gradient_direction=direction)
    i = compare(ours, theirs, f"{kind}, {direction}")
    (v, f, n, val), (V, F, N, VAL) = ours, theirs
    # Normals: the same sign (scikit-image's: along -grad volume, whatever the direction).
    dots = np.einsum("ij,ij->i", n[i], N)
    print(f"mean dot of matched normals {dots.mean():.4f}, min {dots.min():.3f}")
    assert dots.mean() > 0.9 and dots.min() > 0
    # Faces: the same winding relative to the normals (gradient_direction flips it).
    def winding(v, f, n):
        fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        return np.mean(np.einsum("ij,ij->i", fn, n[f].sum(axis=1)) > 0)

    w, W = winding(v, f, n), winding(V, F, N)
    print(f"faces along the normals: ours {w:.3f}, marching_cubes {W:.3f}")
    assert W in (0.0, 1.0) and abs(w - W) < 1e-3
    # Values: the cells' value range, equal at the shared (cube-edge) vertices to
    # 1e-5 abs + 1e-6 rel (f32 rounding).
    np.testing.assert_allclose(val[i], VAL, rtol=1e-6, atol=1e-5)


def test_level_none_is_the_middle_of_the_data_range():
    vol = bright_ball(30, (14.2, 15.3, 13.9), 8.1)
    mid = 0.5 * (float(vol.min()) + float(vol.max()))
    ours = sl.isosurface(vol, None)
    for x, y in zip(ours, sl.isosurface(vol, mid)):
        np.testing.assert_array_equal(x, y)
    compare(ours, measure.marching_cubes(vol), "level=None")


def test_mask_in_fortran_order_and_any_dtype():
    vol = bright_ball(28, (13.2, 14.1, 12.7), 8.3)
    mask = np.zeros(vol.shape, bool)
    mask[:, 14:, :] = True
    c = sl.isosurface(vol, 100.0, mask=mask)
    f = sl.isosurface(np.asfortranarray(vol), 100.0, mask=mask.astype(np.uint8))
    assert len(c[1]) == len(f[1])
    np.testing.assert_allclose(np.sort(c[0], axis=0), np.sort(f[0], axis=0), atol=1e-5)
    np.testing.assert_allclose(np.sort(c[3]), np.sort(f[3]), rtol=1e-6, atol=1e-5)
    compare(f, measure.marching_cubes(vol, 100.0, mask=mask), "Fortran order, uint8 mask")
    # A mask that admits no cut cube: four empty arrays (marching_cubes raises).
    empty = sl.isosurface(vol, 100.0, mask=np.zeros(vol.shape, bool))
    assert [a.shape for a in empty] == [(0, 3), (0, 3), (0, 3), (0,)]
    with pytest.raises(RuntimeError):
        measure.marching_cubes(vol, 100.0, mask=np.zeros(vol.shape, bool))
