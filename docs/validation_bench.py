#!/usr/bin/env python3
"""Validate `levelset segment` against SimpleITK on images `levelset phantom` did not make.

    python3 docs/validation_bench.py                 # phantoms2 at 128³, SNR 2 and 4, + MNI
    python3 docs/validation_bench.py --quick         # smoke test: 64³, SNR 4, no MNI (~2 min)
    python3 docs/validation_bench.py --kinds torus gap --no-mni --only-ours
    python3 docs/validation_bench.py --write-docs    # also fills docs/segmentation.md

The validation set:

* docs/validation/phantoms2.py's phantoms (torus, blobs, tubes, touching, aniso, flipped, gap;
  background 0, object 1, blur σ = 1 voxel, noise σ = 1/SNR) at SNR 2 and 4, each also scaled
  to 1000·I − 500 (NAME-x1000), written to target/validation/phantoms2-nN;
* the MNI ICBM152 2009a T1 (docs/data/fetch_mni.py, into target/validation/mni; fetched by pip
  on first use, or `--mni-wheel` for a local nilearn wheel), white matter (wm probability > 0.5)
  from seed sets A and B, and its copy flipped along i (t1-flipx, set A).

Every volume is segmented, from its seeds file only (seeds, and for the threshold method its
window), with defaults, by

* `levelset segment IMG --method threshold|gac|chan-vese --seed ... [--lower L] [--upper U]
  -o MASK --truth TRUTH --json --threads 2 --quiet`. An open window (seeds file: null) is
  passed by omitting the bound. A binary that refuses that (it says so and exits non-zero) gets,
  from then on, the finite bound SimpleITK gets (below), recorded as `"window_passed"`; NOT a
  huge number such as 1e30: the current threshold speed is (I − L)/half-width, which a huge
  bound makes ~0 everywhere (the seed just sits there). `--open-window` forces either way.
  Exit code 3 is a finished run whose report says the front leaked (`"leaked": true`).
* SimpleITK (2 threads: `SetGlobalDefaultNumberOfThreads(2)`), set up as the ITK Software
  Guide's examples do, by a user WITHOUT the truth:
  - GAC (`GeodesicActiveContourLevelSetImageFilter`): `CurvatureAnisotropicDiffusion` (time
    step 0.0625, the 3D stability limit; conductance 9; 5 iterations) →
    `GradientMagnitudeRecursiveGaussian` (σ = the smallest spacing) → `Sigmoid` to [0, 1] with
    the guide's rule α = −(K_edge − K_in)/6, β = (K_in + K_edge)/2. K_in = the median gradient
    magnitude inside the seed balls; K_edge = the median, over 64 rays per seed (a Fibonacci
    sphere of directions, steps of 0.5 world units, trilinear samples, from the seed's surface
    to the image's border), of the first local maximum of the gradient magnitude after it first
    exceeds 3·K_in (rays that never do are skipped; no ray at all: the 99th percentile of the
    gradient magnitude). The guide's other suggestion, a high percentile of the whole gradient
    image, is noise on these volumes (the objects are a few % of the voxels: the 95th
    percentile is 0.06–0.1 against edges of ~0.22 at SNR 2), so it is not used.
    PropagationScaling 1, CurvatureScaling 1, AdvectionScaling 1 (the guide's).
  - threshold (`ThresholdSegmentationLevelSetImageFilter`): the image smoothed by
    `SmoothingRecursiveGaussian` (σ = the smallest spacing), the seeds file's window;
    PropagationScaling 1, CurvatureScaling 1 (the guide's example). ITK needs finite bounds: an
    open upper bound becomes U = 2·max − L, max that of the smoothed image, so that the
    window's middle is the image maximum and every voxel brighter than L has ITK's speed I − L
    (an open lower bound likewise L = 2·min − U).
  - both: MaximumRMSError 0.02, NumberOfIterations 1000 (not the guide's 800, a 2D example:
    ITK's sparse field moves the front at most half a voxel a step, the torus' front travels
    ~126 voxels around its tube and the MNI white matter ~90 mm from its seeds, ≥ 250–500 steps
    at full speed, and GAC's speed is below 1 in noise); the initial level set is the signed
    distance (world units) to the seed balls, NEGATIVE inside, the mask `output < 0` (ITK's
    convention; see docs/segmentation.md, "Sign conventions, checked"); ITK gets each image
    with its spacing and the identity direction (the voxel grid: see "What ITK is given").
  Chan–Vese runs on our side only.

Each run is one record in target/validation.json, written at once (an interrupted run keeps
its records): volume, scaled, tool, method, Dice against the truth, seconds (the segmentation
itself: ours the `"seconds"` of --json, also the process's wall time; ITK the feature filters
and the evolution), iterations, stop reason, leaked, voxels, whether the mask touches the
image's border, the window and parameters. At the end it prints a markdown table (one row per
volume × method) and the check "the mask of 1000·I − 500 equals the mask of I" per volume,
tool and method (the voxels of the two mask files compared bit for bit). `--write-docs` puts
both between `<!-- VALIDATION -->` and `<!-- /VALIDATION -->` in docs/segmentation.md (nothing
else of that page is touched; without the markers it warns and skips).

Machine use: 2 threads per run, runs one after another. The full set is 28 phantom volumes of
128³ and 3 MNI volumes of 197 × 233 × 189: ITK takes 10–60 s a phantom run and minutes an
MNI run; `--quick` is 14 volumes of 64³.

Python 3.9+ with numpy, scipy, nibabel and SimpleITK 2.5: used as they are when the running
Python has them, else target/segbench-venv (docs/segmentation_bench.py's, with scipy added)
is created or completed and the script re-executes itself there.
"""

