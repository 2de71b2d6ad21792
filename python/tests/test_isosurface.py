"""`isosurface` against the exact sphere, scikit-image's `marching_cubes` and trimesh."""

import numpy as np
import pytest
import trimesh
from scipy import ndimage
from skimage import measure

import sparse_levelset as sl
from conftest import sphere_field


@pytest.mark.parametrize("radius", [10.3, 31.7])
def test_sphere_is_watertight_with_area_within_half_a_percent(radius):
    n = int(2 * radius) + 12
    phi = sphere_field(n, radius)
    verts, faces, normals = sl.isosurface(phi, 0.0)
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
    v, f, n = sl.isosurface(phi, 0.0)
    vf, ff, nf = sl.isosurface(np.asfortranarray(phi.astype(np.float32)), 0.0)
    a = trimesh.Trimesh(v, f, process=False)
    b = trimesh.Trimesh(vf, ff, process=False)
    assert b.is_watertight and b.volume > 0
    assert abs(a.area - b.area) < 1e-3 * a.area
    np.testing.assert_allclose(np.sort(v, axis=0), np.sort(vf, axis=0), atol=1e-5)


def test_bright_object_and_closed_at_the_border():
    # An intensity image: a bright ball cut by the array's border is still closed.
    phi = sphere_field(32, 12.0, center=4.0)
    image = 100.0 - 10.0 * phi
    verts, faces, normals = sl.isosurface(image, 100.0, inside="above")
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
