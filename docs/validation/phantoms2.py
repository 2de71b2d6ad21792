#!/usr/bin/env python3
"""A second phantom set for `levelset segment`, independent of `levelset phantom`.

    python3 docs/validation/phantoms2.py -o target/validation/phantoms2
    python3 docs/validation/phantoms2.py -o DIR --size 64 --snr 4 --kinds torus gap --scaled

`levelset phantom` (src/segment/phantom.rs) draws piecewise-constant objects (background 100,
object 200) with no blur, adds its own SplitMix64 noise and writes seeds. This generator shares
none of that: numpy and scipy only, its own shapes and its own intensity convention.

Image model, per volume:

* the truth is the object's indicator: a voxel is inside when its centre is inside the shape,
  in world units (spacing included);
* the image is that indicator as float (background 0, object 1), blurred by a Gaussian of
  σ = 1 voxel along each axis (`scipy.ndimage.gaussian_filter`, mode "nearest": a scanner's
  point spread), plus white Gaussian noise of σ = 1/SNR (`numpy.random.default_rng` with a
  fixed seed per kind, SNR and size, so the same arguments give the same files);
* the threshold window is what a user without the truth would pick: the object is the bright
  class, so `lower` = 0.5 (midway between background 0 and object 1) and `upper` = null, an
  OPEN window (everything brighter). For `gap`, whose object is the dark cavity, the window is
  open downwards: `lower` = null, `upper` = 0.5.

Kinds (lengths for --size 128; every length scales by size/128, with small floors so the thin
parts stay at least 2 voxels across):

* `torus`: R = 40, r = 12 about the z axis; ONE seed ball of radius 5 on the tube's centreline;
* `blobs`: five balls of radii 20, 12, 15, 8 and 6 at fixed places; the first two overlap by a
  voxel, as do the third and fourth (touching pairs); one seed per ball (radius r/3, 2..5);
* `tubes`: a helix (radius 30 about the z axis, two turns, pitch 44) as a tube of radius 3, and a
  bent tube of radius 6 along the axis (x = c + 12 sin(π s)); four seeds of radius 2 on the
  helix, two of radius 3 on the bent tube;
* `touching`: a ball of radius 24 and a box whose face cuts a 7-voxel-radius disc out of the
  ball's side (one object whose parts meet through a neck); one seed, in the ball;
* `aniso`: spacing (1, 1, 2.5), size × size × ⌈size/2.5⌉ voxels, an ellipsoid of semi-axes
  (42, 30, 45) mm at the centre, truth in world units; one seed of radius 5;
* `flipped`: the `blobs` volume with its data reversed along i and the affine's first column
  negated, with a non-zero origin (so world x = 12.5 + the blobs' i, y − 20.25, z + 30): the
  same object in the same world place, indexed the other way; its seeds are in its own voxel
  indices;
* `gap`: a bright spherical shell (outer radius 30, thickness 3) around a dark cavity of the
  background's intensity, with a circular hole of radius 6 in the shell (where it crosses +x).
  The truth is the cavity (radius 27); the seed (radius 5) is at its centre. The dark cavity is
  connected to the dark outside through the hole, so GAC (and any flow) seeded inside is
  expected to LEAK: its seeds file says `"expect_leak": true`. The test of a leak guard.

Files, for every kind and SNR, NAME = KIND-snrS (e.g. `torus-snr2`), in the output directory:
NAME.nii.gz (float32, with its spacing and affine), NAME-truth.nii.gz (uint8, same affine) and
NAME-seeds.json, in the format `levelset segment` reads
(`{"seeds": [{"center": [i, j, k], "radius": r}], "lower": L, "upper": U}`, centres in voxel
indices, radii in voxels of the smallest spacing, plus descriptive keys `kind`, `snr`, `size`,
`spacing`, `noise_seed`, `expect_leak`). With --scaled, every volume is ALSO written as
1000·I − 500 (NAME-x1000.nii.gz, with NAME-x1000-truth.nii.gz and NAME-x1000-seeds.json whose
window is mapped the same way, 0.5 → 0): a segmentation should not depend on the units. The
directory is thus also a batch for `levelset segment DIR -o OUTDIR`.

Python 3.9+, numpy, scipy and nibabel (for the NIfTI files).
"""

import argparse
import json
import math
import pathlib
import sys

import numpy as np
from scipy import ndimage, spatial