import argparse
import datetime
import json
import math
import os
import pathlib
import platform
import subprocess
import sys
import time

DOCS = pathlib.Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.dont_write_bytecode = True  # no __pycache__ in docs/ from the imports below
sys.path.insert(0, str(DOCS))
sys.path.insert(0, str(DOCS / "validation"))
import segmentation_bench as segbench  # noqa: E402  (venv bootstrap, level set, Dice)

DEFAULT_LEVELSET = ROOT / "target" / "release" / "levelset"
WORK = ROOT / "target" / "validation"
DOC_PAGE = DOCS / "segmentation.md"
BEGIN, END = "<!-- VALIDATION -->", "<!-- /VALIDATION -->"
THREADS = 2
METHODS_OURS = ["threshold", "gac", "chan-vese"]
METHODS_ITK = ["threshold", "gac"]
LEAK_EXIT = 3

# SimpleITK settings (see the docstring).
ITK_ITERATIONS = 1000
ITK_RMS = 0.02
ITK_THRESHOLD = {"propagation": 1.0, "curvature": 1.0}
ITK_GAC = {"propagation": 1.0, "curvature": 1.0, "advection": 1.0}
DIFFUSION = {"time_step": 0.0625, "conductance": 9.0, "iterations": 5}
RAYS_PER_SEED = 64
RAY_STEP = 0.5  # world units
EDGE_FACTOR = 3.0  # a ray's edge search starts where |∇| first exceeds this × K_in
# TODO(open windows): "auto" probes the binary once; set to "omit" when every binary in use
# takes open windows (no --upper / no --lower), "finite" to always pass ITK's finite bounds.
OPEN_WINDOW_DEFAULT = "auto"

MNI_VOLUMES = [  # name, image, truth, seeds
    ("mni-wm-A", "mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz", "wm-truth.nii.gz",
     "wm-seeds-A.json"),
    ("mni-wm-B", "mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz", "wm-truth.nii.gz",
     "wm-seeds-B.json"),
    ("mni-flipx-A", "t1-flipx.nii.gz", "t1-flipx-truth.nii.gz", "t1-flipx-seeds-A.json"),
]
NEEDED = ["SimpleITK", "numpy", "scipy", "nibabel"]


