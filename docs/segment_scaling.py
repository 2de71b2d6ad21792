#!/usr/bin/env python3
"""How `levelset segment` scales from one thread to two on one volume, on images made elsewhere.

    target/py-venv/bin/python docs/segment_scaling.py                 # phantoms2, 128³, SNR 2
    target/py-venv/bin/python docs/segment_scaling.py --mni           # and the MNI T1
    target/py-venv/bin/python docs/segment_scaling.py --kinds torus --repeat 9 --json OUT.json
    target/py-venv/bin/python docs/segment_scaling.py --vs OTHER/levelset --repeat 15

The images come from the second phantom generator, docs/validation/phantoms2.py (NumPy and
SciPy, nothing shared with `levelset phantom`; written into --work if missing), and with
--mni from the MNI ICBM152 2009a T1 that nilearn's wheel ships (docs/data/fetch_mni.py, run
first into target/validation/mni), its white matter from seeds file A. Each method runs with
its default parameters from the generator's seeds (threshold with the seeds file's window),
`--threads 1` and `--threads 2` in turn, --repeat times each; the fastest `seconds` of
`levelset segment --json` is kept (the whole segmentation: feature images, steps, sums,
stopping tests; not reading or writing the files). The table gives both times, their ratio and
the Dice against the truth (the same on both thread counts: the results are bitwise
identical).

With --vs OTHER, the same runs compare two builds of `levelset` instead: on each thread count
the two run in turn, --repeat times, and the table gives each one's median `seconds` and
page faults (the operating system's count for the finished process, reading and writing the
files included) and the median of the pairs' ratios; the two masks must be bitwise the same.
"""

import argparse
import filecmp
import json
import pathlib
import resource
import statistics
import subprocess
import sys

DOCS = pathlib.Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS))
import segmentation_bench as segbench  # noqa: E402  (the seeds files' reader)

METHODS = ["threshold", "gac", "chan-vese"]


def seed_args(seeds_file):
    """The seeds file's seeds as `--seed` arguments, and its threshold window as `--lower` /
    `--upper` (read by docs/segmentation_bench.py's reader)."""
    seeds, lower, upper = segbench.read_seeds(pathlib.Path(seeds_file))
    args = [a for s in seeds for a in ("--seed", segbench.seed_arg(s))]
    window = []
    if lower is not None:
        window += ["--lower", str(lower)]
    if upper is not None:
        window += ["--upper", str(upper)]
    return args, window


def cases(args):
    work = args.work
    for kind in args.kinds:
        name = f"{kind}-snr{args.snr:g}"
        image = work / f"{name}.nii.gz"
        if not image.exists():
            subprocess.run([sys.executable, str(DOCS / "validation" / "phantoms2.py"), "-o",
                            str(work), "--size", str(args.size), "--snr", str(args.snr),
                            "--kinds", kind], check=True)
        yield (f"{name} {args.size}³", image, work / f"{name}-truth.nii.gz",
               *seed_args(work / f"{name}-seeds.json"))
    if args.mni:
        mni = ROOT / "target" / "validation" / "mni"
        image = mni / "mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz"
        if not image.exists():
            sys.exit(f"error: {image} is missing; run python3 docs/data/fetch_mni.py first")
        yield ("MNI T1 white matter", image, mni / "wm-truth.nii.gz",
               *seed_args(mni / "wm-seeds-A.json"))


def run(levelset, image, truth, seeds, window, method, threads, out):
    cmd = [str(levelset), "segment", str(image), "--method", method, *seeds,
           "-o", str(out), "--truth", str(truth), "--threads", str(threads), "--json"]
    if method == "threshold":
        cmd += window
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"error: {' '.join(cmd)} failed:\n{done.stderr}")
    return json.loads(done.stdout)


