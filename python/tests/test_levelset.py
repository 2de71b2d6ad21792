"""`LevelSet`: construction, files, values, measures, CSG, meshes, pictures."""

import numpy as np
import pytest
import trimesh

import sparse_levelset as sl
from conftest import sphere_field


@pytest.fixture(scope="module")
def sphere():
    return sl.LevelSet.sphere(12.0, center=(1.5, -2.0, 0.25), voxel_size=0.5)


def test_sphere_values_measures_and_mesh(sphere):
    assert sphere.voxel_size == 0.5 and sphere.half_width == 3.0
    assert sphere.background == pytest.approx(1.5)
    pts = np.array([[1.5 + 12.0, -2.0, 0.25], [1.5, -2.0, 0.25 + 11.3], [1.5, 10.9, 0.25]])
    np.testing.assert_allclose(sphere.value(pts), [0.0, -0.7, 0.9], atol=0.01)
    assert sphere.value([100.0, 0, 0]) == pytest.approx(1.5)
    assert sphere.value([1.5, -2.0, 0.25]) == pytest.approx(-1.5)
    m = sphere.measure()
    assert m["volume"] == pytest.approx(4 / 3 * np.pi * 12.0**3, rel=2e-3)
    assert m["area"] == pytest.approx(4 * np.pi * 12.0**2, rel=1e-2)
    v, f, n = sphere.mesh()
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.volume > 0
    assert mesh.area == pytest.approx(4 * np.pi * 12.0**2, rel=5e-3)
    np.testing.assert_allclose(mesh.centroid, [1.5, -2.0, 0.25], atol=0.01)
    coarse = trimesh.Trimesh(*sphere.mesh(coarsen=2)[:2], process=False)
    assert coarse.is_watertight and len(coarse.faces) < len(f) / 3


def test_dense_round_trip_and_placement():
    h = 0.25
    phi = sphere_field(48, 4.0, h=h, center=6.0)
    ls = sl.LevelSet.from_dense(phi, voxel_size=h, origin=(10.0, 20.0, 30.0))
    lo, hi = ls.bbox
    dense = ls.to_dense(((0, 0, 0), (47, 47, 47)))
    assert dense.shape == (48, 48, 48)
    g = ls.background
    band = np.abs(phi) < g
    np.testing.assert_allclose(dense[band], phi[band], atol=1e-6)
    assert np.all(np.abs(dense[~band]) == np.float32(g))
    # World placement: the centre is at origin + 6 along every axis.
    assert ls.value([16.0, 26.0, 36.0]) == pytest.approx(-g)
    assert ls.value([16.0 + 4.0, 26.0, 36.0]) == pytest.approx(0.0, abs=1e-3)
    # from_dense(to_dense) gives the same band.
    again = sl.LevelSet.from_dense(ls.to_dense(), voxel_size=h, origin=tuple(10 + h * c for c in lo))
    assert again.band_voxels == ls.band_voxels
    np.testing.assert_allclose(again.measure()["volume"], ls.measure()["volume"], rtol=1e-12)


def test_files_round_trip_bit_for_bit(tmp_path, sphere):
    for name in ("a.sls", "a.vdb"):
        path = tmp_path / name
        sphere.save(path)
        back = sl.LevelSet.load(path)
        assert back.checksum == sphere.checksum
        assert back.voxel_size == sphere.voxel_size and back.origin == sphere.origin
    sphere.save(tmp_path / "zip.vdb", compression="zip")
    assert sl.LevelSet.load(tmp_path / "zip.vdb").checksum == sphere.checksum
    # A dense .npy carries no placement: give it back.
    sphere.save(tmp_path / "a.npy", margin=1)
    arr = np.load(tmp_path / "a.npy")
    assert arr.ndim == 3 and arr.dtype == np.float32
    lo, _ = sphere.bbox
    o = tuple(sphere.origin[i] + sphere.voxel_size * (lo[i] - 1) for i in range(3))
    back = sl.LevelSet.load(tmp_path / "a.npy", voxel_size=0.5, origin=o)
    assert back.band_voxels == sphere.band_voxels


