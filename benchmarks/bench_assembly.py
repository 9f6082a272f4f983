"""Benchmark: the team's consensus assembly (merger.team.consensus.assemble, issue 43) — each pair of clusters
evaluated once per state against evaluating every pair afresh each round (the code before 2026-12-07), and
the paths' conflict checks compiled (Paths.conflict, a numba kernel) against the same in numpy
(Paths.conflict_reference, the code before 2026-12-07's sixth session).

Run from the repository root::

    python benchmarks/bench_assembly.py            # N = 8, 16, 32 maps, 2 s of repeats each
    python benchmarks/bench_assembly.py --sizes 16,32 --seconds 5

Each team: N maps on a circle 360/N° apart (small translations), about half of all pairs measured (ν 0.5–0.9),
a few of them wrong (a turn of 20–340°), and every robot's path (so that the paths' conflict checks run, as in
the simulation). Printed per N: milliseconds per assembly each way, the ratios, and whether they gave the same
assembly (placements, used measurements, rejections with reasons, left-out maps, joins).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import merger.team.consensus as consensus
from merger.team.consensus import Measurement, assemble, compose, inverse


def team(n: int, seed: int = 1, density: float = 0.5, wrong: int = 3, steps: int = 120):
    rng = np.random.default_rng(seed)
    truth = [(360.0 * k / n, *map(float, rng.uniform(-0.2, 0.2, 2))) for k in range(n)]
    names = [f"R{k:02d}" for k in range(n)]
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n) if rng.random() < density]
    bad = {pairs[k] for k in rng.permutation(len(pairs))[:wrong]}
    meas = []
    for i, j in pairs:
        off = (float(rng.uniform(20, 340)), 0.0, 0.0) if (i, j) in bad else (0.0, 0.0, 0.0)
        z = compose(off, compose(inverse(truth[i]), truth[j]))
        meas.append(Measurement(i, j, z, float(rng.uniform(0.5, 0.9)), f"{names[i]}|{names[j]}"))
    paths = []
    for k in range(n):  # robot k's path on a 3 m circle, in its own map's centered coordinates
        t = 0.25 * np.arange(steps)
        phi = np.radians(360.0 * k / n) + 0.05 * t
        world = np.stack([3.0 * np.cos(phi), 3.0 * np.sin(phi)], axis=1)
        inv = inverse(truth[k])
        c, s = math.cos(math.radians(inv[0])), math.sin(math.radians(inv[0]))
        own = np.stack([inv[1] + c * world[:, 0] - s * world[:, 1], inv[2] + s * world[:, 0] + c * world[:, 1]], 1)
        paths.append(np.column_stack([t, own]))
    return meas, names, paths


def timed(n: int, meas, names, paths, once: bool, seconds: float, compiled: bool = True):
    consensus._EVALUATE_ONCE = once
    kernel = consensus.Paths.conflict
    if not compiled:
        consensus.Paths.conflict = consensus.Paths.conflict_reference
    try:
        out, k, t0 = None, 0, time.perf_counter()
        while k == 0 or time.perf_counter() - t0 < seconds:
            out = assemble(n, meas, tested=n * (n - 1) // 2, nu_min=0.5, names=names, trajectories=paths)
            k += 1
        return (time.perf_counter() - t0) / k * 1e3, out
    finally:
        consensus._EVALUATE_ONCE = True
        consensus.Paths.conflict = kernel


def same(a, b) -> bool:
    return (a.place == b.place and [m.label for m in a.used] == [m.label for m in b.used]
            and a.rejected == b.rejected and a.left_out == b.left_out and a.joins == b.joins)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="8,16,32", metavar="N,N,...")
    ap.add_argument("--seconds", type=float, default=2.0, help="repeats per size and way (default 2 s)")
    args = ap.parse_args()
    print("| maps | measurements | afresh, numpy checks (ms) | once, numpy checks (ms) | once, compiled checks (ms) "
          "| once / afresh | compiled / numpy | same assembly |")
    print("|---|---|---|---|---|---|---|---|")
    for n in (int(x) for x in args.sizes.split(",")):
        meas, names, paths = team(n)
        timed(n, meas, names, paths, True, 0.0)  # the kernel compiled (or loaded) before timing
        fresh_ms, fresh = timed(n, meas, names, paths, False, args.seconds, compiled=False)
        numpy_ms, by_numpy = timed(n, meas, names, paths, True, args.seconds, compiled=False)
        once_ms, once = timed(n, meas, names, paths, True, args.seconds)
        print(f"| {n} | {len(meas)} | {fresh_ms:.1f} | {numpy_ms:.1f} | {once_ms:.1f} | {fresh_ms / numpy_ms:.2f}× "
              f"| {numpy_ms / once_ms:.2f}× | {same(once, fresh) and same(once, by_numpy)} |", flush=True)

if __name__ == "__main__":
    main()
