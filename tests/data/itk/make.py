"""Regenerates the reference files of this directory with SimpleITK (2.5.7, ITK 5.4):

    python tests/data/itk/make.py

Each image is small, anisotropic, off the origin and obliquely oriented; reference.json
holds what SimpleITK reads from each file: size, spacing, origin, direction, the voxel
index -> physical (LPS) matrix and the voxel values, x fastest.
"""

import json
import math
import pathlib

import numpy as np
import SimpleITK as sitk

HERE = pathlib.Path(__file__).resolve().parent


def rotation(a, b, c):
    """A proper rotation from three angles (about z, then y, then x)."""
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rx = np.array([[1, 0, 0], [0, math.cos(c), -math.sin(c)], [0, math.sin(c), math.cos(c)]])
    return rx @ ry @ rz


def image(array, spacing, origin, direction):
    im = sitk.GetImageFromArray(array)
    im.SetSpacing(spacing)
    im.SetOrigin(origin)
    im.SetDirection(tuple(np.asarray(direction, dtype=float).ravel()))
    return im


def describe(path):
    im = sitk.ReadImage(str(path))
    d = im.GetDimension()
    corner = im.TransformContinuousIndexToPhysicalPoint([0.0] * d)
    columns = []
    for axis in range(d):
        idx = [0.0] * d
        idx[axis] = 1.0
        p = im.TransformContinuousIndexToPhysicalPoint(idx)
        columns.append([p[r] - corner[r] for r in range(d)])
    a = [[columns[c][r] for c in range(d)] + [corner[r]] for r in range(d)]
    return {
        "size": list(im.GetSize()),
        "spacing": list(im.GetSpacing()),
        "origin": list(im.GetOrigin()),
        "direction": list(im.GetDirection()),
        "index_to_world": a,
        "pixel_type": im.GetPixelIDTypeAsString(),
        "values": sitk.GetArrayFromImage(im).ravel().astype(float).tolist(),
    }


def main():
    rng = np.random.default_rng(5)
    shape = (3, 4, 5)  # (z, y, x)
    ramp = (np.arange(60).reshape(shape) * 37 % 61 - 30).astype(np.int16) * 100
    spacing, origin = (0.7, 0.9, 2.5), (-12.5, 30.25, 7.0)
    proper = rotation(0.3, -0.2, 0.5)
    improper = proper @ np.diag([1.0, -1.0, 1.0])
    ct = image(ramp, spacing, origin, proper)
    floats = image(rng.normal(size=shape).astype(np.float32), spacing, origin, improper)
    words = image((ramp.astype(np.int32) + 4000).astype(np.uint16), spacing, origin, proper)
    mask = image((ramp > 0).astype(np.uint8), spacing, origin, proper)
    a = 0.4
    slice_ = image(
        (np.arange(24).reshape(4, 6) * 7 % 256).astype(np.uint8),
        (0.5, 1.25),
        (3.0, -4.0),
        [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]],
    )
    writes = [
        (ct, "ct.mha", False),
        (ct, "ct-zlib.mha", True),
        (floats, "floats.mhd", False),  # + floats.raw
        (mask, "mask-zlib.mhd", True),  # + mask-zlib.zraw
        (ct, "ct.nrrd", False),
        (ct, "ct-gzip.nrrd", True),
        (words, "words.nhdr", True),  # + words.raw.gz
        (slice_, "slice.mha", False),
        (slice_, "slice.nrrd", False),
    ]
    for im, name, compress in writes:
        sitk.WriteImage(im, str(HERE / name), compress)
    # The same image in RAS: a NRRD header written by hand from ct.nrrd's, x and y negated.
    text = (HERE / "ct.nrrd").read_bytes()
    head, data = text.split(b"\n\n", 1)
    lines = []
    for line in head.decode().split("\n"):
        if line.startswith("space:"):
            line = "space: right-anterior-superior"
        elif line.startswith("space directions:") or line.startswith("space origin:"):
            key, vectors = line.split(": ", 1)
            out = []
            for v in vectors.split(" "):
                x, y, z = (float(c) for c in v.strip("()").split(","))
                out.append(f"({repr(-x)},{repr(-y)},{repr(z)})")
            line = key + ": " + " ".join(out)
        lines.append(line)
    (HERE / "ct-ras.nrrd").write_bytes("\n".join(lines).encode() + b"\n\n" + data)
    names = [name for _, name, _ in writes] + ["ct-ras.nrrd"]
    reference = {name: describe(HERE / name) for name in names}
    (HERE / "reference.json").write_text(json.dumps(reference, indent=1) + "\n")


if __name__ == "__main__":
    main()