def test_csg_operators():
    a = sl.LevelSet.sphere(10.0, center=(-5, 0, 0), voxel_size=0.5)
    b = sl.LevelSet.sphere(10.0, center=(5, 0, 0), voxel_size=0.5)
    va, vb = a.volume, b.volume
    u, i, d = a | b, a & b, a - b
    # Lens volume of two spheres of radius r at distance s: π(4r + s)(2r − s)²/12.
    lens = np.pi * (4 * 10 + 10) * (2 * 10 - 10) ** 2 / 12
    assert i.volume == pytest.approx(lens, rel=0.01)
    # Inclusion–exclusion, up to the voxel measure's error at the creases.
    assert u.volume == pytest.approx(va + vb - i.volume, rel=5e-3)
    assert d.volume == pytest.approx(va - i.volume, rel=5e-3)
    assert (a.union(b)).checksum == u.checksum
    with pytest.raises(ValueError, match="voxel size"):
        a | sl.LevelSet.sphere(10.0, voxel_size=1.0)


def test_from_mesh_matches_the_analytic_sphere():
    s = trimesh.creation.icosphere(subdivisions=5, radius=10.0)
    ls = sl.LevelSet.from_mesh(s.vertices, s.faces, voxel_size=0.5)
    ref = sl.LevelSet.sphere(10.0, voxel_size=0.5)
    # The icosphere's facets sit inside the sphere by at most r(1 − cos θ) ≈ 0.02.
    coords, values = ref.band()
    pts = coords * 0.5
    np.testing.assert_allclose(ls.value(pts), values, atol=0.05)
    assert abs(ls.volume - s.volume) < 2e-3 * s.volume


def test_reinitialize_and_render(sphere):
    wide = sphere.reinitialize(half_width=5.0)
    assert wide.half_width == 5.0 and wide.band_voxels > sphere.band_voxels
    coords, values = sphere.band()
    np.testing.assert_allclose(wide.value(coords * 0.5 + np.array(sphere.origin)), values, atol=0.03)
    img = sphere.render(64, 48, samples=1)
    assert img.shape == (48, 64, 3) and img.dtype == np.uint8
    # The sphere is in the picture: the centre pixel differs from the corner (sky).
    assert np.abs(img[24, 32].astype(int) - img[0, 0].astype(int)).sum() > 30


def test_bad_input(tmp_path):
    with pytest.raises(ValueError, match="interface|empty"):
        sl.LevelSet.from_dense(np.ones((8, 8, 8)))
    with pytest.raises(ValueError, match="voxel size"):
        sl.LevelSet.sphere(5.0, voxel_size=0.0)
    with pytest.raises(ValueError, match="half-width"):
        sl.LevelSet.sphere(5.0, half_width=1.0)
    with pytest.raises(ValueError, match="unknown shape"):
        sl.LevelSet.shape("cone", radius=1.0)
    with pytest.raises(OSError):
        sl.LevelSet.load(tmp_path / "missing.sls")
    (tmp_path / "junk.sls").write_bytes(b"not a level set at all")
    with pytest.raises(OSError):
        sl.LevelSet.load(tmp_path / "junk.sls")
    (tmp_path / "junk.vdb").write_bytes(b"\x20BDV" + b"\0" * 40)
    with pytest.raises(OSError):
        sl.LevelSet.load(tmp_path / "junk.vdb")
    with pytest.raises(ValueError, match="file type"):
        sl.LevelSet.load(tmp_path / "x.txt")
    s = sl.LevelSet.sphere(5.0)
    with pytest.raises(ValueError, match="not finite"):
        s.value([[np.nan, 0, 0]])
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        s.value(np.zeros((4, 2)))
    with pytest.raises(ValueError, match="face 0"):
        sl.LevelSet.from_mesh(np.zeros((3, 3)), [[0, 1, 7]])
    with pytest.raises(TypeError):
        sl.LevelSet(None)


def test_filters_offset_a_sphere_and_refuse_bad_operations():
    ls = sl.LevelSet.sphere(8.0, voxel_size=0.5)
    grown = ls.filter("dilate:2", "renormalize")
    r = (3 * grown.volume / (4 * np.pi)) ** (1 / 3)
    assert abs(r - 10.0) < 0.05
    # Opening then closing by a small radius keeps a sphere (no edges to round).
    smooth = ls.filter("open:1", "close:1", "median:1")
    assert abs(smooth.volume / ls.volume - 1) < 0.02
    with pytest.raises(ValueError, match="unknown filter"):
        ls.filter("shrink:2")
    with pytest.raises(ValueError, match="empty"):
        ls.filter("erode:20")
