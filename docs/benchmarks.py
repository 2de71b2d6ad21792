#!/usr/bin/env python3
"""Writes docs/benchmarks.md from the JSON the project's commands print.

    python3 docs/benchmarks.py collect   # runs the commands below, saves docs/data/*.json (~6 min)
    python3 docs/benchmarks.py write     # docs/data/*.json -> docs/benchmarks.md

Every table in docs/benchmarks.md comes from one of these files; each section names the
command that wrote it. `collect` stamps docs/data/meta.json with the date, CPU and the
vector width the build used. Python 3 standard library only.
"""

import datetime
import json
import pathlib
import subprocess
import sys

DOCS = pathlib.Path(__file__).resolve().parent
ROOT = DOCS.parent
DATA = DOCS / "data"

LEVELSET = ["cargo", "run", "--release", "--locked", "-q", "--bin", "levelset", "--"]
SPEEDUP = ["cargo", "run", "--release", "--locked", "-q", "--"]

# (file, command): what `collect` runs. The speed-up report runs twice: the machines are
# shared, so both runs are quoted.
RUNS = [
    ("speedup-1.json", SPEEDUP + ["--json", "docs/data/speedup-1.json"]),
    ("speedup-2.json", SPEEDUP + ["--json", "docs/data/speedup-2.json"]),
    ("storage.json", SPEEDUP + ["--storage", "--json", "docs/data/storage.json"]),
    # The time-to-solution section alone with Enright's test at 256³ (not in the default run).
    ("solution-256.json", SPEEDUP + ["--solution", "--solution-enright-size", "256",
                                     "--json", "docs/data/solution-256.json"]),
    ("info-sphere.json", LEVELSET + ["info", "--shape", "sphere", "--radius", "100", "--json"]),
    # The Stanford bunny is fetched from npm first (docs/data/fetch_bunny.py; not committed).
    ("memory.json", SPEEDUP + ["--memory", "--memory-mesh", "target/bunny.ply",
                               "--json", "docs/data/memory.json"]),
    # Memory while stepping: a sphere of radius 800 and 1600 voxels, three steps each.
    ("run-sphere-2048", LEVELSET + ["run", "sphere", "--size", "2048", "--steps", "3",
                                    "--quiet", "--out", "docs/data/run-sphere-2048"]),
    ("run-sphere-4096", LEVELSET + ["run", "sphere", "--size", "4096", "--steps", "3",
                                    "--quiet", "--out", "docs/data/run-sphere-4096"]),
    ("run-spiral", LEVELSET + ["run", "spiral", "--quiet", "--out", "docs/data/run-spiral"]),
    ("run-enright", LEVELSET + ["run", "enright", "--quiet", "--out", "docs/data/run-enright"]),
    ("run-expand", LEVELSET + ["run", "expand", "--quiet", "--out", "docs/data/run-expand"]),
    ("run-mcf", LEVELSET + ["run", "sphere", "--size", "64", "--radius", "20", "--time", "100",
                            "--quiet", "--out", "docs/data/run-mcf"]),
    # 50 noisy 96³ phantoms segmented as a batch on 1 and 2 threads (made first, in target/).
    ("segment-batch.json", LEVELSET + ["segment", "target/batch50/in", "--method", "gac",
                                       "-o", "target/batch50/out", "--threads", "N"]),
]

BATCH = 50


def segment_batch():
    """Makes the batch's phantoms if missing, runs it on 1 and 2 threads, saves the figures."""
    src = ROOT / "target/batch50/in"
    if len(list(src.glob("*-seeds.json"))) != BATCH:
        for i in range(1, BATCH + 1):
            subprocess.run(LEVELSET + ["phantom", "ball", "--size", "96", "--snr", "3", "--seed",
                                       str(i), "--name", f"ball{i:02}", "-o", str(src)],
                           cwd=ROOT, check=True, capture_output=True)
    runs = []
    for threads in (1, 2):
        out = ROOT / f"target/batch50/out{threads}"
        subprocess.run(LEVELSET + ["segment", str(src), "--method", "gac", "-o", str(out),
                                   "--threads", str(threads)],
                       cwd=ROOT, check=True, capture_output=True)
        summary = json.loads((out / "summary.json").read_text())
        dice = [r["dice"] for r in summary["records"]]
        runs.append({"threads": threads, "images": summary["images"],
                     "failed": summary["failed"], "wall_seconds": summary["wall_seconds"],
                     "dice_min": min(dice), "dice_max": max(dice)})
    (DATA / "segment-batch.json").write_text(json.dumps(runs, indent=2) + "\n")


