"""Benchmark: the searches on inputs that are hard for their bounds — a real map against itself, with the
center on a cell corner, a cell centre, one of each, or anywhere; even and odd ROI sides; all three
measures; rotation only and with the translation window.

Run from the repository root::

    python benchmarks/bench_worst.py                       # the bundled office map (ROS map_server)
    python benchmarks/bench_worst.py --map other.yaml --center 1.0,2.0
    python benchmarks/bench_worst.py --tile 10             # the map tiled 10 × 10 (a 192 m map)

Why these inputs: a map against itself has a plateau of equal best scores (θ = 0) that the exact
searches must prove, and a center on cell borders puts lattice points on cell borders (a center on a
cell centre with an even ROI side, on a corner with an odd one), where the reference's reads are float
ties and the windowed search's reference ROIs are not plain blocks of the grid. Every answer is checked
against the truth (θ = 0, t = 0; a line is flagged otherwise) and printed with its wall time and the
process's peak memory. Speed is not asserted anywhere; README quotes these figures.
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from merger import search_pair  # noqa: E402
from merger.grid import OccupancyGrid  # noqa: E402
from merger.io.mapio import load_map  # noqa: E402

OFFICE = Path(__file__).resolve().parents[2] / "shared" / "data" / "real-maps" / "turtlebot3_office.yaml"
MEASURES = ("similarity", "birk_carpin", "ncc")


def centers(grid: OccupancyGrid, near) -> dict[str, tuple[float, float]]:
    """Centers near ``near``: on a cell corner, a cell centre, mixed (corner in x, centre in y), anywhere."""
    res, (ox, oy) = grid.resolution, grid.origin
    i, j = round((near[0] - ox) / res), round((near[1] - oy) / res)
    return {"corner": (ox + i * res, oy + j * res),
            "centre": (ox + (i + 0.5) * res, oy + (j + 0.5) * res),
            "mixed": (ox + i * res, oy + (j + 0.5) * res),
            "anywhere": (ox + (i + 0.2137) * res, oy + (j + 0.6311) * res)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--map", type=Path, default=OFFICE, help="a ROS map_server YAML (default: the office map)")
    ap.add_argument("--center", default="-0.25,2.40", help="X,Y near which the centers are placed (metres)")
    ap.add_argument("--roi", type=float, default=8.0, help="ROI side (metres); the odd-side run adds one cell")
    ap.add_argument("--window", type=float, default=0.5)
    ap.add_argument("--tile", type=int, default=1, help="tile the map N × N first (a large map)")
    args = ap.parse_args(argv)
    g = load_map(args.map)
    if args.tile > 1:
        g = OccupancyGrid(np.tile(g.states, (args.tile, args.tile)), g.resolution, g.origin)
    near = tuple(float(v) for v in args.center.split(","))
    print(f"{args.map.name}{f' tiled {args.tile}×{args.tile}' if args.tile > 1 else ''}: {g.shape[1]}×{g.shape[0]} "
          f"cells of {g.resolution} m, against itself")
    print(f"{'center':9s} {'ROI':>6s} {'W':>4s} {'measure':12s} {'ms':>8s}  {'θ':>6s}  t (m)            peak MB")
    worst = 0.0
    bad = 0
    for name, c in centers(g, near).items():
        for roi in (args.roi, args.roi + g.resolution):
            for w in (0.0, args.window):
                for m in MEASURES:
                    t0 = time.perf_counter()
                    al = search_pair(g, g, center_ref=c, roi_m=roi, measure=m, window_m=w)
                    ms = (time.perf_counter() - t0) * 1e3
                    worst = max(worst, ms)
                    ok = abs(((al.theta_deg + 180.0) % 360.0) - 180.0) < 0.05 and max(map(abs, al.translation_m)) < 0.01
                    bad += not ok
                    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
                    print(f"{name:9s} {roi:6.2f} {w:4.1f} {m:12s} {ms:8.0f}  {al.theta_deg:6.2f}  "
                          f"({al.translation_m[0]:+.3f}, {al.translation_m[1]:+.3f})  {rss:7.0f}"
                          f"{'' if ok else '   <-- not the identity'}", flush=True)
    print(f"slowest {worst:.0f} ms; {bad} answers not the identity")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