# --------------------------------------------------------------------------------------------
# Environment
# --------------------------------------------------------------------------------------------


def have_modules() -> bool:
    try:
        import nibabel  # noqa: F401
        import numpy  # noqa: F401
        import scipy  # noqa: F401
        import SimpleITK

        return SimpleITK.Version.VersionString().startswith("2.5")
    except ImportError:
        return False


def levelset_binary(path: pathlib.Path) -> pathlib.Path:
    if not path.exists():
        if path != DEFAULT_LEVELSET:
            sys.exit(f"error: {path} does not exist")
        print("building target/release/levelset", file=sys.stderr)
        subprocess.run(["cargo", "build", "--release", "--bin", "levelset", "-p", "levelset-cli"],
                       cwd=ROOT, check=True)
    return path


# --------------------------------------------------------------------------------------------
# The validation set
# --------------------------------------------------------------------------------------------


class Volume:
    """One image to segment: paths, seeds, window, and which unscaled volume it copies."""

    def __init__(self, name, image, truth, seeds_path, base=None):
        self.name, self.image, self.truth, self.seeds_path = name, image, truth, seeds_path
        doc = json.loads(seeds_path.read_text())
        self.seeds = [{"center": [float(v) for v in s["center"]], "radius": float(s["radius"])}
                      for s in doc["seeds"]]
        self.lower, self.upper = doc.get("lower"), doc.get("upper")
        self.expect_leak = bool(doc.get("expect_leak", False))
        self.base = base  # the unscaled volume's name for an x1000 copy
        self.scaled = base is not None


def phantom_volumes(size, snrs, kinds, log):
    import phantoms2

    out = WORK / f"phantoms2-n{size}"
    log(f"phantoms2: {len(kinds)} kinds × SNR {', '.join(f'{s:g}' for s in snrs)} at {size}³"
        f" (+ x1000 copies) into {out.relative_to(ROOT)}")
    names = phantoms2.generate(out, size, snrs, kinds, scaled=True, log=lambda *_: None)
    vols = []
    for nm in names:
        base = nm[: -len("-x1000")] if nm.endswith("-x1000") else None
        vols.append(Volume(nm, out / f"{nm}.nii.gz", out / f"{nm}-truth.nii.gz",
                           out / f"{nm}-seeds.json", base))
    return vols


def mni_volumes(wheel, log):
    out = WORK / "mni"
    needed = {f for _, *files in MNI_VOLUMES for f in files}
    if not all((out / f).exists() for f in needed):
        cmd = [sys.executable, str(DOCS / "data" / "fetch_mni.py"), "-o", str(out)]
        if wheel:
            cmd += ["--wheel", str(wheel)]
        log("fetching the MNI template: " + " ".join(cmd[1:]))
        subprocess.run(cmd, check=True)
    return [Volume(n, out / i, out / t, out / s) for n, i, t, s in MNI_VOLUMES]


# --------------------------------------------------------------------------------------------
# Measurements
# --------------------------------------------------------------------------------------------


def read_mask(path):
    import nibabel as nib
    import numpy as np

    return np.asarray(nib.load(str(path)).dataobj) != 0


def touches_border(mask) -> bool:
    return bool(mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any()
                or mask[:, :, 0].any() or mask[:, :, -1].any())


def finite_window(lower, upper, lo_value, hi_value):
    """ITK's finite stand-in for an open window: U = 2·max − L (or L = 2·min − U), so that
    the window's middle is the image's extreme and the speed is I − L (U − I) throughout."""
    if upper is None:
        upper = 2.0 * hi_value - lower
    if lower is None:
        lower = 2.0 * lo_value - upper
    return float(lower), float(upper)


# --------------------------------------------------------------------------------------------
# levelset segment
# --------------------------------------------------------------------------------------------