def faults_of(f):
    """`f()` and the page faults of the child processes it waited for."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN).ru_minflt
    out = f()
    return out, resource.getrusage(resource.RUSAGE_CHILDREN).ru_minflt - before


def compare(args):
    """The --vs table: this build against another, run in turn."""
    builds = {"A": args.levelset, "B": args.vs}
    print(f"A: {args.levelset}, B: {args.vs}")
    print("| image | method | threads | A s | B s | A / B | A page faults | B page faults |")
    print("|---|---|---|---|---|---|---|---|")
    for name, image, truth, seeds, window in cases(args):
        for method in args.methods:
            for threads in (1, 2):
                seen = {"A": [], "B": []}
                for _ in range(args.repeat):
                    masks = {}
                    for key, levelset in builds.items():
                        masks[key] = args.work / f"mask-{method}-{threads}t-{key}.nii.gz"
                        r, faults = faults_of(lambda: run(levelset, image, truth, seeds, window,
                                                          method, threads, masks[key]))
                        seen[key].append((r["seconds"], faults))
                    if not filecmp.cmp(masks["A"], masks["B"], shallow=False):
                        sys.exit(f"error: {name} {method} on {threads} threads: the masks differ")
                med = {k: [statistics.median(x[i] for x in v) for i in (0, 1)]
                       for k, v in seen.items()}
                pairs = statistics.median(a[0] / b[0] for a, b in zip(seen["A"], seen["B"]))
                print(f"| {name} | {method} | {threads} | {med['A'][0]:.3f} | {med['B'][0]:.3f} |"
                      f" {pairs:.2f} | {med['A'][1]:.0f} | {med['B'][1]:.0f} |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--levelset", type=pathlib.Path, default=ROOT / "target/release/levelset")
    ap.add_argument("--work", type=pathlib.Path, default=ROOT / "target/segscale",
                    help="phantoms and masks (default target/segscale)")
    ap.add_argument("--size", type=int, default=128, help="n of the n³ phantoms (default 128)")
    ap.add_argument("--snr", type=float, default=2.0, help="the phantoms' SNR (default 2)")
    ap.add_argument("--kinds", nargs="+", default=["blobs", "torus"],
                    help="phantoms2.py kinds (default blobs torus)")
    ap.add_argument("--methods", nargs="+", default=METHODS, choices=METHODS)
    ap.add_argument("--mni", action="store_true", help="also the MNI T1's white matter")
    ap.add_argument("--repeat", type=int, default=5, help="runs per thread count (default 5)")
    ap.add_argument("--json", type=pathlib.Path, help="also write the rows here")
    ap.add_argument("--vs", type=pathlib.Path, metavar="OTHER",
                    help="compare with this other build of levelset instead (see above)")
    args = ap.parse_args()
    for levelset in filter(None, [args.levelset, args.vs]):
        if not levelset.exists():
            sys.exit(f"error: {levelset} is missing (cargo build --release -p levelset-cli)")
    args.work.mkdir(parents=True, exist_ok=True)
    if args.vs:
        if args.json:
            sys.exit("error: --json writes the one-build table; it cannot go with --vs")
        compare(args)
        return
    rows = []
    print("| image | method | 1 thread, s | 2 threads, s | 2 threads / 1 | Dice |")
    print("|---|---|---|---|---|---|")
    for name, image, truth, seeds, window in cases(args):
        for method in args.methods:
            best, dice = {1: None, 2: None}, None
            for _ in range(args.repeat):
                for threads in (1, 2):
                    r = run(args.levelset, image, truth, seeds, window, method, threads,
                            args.work / f"mask-{method}-{threads}t.nii.gz")
                    s = r["seconds"]
                    best[threads] = s if best[threads] is None else min(best[threads], s)
                    dice = r.get("dice")
            ratio = best[1] / best[2]
            rows.append({"image": name, "method": method, "seconds_1": best[1],
                         "seconds_2": best[2], "ratio": ratio, "dice": dice})
            print(f"| {name} | {method} | {best[1]:.3f} | {best[2]:.3f} | {ratio:.2f} |"
                  f" {dice:.4f} |", flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
