#!/usr/bin/env python3
"""Fetch the Stanford bunny and write it as a binary PLY for `levelset voxelize`.

The mesh comes from the npm registry's `bunny` package (Mikola Lysenko's low-resolution
copy of the Stanford 3D Scanning Repository's bunny, https://graphics.stanford.edu/data/3Dscanrep/):
`npm pack bunny` gives a tarball whose index.js holds `exports.positions` and
`exports.cells` as JSON arrays. The file is not committed: the package says "Public
Domain", but the scan is Stanford's, whose repository asks users to credit it; fetch it
where it is needed.

    python3 docs/data/fetch_bunny.py /tmp/bunny.ply
    cargo run --release --bin levelset -- voxelize /tmp/bunny.ply -o /tmp/bunny.npy

Needs npm (the machine's Node.js) and Python 3; nothing else.
"""

import argparse
import json
import pathlib
import struct
import subprocess
import sys
import tarfile
import tempfile


def fetch(version: str) -> tuple[list, list]:
    """Positions and cells of the `bunny` package, by `npm pack` into a temporary dir."""
    with tempfile.TemporaryDirectory() as tmp:
        spec = f"bunny@{version}" if version else "bunny"
        out = subprocess.run(
            ["npm", "pack", spec, "--silent"],
            cwd=tmp,
            check=True,
            capture_output=True,
            text=True,
        )
        tarball = pathlib.Path(tmp) / out.stdout.strip().splitlines()[-1]
        with tarfile.open(tarball) as tar:
            source = tar.extractfile("package/index.js").read().decode("utf-8")
    arrays = {}
    for name in ("positions", "cells"):
        start = source.index(f"exports.{name}=") + len(f"exports.{name}=")
        # The array is JSON and ends at the end of its line.
        end = source.find("\n", start)
        arrays[name] = json.loads(source[start : end if end >= 0 else None].rstrip(";"))
    return arrays["positions"], arrays["cells"]


def write_ply(path: pathlib.Path, positions: list, cells: list) -> None:
    """Binary little-endian PLY: float x y z, faces as list uchar int."""
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        "comment Stanford bunny (Stanford 3D Scanning Repository), via npm package bunny\n"
        f"element vertex {len(positions)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(cells)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    body = bytearray(header.encode("ascii"))
    for p in positions:
        body += struct.pack("<3f", *p)
    for c in cells:
        body += struct.pack(f"<B{len(c)}i", len(c), *c)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(body)
    tmp.replace(path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("output", type=pathlib.Path, help="the .ply file to write")
    ap.add_argument("--version", default="1.0.1", help="npm package version (default 1.0.1)")
    ap.add_argument("--z-up", action="store_true",
                    help="turn the scan's up axis (+y) to +z, (x, y, z) -> (x, -z, y), as the"
                         " renderer's ground plane expects; a rotation, so orientation is kept")
    args = ap.parse_args()
    positions, cells = fetch(args.version)
    if args.z_up:
        positions = [[x, -z, y] for x, y, z in positions]
    n = len(positions)
    bad = [c for c in cells if len(c) < 3 or min(c) < 0 or max(c) >= n]
    if bad:
        print(f"error: {len(bad)} faces with bad indices, e.g. {bad[0]}", file=sys.stderr)
        return 1
    write_ply(args.output, positions, cells)
    triangles = sum(len(c) - 2 for c in cells)
    print(f"wrote {args.output}: {n} vertices, {len(cells)} faces ({triangles} triangles)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