class Ours:
    def __init__(self, levelset, open_window):
        self.levelset = levelset
        self.open_window = open_window  # "auto" | "omit" | "finite"

    def command(self, vol, method, mask, window):
        cmd = [str(self.levelset), "segment", str(vol.image), "--method", method]
        for s in vol.seeds:
            cmd += ["--seed", segbench.seed_arg(s)]
        if method == "threshold":
            lower, upper = window
            if lower is not None:
                cmd += ["--lower", f"{lower:.9g}"]
            if upper is not None:
                cmd += ["--upper", f"{upper:.9g}"]
        cmd += ["-o", str(mask), "--truth", str(vol.truth), "--json", "--threads", str(THREADS),
                "--quiet"]
        return cmd

    def run(self, vol, method, mask):
        import numpy as np

        window = (vol.lower, vol.upper)
        open_bound = method == "threshold" and (vol.lower is None or vol.upper is None)
        if open_bound and self.open_window == "finite":
            window = self.finite(vol)
        if mask.exists():
            mask.unlink()
        cmd = self.command(vol, method, mask, window)
        t0 = time.perf_counter()
        out = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if open_bound and self.open_window == "auto":
            refused = out.returncode not in (0, LEAK_EXIT) and any(
                w in out.stderr for w in ("--upper", "--lower", "finite", "threshold"))
            self.open_window = "finite" if refused else "omit"
            print(f"   open windows: {'refused by the binary, passing finite bounds' if refused else 'accepted'}"
                  + (f" ({out.stderr.strip().splitlines()[-1]})" if refused else ""),
                  file=sys.stderr)
            if refused:
                return self.run(vol, method, mask)
        record = {"command": " ".join(cmd[1:]), "exit_code": out.returncode,
                  "seconds_process": wall, "window_passed": list(window)}
        if out.returncode not in (0, LEAK_EXIT):
            record.update(error=out.stderr.strip()[-2000:], stop="error")
            return record
        try:
            report = json.loads(out.stdout)
        except ValueError:
            report = {}
        record.update(
            dice=report.get("dice"), seconds=report.get("seconds"),
            iterations=report.get("iterations"), stop=report.get("stop"),
            voxels=report.get("voxels"), params=report.get("params"),
            leaked=out.returncode == LEAK_EXIT or report.get("stop") == "leaked",
        )
        if mask.exists():
            m = read_mask(mask)
            t = read_mask(vol.truth)
            record["dice_check"] = segbench.dice(m, t)
            record["touches_border"] = touches_border(m)
            if record.get("voxels") is None:
                record["voxels"] = int(np.count_nonzero(m))
            if record.get("dice") is None:
                record["dice"] = record["dice_check"]
        return record

    def finite(self, vol):
        import nibabel as nib
        import numpy as np

        data = np.asarray(nib.load(str(vol.image)).dataobj, dtype=np.float64)
        return finite_window(vol.lower, vol.upper, float(data.min()), float(data.max()))


# --------------------------------------------------------------------------------------------
# SimpleITK
# --------------------------------------------------------------------------------------------


def fibonacci_sphere(n):
    import numpy as np

    i = np.arange(n) + 0.5
    polar = np.arccos(1.0 - 2.0 * i / n)
    azimuth = math.pi * (1.0 + math.sqrt(5.0)) * i
    return np.stack([np.cos(azimuth) * np.sin(polar), np.sin(azimuth) * np.sin(polar),
                     np.cos(polar)], axis=1)


def seed_balls(shape_kji, spacing, seeds):
    """The union of the seed balls, an array indexed [k, j, i]."""
    import numpy as np

    kk, jj, ii = np.indices(shape_kji, sparse=True)
    h = min(spacing)
    inside = np.zeros(shape_kji, bool)
    for s in seeds:
        c, r = s["center"], s["radius"] * h
        inside |= (((ii - c[0]) * spacing[0]) ** 2 + ((jj - c[1]) * spacing[1]) ** 2
                   + ((kk - c[2]) * spacing[2]) ** 2) <= r * r
    return inside