KINDS = ["torus", "blobs", "tubes", "touching", "aniso", "flipped", "gap"]
# A fixed base of the noise seed per kind (the seed also mixes in the SNR and size).
KIND_SEED = {k: 1000 + 17 * i for i, k in enumerate(KINDS)}
THRESHOLD_MID = 0.5  # midway between background 0 and object 1
SCALE, OFFSET = 1000.0, -500.0


class Volume:
    """One phantom before noise: the truth indicator, its spacing and affine, the seeds, the
    window and whether a leak is expected."""

    def __init__(self, truth, spacing, seeds, lower=THRESHOLD_MID, upper=None, affine=None,
                 expect_leak=False, note=""):
        self.truth = truth.astype(bool)
        self.spacing = tuple(float(s) for s in spacing)
        self.affine = np.diag(list(self.spacing) + [1.0]) if affine is None else affine
        self.seeds = seeds
        self.lower, self.upper = lower, upper
        self.expect_leak = expect_leak
        self.note = note


def grid(dims, spacing):
    """World coordinates of the voxel centres (x, y, z), arrays indexed [i, j, k] (i along x),
    and the world centre of the volume."""
    axes = [np.arange(d, dtype=np.float64) * s for d, s in zip(dims, spacing)]
    x, y, z = np.meshgrid(*axes, indexing="ij", sparse=True)
    centre = np.array([(d - 1) * s / 2.0 for d, s in zip(dims, spacing)])
    return x, y, z, centre


def seed(center, radius):
    return {"center": [round(float(c), 3) for c in center], "radius": round(float(radius), 3)}


def ball(x, y, z, c, r):
    return (x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2 <= r * r


def make_torus(n):
    f = n / 128.0
    x, y, z, c = grid((n, n, n), (1, 1, 1))
    big, small = 40 * f, 12 * f
    truth = (np.hypot(x - c[0], y - c[1]) - big) ** 2 + (z - c[2]) ** 2 <= small * small
    # One seed on the centreline, at angle 0 (on +x of the centre).
    return Volume(truth, (1, 1, 1), [seed((c[0] + big, c[1], c[2]), max(5 * f, 2.0))])


# Blobs at 128: (centre, radius). 0-1 and 2-3 overlap by one voxel (touching pairs).
BLOBS = [((40, 40, 64), 20), ((71, 40, 64), 12), ((88, 88, 44), 15), ((88, 110, 44), 8),
         ((40, 94, 92), 6)]


def make_blobs(n):
    f = n / 128.0
    x, y, z, _ = grid((n, n, n), (1, 1, 1))
    truth = np.zeros((n, n, n), bool)
    seeds = []
    for c, r in BLOBS:
        cc = [v * f for v in c]
        truth |= ball(x, y, z, cc, r * f)
        seeds.append(seed(cc, min(max(r * f / 3.0, 2.0), 5.0)))
    return Volume(truth, (1, 1, 1), seeds)


def tube_mask(points, radius, dims):
    """Voxels whose centre lies within `radius` of a densely sampled centre line (the sampling
    step, 0.1 voxel, makes the distance exact to ~1e-3 voxel); the ends are round caps."""
    tree = spatial.cKDTree(points)
    lo = np.maximum(np.floor(points.min(axis=0) - radius - 1), 0).astype(int)
    hi = np.minimum(np.ceil(points.max(axis=0) + radius + 2), dims).astype(int)
    sub = np.stack(np.meshgrid(*(np.arange(a, b) for a, b in zip(lo, hi)), indexing="ij"), -1)
    d, _ = tree.query(sub.reshape(-1, 3).astype(np.float64), distance_upper_bound=radius + 1e-9)
    mask = np.zeros(dims, bool)
    mask[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]] = (d <= radius).reshape(sub.shape[:3])
    return mask


def polyline(curve, t0, t1, step=0.1):
    """Points of a parametric curve(t) spaced at most `step` apart (by arc length)."""
    t = np.linspace(t0, t1, 64)
    length = np.sum(np.linalg.norm(np.diff(curve(t), axis=0), axis=1))
    return curve(np.linspace(t0, t1, int(math.ceil(length / step)) + 1))


