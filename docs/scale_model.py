#!/usr/bin/env python3
"""The scale model of docs/distributed.md: measured halo traffic extrapolated to many ranks.

Inputs are the summary.json files of two runs of one scenario at size n on this machine:
  --one    `levelset run SCENARIO --size n --threads 1` (one process, one thread): the
           compute time per tile and step, and the tiles;
  --ranks  `mpirun -n 3 levelset run SCENARIO --size n --threads 1` (three ranks): the
           halo bytes, messages, exchanges and reductions per step of the middle rank,
           which has a neighbour on either side like every inner rank of a larger run.

The model, for the same scenario at size N (scale s = N/n, steps not needed: all figures
are per step):
  * tiles grow as s^2 (the band is a surface), slabs (z-layers of tiles) as s;
  * an inner rank sends two ghost slabs per exchange whatever the number of ranks P, so
    its halo bytes per step grow as s (the perimeter of a slab), and its message and
    exchange counts stay;
  * its compute per step is tiles / P times the measured time per tile and step (one
    thread per rank);
  * a reduction (an all-gather) costs ceil(log2 P) latencies, a message one;
  * 80 % efficiency leaves a quarter of the compute time for communication (nothing is
    overlapped): bandwidth >= bytes / (compute / 4 - latencies).
A decomposition into z-slabs needs at least one slab per rank: P <= slabs.

Prints a Markdown table. Example:
  python3 docs/scale_model.py --one e1/summary.json --ranks e3/summary.json \
      --name "Enright" --size 4096 --ranks-list 64 1024
"""

import argparse
import json
import math


def load(path):
    with open(path) as f:
        return json.load(f)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--one", required=True, help="summary.json of one process, one thread")
    ap.add_argument("--ranks", required=True, help="summary.json of a 3-rank run")
    ap.add_argument("--name", required=True)
    ap.add_argument("--size", type=int, default=4096, help="the target size N")
    ap.add_argument("--ranks-list", type=int, nargs="+", default=[64, 1024])
    ap.add_argument("--latency-us", type=float, default=2.0, help="per message or reduction stage")
    args = ap.parse_args()

    one, dist = load(args.one), load(args.ranks)
    n = one["params"]["size"]
    if dist["params"]["size"] != n or one["checksum"] != dist["checksum"]:
        raise SystemExit("the two runs must be the same scenario, size and band (checksum)")
    steps = one["steps_taken"]
    records = one["records"]
    # Mean stored tiles over the run (records are every few steps; close enough for a model).
    tiles = sum(r["tiles"] for r in records) / len(records)
    t_tile = one["seconds"] / (steps * tiles)
    d = dist["distributed"]
    if d["ranks"] < 3:
        raise SystemExit("--ranks: a run on 3 or more ranks (an inner rank has two neighbours)")
    inner = max(d["halo"], key=lambda h: h["bytes"])
    dsteps = dist["steps_taken"]
    bytes_step = inner["bytes"] / dsteps
    msgs_step = inner["messages"] / dsteps
    reductions_step = inner["reductions"] / dsteps
    slabs = d["slabs"]

    s = args.size / n
    big_tiles = tiles * s * s
    big_bytes = bytes_step * s
    big_slabs = slabs * s
    lat = args.latency_us * 1e-6
    print(f"| {args.name} | ranks | tiles per rank | compute per step | halo per rank and step "
          f"| messages + reductions per step | bandwidth for 80 % |")
    print("|---|---|---|---|---|---|---|")
    print(f"| measured at {n}³ (inner rank of 3) | 3 | {tiles / 3:,.0f} | "
          f"{tiles / 3 * t_tile * 1e3:.2f} ms | {bytes_step / 1e3:,.1f} kB | "
          f"{msgs_step:.1f} + {reductions_step:.1f} | |")
    for p in args.ranks_list:
        comp = big_tiles / p * t_tile
        latency = msgs_step * lat + reductions_step * math.ceil(math.log2(p)) * lat
        budget = comp / 4 - latency
        if p > big_slabs:
            # Whole-slab cuts leave ranks empty: the model does not apply.
            bw = f"n/a: {big_slabs:,.0f} slabs for {p:,} ranks"
        elif budget <= 0:
            bw = "latency-bound"
        else:
            bw = f"{big_bytes / budget / 1e9:.2f} GB/s"
        print(f"| {args.size}³ | {p:,} | {big_tiles / p:,.0f} | {comp * 1e3:.1f} ms | "
              f"{big_bytes / 1e6:.2f} MB | {msgs_step:.1f} + {reductions_step:.1f} | {bw} |")
    print()
    print(f"Inputs: {tiles:,.0f} tiles at {n}³ over {steps} steps, {t_tile * 1e6:.2f} µs per "
          f"tile and step on one thread, {slabs} slabs; at {args.size}³ {big_tiles:,.0f} "
          f"tiles, {big_slabs:,.0f} slabs; latency {args.latency_us} µs per message and per "
          f"reduction stage.")


if __name__ == "__main__":
    main()