def shown(cmd):
    """The command as a user types it."""
    if cmd[:6] == LEVELSET[:6]:
        return "levelset " + " ".join(cmd[len(LEVELSET):])
    return "cargo run --release -- " + " ".join(cmd[len(SPEEDUP):])


def collect():
    DATA.mkdir(exist_ok=True)
    only = sys.argv[2:]
    for name, cmd in RUNS:
        if only and name not in only:
            continue
        if name == "memory.json" and not (ROOT / "target/bunny.ply").exists():
            subprocess.run([sys.executable, str(DOCS / "data/fetch_bunny.py"),
                            str(ROOT / "target/bunny.ply")], check=True)
        print("running:", shown(cmd), file=sys.stderr)
        if name == "segment-batch.json":
            segment_batch()
            continue
        out = subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, text=True).stdout
        if name == "info-sphere.json":
            (DATA / name).write_text(out)
    first = json.loads((DATA / "speedup-1.json").read_text())
    today = datetime.date.today().isoformat()
    # The day each file was made: today for those run now, as before for the others.
    try:
        old = json.loads((DATA / "meta.json").read_text())
    except FileNotFoundError:
        old = {}
    dates = {name: old.get("dates", {}).get(name, old.get("date", today)) for name, _ in RUNS}
    machines = {name: old.get("machines", {}).get(name, machine_of(old)) for name, _ in RUNS}
    for name, _ in RUNS:
        if not only or name in only:
            dates[name] = today
            machines[name] = this_machine()
    meta = {
        "date": today,
        "dates": dates,
        "machines": machines,
        "cpu": first["cpu"],
        "target_features": first["target_features"],
        "level": first.get("level", "baseline"),
        "threads": first["threads"],
        "commands": {name: shown(cmd) for name, cmd in RUNS},
    }
    (DATA / "meta.json").write_text(json.dumps(meta, indent=2) + "\n")


def this_machine():
    """The CPU this process runs on and the widest vector level the kernels choose on it at
    run time (from /proc/cpuinfo)."""
    model, flags = "unknown CPU", set()
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and model == "unknown CPU":
                model = " ".join(value.split()[:2])
            elif key.strip() == "flags" and not flags:
                flags = set(value.split())
    except OSError:
        pass
    level = "avx512" if "avx512f" in flags else "avx2" if "avx2" in flags else "sse"
    return f"{model}, {vector_width({'level': level, 'target_features': []})}"


def machine_of(meta):
    """The one machine an older meta.json names for all its files."""
    if not meta:
        return this_machine()
    return f"{meta['cpu']}, {vector_width(meta)}"


def load(name):
    return json.loads((DATA / name).read_text())


def vector_width(meta):
    """The vector unit the kernels ran on: the run-time level (older data: the features
    the build was compiled with)."""
    level = meta.get("level")
    features = meta["target_features"]
    if level == "avx512" or (level is None and "avx512f" in features):
        return "AVX-512 (f32x16 in one register)"
    if level == "avx2" or (level is None and "avx2" in features):
        return "AVX2 (f32x16 as two registers)"
    return "SSE (f32x16 as four registers)"


def pair(a, b, fmt):
    return f"{fmt(a)} / {fmt(b)}"