def make_tubes(n):
    f = n / 128.0
    dims = (n, n, n)
    c = (n - 1) / 2.0
    rad, z0, z1 = 30 * f, 20 * f, 108 * f  # helix radius, start and end heights: two turns

    def helix(t):  # t in [0, 1]
        a = 4 * math.pi * t
        return np.stack([c + rad * np.cos(a), c + rad * np.sin(a), z0 + (z1 - z0) * t], -1)

    def bent(t):  # t in [0, 1]
        zz = 12 * f + (104 * f) * t
        return np.stack([c + 12 * f * np.sin(math.pi * t), np.full_like(t, c), zz], -1)

    thin, thick = max(3 * f, 2.0), max(6 * f, 3.0)
    truth = tube_mask(polyline(helix, 0, 1), thin, dims) | tube_mask(polyline(bent, 0, 1), thick,
                                                                        dims)
    seeds = [seed(helix(np.array([t]))[0], max(2 * f, 1.5)) for t in (0.125, 0.375, 0.625, 0.875)]
    seeds += [seed(bent(np.array([t]))[0], max(3 * f, 2.0)) for t in (0.25, 0.75)]
    return Volume(truth, (1, 1, 1), seeds)


def make_touching(n):
    f = n / 128.0
    x, y, z, c = grid((n, n, n), (1, 1, 1))
    r = 24 * f
    bc = (44 * f, c[1], c[2])
    # The box's face at x = bc + 23·f cuts a disc of radius sqrt(24² − 23²)·f ≈ 7·f from the ball.
    x0, x1 = bc[0] + 23 * f, 104 * f
    half = 20 * f
    box = (x >= x0) & (x <= x1) & (np.abs(y - c[1]) <= half) & (np.abs(z - c[2]) <= half)
    truth = ball(x, y, z, bc, r) | box
    return Volume(truth, (1, 1, 1), [seed(bc, max(5 * f, 2.0))],
                  note="ball and box meet through a neck of radius ~7")


def make_aniso(n):
    spacing = (1.0, 1.0, 2.5)
    dims = (n, n, int(math.ceil(n / 2.5)))
    f = n / 128.0
    x, y, z, c = grid(dims, spacing)
    a, b, cz = 42 * f, 30 * f, 45 * f
    truth = ((x - c[0]) / a) ** 2 + ((y - c[1]) / b) ** 2 + ((z - c[2]) / cz) ** 2 <= 1.0
    centre_vox = [c[i] / spacing[i] for i in range(3)]
    # Radius in voxels of the smallest spacing (1 mm): 5 mm.
    return Volume(truth, spacing, [seed(centre_vox, max(5 * f, 2.0))])


def make_flipped(n):
    v = make_blobs(n)
    truth = v.truth[::-1].copy()
    affine = np.array([[-1.0, 0, 0, (n - 1) + 12.5],
                       [0, 1.0, 0, -20.25],
                       [0, 0, 1.0, 30.0],
                       [0, 0, 0, 1.0]])
    seeds = [seed((n - 1 - s["center"][0], s["center"][1], s["center"][2]), s["radius"])
             for s in v.seeds]
    return Volume(truth, (1, 1, 1), seeds, affine=affine,
                  note="blobs reversed along i, affine x column negated, origin non-zero")


def make_gap(n):
    f = n / 128.0
    x, y, z, c = grid((n, n, n), (1, 1, 1))
    outer, thick, hole = 30 * f, max(3 * f, 2.0), max(6 * f, 3.0)
    r2 = (x - c[0]) ** 2 + (y - c[1]) ** 2 + (z - c[2]) ** 2
    inner = outer - thick
    shell = (r2 <= outer * outer) & (r2 > inner * inner)
    # The hole: the shell's voxels within `hole` of the +x half-axis through the centre.
    in_hole = ((y - c[1]) ** 2 + (z - c[2]) ** 2 <= hole * hole) & (x > c[0])
    shell &= ~in_hole
    cavity = r2 <= inner * inner
    v = Volume(cavity, (1, 1, 1), [seed(c, max(5 * f, 2.0))], lower=None, upper=THRESHOLD_MID,
               expect_leak=True,
               note="dark cavity inside a bright shell with a hole: flows seeded inside leak")
    v.bright = shell  # the image's bright part is the shell, not the truth
    return v


MAKERS = {"torus": make_torus, "blobs": make_blobs, "tubes": make_tubes,
          "touching": make_touching, "aniso": make_aniso, "flipped": make_flipped,
          "gap": make_gap}


def noise_seed(kind, snr, size):
    return [KIND_SEED[kind], int(round(snr * 1000)), int(size)]


