"""Benchmark: what a map world (issue 44, ``world.map``) costs the laser and the loader.

Run from the repository root::

    python benchmarks/bench_map_world.py                     # 5 interleaved rounds, 40 scans per world
    python benchmarks/bench_map_world.py --rounds 9 --scans 100

Scans: the exact ranges of the default laser (:func:`circsim.world.laser.cast`, what every tick of a run
costs per robot) from each robot's start pose, in ``hall8`` (the reference: 20 walls, 8 robots, pillars
and chair legs), in ``office`` (the TurtleBot3 office map, 3,032 wall segments) and in a generated
600 × 600-cell map with thousands of wall pieces (rooms, doors and a few thousand one- to three-cell
specks of clutter, about 12,000 segments). The rounds interleave the worlds, so that a change in the
machine's load hits all of them; the figure to quote is each world's median cost per scan over hall8's
median (target: at most 2).

Loading: a generated 1,000 × 1,000-cell map saved as map_server files, then the scenario loaded
(the map read by merger's loader, the scene checked against it) and the pymunk world built from it
(target: at most 2 s together).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pymunk

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from circsim.config.scenario import bundled_scenarios, load_scenario, scenario_from_dict  # noqa: E402
from circsim.world import laser  # noqa: E402
from circsim.world.motion import trajectories  # noqa: E402
from circsim.world.world import World  # noqa: E402
from merger.grid import Cell, OccupancyGrid  # noqa: E402
from merger.io.mapio import save_map  # noqa: E402

RES = 0.05


def generated_map(n: int, seed: int = 0, specks: int = 3000) -> tuple[OccupancyGrid, tuple[float, float]]:
    """An n x n map at 5 cm: unknown outside, a walled building of 6 m rooms with 1 m doors, clutter
    specks everywhere but a 1.6 m disc about the middle (the robots' circle); and that disc's center."""
    rng = np.random.default_rng(seed)
    s = np.full((n, n), Cell.UNKNOWN, np.uint8)
    m = 10
    s[m:n - m, m:n - m] = Cell.OCCUPIED
    s[m + 2:n - m - 2, m + 2:n - m - 2] = Cell.FREE
    room = int(6.0 / RES)
    for k in range(m + room, n - m - 2, room):  # walls two cells thick, a door in every room's side
        s[m:n - m, k:k + 2] = Cell.OCCUPIED
        s[k:k + 2, m:n - m] = Cell.OCCUPIED
        for j in range(m + room // 2, n - m - 2, room):
            s[j:j + 20, k:k + 2] = Cell.FREE
            s[k:k + 2, j:j + 20] = Cell.FREE
    rows, cols = rng.integers(m + 2, n - m - 5, specks), rng.integers(m + 2, n - m - 5, specks)
    sizes = rng.integers(1, 4, specks)
    for r, c, z in zip(rows, cols, sizes, strict=True):
        s[r:r + z, c:c + z] = Cell.OCCUPIED
    yy, xx = np.mgrid[0:n, 0:n]
    mid = n // 2 + room // 2 if (n // 2 - m) % room < 40 else n // 2
    disc = (yy - mid) ** 2 + (xx - mid) ** 2 <= (1.6 / RES) ** 2
    s[disc] = Cell.FREE
    return OccupancyGrid(s, RES, (0.0, 0.0)), ((mid + 0.5) * RES, (mid + 0.5) * RES)


def map_scenario(folder: Path, n: int, name: str):
    grid, center = generated_map(n)
    save_map(grid, folder / f"{name}.yaml")
    return {"name": name, "world": {"map": str(folder / f"{name}.yaml"), "center": list(center)},
            "robots": {"names": ["A", "B", "C", "D"], "radius_m": 1.2}}


def world_of(sc):
    w = World.from_scenario(sc)
    return w, [(name, t.start_pose()) for name, t in trajectories(sc).items()]


def scan_ms(w, poses, config, scans: int) -> float:
    t0 = time.perf_counter()
    k = 0
    while k < scans:
        for name, pose in poses:
            laser.cast(w, name, pose, config)
            k += 1
    return (time.perf_counter() - t0) / k * 1e3


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--scans", type=int, default=40)
    args = ap.parse_args()
    print(f"python {platform.python_version()}  numpy {np.__version__}  pymunk {pymunk.version}  cpus "
          f"{os.cpu_count()}  load " + " ".join(f"{v:.2f}" for v in os.getloadavg()))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        worlds = {}
        for name in ("hall8", "office"):
            sc = load_scenario(bundled_scenarios()[name])
            worlds[name] = (sc, *world_of(sc))
        sc = scenario_from_dict(map_scenario(folder, 600, "gen600"), source="gen600")
        worlds["generated 600 x 600"] = (sc, *world_of(sc))
        times = {k: [] for k in worlds}
        for _ in range(args.rounds):
            for key, (sc, w, poses) in worlds.items():
                times[key].append(scan_ms(w, poses, sc.laser, args.scans))
        base = statistics.median(times["hall8"])
        print(f"{'world':<22} {'segments':>8} {'circles':>7}  ms per scan (median, range)   / hall8")
        for key, (_, w, _) in worlds.items():
            geo = w.geometry(include_robots=True)
            med = statistics.median(times[key])
            print(f"{key:<22} {len(geo.segments):>8} {len(geo.circles):>7}  {med:6.2f} ({min(times[key]):.2f}–"
                  f"{max(times[key]):.2f})            {med / base:5.2f}")
        raw = map_scenario(folder, 1000, "gen1000")
        t0 = time.perf_counter()
        sc = scenario_from_dict(raw, source="gen1000")
        t1 = time.perf_counter()
        w = World.from_scenario(sc)
        w.geometry()
        t2 = time.perf_counter()
        print("load at the end " + " ".join(f"{v:.2f}" for v in os.getloadavg()))
        print(f"1000 x 1000 map: scenario loaded and checked {t1 - t0:.2f} s, world built {t2 - t1:.2f} s, "
              f"{t2 - t0:.2f} s in all ({len(w.geometry().segments)} segments)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
