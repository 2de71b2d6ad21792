#!/usr/bin/env python3
"""`levelset voxelize` beside OpenVDB's `meshToLevelSet` and ViennaLS's `FromSurfaceMesh` on
one torus mesh: time, band voxels and accuracy, side by side in one run (ratios
within one run, the machines are shared).

Setup, once (Debian's python3-openvdb gives `pyopenvdb` and NumPy to the system Python; the
venv sees them and adds ViennaLS from PyPI):

    sudo apt-get install python3-openvdb            # OpenVDB 10.0.1 on Debian 12
    /usr/bin/python3 -m venv --system-site-packages target/vox-venv
    target/vox-venv/bin/pip install viennals==5.10.0
    cargo build --release                           # target/release/levelset

Run (on a shared machine, hold the CPU lock around every timing):

    flock /tmp/cpu.lock target/vox-venv/bin/python docs/voxelize_bench.py
    flock /tmp/cpu.lock target/vox-venv/bin/python docs/voxelize_bench.py --json target/voxbench.json
    flock /tmp/cpu.lock target/vox-venv/bin/python docs/voxelize_bench.py \\
        --segments 80 40 --voxel-size 0.015625 --repeat 1      # quick smoke test (seconds)

The mesh: a UV torus, major radius 0.32, minor radius 0.14, centred at the origin, axis z,
316 × 158 segments (--segments), two triangles per quad: 49,928 vertices, 99,856 triangles,
every triangle counter-clockwise seen from outside (checked: the signed volume is positive);
voxel size 1/256 (--voxel-size). It is written once as a binary little-endian PLY (float64
coordinates) for the CLI; the peers get the same arrays in memory.

The three conversions (each the fastest of --repeat runs, each run a fresh conversion):

* ours: `levelset voxelize torus.ply --voxel-size H --threads T --quiet -o OUT.sls`
  (half-width 3, exact distances, sign by ray votes: the defaults); the time is the one the
  CLI prints ("…, N band voxels in M tiles, X s on T thread(s)"): the conversion in process,
  without reading the mesh or writing the file. The band is read back from the .sls file
  with the reader below (docs/sls-format.md), no extra package needed. The binary is copied
  into the temporary directory first and the copy is run (its SHA-256 goes into --json).
* OpenVDB: `pyopenvdb.FloatGrid.createLevelSetFromPolygons(points, triangles=tris,
  transform=pyopenvdb.createLinearTransform(voxelSize=H), halfWidth=3.0)`, timed around
  that call (it includes copying the NumPy arrays into OpenVDB's vectors, a few ms). The band
  is the active voxels (`activeVoxelCount()`, `iterOnValues()`), world position H·ijk,
  values in world units. OpenVDB's meshToVolume "is independent of mesh surface normals /
  polygon orientation" (MeshToVolume.h), so the winding does not matter to it.
* ViennaLS: `viennals.d3.FromSurfaceMesh(viennals.d3.Domain(H), mesh).apply()`, timed
  around `apply()`; `Domain(gridDelta)` is "an empty infinite Domain" (lsDomain.hpp), the
  form ViennaLS's own Python tests use for this conversion. The mesh is a `viennals.Mesh`
  filled with `insertNextNode`/`insertNextTriangle` (not timed). Its band is what
  `FromSurfaceMesh` stores: the grid points on either side of every crossing of a grid line
  with a triangle, value = the distance along that grid line in voxels, clamped to ±1
  (`getLevelSetWidth()` reports 2); read back with `viennals.d3.ToMesh` (one node per
  defined point, cell data "LSValues" in grid units). Its sign comes from the triangles'
  winding: counter-clockwise seen from outside gives φ < 0 inside (measured on an 80 × 40
  torus: the flipped mesh gives errors near 2 voxels, this one the expected sign).

Threads: every case runs in its own process under `taskset -c` on the first T CPUs of this
process's affinity mask (T = 1: `taskset -c 0`; T = 2: `taskset -c 0,1`), ours with
`--threads T` too. OpenVDB runs on oneTBB, which takes its default concurrency from the
affinity mask; the worker records its thread count before and after the conversion and
CPU time ÷ wall time of the best run, which show whether the mask held (columns "threads
seen" and "CPU / wall"; measured with Debian 12's TBB: under `-c 0` no TBB worker is added
and CPU/wall is 1.00, under `-c 0,1` one worker is added and CPU/wall is 1.97; the 4 other
threads exist from `import pyopenvdb` on and stay idle). ViennaLS uses OpenMP: OMP_NUM_THREADS=T and `viennals.setNumThreads(T)`,
and only T = 1 is run (the issue's comparison; --viennals-threads for more).

Accuracy: the value error in voxels against the analytic signed distance of the torus,
sqrt((sqrt(x² + y²) − R)² + z²) − r, at each tool's own band voxels: max and mean over those
within 2 voxels of the surface (|exact| < 2h) and over the whole band (|value| < the tool's
half-width: 3 for ours and OpenVDB, 1 for ViennaLS, whose values are clamped to ±1). The
mesh's flat triangles lie inside the round torus (the chord error, printed), so that part of
every tool's error comes from the mesh, not the tool.

Python 3.9+, NumPy; `pyopenvdb` and `viennals` for the peers (--tools to run a subset).
"""