def speedup_section(meta):
    runs = [load("speedup-1.json"), load("speedup-2.json")]
    out = [
        "## The speed-up over the DT-Grid",
        "",
        f"`{meta['commands']['speedup-1.json']}`, run twice (first / second). The same flows,"
        " kernels and band rule on every representation; stepping time only, the fastest of"
        f" {runs[0].get('reps', 1)} runs of each configuration (every grid alike; the four"
        " configurations of a scenario take turns, run by run); every run of a"
        " scenario ends with the same band (checksum below, max |φ_tiles − φ_dtgrid| = 0)."
        " \"Engine / kernel-only\" is tiles SIMD on one thread against the kernels' in-cache"
        " throughput of the same arithmetic (a dense 32³ block). \"Held per band voxel\" is"
        " what tiles SIMD held while stepping (grid, step buffers, neighbour table, the flow's"
        " per-voxel inputs) over its band voxels.",
        "",
        "| scenario | DT-Grid s | tiles scalar | tiles SIMD, 1 thread | tiles SIMD, 2 threads"
        " | 2 threads / 1 | bytes tiles / DT-Grid | held per band voxel | engine / kernel-only"
        " | checksum |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for i, sc in enumerate(runs[0]["scenarios"]):
        both = [r["scenarios"][i] for r in runs]

        def run(s, label):
            grid, lanes, threads = label
            for r in s["runs"]:
                if r["grid"] == grid and (lanes is None or r["lanes"] == lanes) and (
                    threads is None or r["threads"] == threads
                ):
                    return r
            raise KeyError(label)

        dt = [run(s, ("dtgrid", None, None)) for s in both]
        scal = [run(s, ("tiles", "scalar", 1)) for s in both]
        simd1 = [run(s, ("tiles", "simd", 1)) for s in both]
        top = [max(s["runs"], key=lambda r: r["threads"]) for s in both]
        held = lambda r: (
            f"{r['held_bytes_per_band_voxel']:.1f} B" if "held_bytes_per_band_voxel" in r else "—"
        )
        x = lambda v: f"{v:.2f}×"
        out.append(
            f"| {sc['name']} {sc['size']}³, {sc['kernel']}, {sc['steps']} steps"
            f" | {pair(dt[0]['seconds'], dt[1]['seconds'], lambda v: f'{v:.2f}')}"
            f" | {pair(scal[0]['speedup_vs_dtgrid'], scal[1]['speedup_vs_dtgrid'], x)}"
            f" | {pair(simd1[0]['speedup_vs_dtgrid'], simd1[1]['speedup_vs_dtgrid'], x)}"
            f" | {pair(top[0]['speedup_vs_dtgrid'], top[1]['speedup_vs_dtgrid'], x)}"
            f" | {pair(simd1[0]['seconds'] / top[0]['seconds'], simd1[1]['seconds'] / top[1]['seconds'], lambda v: f'{v:.2f}')}"
            f" | {top[0]['bytes_vs_dtgrid']:.2f}"
            f" | {held(simd1[0])}"
            f" | {pair(both[0]['engine_fraction_of_kernel'], both[1]['engine_fraction_of_kernel'], lambda v: f'{100 * v:.0f} %')}"
            f" | `{dt[0]['checksum']}` |"
        )
    out += [
        "",
        "Operators on the sphere benchmark's initial band (the same runs; best of 3):",
        "",
        "| operator | grid | band voxels | seconds | band Mvoxel/s | result |",
        "|---|---|---|---|---|---|",
    ]
    for i, t in enumerate(runs[0]["tools"]):
        u = runs[1]["tools"][i]
        out.append(
            f"| {t['name']} | {t['grid']} | {t['band_voxels']:,}"
            f" | {pair(t['seconds'], u['seconds'], lambda v: f'{v:.3f}')}"
            f" | {pair(t['band_voxels_per_s'] / 1e6, u['band_voxels_per_s'] / 1e6, lambda v: f'{v:.2f}')}"
            f" | {t['output']} |"
        )
    return out


# The fields of the report's `params` when the time-to-solution section was written; a
# field added since shows up in the settings column by itself.
PARAMS_KNOWN = {
    "scenario", "size", "grid", "lanes", "threads", "scheme", "integrator", "cfl", "voxel_size",
    "half_width", "radius", "epsilon", "speed", "period", "depth", "volume_conserving",
    "rescale", "steps", "time", "record_every", "reinit", "init", "shape", "target",
}


def num(v):
    """A number with up to six significant digits."""
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def solution_settings(p):
    """The method and the end a run used, from its `params`."""
    parts = [f"{p['scheme']} + {p['integrator']}, CFL {num(p['cfl'])}"]
    if p.get("steps") is not None:
        parts.append(f"{p['steps']} steps")
    if p.get("time") is not None:
        parts.append(f"to t = {num(p['time'])}")
    if p.get("volume_conserving"):
        parts.append("volume-conserving")
    if p.get("reinit") is not None:
        parts.append(f"reinit {p['reinit']}")
    parts += [f"{k} {num(v)}" for k, v in p.items() if k not in PARAMS_KNOWN and v is not None]
    return ", ".join(parts)


def solution_error(r):
    if r["error_kind"] == "voxels":
        return f"{r['error']:.4g} voxels"
    kind = r["error_kind"].replace("-", "−").replace("|", "\\|")  # a cell of a Markdown table
    return f"{kind} = {r['error']:.4g}"


def solution_section(meta):
    runs = []
    for name in ["speedup-1.json", "speedup-2.json"]:
        if (DATA / name).exists():
            runs.append(load(name))
    out = ["## Time to solution", ""]
    runs = [r for r in runs if "time_to_solution" in r]
    if not runs:
        return out + [
            "The data files (`docs/data/speedup-*.json`) do not hold this section yet;"
            " `python3 docs/benchmarks.py collect` writes it."
        ]
    extra = load("solution-256.json") if (DATA / "solution-256.json").exists() else None
    out += [
        f"The last section of `{meta['commands']['speedup-1.json']}`"
        + (f" ({len(runs)} runs: first / second)" if len(runs) > 1 else "")
        + ": each scenario run to its end with its default settings (tiles, SIMD lanes),"
        " seconds of stepping (the fastest of"
        f" {runs[0].get('reps', 1)} runs, the thread counts taking turns) against the error of"
        " the answer. Spheres under mean curvature"
        " flow: the radius from the enclosed volume, r = (3V/4π)^(1/3), against √(r₀² − 2εt)"
        " at the final time, error in voxels; Enright's test: V(T)/V(0), exact 1; the"
        " volume-conserving spiral: V/V(0) at the end, exact 1.",
        "",
        "| case | settings | threads | steps | seconds | final t | measured | exact | error"
        " | relative error | checksum |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    key = lambda r: (r["case"], r["size"], r["threads"])
    rows = [(r, [{key(x): x for x in run["time_to_solution"]}.get(key(r)) for run in runs], False)
            for r in runs[0]["time_to_solution"]]
    if extra is not None:
        seen = {(r["case"], r["size"]) for r in runs[0]["time_to_solution"]}
        rows += [(r, [r], True) for r in extra.get("time_to_solution", [])
                 if (r["case"], r["size"]) not in seen]
    for r, same, separate in rows:
        same = [x for x in same if x is not None]
        p = r["params"]
        case = f"{r['case']} {r['size']}³"
        if r["error_kind"] == "voxels":
            case += f", r₀ = {num(p['radius'])}"
        if separate:
            cmd = meta["commands"].get("solution-256.json", "levelset-speedup --solution")
            case += f" (`{cmd}`)"
        sums = sorted({x["checksum"] for x in same})
        seconds = " / ".join(f"{x['seconds']:.{2 if x['seconds'] >= 1 else 3}f}" for x in same)
        out.append(
            f"| {case} | {solution_settings(p)} | {r['threads']} | {r['steps']}"
            f" | {seconds}"
            f" | {num(r['final_time'])}{' (collapsed)' if r['collapsed'] else ''}"
            f" | {r['measured']:.6f} | {r['exact']:.6f} | {solution_error(r)}"
            f" | {r['relative_error']:.3g} | {', '.join(f'`{c}`' for c in sums)} |"
        )
    return out


def storage_section(meta):
    s = load("storage.json")
    out = [
        "## The storage benchmark and the kernels",
        "",
        f"`{meta['commands']['storage.json']}`: the same scalar arithmetic on both grids, runs"
        " alternating between the grids, best of several.",
        "",
        "| shape | operation | DT-Grid s | tiles s | tiles / DT-Grid speed-up |",
        "|---|---|---|---|---|",
    ]
    for shape in s["scenarios"]:
        first = True
        for op in shape["ops"]:
            name = f"{shape['name']} ({shape['band_voxels']:,} band voxels)" if first else ""
            first = False
            out.append(
                f"| {name} | {op['op']} | {op['dtgrid_seconds']:.4f} | {op['tiles_seconds']:.4f}"
                f" | {op['speedup_vs_dtgrid']:.2f}× |"
            )
    kernels = {}
    for r in s["kernels"]:
        kernels.setdefault(r["kernel"], []).append(r)
    if kernels:
        lanes = [r["lanes"] for r in next(iter(kernels.values()))]
        out += [
            "",
            "Kernels alone on a dense in-cache 32³ block, one thread, Mvoxel-updates/s (speed-up"
            " over f32):",
            "",
            "| kernel | " + " | ".join(lanes) + " |",
            "|---|" + "---|" * len(lanes),
        ]
        for name, rows in kernels.items():
            base = rows[0]["voxel_updates_per_s"]
            cells = [
                f"{r['voxel_updates_per_s'] / 1e6:.1f} ({r['voxel_updates_per_s'] / base:.1f}×)"
                for r in rows
            ]
            out.append(f"| {name} | " + " | ".join(cells) + " |")
    return out


def info_section(meta):
    d = load("info-sphere.json")
    out = [
        "## Memory",
        "",
        f"`{meta['commands']['info-sphere.json']}`:",
        "",
        "| grid | band voxels | stored voxels | tiles | values B | indices B | flags B | total B"
        " | bytes / band voxel |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for g in d["grids"]:
        b = g["bytes"]
        total = b["values"] + b["indices"] + b["flags"] + b.get("slack", 0)
        out.append(
            f"| {g['grid']} | {g['band_voxels']:,} | {g['stored_voxels']:,} | {g['tiles'] or '–'}"
            f" | {b['values']:,} | {b['indices']:,} | {b['flags']:,} | {total:,}"
            f" | {g['bytes_per_band_voxel']:.2f} |"
        )
    line = f"Tiles / DT-Grid bytes: {d['tiles_over_dtgrid_bytes']:.2f}."
    if "hrle_over_dtgrid_bytes" in d:
        line += (f" H-RLE / DT-Grid bytes: {d['hrle_over_dtgrid_bytes']:.3f}."
                 f" The `.sls` file: {d['sls_bytes']:,} bytes.")
    out += ["", line]
    return out


def memory_table_section(meta):
    d = load("memory.json")
    out = [
        "## Memory of the H-RLE, the DT-Grid, the tiles and the `.sls` file",
        "",
        "`python3 docs/data/fetch_bunny.py target/bunny.ply` (the Stanford bunny from npm's"
        " `bunny` package, 3,674 triangles), then"
        f" `{meta['commands']['memory.json']}` (half-width {d['half_width']:g}, the H-RLE"
        " paper's band of 6 voxels; bytes in use; the `.sls` file as written). The H-RLE"
        " paper's Table II measured H-RLE / DT-Grid = 1.05–1.07 on the Stanford models.",
        "",
        "| model | bounding box | band voxels | H-RLE | DT-Grid | tiles | .sls | H-RLE / DT-Grid |",
        "|---|---|---|---|---|---|---|---|",
    ]
    mib = lambda b: f"{b / 2**20:,.1f} MiB"
    for r in d["rows"]:
        b = r["bounding_box"]
        out.append(
            f"| {r['model']} | {b[0]}×{b[1]}×{b[2]} | {r['band_voxels']:,} | {mib(r['hrle_bytes'])}"
            f" | {mib(r['dtgrid_bytes'])} | {mib(r['tiles_bytes'])} | {mib(r['sls_bytes'])}"
            f" | {r['hrle_over_dtgrid']:.3f} |"
        )
    out += [
        "",
        "The unenclosed row stores a sphere clipped by the plane x = 0: open in the H-RLE"
        " (its domain reads +γ beyond the cut), while the DT-Grid and the tiles must hold the"
        " closed hemisphere, with a band along the cut.",
    ]
    return out


def evolution_section(meta):
    out = [
        "## Evolution",
        "",
        "Tile engine, SIMD lanes, both cores; the numbers are from each run's"
        " `summary.json` (`--out DIR`).",
        "",
        "| command | steps | result |",
        "|---|---|---|",
    ]
    for name in ["run-spiral", "run-enright", "run-expand", "run-mcf"]:
        s = load(f"{name}/summary.json")
        recs = s["records"]
        v0, v1 = recs[0]["volume"], recs[-1]["volume"]
        result = f"V/V0 = {v1 / v0:.6f}"
        if s.get("volume_ratio_half_period") is not None:
            result = (
                f"V(T/2)/V(0) = {s['volume_ratio_half_period']:.6f},"
                f" V(T)/V(0) = {s['volume_ratio_period']:.6f}"
            )
        if name == "run-mcf":
            r = (3 * v1 / (4 * 3.141592653589793)) ** (1 / 3)
            result += f", radius from the volume {r:.2f} (exact √(20² − 2·100) = 14.14)"
        if name == "run-expand":
            r = (3 * v1 / (4 * 3.141592653589793)) ** (1 / 3)
            result += f", radius from the volume {r:.2f}, bytes {recs[0]['bytes']:,} → {recs[-1]['bytes']:,}"
        out.append(f"| `{meta['commands'][name]}` | {s['steps_taken']} | {result} |")
    return out


def stepping_memory_section(meta):
    out = [
        "## Memory while stepping",
        "",
        "Large spheres on tiles (first-order upwind, forward Euler, two renormalisation"
        " sweeps per step with their anchors: the `sphere` scenario's defaults), both cores;"
        " from each run's `summary.json`. Peak resident is the process's (`VmHWM`), set-up"
        " included; the estimate is what the run was admitted with before the band was built"
        " (the shape's area times the band's stored thickness, times the engine's bytes per"
        " tile while stepping). Bands of these sizes step with φⁿ packed and every sweep in"
        " place; bands whose values take at most `Settings::double_buffer_bytes` (64 MiB by"
        " default) keep φⁿ whole beside a double buffer instead, faster and about two value"
        " arrays larger (decision 0043).",
        "",
        "| command | band voxels | grid bytes | seconds per step | peak resident"
        " | per band voxel | × grid | estimate (error) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in ["run-sphere-2048", "run-sphere-4096"]:
        s = load(f"{name}/summary.json")
        last, m = s["records"][-1], s["memory"]
        peak, est = m["peak_resident_bytes"], m["estimated_bytes"]
        out.append(
            f"| `{meta['commands'][name]}` | {last['band_voxels']:,} | {last['bytes'] / 1e9:.3f} GB"
            f" | {s['seconds'] / s['steps_taken']:.2f} | {peak / 1e9:.2f} GB"
            f" | {m['peak_resident_per_band_voxel']:.1f} B | {m['peak_resident_over_grid']:.2f}"
            f" | {est / 1e9:.2f} GB ({100 * (est - peak) / peak:+.0f} %) |"
        )
    return out


def segmentation_section(meta):
    runs = [load("speedup-1.json"), load("speedup-2.json")]
    rows = runs[0]["segmentation"]
    out = [
        "## Segmentation",
        "",
        f"From the same two runs of `{meta['commands']['speedup-1.json']}` (first / second):"
        f" `levelset segment`'s methods with their defaults on the {rows[0]['phantom']}"
        " phantom (`levelset phantom`), the fastest of the runs of each. Mvox/s counts"
        " stored voxels × RK stages per second of stepping, as the scenarios above; seconds"
        " are the whole segmentation (feature images, steps, region sums, stopping tests)."
        " The comparison with SimpleITK is in [segmentation.md](segmentation.md).",
        "",
        "| method | threads | steps | seconds | step seconds | Mvox/s | Dice |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(rows):
        b = runs[1]["segmentation"][i]
        out.append(
            f"| {r['method']} | {r['threads']} | {r['steps']} | "
            f"{pair(r['seconds'], b['seconds'], lambda v: f'{v:.3f}')} | "
            f"{pair(r['seconds_steps'], b['seconds_steps'], lambda v: f'{v:.3f}')} | "
            f"{pair(r['voxel_updates_per_s'], b['voxel_updates_per_s'], lambda v: f'{v / 1e6:.1f}')} | "
            f"{r['dice']:.4f} |"
        )
    batch = load("segment-batch.json")
    out += [
        "",
        f"A batch of {batch[0]['images']} noisy 96³ balls (`levelset phantom ball --size 96"
        " --snr 3 --seed i`), `levelset segment DIR --method gac -o OUT --threads N`: images"
        " in parallel, one thread each.",
        "",
        "| threads | wall seconds | failed | Dice min – max |",
        "|---|---|---|---|",
    ]
    for r in batch:
        out.append(f"| {r['threads']} | {r['wall_seconds']:.1f} | {r['failed']} |"
                   f" {r['dice_min']:.4f} – {r['dice_max']:.4f} |")
    return out


def python_section(meta):
    runs = [load("python-1.json"), load("python-2.json")]
    out = [
        "## Python beside scikit-fmm and scikit-image",
        "",
        f"Two runs of `{runs[0]['command']}` (first / second; calls of the two alternated, the fastest of each side's):"
        " `sparse_levelset.distance` against `skfmm.distance` (order 2) on a distorted torus"
        " (n³) and circle (n²),"
        " `sparse_levelset.isosurface` against `skimage.measure.marching_cubes` on a sphere;"
        " errors in voxels (the same in both runs). Tables and conditions:"
        " [python.md](python.md).",
        "",
        "| size | narrow | max error ≤ 2.5 voxels: scikit-fmm / ours | seconds: scikit-fmm | seconds: ours | speed-up |",
        "|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(runs[0]["distance"]):
        b = runs[1]["distance"][i]
        narrow = "—" if r["narrow"] is None else f"{r['narrow']:g}"
        out.append(
            f"| {r['n']}{'²' if r.get('dims', 3) == 2 else '³'} | {narrow} |"
            f" {r['max_near_skfmm']:.3f} / {r['max_near_ours']:.3f} | "
            f"{pair(r['t_skfmm'], b['t_skfmm'], lambda v: f'{v:.3f}')} | "
            f"{pair(r['t_ours'], b['t_ours'], lambda v: f'{v:.3f}')} | "
            f"{r['t_skfmm'] / r['t_ours']:.1f}× / {b['t_skfmm'] / b['t_ours']:.1f}× |"
        )
    out += [
        "",
        "| n³ | area error: marching_cubes / ours | seconds: marching_cubes | seconds: ours | speed-up |",
        "|---|---|---|---|---|",
    ]
    for i, r in enumerate(runs[0]["isosurface"]):
        b = runs[1]["isosurface"][i]
        out.append(
            f"| {r['n']} | {100 * r['err_skimage']:+.3f} % / {100 * r['err_ours']:+.3f} % | "
            f"{pair(r['t_skimage'], b['t_skimage'], lambda v: f'{v:.3f}')} | "
            f"{pair(r['t_ours'], b['t_ours'], lambda v: f'{v:.3f}')} | "
            f"{r['t_skimage'] / r['t_ours']:.1f}× / {b['t_skimage'] / b['t_ours']:.1f}× |"
        )
    return out


def voxelize_section(meta):
    runs = [load("voxelize-1.json"), load("voxelize-2.json")]
    names = {"ours": "`levelset voxelize`", "openvdb": "OpenVDB `meshToLevelSet`",
             "viennals": "ViennaLS `FromSurfaceMesh`"}
    m = runs[0]["meta"]
    mesh = m["mesh"]
    out = [
        "## Voxelization beside OpenVDB and ViennaLS",
        "",
        f"Two runs of `{m['command'].replace('voxelize-1.json', 'voxelize-N.json')}`"
        f" on {m['date'][:10]} (first / second; the fastest of {m['repeat']} conversions each, every"
        " tool in its own process under `taskset` on the CPUs named): a UV torus of"
        f" {mesh['triangles']:,} triangles (major radius {mesh['major_radius']}, minor radius"
        f" {mesh['minor_radius']}) at voxel size {m['voxel_size']} (1/256). Ours and"
        " OpenVDB keep a band of half-width 3, ViennaLS what `FromSurfaceMesh` stores (the"
        " grid points on either side of each grid line's crossing, values clamped to ±1"
        " voxel). Errors in voxels against the analytic torus's signed distance at each"
        " tool's band voxels within 2 voxels of the surface (the mesh's own chord error is"
        " 0.013 voxel).",
        "",
        "| tool | threads | seconds | band voxels | ns per band voxel | ns per band voxel ÷ ours | max / mean error near the surface |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, r in enumerate(runs[0]["records"]):
        b = runs[1]["records"][i]
        ours = [x for x in runs[0]["records"] if x["tool"] == "ours" and x["threads"] == r["threads"]][0]
        ours_b = [x for x in runs[1]["records"] if x["tool"] == "ours" and x["threads"] == r["threads"]][0]
        e = r["errors"]
        out.append(
            f"| {names[r['tool']]} | {r['threads']} |"
            f" {pair(r['seconds'], b['seconds'], lambda v: f'{v:.3f}')} |"
            f" {r['band_voxels']:,} | {pair(r['ns_per_voxel'], b['ns_per_voxel'], lambda v: f'{v:.0f}')} |"
            f" {r['ns_per_voxel'] / ours['ns_per_voxel']:.2f} / {b['ns_per_voxel'] / ours_b['ns_per_voxel']:.2f} |"
            f" {e['max_near']:.3f} / {e['mean_near']:.4f} |"
        )
    return out


def segment2d_section(meta):
    """2-D images beside scikit-image's morphological snakes (docs/segment2d_bench.py)."""
    runs = [load("segment2d-1.json"), load("segment2d-2.json")]
    out = [
        "## 2-D segmentation beside scikit-image's morphological snakes",
        "",
        "Two runs of `target/py-venv/bin/python docs/segment2d_bench.py --repeat 2 --json"
        " docs/data/segment2d-N.json` (first / second; the fastest of 2 calls each, in one"
        " process; ours on both cores). scikit-image's side is called as its gallery example"
        " \"Morphological Snakes\" calls it; the references (Otsu's partition for `camera()`,"
        " scikit-image's own watershed segmentation for `coins()`, the disk for the noisy disk)"
        " and the starts are described in the script. The last column is scikit-image's time"
        " for the same method (Chan–Vese or GAC) on the same image ÷ ours.",
        "",
        "| image | side | method and start | seconds | Dice | scikit-image's time ÷ ours | ours: iterations, stop |",
        "|---|---|---|---|---|---|---|",
    ]
    out[2] += f" Run 1: {runs[0]['note']} Run 2: {runs[1]['note']}"
    for r, b in zip(runs[0]["records"], runs[1]["records"]):
        ours = r["side"] == "ours"
        out.append(
            f"| {r['image']} | {r['side']} | {r['tool']} |"
            f" {pair(r['seconds'], b['seconds'], lambda v: f'{v:.3f}')} |"
            f" {pair(r['dice'], b['dice'], lambda v: f'{v:.4f}')} |"
            f" {pair(r['speed'], b['speed'], lambda v: f'{v:.2f}') if ours else '—'} |"
            f" {r['note'] if ours else '—'} |"
        )
    return out


def distributed_section(meta):
    """Enright 256³: one process on two threads against two MPI ranks on one thread each."""
    one = [load(f"distributed/e1x2-{i}.json") for i in (1, 2)]
    two = [load(f"distributed/e2x1-{i}.json") for i in (1, 2)]
    serial = load("distributed/e1.json")
    sums = {r["checksum"] for r in one + two + [serial]}
    if len(sums) != 1:
        raise KeyError("the distributed runs end with different bands")
    halo = [h for r in two for h in r["distributed"]["halo"]]
    share = [h["seconds"] / r["seconds"] for r in two for h in r["distributed"]["halo"]]
    red = [h["reduction_seconds"] / r["seconds"] for r in two for h in r["distributed"]["halo"]]
    steps = two[0]["steps_taken"]
    return [
        "## Distributed runs (MPI)",
        "",
        "`levelset run enright --size 256` (1,200 steps, one period) on this 2-core machine,"
        " two alternated runs each (first / second), measured on 2026-11-24 (AMD EPYC,"
        " AVX-512, OpenMPI 4.1.4, a build with `--features mpi`): one process with"
        " `--threads 2` against `mpirun -n 2 ... --threads 1`, and one process on one thread."
        " Every run ended with the same band (checksum"
        f" `{sums.pop()}`). The model of larger runs: [distributed.md](distributed.md).",
        "",
        "| layout | seconds of stepping | ÷ seconds of 1 process × 2 threads |",
        "|---|---|---|",
        f"| 1 process × 1 thread | {serial['seconds']:.2f} | "
        f"{serial['seconds'] / one[0]['seconds']:.2f}× |",
        f"| 1 process × 2 threads | {pair(one[0]['seconds'], one[1]['seconds'], lambda v: f'{v:.2f}')} | 1 |",
        f"| 2 ranks × 1 thread | {pair(two[0]['seconds'], two[1]['seconds'], lambda v: f'{v:.2f}')} | "
        f"{two[0]['seconds'] / one[0]['seconds']:.2f}× / {two[1]['seconds'] / one[1]['seconds']:.2f}× |",
        "",
        f"On 2 ranks, each rank sent {min(h['bytes'] for h in halo) / steps / 1e3:.0f}–"
        f"{max(h['bytes'] for h in halo) / steps / 1e3:.0f} kB per step in"
        f" {halo[0]['messages'] / steps:.1f} messages (five exchanges: three RK stages, the"
        " renormalisation sweep, the hand-over after tile management) and spent"
        f" {100 * min(share):.1f}–{100 * max(share):.1f} % of its stepping time in the"
        f" exchanges (packing, transfer and waiting for the other rank) and"
        f" {100 * min(red):.1f}–{100 * max(red):.1f} % in the"
        f" {halo[0]['reductions'] / steps:.1f} reductions per step; the cuts moved"
        f" {halo[0]['rebalances']} times.",
    ]


def run_days(meta):
    """When and where the files were made: one day and machine, or each with its files."""
    dates = meta.get("dates") or {name: meta["date"] for name in meta["commands"]}
    machines = meta.get("machines") or {}
    where = {name: machines.get(name, machine_of(meta)) for name in dates}
    runs = sorted(set((dates[n], where[n]) for n in dates))
    if len(runs) == 1:
        return f"on {runs[0][0]}: CPU {runs[0][1]}, {meta['threads']} cores"
    groups = [
        f"{d} on {m} ({', '.join(sorted(n for n in dates if (dates[n], where[n]) == (d, m)))})"
        for d, m in runs
    ]
    return (
        f"on these days and CPUs ({meta['threads']} cores each), by the files in `docs/data/`: "
        + "; ".join(groups)
    )


def write():
    meta = load("meta.json")
    parts = [
        "# Measured figures",
        "",
        "Written by `python3 docs/benchmarks.py write` from the JSON files in `docs/data/`,"
        " which `python3 docs/benchmarks.py collect` made by running the commands named in"
        f" each section {run_days(meta)}. A JSON file that records a `level` comes from"
        " a release build for the x86-64 baseline that ran at that instruction-set level,"
        " chosen at run time; one without comes from a release build with"
        " `-C target-cpu=native` (the same kernels, at the same width)."
        " The machine is shared: ratios within one run are what"
        " to compare, and the speed-up report is quoted from two runs.",
        "",
    ]
    sections = [speedup_section, segmentation_section, python_section, voxelize_section,
                segment2d_section, distributed_section,
                solution_section, info_section, memory_table_section, storage_section,
                stepping_memory_section, evolution_section]
    for section in sections:
        try:
            parts += section(meta) + [""]
        except (FileNotFoundError, KeyError) as e:
            print(f"skipped {section.__name__}: missing {e}", file=sys.stderr)
    accuracy = DATA / "accuracy.md"
    if accuracy.exists():
        parts += [accuracy.read_text().rstrip(), ""]
    (DOCS / "benchmarks.md").write_text("\n".join(parts))


if __name__ == "__main__":
    {"collect": collect, "write": write}[sys.argv[1] if len(sys.argv) > 1 else "write"]()