def edge_statistics(grad, spacing, seeds):
    """K_in (median |∇| in the seed balls) and K_edge (median over rays of the first peak of
    |∇| after it exceeds EDGE_FACTOR·K_in); see the module's docstring."""
    import numpy as np
    from scipy import ndimage

    sp = np.asarray(spacing, dtype=np.float64)
    dims = np.array(grad.shape[::-1], dtype=np.float64)  # (ni, nj, nk)
    k_in = float(np.median(grad[seed_balls(grad.shape, spacing, seeds)]))
    peaks = []
    reach = float(np.linalg.norm(dims * sp))
    for s in seeds:
        c = np.asarray(s["center"], dtype=np.float64)
        t = np.arange(s["radius"] * sp.min(), reach, RAY_STEP)
        for u in fibonacci_sphere(RAYS_PER_SEED):
            pts = c[None, :] + t[:, None] * (u / sp)[None, :]
            inside = np.all((pts >= 0) & (pts <= dims - 1), axis=1)
            n = len(inside) if inside.all() else int(np.argmin(inside))
            if n < 2:
                continue
            v = ndimage.map_coordinates(grad, [pts[:n, 2], pts[:n, 1], pts[:n, 0]], order=1)
            above = np.nonzero(v > EDGE_FACTOR * k_in)[0]
            if not len(above):
                continue
            q = int(above[0])
            while q + 1 < n and v[q + 1] >= v[q]:
                q += 1
            peaks.append(float(v[q]))
    k_edge = float(np.median(peaks)) if peaks else float(np.percentile(grad, 99))
    return k_in, k_edge, len(peaks)


def itk_run(vol, method, mask_path):
    import numpy as np
    import SimpleITK as sitk

    sitk.ProcessObject.SetGlobalDefaultNumberOfThreads(THREADS)
    image = sitk.ReadImage(str(vol.image), sitk.sitkFloat32)
    # The voxel grid: true spacing, identity direction, zero origin (no voxel changes).
    image.SetDirection((1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0))
    image.SetOrigin((0.0, 0.0, 0.0))
    spacing = image.GetSpacing()
    sigma = float(min(spacing))
    truth = read_mask(vol.truth).transpose(2, 1, 0)  # nibabel [i, j, k] → ITK's [k, j, i]
    params = {"sigma": sigma, "iterations": ITK_ITERATIONS, "max_rms": ITK_RMS,
              "threads": THREADS}
    t0 = time.perf_counter()
    init = segbench.initial_level_set(image, vol.seeds)
    if method == "threshold":
        feature = sitk.SmoothingRecursiveGaussian(image, sigma)
        stats = sitk.StatisticsImageFilter()
        stats.Execute(feature)
        lower, upper = finite_window(vol.lower, vol.upper, stats.GetMinimum(), stats.GetMaximum())
        t1 = time.perf_counter()
        f = sitk.ThresholdSegmentationLevelSetImageFilter()
        f.SetLowerThreshold(lower)
        f.SetUpperThreshold(upper)
        f.SetPropagationScaling(ITK_THRESHOLD["propagation"])
        f.SetCurvatureScaling(ITK_THRESHOLD["curvature"])
        params.update(ITK_THRESHOLD, lower=lower, upper=upper, feature="gaussian")
    elif method == "gac":
        diffused = sitk.CurvatureAnisotropicDiffusion(
            image, timeStep=DIFFUSION["time_step"], conductanceParameter=DIFFUSION["conductance"],
            numberOfIterations=DIFFUSION["iterations"])
        grad = sitk.GradientMagnitudeRecursiveGaussian(diffused, sigma)
        k_in, k_edge, rays = edge_statistics(sitk.GetArrayViewFromImage(grad), spacing, vol.seeds)
        alpha, beta = -(k_edge - k_in) / 6.0, (k_in + k_edge) / 2.0
        feature = sitk.Sigmoid(grad, alpha=alpha, beta=beta, outputMaximum=1.0, outputMinimum=0.0)
        t1 = time.perf_counter()
        f = sitk.GeodesicActiveContourLevelSetImageFilter()
        f.SetPropagationScaling(ITK_GAC["propagation"])
        f.SetCurvatureScaling(ITK_GAC["curvature"])
        f.SetAdvectionScaling(ITK_GAC["advection"])
        params.update(ITK_GAC, diffusion=DIFFUSION, k_in=k_in, k_edge=k_edge, rays=rays,
                      sigmoid_alpha=alpha, sigmoid_beta=beta)
    else:
        raise ValueError(method)
    f.SetNumberOfIterations(ITK_ITERATIONS)
    f.SetMaximumRMSError(ITK_RMS)
    f.SetNumberOfThreads(THREADS)
    out = f.Execute(init, feature)
    t2 = time.perf_counter()
    mask = sitk.GetArrayFromImage(out) < 0
    iterations = int(f.GetElapsedIterations())
    m = sitk.GetImageFromArray(mask.astype(np.uint8))
    m.CopyInformation(image)
    sitk.WriteImage(m, str(mask_path))
    return {
        "dice": segbench.dice(mask, truth), "iterations": iterations, "seconds": t2 - t0,
        "seconds_features": t1 - t0, "seconds_evolution": t2 - t1, "rms": float(f.GetRMSChange()),
        "stop": "max-iterations" if iterations >= ITK_ITERATIONS else "rms",
        "voxels": int(np.count_nonzero(mask)), "touches_border": touches_border(mask),
        "leaked": None, "params": params,
    }