import argparse
import datetime
import hashlib
import json
import os
import platform
import re
import resource
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_LEVELSET = ROOT / "target" / "release" / "levelset"
MAJOR, MINOR = 0.32, 0.14
TOOLS = ["ours", "openvdb", "viennals"]
LABEL = {"ours": "ours (`levelset voxelize`)", "openvdb": "OpenVDB `meshToLevelSet`",
         "viennals": "ViennaLS `FromSurfaceMesh`"}


# ---------------------------------------------------------------------------- the mesh


def torus_mesh(nu, nv, R=MAJOR, r=MINOR):
    """UV torus: nu segments around the axis, nv around the tube; triangles (a, b, c) and
    (a, c, d) of every quad, counter-clockwise seen from outside."""
    u = 2 * np.pi * np.arange(nu) / nu
    v = 2 * np.pi * np.arange(nv) / nv
    U, V = np.meshgrid(u, v, indexing="ij")
    ring = R + r * np.cos(V)
    points = np.stack([ring * np.cos(U), ring * np.sin(U), r * np.sin(V)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                           np.stack([a, c, d], -1).reshape(-1, 3)]).astype(np.int32)
    return points, tris


def exact_sd(x):
    return np.sqrt((np.hypot(x[:, 0], x[:, 1]) - MAJOR) ** 2 + x[:, 2] ** 2) - MINOR


def mesh_checks(points, tris):
    """Signed volume (positive: outward winding), its analytic value, and the chord error:
    the largest |exact distance| over the triangles' vertices, edge midpoints (the quads'
    diagonals included) and centroids."""
    A, B, C = points[tris[:, 0]], points[tris[:, 1]], points[tris[:, 2]]
    volume = float(np.einsum("ij,ij->i", A, np.cross(B, C)).sum() / 6)
    samples = np.concatenate([A, (A + B) / 2, (B + C) / 2, (C + A) / 2, (A + B + C) / 3])
    return {"signed_volume": volume, "torus_volume": 2 * np.pi**2 * MAJOR * MINOR**2,
            "chord_error": float(np.abs(exact_sd(samples)).max())}


