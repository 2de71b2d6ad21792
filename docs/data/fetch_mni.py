#!/usr/bin/env python3
"""Fetch the MNI ICBM152 2009a template and write white-matter truth, seeds and thresholds for
`levelset segment`.

The template ships inside nilearn's wheel (PyPI package `nilearn`, BSD licence; the template
itself is © McConnell Brain Imaging Centre, Montreal Neurological Institute, free to use with
credit: Fonov et al., NeuroImage 2011 and 2009): `pip download --no-deps nilearn==0.14.1` gives
the wheel, whose nilearn/datasets/data/ holds mni_icbm152_{t1,wm,gm}_tal_nlin_sym_09a_converted
.nii.gz, the symmetric 2009a template at 1 mm (197 × 233 × 189 voxels, uint8): the T1 (0–255)
and the white- and grey-matter probability maps. Those maps are uint8 WITHOUT a scale factor:
probability = value / 255. The files are not committed; fetch them where they are needed.

    python3 docs/data/fetch_mni.py                      # into target/validation/mni
    python3 docs/data/fetch_mni.py -o DIR --wheel nilearn-0.14.1-py3-none-any.whl
    levelset segment target/validation/mni/mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz \\
        --method threshold --seed 69,126,105:3 --seed 127,126,105:3 --lower 196 --upper 255 \\
        -o /tmp/wm.nii.gz --truth target/validation/mni/wm-truth.nii.gz --json

Written into the output directory (default target/validation/mni):

* the three template files, as they are in the wheel;
* wm-truth.nii.gz and gm-truth.nii.gz: wm (gm) probability > 0.5, uint8, the T1's affine;
* wm-seeds-A.json, wm-seeds-B.json, wm-seeds-C.json, in the seeds-file format of
  `levelset segment` ({"seeds": [{"center": [i, j, k], "radius": 3}], "lower": L, "upper": U},
  voxel indices; plus descriptive keys: world coordinates, the T1 at each seed, the rule);
* t1-flipx.nii.gz: the T1 with its data reversed along i and the affine's first column negated
  (origin moved so every voxel keeps its world coordinates), with t1-flipx-truth.nii.gz (the
  white-matter truth flipped the same way) and t1-flipx-seeds-{A,B,C}.json (i → n−1−i): the
  same segmentation problem in another index order, to test affine conventions.

The seeds are chosen from the white-matter probability map only (not from the truth mask's
boundary, and not tuned on any result): "core" = wm probability > 0.9, d = its Euclidean
distance map (voxels); the hemispheres are world x < 0 and x > 0. In each hemisphere:

* set A: the core voxel of largest d (deep white matter; the corona radiata at z ≈ 33 mm);
* set B: the core voxel of largest d at least 10 mm above set A's (world z ≥ z_A + 10): the
  centrum semiovale above the ventricles, some 16 mm from A;
* set C: the core voxel of largest d at least 20 mm in front of A (y ≥ y_A + 20: frontal white
  matter) and the one at least 20 mm behind it (y ≤ y_A − 20: parieto-occipital), 4 seeds.

Ties go to the first voxel in array order, so the choice is deterministic. Every seed ball
(radius 3) lies inside the core (d ≥ 4 is checked).

The threshold window is what a user without the truth picks: white matter is the brightest
tissue of a T1, so the window is open upwards (upper = 255, the T1's largest possible value),
and lower = midway between the two classes the histogram shows, the same "midway between the
classes" rule as the phantoms' 0.5 (docs/validation/phantoms2.py). The histogram is that of
the head (T1 > 0) in 1-unit bins, smoothed by a Gaussian of σ = 2 bins; the white-matter peak
is its local maximum nearest the median T1 in the seed balls of set A, the grey-matter peak
the highest local maximum more than 10 below it; lower = their mean, rounded (one window for
every set). On this T1: seeds' median
221, peaks 172 and 220, lower = 196 (the histogram's valley between them is at 203; a
literature window [194, 255] was used in an earlier report). The rule "seeds' median − 3
robust σ" is recorded too but not used: the template is an average of many brains, so the
white matter around the seeds is nearly flat (robust σ ≈ 1.5) and that rule gives ≈ 217,
above the median white-matter voxel (215).

Needs pip (for the download), numpy, scipy and nibabel: run it with the benchmark's venv
(target/segbench-venv, see docs/validation_bench.py) or any Python that has them.
"""

import argparse
import json
import pathlib
import subprocess
import sys
import tempfile
import zipfile

ROOT = pathlib.Path(__file__).resolve().parent.parent.parent
VERSION = "0.14.1"
MEMBER = "nilearn/datasets/data/mni_icbm152_{}_tal_nlin_sym_09a_converted.nii.gz"
T1, WM, GM = (MEMBER.format(k).rsplit("/", 1)[1] for k in ("t1", "wm", "gm"))
SEED_RADIUS = 3.0
CORE = 0.9  # wm probability of the core the seeds are placed in
HIST_SIGMA = 2.0  # bins of the histogram smoothing
PEAK_GAP = 10  # the grey-matter peak lies more than this below the white-matter peak


