#!/usr/bin/env python3
"""2-D segmentation with `sparse_levelset.segment` beside scikit-image's morphological
snakes, on scikit-image's own images and on a noisy disk, in one process (ratios within
one run; the machines are shared).

    target/py-venv/bin/python docs/segment2d_bench.py                 # print the table
    target/py-venv/bin/python docs/segment2d_bench.py --json FILE     # and the records

Needs the package, scikit-image and SciPy (`bash scripts/test.sh` makes target/py-venv).
Every time is the fastest of --repeat calls; ours runs on all CPUs (its default).

Cases, scikit-image's side as its gallery example "Morphological Snakes" calls it:

* camera(): `morphological_chan_vese(image, num_iter=35, init_level_set=
  checkerboard_level_set(image.shape, 6), smoothing=3)`; ours: `segment(image,
  "chan-vese", init_mask=<the same checkerboard>)`, and from one seed at the image's centre.
  Reference: Otsu's threshold, the two-phase intensity partition that the piecewise-constant
  Chan–Vese model approximates. A photograph has no truth: this Dice measures agreement
  with that partition, taking either phase as the object (a checkerboard start may end with
  either phase inside).
* coins(): `morphological_geodesic_active_contour(inverse_gaussian_gradient(image),
  num_iter=230, init_level_set=<1 on image[10:-10, 10:-10]>, smoothing=1, balloon=-1,
  threshold=0.69)`; ours: `segment(image, "gac", init_mask=<the same rectangle>,
  propagation_scaling=-1)`, the contour shrinking from the rectangle as balloon −1 makes it.
  Reference: scikit-image's own segmentation of this image in its gallery example
  "Comparing edge-based and region-based segmentation" (watershed of the Sobel elevation
  map from the markers image < 30 and image > 150, holes filled).
* noisy disk: 256², a disk of radius 60 at the centre, 1 inside and 0 outside, Gaussian
  noise of standard deviation 0.5 (SNR 2, NumPy's default_rng(1)); truth: the disk.
  scikit-image's Chan–Vese and GAC as for the two images above (GAC with
  `threshold="auto"`, the image being noisy); ours Chan–Vese from the checkerboard and from
  a seed at the centre, GAC from the seed.
"""

import argparse
import datetime
import json
import platform
import sys
import warnings
from pathlib import Path

import numpy as np
import scipy.ndimage as ndi
import skimage
from skimage import data, filters, img_as_float
from skimage import segmentation as seg

import sparse_levelset as sl

sys.path.insert(0, str(Path(__file__).resolve().parent))
from python_bench import best_of, machine  # noqa: E402  (the fastest of several calls)


def dice(a, b):
    a, b = a.astype(bool), b.astype(bool)
    return 2.0 * (a & b).sum() / max(a.sum() + b.sum(), 1)


def camera():
    image = img_as_float(data.camera())
    return image, image > filters.threshold_otsu(image), True


def coins():
    image = data.coins()
    markers = np.zeros_like(image)
    markers[image < 30] = 1
    markers[image > 150] = 2
    labels = seg.watershed(filters.sobel(image), markers)
    return img_as_float(image), ndi.binary_fill_holes(labels == 2), False


def noisy_disk(n=256, radius=60.0, sigma=0.5):
    y, x = np.mgrid[:n, :n]
    truth = (x - (n - 1) / 2) ** 2 + (y - (n - 1) / 2) ** 2 < radius**2
    rng = np.random.default_rng(1)
    return truth + rng.normal(0.0, sigma, truth.shape), truth, False


def theirs_cv(image):
    init = seg.checkerboard_level_set(image.shape, 6)
    return seg.morphological_chan_vese(image, num_iter=35, init_level_set=init, smoothing=3)


def theirs_gac(image, threshold):
    gimage = seg.inverse_gaussian_gradient(image)
    init = np.zeros(image.shape, dtype=np.int8)
    init[10:-10, 10:-10] = 1
    return seg.morphological_geodesic_active_contour(
        gimage, num_iter=230, init_level_set=init, smoothing=1, balloon=-1, threshold=threshold
    )


