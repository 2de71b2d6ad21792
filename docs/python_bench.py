#!/usr/bin/env python3
"""Accuracy and time of `sparse_levelset` beside scikit-fmm and scikit-image on their own
problems, in one process (ratios within one run; the machines are shared).

    target/py-venv/bin/python docs/python_bench.py               # print the tables
    target/py-venv/bin/python docs/python_bench.py --write-docs  # also fill docs/python.md
    target/py-venv/bin/python docs/python_bench.py --json docs/data/python-1.json
                                   # the records, for docs/benchmarks.py's Python section

Needs the package and the references installed (`bash scripts/test.sh` makes
target/py-venv). Each pair of calls (theirs, ours) alternates, theirs first, at least
--repeat times and until each side has run for MIN_SECONDS (at most MAX_CALLS pairs), so
that drift of the machine's speed reaches both sides alike and calls of a few milliseconds
are sampled as often as those of seconds; every time is the fastest of its side's calls.

* distance: a distorted torus (the exact signed distance of a torus, multiplied by a
  smooth positive factor between about 0.4 and 2: same zero set, not a distance), n³
  voxels; max and mean error against the exact distance within 2.5 voxels of the surface and
  over the whole array; `skfmm.distance(phi, order=2)` and `sl.distance(phi, order=2)`,
  then both with `narrow=3` (distances only within 3 voxels, what a level-set method
  needs). Then the same in 2-D (--sizes-2d, default 1024): a distorted circle of radius
  0.3 n on n² pixels (the exact signed distance of the circle times a smooth positive
  factor between about 0.4 and 1.8).
* isosurface: the signed distance of a sphere of radius 0.4 n on n³ voxels; relative area
  error, watertightness (trimesh), and time of `skimage.measure.marching_cubes(vol, 0)`
  and `sl.isosurface(vol, 0)`.
"""

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
import skfmm
import trimesh
from skimage import measure

import sparse_levelset as sl

DOC_PAGE = Path(__file__).resolve().parent / "python.md"
TABLE_BEGIN = "<!-- TABLE: filled by docs/python_bench.py -->"
TABLE_END = "<!-- /TABLE -->"