def fetch(version: str, wheel, out: pathlib.Path) -> None:
    """Extract the three template files from nilearn's wheel (`pip download` into a
    temporary dir, unless `wheel` is given) into `out`."""
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        if wheel is None:
            subprocess.run(
                [sys.executable, "-m", "pip", "download", "--no-deps", "--only-binary=:all:",
                 "--disable-pip-version-check", "-q", "-d", tmp, f"nilearn=={version}"],
                check=True,
            )
            wheel = next(pathlib.Path(tmp).glob("nilearn-*.whl"))
        with zipfile.ZipFile(wheel) as z:
            for kind in ("t1", "wm", "gm"):
                member = MEMBER.format(kind)
                target = out / member.rsplit("/", 1)[1]
                part = target.with_name(f".{target.name}.tmp")
                part.write_bytes(z.read(member))
                part.replace(target)


def save(path: pathlib.Path, data, affine, header=None) -> None:
    import nibabel as nib

    img = nib.Nifti1Image(data, affine, header=header)
    img.header.set_xyzt_units("mm")
    if header is None:
        img.set_qform(affine, code=1)
        img.set_sform(affine, code=1)
    else:  # the template's own codes (qform 0, sform 2)
        img.set_qform(affine, code=int(header["qform_code"]))
        img.set_sform(affine, code=int(header["sform_code"]))
    tmp = path.with_name(f".{path.name}.tmp.nii.gz")
    nib.save(img, str(tmp))
    tmp.replace(path)


def choose_seeds(wm_prob, affine):
    """Sets A, B, C (voxel indices) by the rule of the module's docstring."""
    import numpy as np
    from scipy import ndimage

    core = wm_prob > CORE
    dist = ndimage.distance_transform_edt(core)
    ii, jj, kk = np.indices(core.shape, sparse=True)
    world = [affine[r, 0] * ii + affine[r, 1] * jj + affine[r, 2] * kk + affine[r, 3]
             for r in range(3)]
    x, y, z = world

    def deepest(cond):
        d = np.where(cond, dist, 0.0)
        idx = np.unravel_index(int(np.argmax(d)), d.shape)
        if d[idx] < SEED_RADIUS + 1:
            sys.exit(f"error: no core voxel deep enough for a seed ({d[idx]:.1f})")
        return tuple(int(v) for v in idx)

    def pos(idx, axis):
        return float(affine[axis, :3] @ np.array(idx, dtype=np.float64) + affine[axis, 3])

    sets = {}
    sets["A"] = [deepest(x < 0), deepest(x > 0)]
    a_y = [pos(p, 1) for p in sets["A"]]
    a_z = [pos(p, 2) for p in sets["A"]]
    sets["B"] = [deepest((x < 0) & (z >= a_z[0] + 10)), deepest((x > 0) & (z >= a_z[1] + 10))]
    sets["C"] = [deepest((x < 0) & (y >= a_y[0] + 20)), deepest((x > 0) & (y >= a_y[1] + 20)),
                 deepest((x < 0) & (y <= a_y[0] - 20)), deepest((x > 0) & (y <= a_y[1] - 20))]
    depth = {p: float(dist[p]) for s in sets.values() for p in s}
    return sets, depth


def seed_intensities(t1, seeds):
    """T1 values inside the seed balls (radius SEED_RADIUS voxels)."""
    import numpy as np

    ii, jj, kk = np.indices(t1.shape, sparse=True)
    inside = np.zeros(t1.shape, bool)
    for p in seeds:
        inside |= (ii - p[0]) ** 2 + (jj - p[1]) ** 2 + (kk - p[2]) ** 2 <= SEED_RADIUS ** 2
    return t1[inside]


def window(t1, seeds):
    """lower = midway between the white- and grey-matter peaks of the head's T1 histogram;
    upper = 255. Returns (lower, upper, figures)."""
    import numpy as np
    from scipy import ndimage

    values = seed_intensities(t1, seeds)
    median = float(np.median(values))
    robust_sd = float(1.4826 * np.median(np.abs(values - median)))
    hist = np.bincount(t1[t1 > 0].astype(np.int64).ravel(), minlength=256).astype(np.float64)
    smooth = ndimage.gaussian_filter1d(hist, HIST_SIGMA)
    peaks = [v for v in range(1, len(smooth) - 1)
             if smooth[v] > smooth[v - 1] and smooth[v] >= smooth[v + 1]]
    wm_peak = min(peaks, key=lambda p: (abs(p - median), p))
    below = [p for p in peaks if p < wm_peak - PEAK_GAP]
    if not below:
        sys.exit("error: the T1 histogram has no peak below the white matter's")
    gm_peak = max(below, key=lambda p: smooth[p])
    valley = gm_peak + int(np.argmin(smooth[gm_peak:wm_peak + 1]))
    lower = float(round((gm_peak + wm_peak) / 2.0))
    upper = 255.0
    figures = {"seed_median": median, "seed_robust_sd": robust_sd,
               "seed_min": float(values.min()), "seed_max": float(values.max()),
               "median_minus_3sd": median - 3 * robust_sd, "wm_peak": wm_peak,
               "gm_peak": gm_peak, "valley": valley, "t1_min": float(t1.min()),
               "t1_max": float(t1.max())}
    return lower, upper, figures