# --------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------


def fmt(v, spec):
    return "–" if v is None else format(v, spec)


def dims_of(rec):
    return "×".join(str(d) for d in rec.get("dims", []))


def table(records) -> str:
    rows = {}
    for r in records:
        key = (r["volume"], r["method"])
        rows.setdefault(key, {})[r["tool"]] = r
    out = ["| volume | method | Dice ours | Dice ITK | s ours | s ITK | ITK/ours | ours' stop |",
           "|---|---|---|---|---|---|---|---|"]
    methods = {m: i for i, m in enumerate(METHODS_OURS)}
    for (volume, method) in sorted(rows, key=lambda k: (k[0], methods.get(k[1], 9))):
        ours, itk = rows[(volume, method)].get("levelset"), rows[(volume, method)].get("SimpleITK")
        ratio = None
        if ours and itk and ours.get("seconds") and itk.get("seconds"):
            ratio = itk["seconds"] / ours["seconds"]
        stop = "–"
        if ours:
            stop = str(ours.get("stop"))
            if ours.get("leaked") and stop != "leaked":
                stop += " (leaked)"
            if ours.get("window_passed") and method == "threshold" and (
                    ours["window_passed"] != [ours.get("lower"), ours.get("upper")]):
                stop += " †"
        any_rec = ours or itk
        out.append(f"| {volume} {dims_of(any_rec)} | {method}"
                   f" | {fmt(ours and ours.get('dice'), '.4f')}"
                   f" | {fmt(itk and itk.get('dice'), '.4f')}"
                   f" | {fmt(ours and ours.get('seconds'), '.2f')}"
                   f" | {fmt(itk and itk.get('seconds'), '.2f')}"
                   f" | {fmt(ratio, '.1f')} | {stop} |")
    return "\n".join(out)


def scale_checks(records):
    """Per unscaled volume, tool and method: do the masks of I and 1000·I − 500 agree voxel for
    voxel? Returns rows (volume, tool, method, equal, differing voxels)."""
    import numpy as np

    by = {(r["volume"], r["tool"], r["method"]): r for r in records}
    rows = []
    for (volume, tool, method), r in sorted(by.items()):
        if r.get("scaled"):
            continue
        s = by.get((f"{volume}-x1000", tool, method))
        if s is None or not r.get("mask") or not s.get("mask"):
            continue
        a, b = pathlib.Path(r["mask"]), pathlib.Path(s["mask"])
        if not (a.exists() and b.exists()):
            rows.append((volume, tool, method, None, None))
            continue
        ma, mb = read_mask(a), read_mask(b)
        diff = int(np.count_nonzero(ma != mb)) if ma.shape == mb.shape else -1
        rows.append((volume, tool, method, diff == 0, diff))
    return rows


