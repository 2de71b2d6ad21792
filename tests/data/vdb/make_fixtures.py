#!/usr/bin/python3
"""Writes the OpenVDB fixtures of tests/vdb.rs with OpenVDB itself.

Usage (Debian: apt-get install python3-openvdb libopenvdb-tools; Debian's own
/usr/bin/python3, where the module `pyopenvdb` lives):

    cd tests/data/vdb && /usr/bin/python3 make_fixtures.py

For each NAME.vdb it writes NAME.npy: the active voxels as OpenVDB reads them, an
int32 array of shape (N, 4) with columns x, y, z and the float32 bits of the value
(so the Rust test compares values bit for bit), sorted by (x, y, z).
Fixtures:
  sphere_blosc   createLevelSetSphere written by pyopenvdb.write: OpenVDB's default
                 (Debian's build: Blosc + active-value mask compression); radius 11,
                 centred so that whole leaves lie inside (inactive -background tiles)
  sphere_none    voxel size 0.37, a non-zero origin, no compression at all
                 (vdb_tool codec=none: every value stored)
  sphere_active  active-value mask compression only (vdb_tool codec=active)
  sphere_zip     class "unknown" (OpenVDB never zips level sets) with zlib compression
                 (vdb_tool codec=zip): read by name
  sphere_half    saved as half floats (saveFloatAsHalf, Blosc)
  two_grids      a fog volume first, then a level set: the reader picks the level set
  velocity       a Vec3s grid (a rotation about an axis plus a drift) on the voxels
                 [-4, 12) x [0, 16) x [2, 18), voxel size 0.5, translation (0.25, -0.5, 1),
                 and an active 8^3 tile of (1, 2, 3) at [16, 24) x [0, 8) x [0, 8)
                 (a tile of a lower internal node), behind a float grid; velocity.npy
                 holds what OpenVDB reads on the box [-4, 24) x [0, 16) x [0, 18), as
                 float32 of shape (nz, ny, nx, 3)
"""
import subprocess

import numpy as np
import pyopenvdb as vdb


def dump(grid, name):
    rows = []
    for item in grid.citerOnValues():
        lo, hi = item["min"], item["max"]
        assert lo == hi, "active tiles are not expected in these fixtures"
        bits = np.array([item["value"]], dtype=np.float32).view(np.int32)[0]
        rows.append((lo[0], lo[1], lo[2], bits))
    rows.sort()
    np.save(name + ".npy", np.array(rows, dtype=np.int32).reshape(-1, 4))


def sphere(radius, center, voxel_size=1.0, half_width=3.0, name="sphere"):
    g = vdb.createLevelSetSphere(radius=radius, center=center, voxelSize=voxel_size,
                                 halfWidth=half_width)
    g.name = name
    return g


def tool(src, dst, *args):
    subprocess.run(["vdb_tool", "-read", src, "-write", *args, dst], check=True,
                   stdout=subprocess.DEVNULL)


def main():
    g = sphere(11.0, (3.5, 3.5, 3.5))
    vdb.write("sphere_blosc.vdb", grids=[g])
    dump(vdb.read("sphere_blosc.vdb", "sphere"), "sphere_blosc")

    # Voxel size 0.37 and the origin moved: index (i, j, k) is at 0.37 (i, j, k) + t.
    g = sphere(2.0, (10.0, 11.0, 12.0), voxel_size=0.37)
    g.transform.translate((0.25, -0.5, 1.0))
    vdb.write("tmp.vdb", grids=[g])
    tool("tmp.vdb", "sphere_none.vdb", "codec=none")
    dump(vdb.read("sphere_none.vdb", "sphere"), "sphere_none")

    g = sphere(5.0, (-20.0, 30.0, -40.0))
    vdb.write("tmp.vdb", grids=[g])
    tool("tmp.vdb", "sphere_active.vdb", "codec=active")
    dump(vdb.read("sphere_active.vdb", "sphere"), "sphere_active")

    g = sphere(5.0, (-20.5, 30.0, 40.0))
    g.gridClass = vdb.GridClass.UNKNOWN
    vdb.write("tmp.vdb", grids=[g])
    tool("tmp.vdb", "sphere_zip.vdb", "codec=zip")
    dump(vdb.read("sphere_zip.vdb", "sphere"), "sphere_zip")

    g = sphere(6.0, (0.3, -0.2, 0.1))
    g.saveFloatAsHalf = True
    vdb.write("sphere_half.vdb", grids=[g])
    dump(vdb.read("sphere_half.vdb", "sphere"), "sphere_half")

    fog = vdb.FloatGrid()
    fog.name = "density"
    fog.gridClass = vdb.GridClass.FOG_VOLUME
    fog.fill((0, 0, 0), (3, 3, 3), 0.5)
    ls = sphere(4.0, (8.0, 8.0, 8.0), half_width=2.0, name="surface")
    vdb.write("two_grids.vdb", grids=[fog, ls])
    dump(vdb.read("two_grids.vdb", "surface"), "two_grids")

    vel = vdb.Vec3SGrid()
    vel.name = "velocity"
    ijk = np.indices((16, 16, 16)).astype(np.float32)  # [axis, i, j, k]
    x, y, z = ijk[0] - 4, ijk[1], ijk[2] + 2
    field = np.stack([-0.3 * (y - 8.0), 0.3 * (x - 4.0), 0.05 * z + 0.125], axis=-1)
    vel.copyFromArray(np.ascontiguousarray(field, dtype=np.float32), ijk=(-4, 0, 2))
    vel.fill((16, 0, 0), (23, 7, 7), (1.0, 2.0, 3.0), True)
    vel.transform = vdb.createLinearTransform(voxelSize=0.5)
    vel.transform.translate((0.25, -0.5, 1.0))
    vdb.write("velocity.vdb", grids=[fog, vel])
    back = vdb.read("velocity.vdb", "velocity")
    out = np.zeros((28, 16, 18, 3), dtype=np.float32)  # [x, y, z, c] from (-4, 0, 0)
    back.copyToArray(out, ijk=(-4, 0, 0))
    np.save("velocity.npy", np.ascontiguousarray(out.transpose(2, 1, 0, 3)))

    subprocess.run(["rm", "-f", "tmp.vdb"], check=True)


if __name__ == "__main__":
    main()