def seeds_doc(seeds, lower, upper, figures, t1, affine, depth, name, flipped_from=None):
    import numpy as np

    world = [[float(v) for v in (affine @ np.array([*p, 1.0]))[:3]] for p in seeds]
    return {
        "seeds": [{"center": [int(v) for v in p], "radius": SEED_RADIUS} for p in seeds],
        "lower": lower,
        "upper": upper,
        "set": name,
        "world": world,
        "t1_at_seeds": [float(t1[p]) for p in seeds],
        "depth_voxels": [round(depth[q], 3) for q in (flipped_from or seeds)],
        "window": figures,
        "rule": "seeds: deepest voxels of wm probability > 0.9 (see docs/data/fetch_mni.py);"
                " lower: midway between the grey- and white-matter peaks of the T1 histogram;"
                " upper: 255 (open: the T1's largest value)",
    }


def dump_json(path: pathlib.Path, doc) -> None:
    """Writes `doc` as the phantom generator writes its seeds files (one seed per line)."""
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "validation"))
    import phantoms2  # noqa: E402  (docs/validation/phantoms2.py)

    path.write_text(phantoms2.dump_json(doc))


def derive(out: pathlib.Path, log=print) -> dict:
    """Truth masks, seed sets and the flipped copy from the three template files in `out`."""
    import nibabel as nib
    import numpy as np

    t1_img = nib.load(str(out / T1))
    t1 = np.asanyarray(t1_img.dataobj)
    affine = t1_img.affine
    probs = {}
    for name, fname in (("wm", WM), ("gm", GM)):
        img = nib.load(str(out / fname))
        if img.shape != t1.shape or not np.allclose(img.affine, affine):
            sys.exit(f"error: {fname} does not match the T1's grid")
        raw = np.asanyarray(img.dataobj)
        # uint8 without a scale factor: probability = value / 255.
        probs[name] = raw.astype(np.float64) / 255.0 if raw.dtype == np.uint8 else raw
        save(out / f"{name}-truth.nii.gz", (probs[name] > 0.5).astype(np.uint8), affine)
    wm_truth = (probs["wm"] > 0.5).astype(np.uint8)

    sets, depth = choose_seeds(probs["wm"], affine)
    lower, upper, figures = window(t1, sets["A"])
    n = t1.shape[0]
    flip = np.diag([-1.0, 1.0, 1.0, 1.0])
    flip[0, 3] = n - 1
    affine_flip = affine @ flip  # voxel i' = n−1−i has the world position of voxel i
    for name, seeds in sets.items():
        dump_json(out / f"wm-seeds-{name}.json",
                  seeds_doc(seeds, lower, upper, figures, t1, affine, depth, name))
        mirrored = [(n - 1 - p[0], p[1], p[2]) for p in seeds]
        dump_json(out / f"t1-flipx-seeds-{name}.json",
                  seeds_doc(mirrored, lower, upper, figures, t1[::-1], affine_flip, depth,
                            name, flipped_from=seeds))
        log(f"wm seeds {name}: " + "; ".join(
            f"({p[0]},{p[1]},{p[2]}) T1 {int(t1[p])}" for p in seeds))
    save(out / "t1-flipx.nii.gz", np.ascontiguousarray(t1[::-1]), affine_flip,
         header=t1_img.header)
    save(out / "t1-flipx-truth.nii.gz", np.ascontiguousarray(wm_truth[::-1]), affine_flip)
    log(f"T1 range {figures['t1_min']:g}..{figures['t1_max']:g}; seeds' median"
        f" {figures['seed_median']:g} (robust σ {figures['seed_robust_sd']:.2f}); histogram"
        f" peaks gm {figures['gm_peak']}, wm {figures['wm_peak']}, valley {figures['valley']};"
        f" window [{lower:g}, {upper:g}]")
    log(f"truth voxels: wm {int(wm_truth.sum())}, gm {int((probs['gm'] > 0.5).sum())}")
    return {"sets": sets, "lower": lower, "upper": upper, "figures": figures}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--output", type=pathlib.Path,
                    default=ROOT / "target" / "validation" / "mni",
                    help="output directory (default target/validation/mni)")
    ap.add_argument("--version", default=VERSION, help=f"nilearn version (default {VERSION})")
    ap.add_argument("--wheel", type=pathlib.Path,
                    help="use this nilearn wheel instead of downloading one")
    args = ap.parse_args()
    if args.wheel is not None and not args.wheel.is_file():
        print(f"error: {args.wheel} does not exist", file=sys.stderr)
        return 1
    fetch(args.version, args.wheel, args.output)
    derive(args.output)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
