"""Benchmark: peak memory of `merger merge` / `merger align` on large maps, per stage (issue 37, item 6).

Run from the repository root::

    python benchmarks/bench_large_merge.py                 # three 4224² maps (the office tiled 11 × 11)
    python benchmarks/bench_large_merge.py --tile 8 --maps 2 --command align

The maps are the bundled TurtleBot3 office map tiled N × N (4224 cells a side for 11: beyond 4096 the
warps run in numpy, not OpenCV), written to a temporary folder; the command runs in this process with a
5 ms resident-memory sampler, and each stage is marked by wrapping the function that does it (load the
maps, the orders' searches and verifications on the thread pool, the refinement of the chosen placement,
the fusion, writing the merged map and its overlay). It prints each stage's peak RSS and the process's
ru_maxrss; `/usr/bin/time -v` on the same command gives the same total without the sampler.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import resource
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

OFFICE = Path(__file__).resolve().parents[1] / "tests" / "data" / "real-maps" / "turtlebot3_office.yaml"
STAGES = [("merger.io.inputs", "load_map", "load the maps"),
          ("merger.team.orders", "parallel_map", "search and verify the orders (thread pool)"),
          ("merger.team.orders", "refine_chosen", "refine the chosen placement on the whole maps"),
          ("merger.team.orders", "fuse", "fuse the merged map"),
          ("merger.cli.commands", "write_merge", "write the merged map and its overlay")]


def rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return 0.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tile", type=int, default=11, help="tile the office map N × N (default 11: 4224²)")
    ap.add_argument("--maps", type=int, default=3)
    ap.add_argument("--command", choices=("merge", "align"), default="merge")
    args = ap.parse_args(argv)

    import importlib

    import merger.cli as cli
    from merger.grid import OccupancyGrid
    from merger.io.mapio import load_map, save_map

    label, peaks, order, stop = ["(between stages)"], {}, [], []

    def sample():
        while not stop:
            k = label[-1]
            if k not in peaks:
                order.append(k)
            peaks[k] = max(peaks.get(k, 0.0), rss_mb())
            time.sleep(0.005)

    def mark(module, name, tag):
        mod = importlib.import_module(module)
        if not hasattr(mod, name):
            return
        f = getattr(mod, name)

        def wrapped(*a, **k):
            label.append(tag)
            try:
                return f(*a, **k)
            finally:
                label.pop()
        setattr(mod, name, wrapped)

    with tempfile.TemporaryDirectory() as tmp:
        g = load_map(OFFICE)
        big = OccupancyGrid(np.tile(g.states, (args.tile, args.tile)), g.resolution, g.origin)
        paths = [str(save_map(big, Path(tmp) / f"m{k}")[0]) for k in range(args.maps)]
        del g, big
        for m in STAGES:
            mark(*m)
        cmd = [args.command, *paths[: 2 if args.command == "align" else None], "--center", "-0.25,2.40"]
        if args.command == "merge":
            cmd += ["-o", str(Path(tmp) / "merged")]
        n = 2 if args.command == "align" else args.maps
        print(f"merger {args.command} of {n} maps of {384 * args.tile}² cells", flush=True)
        threading.Thread(target=sample, daemon=True).start()
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):  # the command's own report
            code = cli.main(cmd)
        wall = time.perf_counter() - t0
        stop.append(True)
        time.sleep(0.02)
    for k in order:
        print(f"  {peaks[k]:7.0f} MB  {k}")
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB, {wall:.1f} s, exit {code} "
          "(the machine's load changes the time, not the memory)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