def write_ply(path, points, tris):
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
              "property double x\nproperty double y\nproperty double z\n"
              f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n")
    faces = np.zeros(len(tris), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"], faces["i"] = 3, tris
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(points.astype("<f8").tobytes())
        f.write(faces.tobytes())


# ---------------------------------------------------------------------------- .sls reader


def read_sls(path):
    """The band of a .sls file (docs/sls-format.md, version 1): (ijk (N, 3) int64 in x, y, z
    order, values (N,) float32 in world units, header dict). Checks the magic, version and
    CRC-32; augmented fields are skipped."""
    data = Path(path).read_bytes()
    if data[:8] != b"\x89SLS\r\n\x1a\n":
        raise ValueError(f"{path}: not a .sls file")
    if zlib.crc32(data[:-4]) != struct.unpack_from("<I", data, len(data) - 4)[0]:
        raise ValueError(f"{path}: checksum mismatch")
    (version, _flags, h, ox, oy, oz, half_width, _src, *_dom, count, rz, ry, rx,
     _fields) = struct.unpack_from("<IIf3dfI6iQ3QI", data, 8)
    if version != 1:
        raise ValueError(f"{path}: version {version}, this reader knows 1")
    pos = 112

    def varint():
        nonlocal pos
        out = shift = 0
        while True:
            byte = data[pos]
            pos += 1
            out |= (byte & 0x7F) << shift
            if byte < 0x80:
                return out
            shift += 7

    def segment():
        """The defined coordinates of one scan line, in order."""
        nonlocal pos
        k = varint()
        pos += 1  # the first run's kind (never defined)
        starts, kinds, prev = [], [], None
        for n in range(k):
            code = varint()
            d, kind = code >> 2, code & 3
            start = ((d >> 1) ^ -(d & 1)) if n == 0 else prev + 1 + d
            starts.append(start)
            kinds.append(kind)
            prev = start
        out = []
        for n in range(k - 1):
            if kinds[n] == 2:
                out.extend(range(starts[n], starts[n + 1]))
        return out

    zs = segment()
    zy = [(z, y) for z in zs for y in segment()]
    ijk = np.empty((count, 3), dtype=np.int64)
    at = 0
    for z, y in zy:
        xs = segment()
        ijk[at:at + len(xs), 0] = xs
        ijk[at:at + len(xs), 1] = y
        ijk[at:at + len(xs), 2] = z
        at += len(xs)
    if at != count:
        raise ValueError(f"{path}: {at} defined voxels in the runs, {count} in the header")
    values = np.frombuffer(data, dtype="<f4", count=count, offset=pos).copy()
    header = {"voxel_size": h, "origin": (ox, oy, oz), "half_width": half_width,
              "runs": (rz, ry, rx)}
    return ijk, values, header


# ---------------------------------------------------------------------------- workers


def thread_count():
    for line in open("/proc/self/status"):
        if line.startswith("Threads:"):
            return int(line.split()[1])
    return -1


def cpu_seconds():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def timed_runs(repeat, make):
    """Fastest of `repeat` calls of make(); (seconds of each run, CPU/wall of the best, the
    last result)."""
    times, ratios, out = [], [], None
    for _ in range(repeat):
        out = None
        c0, t0 = cpu_seconds(), time.perf_counter()
        out = make()
        wall, cpu = time.perf_counter() - t0, cpu_seconds() - c0
        times.append(wall)
        ratios.append(cpu / wall if wall > 0 else float("nan"))
    best = int(np.argmin(times))
    return times, ratios[best], out


def worker_openvdb(mesh, h, repeat):
    import pyopenvdb as vdb
    points, tris = mesh["points"], mesh["triangles"]
    threads_before = thread_count()
    times, cpu_wall, grid = timed_runs(repeat, lambda: vdb.FloatGrid.createLevelSetFromPolygons(
        points, triangles=tris, transform=vdb.createLinearTransform(voxelSize=h),
        halfWidth=3.0))
    threads_after = thread_count()
    ijk, values = [], []
    for item in grid.iterOnValues():
        if item.count != 1:
            raise RuntimeError("an active tile in the level set")
        ijk.append(item.min)
        values.append(item.value)
    return {"times": times, "cpu_wall": cpu_wall, "threads_before": threads_before,
            "threads_after": threads_after, "band_voxels": int(grid.activeVoxelCount()),
            "half_width": 3.0, "version": ".".join(map(str, vdb.LIBRARY_VERSION)),
            "call": "pyopenvdb.FloatGrid.createLevelSetFromPolygons(points, triangles=tris, "
                    "transform=pyopenvdb.createLinearTransform(voxelSize=h), halfWidth=3.0)"
            }, h * np.asarray(ijk, dtype=np.float64), np.asarray(values, dtype=np.float64)


def worker_viennals(mesh, h, repeat, threads):
    import viennals
    import viennals.d3 as d3
    viennals.setNumThreads(threads)
    m = viennals.Mesh()
    for p in mesh["points"].tolist():
        m.insertNextNode(p)
    for t in mesh["triangles"].tolist():
        m.insertNextTriangle(t)
    threads_before = thread_count()
    domains = [d3.Domain(h) for _ in range(repeat)]  # fresh ones, made outside the timing
    runs = iter(domains)

    def convert():
        dom = next(runs)
        d3.FromSurfaceMesh(dom, m).apply()
        return dom

    times, cpu_wall, dom = timed_runs(repeat, convert)
    threads_after = thread_count()
    out = viennals.Mesh()
    d3.ToMesh(dom, out).apply()
    X = np.asarray(out.getNodes(), dtype=np.float64)
    values = np.asarray(out.getCellData().getScalarData("LSValues", True), dtype=np.float64)
    return {"times": times, "cpu_wall": cpu_wall, "threads_before": threads_before,
            "threads_after": threads_after, "band_voxels": int(dom.getNumberOfPoints()),
            "level_set_width": int(dom.getLevelSetWidth()), "half_width": 1.0,
            "version": viennals.__version__,
            "call": "viennals.d3.FromSurfaceMesh(viennals.d3.Domain(h), mesh).apply()"
            }, X, values * h


def worker_main(a):
    mesh = np.load(a.mesh)
    if a.worker == "openvdb":
        info, X, values = worker_openvdb(mesh, a.voxel_size, a.repeat)
    else:
        info, X, values = worker_viennals(mesh, a.voxel_size, a.repeat, a.worker_threads)
    info["affinity"] = sorted(os.sched_getaffinity(0))
    np.savez(a.out, X=X, values=values, info=json.dumps(info))


# ---------------------------------------------------------------------------- the parent


def cpus_for(threads):
    cpus = sorted(os.sched_getaffinity(0))
    if threads > len(cpus):
        sys.exit(f"error: {threads} threads asked, {len(cpus)} CPUs in the affinity mask")
    return ",".join(map(str, cpus[:threads]))


def run_peer(tool, threads, mesh_path, h, repeat, work):
    out = work / f"{tool}-{threads}.npz"
    env = dict(os.environ)
    if tool == "viennals":
        env["OMP_NUM_THREADS"] = str(threads)
    cmd = ["taskset", "-c", cpus_for(threads), sys.executable, str(Path(__file__).resolve()),
           "--worker", tool, "--mesh", str(mesh_path), "--voxel-size", repr(h),
           "--repeat", str(repeat), "--worker-threads", str(threads), "--out", str(out)]
    subprocess.run(cmd, check=True, env=env)
    with np.load(out) as f:
        info = json.loads(str(f["info"]))
        return info, f["X"], f["values"]


OURS_LINE = re.compile(r"([0-9]+) band voxels in ([0-9]+) tiles, ([0-9.eE+-]+) s on ([0-9]+) thread")


def run_ours(levelset, threads, ply, h, repeat, work):
    out = work / f"ours-{threads}.sls"
    cmd = ["taskset", "-c", cpus_for(threads), str(levelset), "voxelize", str(ply),
           "--voxel-size", repr(h), "--threads", str(threads), "--quiet", "-o", str(out)]
    times, walls, band, text = [], [], None, ""
    for _ in range(repeat):
        t0 = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True)
        walls.append(time.perf_counter() - t0)
        text = p.stdout + p.stderr
        if p.returncode != 0:
            sys.exit(f"error: {' '.join(cmd)} failed ({p.returncode}):\n{text}")
        m = OURS_LINE.search(text)
        if not m or int(m.group(4)) != threads:
            sys.exit(f"error: no timing line for {threads} thread(s) in the output of "
                     f"{' '.join(cmd)}:\n{text}")
        band = int(m.group(1))
        times.append(float(m.group(3)))
    ijk, values, header = read_sls(out)
    if len(values) != band:
        sys.exit(f"error: {out} holds {len(values)} voxels, the CLI reported {band}")
    X = np.asarray(header["origin"]) + header["voxel_size"] * ijk
    info = {"times": times, "process_wall": walls, "band_voxels": band,
            "half_width": header["half_width"], "affinity_cpus": cpus_for(threads),
            "output_line": text.strip().splitlines()[0],
            "call": " ".join(["levelset"] + cmd[4:])}
    return info, X, values.astype(np.float64)