def scale_table(rows) -> str:
    out = ["| volume | tool | method | mask(1000·I−500) = mask(I) | differing voxels |",
           "|---|---|---|---|---|"]
    for volume, tool, method, equal, diff in rows:
        eq = "–" if equal is None else ("yes" if equal else "**no**")
        out.append(f"| {volume} | {tool} | {method} | {eq} | {fmt(diff, 'd')} |")
    return "\n".join(out)


def write_docs(text_block) -> None:
    text = DOC_PAGE.read_text()
    if BEGIN not in text or END not in text:
        print(f"warning: {DOC_PAGE.relative_to(ROOT)} has no {BEGIN} … {END} markers;"
              " --write-docs skipped", file=sys.stderr)
        return
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    DOC_PAGE.write_text(head + BEGIN + "\n" + text_block + "\n" + END + tail)
    print(f"wrote the table into {DOC_PAGE.relative_to(ROOT)}", file=sys.stderr)


# --------------------------------------------------------------------------------------------


def main() -> int:
    global ITK_RMS
    import phantoms2

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="smoke test: 64³ phantoms, SNR 4 (unless --size/--snr given), no MNI")
    ap.add_argument("--size", type=int, default=128, help="phantom size (default 128)")
    ap.add_argument("--snr", type=float, nargs="+", default=[2.0, 4.0],
                    help="phantom SNRs (default 2 4)")
    ap.add_argument("--kinds", nargs="+", default=phantoms2.KINDS, choices=phantoms2.KINDS,
                    help="phantom kinds (default all)")
    ap.add_argument("--no-phantoms", action="store_true", help="skip the phantoms")
    ap.add_argument("--no-mni", action="store_true", help="skip the MNI volumes")
    ap.add_argument("--mni-wheel", type=pathlib.Path,
                    help="a local nilearn 0.14.1 wheel for docs/data/fetch_mni.py --wheel")
    ap.add_argument("--only-ours", action="store_true", help="run only `levelset segment`")
    ap.add_argument("--only-itk", action="store_true", help="run only SimpleITK")
    ap.add_argument("--levelset", type=pathlib.Path, default=DEFAULT_LEVELSET,
                    help="the levelset binary (default target/release/levelset, built if missing)")
    ap.add_argument("--open-window", choices=["auto", "omit", "finite"],
                    default=OPEN_WINDOW_DEFAULT,
                    help="how ours gets an open window: omit the bound, pass ITK's finite one,"
                         " or try omitting once (default auto)")
    ap.add_argument("--itk-rms", type=float, default=ITK_RMS,
                    help=f"SimpleITK's MaximumRMSError (default {ITK_RMS}, the guide's)")
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "target" / "validation.json",
                    help="the records (default target/validation.json)")
    ap.add_argument("--write-docs", action="store_true",
                    help="replace the text between the VALIDATION markers of docs/segmentation.md")
    args = ap.parse_args()
    given = set(a.split("=")[0] for a in sys.argv[1:])
    if args.quick:
        if "--size" not in given:
            args.size = 64
        if "--snr" not in given:
            args.snr = [4.0]
        args.no_mni = True
    ITK_RMS = args.itk_rms
    if args.only_ours and args.only_itk:
        sys.exit("error: --only-ours and --only-itk exclude each other")

    import nibabel as nib
    import numpy as np
    import SimpleITK as sitk

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    ours = None
    if not args.only_itk:
        ours = Ours(levelset_binary(args.levelset), args.open_window)
    volumes = []
    if not args.no_phantoms:
        volumes += phantom_volumes(args.size, args.snr, args.kinds, log)
    if not args.no_mni:
        volumes += mni_volumes(args.mni_wheel, log)

    meta = {
        "date": datetime.date.today().isoformat(),
        "cpu": segbench.cpu_name(), "cores": os.cpu_count(),
        "loadavg_at_start": [round(v, 2) for v in os.getloadavg()],
        "python": platform.python_version(), "simpleitk": sitk.Version.VersionString(),
        "numpy": np.__version__,
        "command": "python3 docs/validation_bench.py " + " ".join(sys.argv[1:]),
        "levelset": None if ours is None else str(ours.levelset),
        "threads": THREADS,
        "itk": {"iterations": ITK_ITERATIONS, "max_rms": ITK_RMS, "threshold": ITK_THRESHOLD,
                "gac": ITK_GAC, "diffusion": DIFFUSION, "rays_per_seed": RAYS_PER_SEED,
                "edge_factor": EDGE_FACTOR},
    }
    records = []

    def save():
        args.out.parent.mkdir(parents=True, exist_ok=True)
        tmp = args.out.with_name(args.out.name + ".tmp")
        tmp.write_text(json.dumps({"meta": meta, "records": records}, indent=1) + "\n")
        tmp.replace(args.out)

    masks = WORK / "masks"
    masks.mkdir(parents=True, exist_ok=True)
    for vol in volumes:
        dims = list(nib.load(str(vol.image)).shape)
        base = {"volume": vol.name, "scaled": vol.scaled, "dims": dims, "image": str(vol.image),
                "truth": str(vol.truth), "seeds": vol.seeds, "lower": vol.lower,
                "upper": vol.upper, "expect_leak": vol.expect_leak}
        log(f"== {vol.name} {'×'.join(map(str, dims))}: {len(vol.seeds)} seed(s), window"
            f" [{fmt(vol.lower, 'g')}, {fmt(vol.upper, 'g')}]"
            + (", leak expected" if vol.expect_leak else ""))
        runs = []
        if ours is not None:
            runs += [("levelset", m) for m in METHODS_OURS]
        if not args.only_ours:
            runs += [("SimpleITK", m) for m in METHODS_ITK]
        for tool, method in runs:
            mask = masks / f"{vol.name}-{'ours' if tool == 'levelset' else 'itk'}-{method}.nii.gz"
            if tool == "levelset":
                r = ours.run(vol, method, mask)
            else:
                r = itk_run(vol, method, mask)
            records.append(dict(base, tool=tool, method=method, mask=str(mask), **r))
            save()
            extra = " LEAKED" if r.get("leaked") else ""
            extra += " (touches the border)" if r.get("touches_border") else ""
            if r.get("error"):
                extra += f" ERROR: {r['error'].splitlines()[-1]}"
            log(f"   {tool:9} {method:9}: Dice {fmt(r.get('dice'), '.4f')},"
                f" {fmt(r.get('iterations'), 'd')} it, {fmt(r.get('seconds'), '.2f')} s,"
                f" stop {r.get('stop')}{extra}")

    checks = scale_checks(records)
    note = (f"Measured {meta['date']} on {meta['cpu']} ({meta['cores']} cores, {THREADS} threads"
            f" a run), SimpleITK {meta['simpleitk']}; command: `{meta['command']}`.")
    block = note + "\n\n" + table(records)
    if any(r.get("tool") == "levelset" and r.get("method") == "threshold"
           and r.get("window_passed") != [r.get("lower"), r.get("upper")] for r in records):
        block += ("\n\n† the binary refused the open window; it was given ITK's finite bound"
                  " (U = 2·max − L).")
    if checks:
        block += "\n\n" + scale_table(checks)
    print(block)
    log(f"\nrecords: {args.out}")
    if args.write_docs:
        write_docs(block)
    return 0


if __name__ == "__main__":
    if not have_modules():
        segbench.ensure_venv(pathlib.Path(__file__).resolve(), extra_requirements=["scipy"],
                             extra_modules=["scipy"])
    sys.exit(main())