def ours(image, method, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = sl.segment(image.astype(np.float32), method, **kw)
    mask = np.asarray(r.mask).reshape(image.shape).astype(bool)
    note = f"{r.report['iterations']} iterations, stop: {r.report['stop']}"
    if caught:
        note += f" ({caught[0].category.__name__})"
    return mask, note


def cases():
    centre = lambda im: [[(im.shape[1] - 1) / 2, (im.shape[0] - 1) / 2, 0]]
    rect = lambda im: np.pad(np.ones((im.shape[0] - 20, im.shape[1] - 20), bool), 10)
    checker = lambda im: seg.checkerboard_level_set(im.shape, 6).astype(bool)
    return {
        "camera": (camera, [
            ("morphological_chan_vese", lambda im: (theirs_cv(im), "35 iterations")),
            ("chan-vese, checkerboard", lambda im: ours(im, "chan-vese", init_mask=checker(im))),
            ("chan-vese, centre seed", lambda im: ours(im, "chan-vese", seeds=centre(im))),
        ]),
        "coins": (coins, [
            ("morphological_geodesic_active_contour",
             lambda im: (theirs_gac(im, 0.69), "230 iterations")),
            ("gac, shrinking from the rectangle",
             lambda im: ours(im, "gac", init_mask=rect(im), propagation_scaling=-1.0)),
        ]),
        "noisy disk": (noisy_disk, [
            ("morphological_chan_vese", lambda im: (theirs_cv(im), "35 iterations")),
            ("morphological_geodesic_active_contour",
             lambda im: (theirs_gac(im, "auto"), "230 iterations")),
            ("chan-vese, checkerboard", lambda im: ours(im, "chan-vese", init_mask=checker(im))),
            ("chan-vese, centre seed", lambda im: ours(im, "chan-vese", seeds=centre(im))),
            ("gac, centre seed", lambda im: ours(im, "gac", seeds=centre(im))),
        ]),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--json", type=Path, help="also write the records to this JSON file")
    a = ap.parse_args()
    records = []
    for name, (make, runs) in cases().items():
        image, truth, either = make()
        for tool, run in runs:
            seconds, (mask, note) = best_of(a.repeat, lambda: run(image))
            mask = np.asarray(mask).astype(bool)
            d = max(dice(mask, truth), dice(~mask, truth)) if either else dice(mask, truth)
            side = "scikit-image" if tool.startswith("morphological") else "ours"
            records.append({"image": name, "side": side, "tool": tool, "seconds": seconds,
                            "dice": d, "note": note, "shape": list(image.shape)})
            print(f"[{name}] {side} {tool}: {seconds:.3f} s, Dice {d:.4f} ({note})", flush=True)
    # Ours against scikit-image's same method (Chan–Vese or GAC) on the same image.
    for r in records:
        kind = "chan" if "chan" in r["tool"] else "geodesic"
        theirs = [t["seconds"] for t in records if t["image"] == r["image"]
                  and t["side"] == "scikit-image" and kind in t["tool"]]
        r["speed"] = theirs[0] / r["seconds"] if r["side"] == "ours" else None
    note = (f"Measured {datetime.datetime.now().isoformat(timespec='seconds')} on {machine()} with "
            f"`target/py-venv/bin/python docs/segment2d_bench.py --repeat {a.repeat}` "
            f"(fastest of {a.repeat}; sparse_levelset {sl.__version__}, scikit-image "
            f"{skimage.__version__}, NumPy {np.__version__}, Python "
            f"{platform.python_version()}).")
    print("\n" + note + "\n")
    print("| image | side | method and start | seconds | Dice | scikit-image's time ÷ ours |")
    print("|---|---|---|---|---|---|")
    for r in records:
        speed = "—" if r["speed"] is None else f"{r['speed']:.2f}"
        print(f"| {r['image']} | {r['side']} | {r['tool']} | {r['seconds']:.3f} | "
              f"{r['dice']:.4f} | {speed} |")
    if a.json:
        a.json.write_text(json.dumps({"note": note, "records": records}, indent=2) + "\n")


if __name__ == "__main__":
    main()