def errors(X, values, h, half_width):
    exact = exact_sd(X)
    err = np.abs(values - exact) / h
    near = np.abs(exact) < 2 * h
    band = np.abs(values) < half_width * h
    pick = lambda m: (float(err[m].max()), float(err[m].mean()), int(m.sum())) if m.any() \
        else (float("nan"), float("nan"), 0)
    (mn, an, nn), (mb, ab, nb) = pick(near), pick(band)
    wrong_sign = int(np.sum((np.sign(values) != np.sign(exact)) & (np.abs(exact) > 0.5 * h)))
    return {"max_near": mn, "mean_near": an, "n_near": nn, "max_band": mb, "mean_band": ab,
            "n_band": nb, "wrong_sign_beyond_half_voxel": wrong_sign}


def machine():
    cpu, width = platform.processor() or "unknown CPU", "unknown"
    try:
        text = open("/proc/cpuinfo").read()
        for line in text.splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
        width = "AVX-512" if "avx512f" in text else ("AVX2" if "avx2" in text else "SSE")
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "simd": width,
            "loadavg_at_start": [round(v, 2) for v in os.getloadavg()]}


def fmt_s(t):
    return f"{t:.3f}" if t >= 0.01 else f"{t:.4f}"


def tables(records, meta, a):
    h = a.voxel_size
    ours = {r["threads"]: r for r in records if r["tool"] == "ours"}
    out = [f"**Torus mesh → narrow-band level set** ({meta['mesh']['triangles']:,} triangles, "
           f"R = {MAJOR}, r = {MINOR}, voxel size h = {h:g}; seconds: the fastest of "
           f"{a.repeat}; ratios against ours on the same threads; errors in voxels against "
           "the analytic torus distance)\n"]
    out.append("| tool | threads (CPUs) | seconds | band voxels | ns / band voxel | time ÷ ours "
               "| (ns / voxel) ÷ ours | max / mean error, \\|exact\\| < 2h | max / mean error, "
               "whole band | half-width | CPU / wall | threads seen |")
    out.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in records:
        o = ours.get(r["threads"])
        if o is not None and r["tool"] != "ours":
            ratio = f"{r['seconds'] / o['seconds']:.2f}"
            per = f"{r['ns_per_voxel'] / o['ns_per_voxel']:.2f}"
        else:
            ratio = per = "1" if r["tool"] == "ours" else "—"
        e = r["errors"]
        seen = (f"{r['threads_before']} → {r['threads_after']}" if "threads_after" in r
                else "—")
        cw = f"{r['cpu_wall']:.2f}" if "cpu_wall" in r else "—"
        out.append(
            f"| {LABEL[r['tool']]} | {r['threads']} ({r['cpus']}) | {fmt_s(r['seconds'])} | "
            f"{r['band_voxels']:,} | {r['ns_per_voxel']:.0f} | {ratio} | {per} | "
            f"{e['max_near']:.3f} / {e['mean_near']:.4f} | {e['max_band']:.3f} / "
            f"{e['mean_band']:.4f} | {r['half_width']:g} | {cw} | {seen} |")
    out.append("")
    m = meta["mesh"]
    out.append(f"Mesh: {m['vertices']:,} vertices, {m['triangles']:,} triangles, signed volume "
               f"{m['signed_volume']:.6f} (torus {m['torus_volume']:.6f}: outward winding); "
               f"chord error (largest |exact distance| at the triangles' edge midpoints and "
               f"centroids) {m['chord_error'] / h:.4f} voxel.")
    find = lambda tool, t: next((r for r in records if r["tool"] == tool and r["threads"] == t),
                                None)
    lines = []
    o2, v2 = find("ours", 2), find("openvdb", 2)
    if o2 and v2:
        lines.append(f"- OpenVDB on 2 threads ÷ ours on 2 threads, time: "
                     f"**{v2['seconds'] / o2['seconds']:.2f}×** (the target ≥ 3×: ours at "
                     "least three times as fast).")
    o1, l1 = find("ours", 1), find("viennals", 1)
    if o1 and l1:
        lines.append(f"- ViennaLS on 1 thread ÷ ours on 1 thread, time per band voxel: "
                     f"**{l1['ns_per_voxel'] / o1['ns_per_voxel']:.2f}×** (the target ≥ 1×: "
                     f"ours at least as fast per band voxel; whole time: "
                     f"{l1['seconds'] / o1['seconds']:.3f}×, ours stores "
                     f"{o1['band_voxels'] / l1['band_voxels']:.2f}× as many voxels).")
    walls = [f"{min(r['process_wall']):.3f} s on {r['threads']} thread(s)" for r in records
             if r["tool"] == "ours"]
    if walls:
        lines.append("- ours, the whole `levelset voxelize` process (start, reading the PLY, "
                     "writing the .sls; fastest of the same runs): " + ", ".join(walls) + ".")
    if lines:
        out.append("")
        out.extend(lines)
    out.append("")
    out.append("\"threads seen\": the worker process's threads before → after the conversion "
               "(TBB and OpenMP keep their workers); \"CPU / wall\": CPU seconds of the process "
               "÷ wall seconds over the fastest run (1 ≈ one busy thread).")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--levelset", type=Path, default=DEFAULT_LEVELSET,
                    help="the levelset binary (default target/release/levelset)")
    ap.add_argument("--segments", type=int, nargs=2, default=[316, 158], metavar=("NU", "NV"),
                    help="torus segments around the axis and around the tube (default 316 158)")
    ap.add_argument("--voxel-size", type=float, default=1 / 256, help="default 1/256")
    ap.add_argument("--repeat", type=int, default=3, help="runs per case, the fastest counts")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2],
                    help="thread counts for ours and OpenVDB (default 1 2)")
    ap.add_argument("--viennals-threads", type=int, nargs="+", default=[1],
                    help="thread counts for ViennaLS (default 1)")
    ap.add_argument("--tools", nargs="+", default=TOOLS, choices=TOOLS)
    ap.add_argument("--json", type=Path, help="also write the records to this JSON file")
    # internal: one peer conversion in its own (taskset) process
    ap.add_argument("--worker", choices=["openvdb", "viennals"], help=argparse.SUPPRESS)
    ap.add_argument("--worker-threads", type=int, default=1, help=argparse.SUPPRESS)
    ap.add_argument("--mesh", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.worker:
        return worker_main(a)

    h = a.voxel_size
    if "ours" in a.tools and not a.levelset.exists():
        sys.exit(f"error: {a.levelset} not found (cargo build --release, or --levelset PATH)")
    points, tris = torus_mesh(*a.segments)
    meta = {"date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "machine": machine(), "python": platform.python_version(),
            "numpy": np.__version__,
            "command": "target/vox-venv/bin/python docs/voxelize_bench.py "
                       + " ".join(sys.argv[1:]),
            "voxel_size": h, "repeat": a.repeat,
            "mesh": {"segments": a.segments, "major_radius": MAJOR, "minor_radius": MINOR,
                     "vertices": len(points), "triangles": len(tris),
                     **mesh_checks(points, tris)}}
    if meta["mesh"]["signed_volume"] <= 0:
        sys.exit("error: the torus mesh is not outward-oriented")
    if "ours" in a.tools:
        meta["levelset"] = subprocess.run([str(a.levelset), "--version"], capture_output=True,
                                          text=True).stdout.strip()
        binary = a.levelset.resolve()
        meta["levelset_binary"] = {
            "path": str(binary),
            "modified": datetime.datetime.fromtimestamp(
                binary.stat().st_mtime, datetime.timezone.utc).isoformat(timespec="seconds")}
    records = []
    with tempfile.TemporaryDirectory(prefix="voxbench-") as tmp:
        work = Path(tmp)
        ply, npz = work / "torus.ply", work / "torus.npz"
        write_ply(ply, points, tris)
        np.savez(npz, points=points, triangles=tris)
        levelset = a.levelset
        if "ours" in a.tools:
            # Run a private copy: a rebuild of the binary during the run cannot mix builds.
            levelset = work / "levelset"
            shutil.copy2(a.levelset, levelset)
            meta["levelset_binary"]["sha256"] = hashlib.sha256(
                levelset.read_bytes()).hexdigest()
        cases = [(t, tool) for t in sorted(set(a.threads) | set(a.viennals_threads))
                 for tool in a.tools
                 if t in (a.viennals_threads if tool == "viennals" else a.threads)]
        for threads, tool in cases:
            print(f"[{tool}, {threads} thread(s)] …", file=sys.stderr, flush=True)
            if tool == "ours":
                info, X, values = run_ours(levelset, threads, ply, h, a.repeat, work)
            else:
                info, X, values = run_peer(tool, threads, npz, h, a.repeat, work)
            seconds = min(info["times"])
            rec = {"tool": tool, "threads": threads, "cpus": cpus_for(threads),
                   "seconds": seconds, "ns_per_voxel": 1e9 * seconds / info["band_voxels"],
                   **info, "errors": errors(X, values, h, info["half_width"])}
            if len(values) != info["band_voxels"]:
                rec["note"] = f"{len(values)} voxels read back, {info['band_voxels']} reported"
            for k in ("version",):
                if k in info:
                    meta[f"{tool}_version"] = info[k]
            records.append(rec)
    body = tables(records, meta, a)
    versions = ", ".join(v for v in (
        meta.get("levelset"), meta.get("openvdb_version") and f"OpenVDB {meta['openvdb_version']}"
        " (pyopenvdb)", meta.get("viennals_version") and f"ViennaLS {meta['viennals_version']}")
        if v)
    note = (f"Measured {meta['date']} on {meta['machine']['cpu']}, {meta['machine']['cores']} "
            f"cores, {meta['machine']['simd']} (load {meta['machine']['loadavg_at_start'][0]} at "
            f"start) with `{meta['command']}` ({versions}; NumPy {np.__version__}, Python "
            f"{platform.python_version()}).")
    print(note + "\n\n" + body)
    if a.json:
        clean = lambda v: None if isinstance(v, float) and v != v else v
        for r in records:
            r["errors"] = {k: clean(v) for k, v in r["errors"].items()}
        a.json.parent.mkdir(parents=True, exist_ok=True)
        a.json.write_text(json.dumps({"note": note, "meta": meta, "records": records},
                                     indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
