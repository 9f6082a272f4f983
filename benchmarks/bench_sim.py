"""Benchmark: how fast the bench runs a full tour of scene 1 (issue 4), and what recording costs (issue 5).

Run from the repository root::

    python benchmarks/bench_sim.py              # scene1, 60 s (one tour + 10 s), fast search
    python benchmarks/bench_sim.py --quick      # 20 s tour, shorter reference comparison

It runs, in the same process and one after the other:

1. the full tour with the scenario's merger (``method: fast``), 3 robots, 10 Hz laser, merging on:
   ``realtime_factor`` = simulated seconds / wall seconds, and where the wall time went
   (the merge cycles, and the laser and SLAM that run beside them);
2. the same tour recorded to a temporary .rrd (the ``circsim run --rrd`` path): the recording overhead
   as a wall-time ratio, and the file size;
3. the reference search (``merger.method=reference``) on the first ``--reference-s`` simulated seconds
   of the same scenario, against the fast search on the same span: the per-cycle ratio;
4. the same tour with the translation window (``merger.window_m``, default 0.5 m) and every given center
   off by ``--window-error`` (default 0.25 m): realtime factor and cycle cost against run 1 (issue 9's
   target: ≥ 5× real time on scene 1).

The metrics of (1) and (2) must be identical (recording is an observer; a difference is a bug and is
reported as such).
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

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from circsim.config.scenario import load_scenario  # noqa: E402
from circsim.events import Observer  # noqa: E402
from circsim.sim import Simulation  # noqa: E402


class _MergeWall(Observer):
    """The wall time the merge cycles took in this process (``cycle_ms`` is their cost: wall time plus the
    computing time of the results a robot took from the run's shared memo, merger.team.memo)."""

    def __init__(self) -> None:
        self.ms = 0.0

    def on_merge_cycle(self, c) -> None:
        self.ms += c.result.wall_ms


def _run(sc, observers=()):
    """One run; ``res.merge_wall_s``: the cycles' wall time, ``res.sensing_s``: the robots' scans and SLAM
    updates (the main thread; a tick's cycles run on their own thread beside the next tick's scans)."""
    import circsim.sim as sim_module

    mw = _MergeWall()
    sensing = [0.0]
    scan, update = sim_module.laser_scan, sim_module.Slam.update

    def timed(fn):
        def run(*args, **kwargs):
            t = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                sensing[0] += time.perf_counter() - t
        return run
    sim_module.laser_scan, sim_module.Slam.update = timed(scan), timed(update)
    try:
        t0 = time.perf_counter()
        cpu0 = time.process_time()
        res = Simulation(sc, [*observers, mw]).run()
        wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    finally:
        sim_module.laser_scan, sim_module.Slam.update = scan, update
    res.merge_wall_s = mw.ms / 1000.0
    res.sensing_s = sensing[0]
    return res, wall, cpu


def _metrics(res) -> dict:
    d = res.to_dict()
    for k in ("wall_s", "realtime_factor", "merge_cycle_ms", "outputs"):
        d.pop(k, None)
    return d


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scenario", nargs="?", default="scene1")
    ap.add_argument("--duration", type=float, default=None, help="simulated seconds (default: the scenario's)")
    ap.add_argument("--reference-s", type=float, default=8.0, help="simulated seconds of the reference comparison")
    ap.add_argument("--quick", action="store_true", help="20 s tour, 4 s reference comparison")
    ap.add_argument("--no-record", action="store_true", help="skip the recording overhead run")
    ap.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE",
                    help="override a scenario value for every run (repeatable)")
    ap.add_argument("--window", type=float, default=0.5,
                    help="4.: the same run with this merger.window_m and center error --window-error (0: skip)")
    ap.add_argument("--window-error", type=float, default=0.25, help="center error of run 4, metres")
    args = ap.parse_args(argv)

    from circsim.commands import resolve_scenario

    sc = load_scenario(resolve_scenario(args.scenario))
    duration = 20.0 if args.quick and args.duration is None else args.duration
    if duration is not None:
        sc = sc.with_overrides([f"duration_s={duration}"])
    if args.set:
        sc = sc.with_overrides(args.set)
    ref_s = 4.0 if args.quick else args.reference_s
    print(f"python {platform.python_version()}  cpus {os.cpu_count()}  load "
          + " ".join(f"{v:.2f}" for v in os.getloadavg()))
    print(f"scenario {sc.name}: {sc.duration_s:g} s simulated, {len(sc.robots.names)} robots, "
          f"laser {sc.laser.beams} beams at {1 / sc.dt_s:g} Hz, merger method {sc.merger.method}\n")

    res, wall, cpu = _run(sc)
    cyc = res.cycle_ms
    merge_s = res.merge_wall_s
    print("1. full run, no recording")
    print(f"   wall {wall:.1f} s (CPU {cpu:.1f} s)   realtime_factor {res.realtime_factor:.2f}×")
    print(f"   merge cycles {len(cyc)}: cost median {statistics.median(cyc):.1f} ms, "
          f"p95 {sorted(cyc)[int(0.95 * (len(cyc) - 1))]:.1f} ms (what a robot computing alone pays); "
          f"wall time of all cycles {merge_s:.1f} s ({100 * merge_s / wall:.0f}% of wall; the robots share "
          f"their searches)")
    print(f"   laser + SLAM: {res.sensing_s:.1f} s ({1000 * res.sensing_s / (sc.duration_s / sc.dt_s + 1):.1f} ms "
          f"per tick for all robots; beside the last tick's merge cycles, which run on their own thread)")
    print("   first merges: " + ", ".join(
        f"{n} {m.first_merge_s:.1f} s/{m.first_merge_arc_deg:.0f}°" if m.first_merge_s is not None
        else f"{n} never" for n, m in res.robots.items())
          + f"   false merges {res.false_merges}")

    if not args.no_record:
        from circsim.record.rerun import RerunRecorder

        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "bench.rrd"
            rec = RerunRecorder(str(path), scan_log_hz=sc.output.scan_log_hz)
            res_r, wall_r, _ = _run(sc, [rec])
            size = path.stat().st_size
        same = _metrics(res_r) == _metrics(res)
        print("\n2. the same run recorded to .rrd")
        print(f"   wall {wall_r:.1f} s   overhead ratio {wall_r / wall:.2f}   file {size / 1e6:.1f} MB   "
              f"metrics identical to run 1: {'yes' if same else 'NO (bug)'}")

    short = sc.with_overrides([f"duration_s={ref_s}"])
    fast_res, fast_wall, _ = _run(short)
    ref_res, ref_wall, _ = _run(short.with_overrides(["merger.method=reference"]))
    fm, rm = statistics.median(fast_res.cycle_ms), statistics.median(ref_res.cycle_ms)
    same = [r.first_merge_s for r in fast_res.robots.values()] == [r.first_merge_s for r in ref_res.robots.values()]
    print(f"\n3. reference vs fast search, first {ref_s:g} s simulated")
    print(f"   {'':>10} {'wall s':>8} {'realtime×':>10} {'cycles':>7} {'cycle ms (median)':>18}")
    print(f"   {'reference':>10} {ref_wall:>8.1f} {ref_res.realtime_factor:>10.3f} {len(ref_res.cycle_ms):>7} {rm:>18.1f}")
    print(f"   {'fast':>10} {fast_wall:>8.1f} {fast_res.realtime_factor:>10.3f} {len(fast_res.cycle_ms):>7} {fm:>18.1f}")
    print(f"   ratio reference/fast: run {ref_wall / fast_wall:.0f}×, merge cycle {rm / fm:.0f}×; "
          f"same first merges: {'yes' if same else 'no'}")
    if args.window > 0:
        wsc = sc.with_overrides([f"merger.window_m={args.window}",
                                 f"center_error.magnitude_m={args.window_error}"])
        wres, wwall, wcpu = _run(wsc)
        wc = wres.cycle_ms
        print(f"\n4. the translation window: merger.window_m={args.window:g}, every center off by "
              f"{args.window_error:g} m (run 1's settings otherwise)")
        print(f"   wall {wwall:.1f} s (CPU {wcpu:.1f} s)   realtime_factor {wres.realtime_factor:.2f}×   "
              f"merge cycles {len(wc)}: cost median {statistics.median(wc):.1f} ms, "
              f"p95 {sorted(wc)[int(0.95 * (len(wc) - 1))]:.1f} ms "
              f"({statistics.median(wc) / statistics.median(cyc):.1f}× run 1's median); "
              f"wall time of all cycles {wres.merge_wall_s:.1f} s")
        print("   first merges: " + ", ".join(
            f"{n} {m.first_merge_s:.1f} s/{m.first_merge_arc_deg:.0f}°" if m.first_merge_s is not None
            else f"{n} never" for n, m in wres.robots.items()) + f"   false merges {wres.false_merges}")
    print("load at the end " + " ".join(f"{v:.2f}" for v in os.getloadavg()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
