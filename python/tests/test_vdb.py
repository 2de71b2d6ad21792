"""`.vdb` files checked against OpenVDB itself (Debian's OpenVDB 10, `pyopenvdb` for
/usr/bin/python3, installed by scripts/test.sh): our files read there with the same active
voxels and values, and files written by OpenVDB read here the same way."""

import json
import subprocess

import numpy as np
import pytest

import sparse_levelset as sl

SYSTEM_PYTHON = "/usr/bin/python3"

# Runs under Debian's Python with OpenVDB: dumps the first grid of a file (active voxels,
# values, transform, background, class, metadata) to an .npz and a .json.
DUMP = r"""
import json, sys
import numpy as np
import pyopenvdb as vdb
path, out = sys.argv[1], sys.argv[2]
grids, meta = vdb.readAll(path)
g = grids[0]
ijk, val = [], []
for item in g.citerOnValues():
    assert item.count == 1, "an active tile"
    ijk.append(item.min)
    val.append(item.value)
np.savez(out + ".npz", ijk=np.array(ijk, dtype=np.int32).reshape(-1, 3),
         val=np.array(val, dtype=np.float32))
info = dict(name=g.name, grid_class=g.gridClass, background=g.background,
            voxel_size=list(g.transform.voxelSize()),
            origin=list(g.transform.indexToWorld((0, 0, 0))),
            type=g.valueTypeName, active=g.activeVoxelCount(),
            metadata={k: str(v) for k, v in g.metadata.items()})
json.dump(info, open(out + ".json", "w"))
"""

# Writes OpenVDB's own level sets with its default compression (Blosc + active mask): a
# sphere, the same sphere moved by a translation in its transform and bitten by a second
# sphere (OpenVDB's combine, max(a, -b)), and one saved as half floats.
WRITE = r"""
import sys
import pyopenvdb as vdb
out = sys.argv[1]
a = vdb.createLevelSetSphere(11.0, center=(1.25, -2.5, 3.0), voxelSize=0.5, halfWidth=3.0)
a.name = "sphere"
vdb.write(out + "/sphere.vdb", grids=[a])
b = vdb.createLevelSetSphere(9.0, center=(6.0, 0.0, 0.0), voxelSize=0.5, halfWidth=3.0)
c = a.deepCopy()
c.combine(b, lambda x, y: max(x, -y))
c.transform = vdb.createLinearTransform(
    [[0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 0.5, 0], [0.1, -0.2, 0.3, 1]])
c.name = "bitten"
vdb.write(out + "/bitten.vdb", grids=[c])
h = vdb.createLevelSetSphere(7.0, center=(0.0, 0.0, 0.0), voxelSize=0.3, halfWidth=4.0)
h.name = "half"
h.saveFloatAsHalf = True
vdb.write(out + "/half.vdb", grids=[h])
"""


def run_openvdb(script, *args):
    subprocess.run([SYSTEM_PYTHON, "-c", script, *map(str, args)], check=True)


def dump(path, tmp_path):
    out = tmp_path / (path.stem + "-dump")
    run_openvdb(DUMP, path, out)
    d = np.load(str(out) + ".npz")
    info = json.loads((tmp_path / (path.stem + "-dump.json")).read_text())
    return d["ijk"], d["val"], info


def as_dict(ijk, val):
    return {tuple(c): v for c, v in zip(ijk.tolist(), val.view(np.uint32).tolist())}


def test_openvdb_is_installed():
    # Not a skip: the cross-checks below must run (scripts/test.sh installs OpenVDB).
    subprocess.run([SYSTEM_PYTHON, "-c", "import pyopenvdb"], check=True)


@pytest.mark.parametrize("compression", ["zip", "none"])
@pytest.mark.parametrize("case", ["sphere", "torus", "offset"])
def test_our_files_read_in_openvdb_with_identical_values(tmp_path, case, compression):
    if case == "sphere":
        ls = sl.LevelSet.sphere(12.0, center=(0.3, -0.7, 0.2), voxel_size=0.5)
    elif case == "torus":
        ls = sl.LevelSet.shape("torus", radius=14.0, minor_radius=4.0, voxel_size=0.37)
    else:
        # A placed dense field: non-zero origin, band reaching negative and positive voxels.
        z, y, x = np.mgrid[:40, :40, :40].astype(np.float64) * 0.25
        phi = np.sqrt((x - 3) ** 2 + (y - 5) ** 2 + (z - 4) ** 2) - 2.5
        ls = sl.LevelSet.from_dense(phi, voxel_size=0.25, origin=(-10.0, 2.0, 7.5))
    path = tmp_path / f"{case}.vdb"
    ls.save(path, compression=compression)
    ijk, val, info = dump(path, tmp_path)
    coords, values = ls.band()
    assert info["grid_class"] == "level set" and info["type"] == "float"
    assert info["background"] == pytest.approx(ls.background, rel=1e-7)
    np.testing.assert_allclose(info["voxel_size"], [ls.voxel_size] * 3, rtol=1e-7)
    np.testing.assert_allclose(info["origin"], ls.origin, atol=1e-9)
    assert info["active"] == ls.band_voxels
    assert as_dict(ijk, val) == as_dict(coords, values)
    vdb_print = subprocess.run(["vdb_print", "-l", str(path)], check=True,
                               capture_output=True, text=True).stdout
    assert "Tree_float_5_4_3" in vdb_print and "class: level set" in vdb_print


@pytest.mark.parametrize("name", ["sphere", "bitten", "half"])
def test_openvdb_files_read_here_with_identical_values(tmp_path, name):
    run_openvdb(WRITE, tmp_path)
    path = tmp_path / f"{name}.vdb"
    ijk, val, info = dump(path, tmp_path)
    ls = sl.LevelSet.load(path)
    assert ls.voxel_size == pytest.approx(info["voxel_size"][0], rel=1e-7)
    assert ls.background == pytest.approx(info["background"], rel=1e-6)
    np.testing.assert_allclose(ls.origin, info["origin"], atol=1e-9)
    coords, values = ls.band()
    # Every active voxel of OpenVDB's with |φ| < γ is a band voxel here with the same bits;
    # active voxels at ±γ (OpenVDB keeps a few) read ±γ here.
    gamma = np.float32(ls.background)
    inner = np.abs(val) < gamma
    assert as_dict(ijk[inner], val[inner]) == as_dict(coords, values)
    if (~inner).any():
        dense_at = [ls.to_dense((tuple(c), tuple(c)))[0, 0, 0] for c in ijk[~inner][:50]]
        np.testing.assert_array_equal(np.abs(dense_at), gamma)
    # The inside is inside: the sphere's centre reads −γ.
    if name == "sphere":
        assert ls.value([1.25, -2.5, 3.0]) == pytest.approx(-ls.background)
    if name == "bitten":
        assert ls.value([1.25 - 8.0 + 0.1, -2.5 - 0.2, 3.0 + 0.3]) == pytest.approx(-ls.background)
        assert ls.value([1.25 + 8.0 + 0.1, -2.5 - 0.2, 3.0 + 0.3]) == pytest.approx(ls.background)
    # And the round trip through our writer is exact.
    ls.save(tmp_path / "again.vdb")
    assert sl.LevelSet.load(tmp_path / "again.vdb").checksum == ls.checksum