def render(vol, kind, snr, size):
    """The image: indicator (0/1) blurred by σ = 1 voxel, plus N(0, 1/SNR) noise (float32)."""
    bright = getattr(vol, "bright", vol.truth).astype(np.float64)
    if kind == "flipped":
        # The same noise as `blobs`, reversed with the data: only the indexing differs.
        rng = np.random.default_rng(noise_seed("blobs", snr, size))
        blurred = ndimage.gaussian_filter(bright[::-1], 1.0, mode="nearest")[::-1]
        noise = rng.standard_normal(bright.shape)[::-1]
    else:
        rng = np.random.default_rng(noise_seed(kind, snr, size))
        blurred = ndimage.gaussian_filter(bright, 1.0, mode="nearest")
        noise = rng.standard_normal(bright.shape)
    return (blurred + noise / snr).astype(np.float32)


def write_nifti(path, data, affine):
    import nibabel as nib

    img = nib.Nifti1Image(data, affine)
    img.header.set_xyzt_units("mm")
    img.set_qform(affine, code=1)
    img.set_sform(affine, code=1)
    tmp = path.with_name(f".{path.name}.tmp.nii.gz")
    nib.save(img, str(tmp))
    tmp.replace(path)


def seeds_doc(vol, kind, snr, size, lower, upper, scaled):
    return {"seeds": vol.seeds, "lower": lower, "upper": upper, "kind": kind, "snr": snr,
            "size": size, "dims": list(vol.truth.shape), "spacing": list(vol.spacing),
            "noise_seed": noise_seed("blobs" if kind == "flipped" else kind, snr, size),
            "intensity": "1000*I-500" if scaled else "I (background 0, object 1)",
            "expect_leak": vol.expect_leak, "note": vol.note,
            "generator": "docs/validation/phantoms2.py"}


def dump_json(doc):
    """JSON with one top-level key per line and each seed on one line."""
    lines = []
    for k, v in doc.items():
        if k == "seeds":
            body = ",\n".join("  " + json.dumps(s) for s in v)
            lines.append(f' "seeds": [\n{body}\n ]')
        else:
            lines.append(f" {json.dumps(k)}: {json.dumps(v)}")
    return "{\n" + ",\n".join(lines) + "\n}\n"


def scale_window(v):
    return None if v is None else SCALE * v + OFFSET


def generate(out, size, snrs, kinds, scaled, log=print):
    """Write the set; returns the names written (NAME, NAME-x1000 ...)."""
    out.mkdir(parents=True, exist_ok=True)
    names = []
    for kind in kinds:
        vol = MAKERS[kind](size)
        truth = vol.truth.astype(np.uint8)
        for snr in snrs:
            name = f"{kind}-snr{snr:g}"
            image = render(vol, kind, snr, size)
            variants = [(name, image, vol.lower, vol.upper, False)]
            if scaled:
                variants.append((f"{name}-x1000", (SCALE * image.astype(np.float64) + OFFSET)
                                 .astype(np.float32), scale_window(vol.lower),
                                 scale_window(vol.upper), True))
            for nm, data, lower, upper, sc in variants:
                write_nifti(out / f"{nm}.nii.gz", data, vol.affine)
                write_nifti(out / f"{nm}-truth.nii.gz", truth, vol.affine)
                doc = seeds_doc(vol, kind, snr, size, lower, upper, sc)
                (out / f"{nm}-seeds.json").write_text(dump_json(doc))
                names.append(nm)
            log(f"{name}: {'×'.join(map(str, truth.shape))}, spacing {vol.spacing},"
                f" {int(truth.sum())} truth voxels, {len(vol.seeds)} seed(s)"
                + (", expect leak" if vol.expect_leak else ""))
    return names


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--output", type=pathlib.Path, required=True, help="output directory")
    ap.add_argument("--size", type=int, default=128, help="n of the n³ volumes (default 128)")
    ap.add_argument("--snr", type=float, nargs="+", default=[2.0, 3.0, 4.0],
                    help="SNR values, contrast 1 over noise σ (default 2 3 4)")
    ap.add_argument("--kinds", nargs="+", default=KINDS, choices=KINDS, help="kinds (default all)")
    ap.add_argument("--scaled", action="store_true",
                    help="also write every volume as 1000·I − 500 (NAME-x1000.*)")
    args = ap.parse_args()
    if args.size < 32:
        sys.exit("error: --size must be at least 32")
    generate(args.output, args.size, args.snr, args.kinds, args.scaled)
    return 0


if __name__ == "__main__":
    sys.exit(main())