def best_of(repeat, f):
    """The fastest of `repeat` calls of `f`, and its last result."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t)
    return best, out


MIN_SECONDS = 1.0
MAX_CALLS = 200


def race(repeat, theirs, ours):
    """Alternated calls of `theirs` and `ours` (see the module docs): their fastest
    times and last results."""
    best, out, spent = [float("inf")] * 2, [None, None], [0.0, 0.0]
    calls = 0
    while calls < repeat or (min(spent) < MIN_SECONDS and calls < MAX_CALLS):
        for k, f in enumerate((theirs, ours)):
            t = time.perf_counter()
            out[k] = f()
            dt = time.perf_counter() - t
            best[k], spent[k] = min(best[k], dt), spent[k] + dt
        calls += 1
    return best[0], out[0], best[1], out[1]


def torus(n):
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float64)
    c = (n - 1) / 2
    X, Y, Z = x - c, y - c, z - c
    R, r = 0.27 * n, 0.1 * n
    exact = np.sqrt((np.sqrt(X**2 + Y**2) - R) ** 2 + Z**2) - r
    factor = (1 + 0.5 * np.sin(X / 7) * np.cos(Y / 5) + 0.3 * Z / n) * np.exp(0.02 * X)
    return exact * factor, exact


def circle(n):
    y, x = np.mgrid[:n, :n].astype(np.float64)
    c = (n - 1) / 2
    X, Y = x - c, y - c
    exact = np.sqrt(X**2 + Y**2) - 0.3 * n
    factor = (1 + 0.4 * np.sin(X / 23) * np.cos(Y / 17) + 0.2 * Y / n) * np.exp(0.0004 * X)
    return exact * factor, exact


def distance_rows(n, repeat, dims=3):
    phi, exact = torus(n) if dims == 3 else circle(n)
    near = np.abs(exact) < 2.5
    rows = []
    for narrow in (None, 3.0):
        kw = {} if narrow is None else {"narrow": narrow}
        t_them, theirs, t_us, ours = race(
            repeat, lambda: skfmm.distance(phi, order=2, **kw), lambda: sl.distance(phi, order=2, **kw)
        )
        row = {"n": n, "dims": dims, "narrow": narrow, "t_skfmm": t_them, "t_ours": t_us}
        for name, d in (("skfmm", theirs), ("ours", ours)):
            err = np.abs(np.ma.getdata(d) - exact)
            row[f"max_near_{name}"] = err[near].max()
            row[f"mean_near_{name}"] = err[near].mean()
            row[f"max_all_{name}"] = err.max() if narrow is None else float("nan")
        rows.append(row)
    return rows


def iso_row(n, repeat):
    z, y, x = np.mgrid[:n, :n, :n].astype(np.float32)
    c, radius = (n - 1) / 2, 0.4 * n
    vol = np.sqrt((x - c) ** 2 + (y - c) ** 2 + (z - c) ** 2) - radius
    exact = 4 * np.pi * radius**2
    t_them, (v, f, _, _), t_us, (vo, fo, _, _) = race(
        repeat, lambda: measure.marching_cubes(vol, 0.0), lambda: sl.isosurface(vol, 0.0)
    )
    a = trimesh.Trimesh(v, f, process=False)
    b = trimesh.Trimesh(vo, fo, process=False)
    return {
        "n": n, "t_skimage": t_them, "t_ours": t_us,
        "err_skimage": (a.area - exact) / exact, "err_ours": (b.area - exact) / exact,
        "tri_skimage": len(f), "tri_ours": len(fo),
        "wt_skimage": a.is_watertight, "wt_ours": b.is_watertight,
    }


def machine():
    cpu = platform.processor() or "unknown CPU"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
        flags = open("/proc/cpuinfo").read()
        width = "AVX-512" if "avx512f" in flags else ("AVX2" if "avx2" in flags else "SSE")
    except OSError:
        width = "unknown"
    return f"{cpu}, {os.cpu_count()} cores, {width}"


def size(r):
    """n³ or n² (records without `dims` are 3-D)."""
    return f"{r['n']}{'²' if r.get('dims', 3) == 2 else '³'}"


def tables(dist, iso, repeat):
    out = []
    out.append("**Signed distance of the distorted torus (n³) and circle (n²)** (order 2; error "
               "in voxels against the exact distance; time in seconds)\n")
    out.append("| size | narrow | max error ≤ 2.5 voxels: scikit-fmm / ours | mean error ≤ 2.5 voxels: "
               "scikit-fmm / ours | max error, whole array: scikit-fmm / ours | time: scikit-fmm "
               "/ ours | speed-up |")
    out.append("|---|---|---|---|---|---|---|")
    for r in dist:
        narrow = "—" if r["narrow"] is None else f"{r['narrow']:g}"
        whole = ("—" if r["narrow"] is not None
                 else f"{r['max_all_skfmm']:.3f} / {r['max_all_ours']:.3f}")
        out.append(
            f"| {size(r)} | {narrow} | {r['max_near_skfmm']:.3f} / {r['max_near_ours']:.3f} | "
            f"{r['mean_near_skfmm']:.4f} / {r['mean_near_ours']:.4f} | {whole} | "
            f"{r['t_skfmm']:.3f} / {r['t_ours']:.3f} | {r['t_skfmm'] / r['t_ours']:.1f}× |"
        )
    out.append("")
    out.append("**Isosurface of a sphere of radius 0.4 n** (area error against 4πr²; time in "
               "seconds)\n")
    out.append("| n³ | area error: marching_cubes / ours | watertight: marching_cubes / ours | "
               "triangles: marching_cubes / ours | time: marching_cubes / ours | speed-up |")
    out.append("|---|---|---|---|---|---|")
    for r in iso:
        out.append(
            f"| {r['n']} | {100 * r['err_skimage']:+.3f} % / {100 * r['err_ours']:+.3f} % | "
            f"{'yes' if r['wt_skimage'] else 'no'} / {'yes' if r['wt_ours'] else 'no'} | "
            f"{r['tri_skimage']:,} / {r['tri_ours']:,} | "
            f"{r['t_skimage']:.3f} / {r['t_ours']:.3f} | {r['t_skimage'] / r['t_ours']:.1f}× |"
        )
    return "\n".join(out)


def args(a):
    """The command line of this run (without the output options)."""
    return (f"--sizes {' '.join(map(str, a.sizes))} --sizes-2d {' '.join(map(str, a.sizes_2d))} "
            f"--repeat {a.repeat}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[96, 160])
    ap.add_argument("--sizes-2d", type=int, nargs="*", default=[1024])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--write-docs", action="store_true", help="fill the table in docs/python.md")
    ap.add_argument("--json", type=Path, help="also write the records to this JSON file")
    a = ap.parse_args()
    dist = [row for n in a.sizes for row in distance_rows(n, a.repeat)]
    dist += [row for n in a.sizes_2d for row in distance_rows(n, a.repeat, dims=2)]
    iso = [iso_row(n, a.repeat) for n in a.sizes]
    body = tables(dist, iso, a.repeat)
    import skimage
    note = (
        f"Measured {datetime.date.today().isoformat()} on {machine()} with "
        f"`target/py-venv/bin/python docs/python_bench.py {args(a)}` (fastest of at least {a.repeat} alternated calls and {MIN_SECONDS:g} s per side; sparse_levelset {sl.__version__}, "
        f"scikit-fmm {skfmm.__version__}, scikit-image {skimage.__version__}, NumPy "
        f"{np.__version__}, Python {platform.python_version()})."
    )
    print(note + "\n\n" + body)
    if a.json:
        command = f"target/py-venv/bin/python docs/python_bench.py {args(a)}"
        clean = lambda rows: [{k: (None if isinstance(v, float) and v != v else v) for k, v in r.items()} for r in rows]
        a.json.write_text(json.dumps({"note": note, "command": command, "distance": clean(dist),
                                      "isosurface": clean(iso)}, indent=2, default=bool) + "\n")
    if a.write_docs:
        text = DOC_PAGE.read_text()
        if TABLE_BEGIN not in text or TABLE_END not in text:
            sys.exit(f"error: {DOC_PAGE} lacks the markers {TABLE_BEGIN} … {TABLE_END}")
        head, rest = text.split(TABLE_BEGIN, 1)
        _, tail = rest.split(TABLE_END, 1)
        DOC_PAGE.write_text(head + TABLE_BEGIN + "\n" + note + "\n\n" + body + "\n" + TABLE_END + tail)


if __name__ == "__main__":
    main()
