#!/usr/bin/python3
"""Reads a .vdb file with OpenVDB itself and dumps what OpenVDB sees, to check the files
sparse-levelset writes.

Usage (Debian: apt-get install python3-openvdb; run with Debian's /usr/bin/python3):

    /usr/bin/python3 check_with_openvdb.py FILE.vdb OUT.npz [GRID_NAME]

OUT.npz holds:
  coords       int32 (N, 3)  the active voxels (x, y, z), sorted
  values       float32 (N)   their values
  voxel_size   float64 (3)   the transform's voxel size
  origin       float64 (3)   world position of voxel (0, 0, 0)
  background   float32       the background value
  grid_class   str           the grid's class ("level set", ...)
  inactive     int32 (M, 4)  the inactive tiles and leaf voxels OpenVDB iterates:
                             x, y, z of the region's first voxel and the sign of its
                             value (-1 or +1)
It prints a one-line summary. The grid read is GRID_NAME, or the file's first grid.
"""
import sys

import numpy as np
import pyopenvdb as vdb


def main(argv):
    if len(argv) not in (3, 4):
        sys.exit(__doc__)
    path, out = argv[1], argv[2]
    if len(argv) == 4:
        grid = vdb.read(path, argv[3])
    else:
        grid = vdb.readAll(path)[0][0]
    coords, values, inactive = [], [], []
    for item in grid.citerOnValues():
        lo, hi = item["min"], item["max"]
        if lo != hi:
            sys.exit(f"{path}: an active tile {lo}..{hi}: not a level set's band")
        coords.append(lo)
        values.append(item["value"])
    for item in grid.citerOffValues():
        lo = item["min"]
        inactive.append((lo[0], lo[1], lo[2], -1 if item["value"] < 0 else 1))
    order = sorted(range(len(coords)), key=lambda i: coords[i])
    coords = np.array([coords[i] for i in order], dtype=np.int32).reshape(-1, 3)
    values = np.array([values[i] for i in order], dtype=np.float32)
    xform = grid.transform
    origin = np.array(xform.indexToWorld((0, 0, 0)), dtype=np.float64)
    voxel_size = np.array(xform.voxelSize(), dtype=np.float64)
    np.savez(out, coords=coords, values=values, voxel_size=voxel_size, origin=origin,
             background=np.float32(grid.background), grid_class=str(grid.gridClass),
             inactive=np.array(inactive, dtype=np.int32).reshape(-1, 4))
    print(f"{path}: grid {grid.name!r}, class {grid.gridClass}, {len(values)} active voxels, "
          f"voxel size {voxel_size.tolist()}, origin {origin.tolist()}, background "
          f"{grid.background}, {len(inactive)} inactive tiles/voxels")


if __name__ == "__main__":
    main(sys.argv)
