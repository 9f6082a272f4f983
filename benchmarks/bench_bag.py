"""What `circsim run --bag` costs (issue 35; target: at most 10% extra run time on a 60 s scene1).

Runs the scenario with and without the bag recorder, interleaved (with, without, with, ...; the merger's
caches emptied before each run), and prints the wall times, their medians and ratio, and the time spent
inside the recorder's hooks (serializing and writing the messages). Each bag is read back and its
message count printed.

    .venv/bin/python benchmarks/bench_bag.py [--scenario scene1] [--duration 60] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.record.bag import BagRecorder
from circsim.sim import Simulation
from merger.caches import clear_all


class TimedBag(BagRecorder):
    """The recorder, with the wall time of its hooks summed."""

    spent = 0.0

    def _timed(self, name, *args):
        t0 = time.perf_counter()
        getattr(BagRecorder, name)(self, *args)
        self.spent += time.perf_counter() - t0

    def on_start(self, sim):
        self._timed("on_start", sim)

    def on_tick(self, *a):
        self._timed("on_tick", *a)

    def on_map_published(self, *a):
        self._timed("on_map_published", *a)

    def on_merge_cycle(self, *a):
        self._timed("on_merge_cycle", *a)

    def on_end(self, *a):
        self._timed("on_end", *a)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="scene1")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    sc = load_scenario(bundled_scenarios().get(a.scenario, a.scenario)).with_overrides([f"duration_s={a.duration}"])
    Simulation(sc.with_overrides(["duration_s=2"])).run()  # load the compiled kernels once
    walls = {"without": [], "with": []}
    spent = []
    with tempfile.TemporaryDirectory() as d:
        for k in range(a.repeats):
            for mode in ("with", "without"):
                clear_all()
                obs = [TimedBag(Path(d) / f"run{k}")] if mode == "with" else []
                t0 = time.perf_counter()
                Simulation(sc, obs).run()
                walls[mode].append(time.perf_counter() - t0)
                if obs:
                    spent.append(obs[0].spent)
                    n = sum(obs[0].counts.values())
                    size = sum(f.stat().st_size for f in (Path(d) / f"run{k}").iterdir()) / 1e6
                print(f"{mode:>8} bag: {walls[mode][-1]:6.2f} s" + (f"  (recorder {spent[-1]:.2f} s, {n} messages, "
                                                                    f"{size:.1f} MB)" if obs else ""), flush=True)
    w, wo = statistics.median(walls["with"]), statistics.median(walls["without"])
    print(f"{a.scenario} {a.duration:g} s: median {wo:.2f} s without the bag, {w:.2f} s with it: "
          f"ratio {w / wo:.3f}; the recorder's own hooks {statistics.median(spent):.2f} s "
          f"({100 * statistics.median(spent) / wo:.1f}% of the run without it)")


if __name__ == "__main__":
    main()
