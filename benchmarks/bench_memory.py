"""Benchmark: is a long run flat in memory and in merge-cycle cost? (issue 10, item 1)

Run from the repository root::

    python benchmarks/bench_memory.py                   # scene1, 600 s simulated
    python benchmarks/bench_memory.py scene2 --duration 300 --set merger.window_m=0.5

One run of the scenario (``duration_s`` overridden, 10 minutes by default, the robots drive round their
circle again and again; their maps stop growing after the first tour, but every publish period brings
new maps and new merge cycles). Every ``--every`` simulated seconds it prints the process's resident
memory (VmRSS), the merger's cache sizes and the median merge cycle of that span; at the end, RSS at
60 s against RSS at the end (issue 10's target: within 10%) and the cycle cost of the first minute
against the last. Wall-clock figures depend on the machine's load; the process CPU seconds of every span
(the same number of ticks and cycles each) depend less on it.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from circsim.config.scenario import load_scenario  # noqa: E402
from circsim.events import Observer  # noqa: E402
from circsim.sim import Simulation  # noqa: E402


def rss_mb() -> float:
    """Resident set size of this process, MiB (Linux /proc; else the peak from getrusage)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


class MemoryProbe(Observer):
    """Samples RSS and the span's merge cycles every ``every_s`` simulated seconds."""

    def __init__(self, every_s: float, verbose: bool = True) -> None:
        self.every_s = every_s
        self.verbose = verbose
        self.samples: list[dict] = []
        self._cycles: list[float] = []
        self._next = every_s
        self._t0 = time.perf_counter()
        self._cpu = time.process_time()

    def on_merge_cycle(self, cycle) -> None:
        self._cycles.append(cycle.result.cost_ms)  # what a robot computing alone pays

    def on_tick(self, t, step, ticks) -> None:
        if t + 1e-9 < self._next:
            return
        self._next += self.every_s
        from merger import caches

        cpu = time.process_time()
        s = {"t": t, "rss_mb": rss_mb(), "wall_s": time.perf_counter() - self._t0, "span_cpu_s": cpu - self._cpu,
             "cycles": len(self._cycles),
             "cycle_ms": statistics.median(self._cycles) if self._cycles else None,
             "searchers": len(caches._SEARCHERS)}
        self.samples.append(s)
        self._cycles = []
        self._cpu = cpu
        if self.verbose:
            ms = "-" if s["cycle_ms"] is None else f"{s['cycle_ms']:.1f}"
            print(f"  t {t:6.0f} s  wall {s['wall_s']:6.1f} s  RSS {s['rss_mb']:6.1f} MB  cycles {s['cycles']:4d}"
                  f"  median {ms:>6} ms  CPU {s['span_cpu_s']:5.1f} s  searchers {s['searchers']:2d}"
                  , flush=True)

    def at(self, t: float) -> dict:
        """The first sample at or after ``t``."""
        return next(s for s in self.samples if s["t"] + 1e-9 >= t)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenario", nargs="?", default="scene1")
    ap.add_argument("--duration", type=float, default=600.0, help="simulated seconds (default 600)")
    ap.add_argument("--every", type=float, default=30.0, help="sampling period, simulated seconds")
    ap.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE",
                    help="override a scenario value (repeatable)")
    args = ap.parse_args(argv)

    from circsim.commands import resolve_scenario

    sc = load_scenario(resolve_scenario(args.scenario)).with_overrides([f"duration_s={args.duration}", *args.set])
    print(f"cpus {os.cpu_count()}  load " + " ".join(f"{v:.2f}" for v in os.getloadavg()))
    print(f"{sc.name}: {len(sc.robots.names)} robots, {args.duration:g} s simulated, RSS before the run "
          f"{rss_mb():.1f} MB")
    probe = MemoryProbe(args.every)
    res = Simulation(sc, [probe]).run()
    first = probe.at(min(60.0, args.duration))
    last = probe.samples[-1]
    def span(t0: float, t1: float) -> list[dict]:
        return [s for s in probe.samples if t0 + 1e-9 < s["t"] <= t1 + 1e-9]

    end = last["t"]
    print("process CPU per simulated minute (the first tour builds the maps, later ones only refresh them):")
    for label, (t0, t1) in (("first minute", (0.0, 60.0)), ("second minute", (60.0, 120.0)),
                            ("last minute", (end - 60.0, end))):
        rows = span(t0, t1)
        if rows and t1 <= end + 1e-9:
            cyc = [s["cycle_ms"] for s in rows if s["cycle_ms"] is not None]
            print(f"  {label:13s} ({t0:.0f}-{t1:.0f} s): CPU {sum(s['span_cpu_s'] for s in rows):5.1f} s, "
                  f"median merge cycle {statistics.median(cyc) if cyc else float('nan'):.1f} ms")
    growth = (last["rss_mb"] - first["rss_mb"]) / first["rss_mb"]
    print(f"RSS at {first['t']:.0f} s {first['rss_mb']:.1f} MB, at {last['t']:.0f} s {last['rss_mb']:.1f} MB: "
          f"{growth:+.1%} (issue 10's target: within 10%)")
    mc = res.merge_cycle_ms()
    print(f"whole run: {mc['count']} cycles, median {mc['median']:.1f} ms, p95 {mc['p95']:.1f} ms; "
          f"realtime factor {res.realtime_factor:.2f}; false merges {res.false_merges}; "
          f"all merged {res.all_merged()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
