"""Benchmark: what the scan-matching SLAM costs the bench (issue 22's target: scene1 ≥ 8× real time on two
cores with merging on).

Run from the repository root::

    python benchmarks/bench_slam.py                 # scene1, 60 s, 3 rounds
    python benchmarks/bench_slam.py --rounds 5 --scene hall4 --duration 30

Each round runs the scenario twice in this process, ``slam.model: scan_matching`` (the default) then
``odometry_only`` (the random walk, the cost of the bench before issue 22), merging on, and reports each
run's realtime factor (simulated seconds per wall second) and the wall time spent in the SLAM's updates.
The machine may be shared: the rounds interleave the two models so that a change in load hits both, and
the figure to quote is the median ratio of the realtime factors (new / old).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from circsim import slam as slam_module  # noqa: E402
from circsim.config.scenario import bundled_scenarios, load_scenario  # noqa: E402
from circsim.sim import Simulation  # noqa: E402


def _timed_updates():
    """Wrap Slam.update to sum its wall time; returns (restore, read)."""
    original = slam_module.Slam.update
    spent = [0.0, 0]

    def update(self, *a, **k):
        t0 = time.perf_counter()
        try:
            return original(self, *a, **k)
        finally:
            spent[0] += time.perf_counter() - t0
            spent[1] += 1

    slam_module.Slam.update = update
    return (lambda: setattr(slam_module.Slam, "update", original)), (lambda: tuple(spent))


def run_once(name: str, duration: float, model: str) -> tuple[float, float, int]:
    sc = load_scenario(bundled_scenarios()[name]).with_overrides(
        [f"duration_s={duration}", f"slam.model={model}", "output.rrd=null", "output.json=null"])
    restore, read = _timed_updates()
    try:
        t0 = time.perf_counter()
        res = Simulation(sc).run()
        wall = time.perf_counter() - t0
    finally:
        restore()
    slam_s, n = read()
    return res.sim_s / wall, slam_s, n


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="scene1")
    p.add_argument("--duration", type=float, default=60.0)
    p.add_argument("--rounds", type=int, default=3)
    a = p.parse_args(argv)
    run_once(a.scene, 2.0, "scan_matching")  # compile / load the kernels first
    ratios = []
    print(f"{a.scene}, {a.duration:g} s simulated, merging on; realtime factor and SLAM time per update")
    for k in range(a.rounds):
        new, new_s, n = run_once(a.scene, a.duration, "scan_matching")
        old, old_s, m = run_once(a.scene, a.duration, "odometry_only")
        ratios.append(new / old)
        print(f"round {k + 1}: scan_matching {new:5.1f}x ({1000 * new_s / n:.2f} ms/update)   "
              f"odometry_only {old:5.1f}x ({1000 * old_s / m:.2f} ms/update)   ratio {new / old:.2f}")
    print(f"median ratio (scan_matching / odometry_only realtime factor): {statistics.median(ratios):.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
