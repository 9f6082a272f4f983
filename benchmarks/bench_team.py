"""Benchmark: teams of 2 to 8 robots (issue 10, item 6) — cycle time, realtime factor, memory, merges.

Run from the repository root::

    python benchmarks/bench_team.py                       # N = 2..8, strategy tree, 30 s each
    python benchmarks/bench_team.py --strategy orders --strategy tree --orders-max 4 --duration 30

Every team is the bundled hall (``circsim/scenarios/hall8.yaml``: 14 × 10 m, asymmetric pillars, boxes
and chairs) with its first N robots spread evenly on the 2.5 m circle (start angles 90° + k·360°/N),
merging the maps they hold (``merger.min_maps: 2``). Each (strategy, N) runs in its own process, one after
the other, so that its resident memory is its own. Reported per run: the median and p95 merge cycle
(wall ms) and the median per map of the cycle (cycle / N), the realtime factor (simulated / wall seconds)
and the CPU realtime factor (simulated / process CPU seconds: less sensitive to other load on the
machine), peak and final RSS, how many robots placed every teammate correctly (and the median time of
their first full merge), the median first pair merge, and false merges.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def team_scenario(n: int, duration: float, strategy: str, seed: int, extra=()):
    """The hall with its first ``n`` robots evenly spread on the circle."""
    from circsim.config.scenario import bundled_scenarios, load_scenario

    base = load_scenario(bundled_scenarios()["hall8"])
    names = list(base.robots.names)[:n]
    angles = [round((90.0 + k * 360.0 / n) % 360.0, 3) for k in range(n)]
    return base.with_overrides([f"robots.names=[{', '.join(names)}]",
                                f"robots.start_angles_deg=[{', '.join(map(str, angles))}]",
                                f"duration_s={duration}", f"seed={seed}", f"merger.strategy={strategy}",
                                "merger.min_maps=2", *extra])


def child(n: int, duration: float, strategy: str, seed: int, extra) -> dict:
    import resource

    from circsim.sim import Simulation

    sc = team_scenario(n, duration, strategy, seed, extra)
    cpu0 = time.process_time()
    res = Simulation(sc).run()
    cpu = time.process_time() - cpu0
    d = res.to_dict()
    firsts = [r["first_merge_s"] for r in d["robots"].values() if r["first_merge_s"] is not None]
    pairs = [r["first_pair_merge_s"] for r in d["robots"].values() if r["first_pair_merge_s"] is not None]
    rss = None
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                rss = int(line.split()[1]) / 1024.0
    mc = d["merge_cycle_ms"]
    return {"n": n, "strategy": strategy, "sim_s": d["sim_s"], "wall_s": d["wall_s"], "cpu_s": cpu,
            "realtime_factor": d["realtime_factor"], "cpu_realtime_factor": d["sim_s"] / cpu if cpu > 0 else None,
            "cycles": mc["count"], "cycle_ms_median": mc["median"], "cycle_ms_p95": mc["p95"],
            "per_map_cycle_ms": mc["median"] / n if mc["median"] is not None else None,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, "final_rss_mb": rss,
            "robots_merged": len(firsts), "first_merge_s_median": statistics.median(firsts) if firsts else None,
            "first_pair_merge_s_median": statistics.median(pairs) if pairs else None,
            "teammates_placed_final": [r["teammates_placed_final"] for r in d["robots"].values()],
            "false_merges": d["false_merges"], "rejected_correct": d["rejected_correct"]}


def _fmt(v, spec=".1f"):
    return "—" if v is None else format(v, spec)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="2,3,4,5,6,7,8", help="team sizes, comma-separated (2..8)")
    ap.add_argument("--duration", type=float, default=30.0, help="simulated seconds per run")
    ap.add_argument("--strategy", action="append", choices=("orders", "tree"),
                    help="merge strategy (repeatable; default: tree)")
    ap.add_argument("--orders-max", type=int, default=4,
                    help="largest team run with the orders strategy (its cost grows ~N^5 per second)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE",
                    help="override a scenario value for every run (repeatable)")
    ap.add_argument("--json", help="also write the rows to this file")
    ap.add_argument("--child", nargs=3, metavar=("N", "DURATION", "STRATEGY"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        n, dur, strategy = args.child
        print(json.dumps(child(int(n), float(dur), strategy, args.seed, args.set)))
        return 0

    sizes = [int(s) for s in args.sizes.split(",")]
    if any(not 2 <= n <= 8 for n in sizes):
        ap.error("--sizes: team sizes between 2 and 8")
    strategies = args.strategy or ["tree"]
    print(f"cpus {os.cpu_count()}  load " + " ".join(f"{v:.2f}" for v in os.getloadavg())
          + f"  hall, {args.duration:g} s simulated per run, seed {args.seed}")
    rows = []
    for strategy in strategies:
        for n in sizes:
            if strategy == "orders" and n > args.orders_max:
                continue
            cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(n), str(args.duration), strategy,
                   "--seed", str(args.seed)] + [x for s in args.set for x in ("--set", s)]
            out = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
            if out.returncode != 0:
                print(f"{strategy} N={n}: failed\n{out.stderr}", file=sys.stderr)
                return 1
            row = json.loads(out.stdout.strip().splitlines()[-1])
            rows.append(row)
            print(f"  {strategy:6s} N={n}: {row['cycles']} cycles, median {_fmt(row['cycle_ms_median'])} ms, "
                  f"realtime x{_fmt(row['realtime_factor'], '.2f')} (CPU x{_fmt(row['cpu_realtime_factor'], '.2f')}), "
                  f"peak RSS {row['peak_rss_mb']:.0f} MB, merged {row['robots_merged']}/{n}, "
                  f"false merges {row['false_merges']}", flush=True)
    print("\n| strategy | N | cycles | cycle ms median (p95) | per map ms | realtime × (CPU ×) | peak RSS MB |"
          " all placed | first merge s (median) | first pair s (median) | false merges |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['strategy']} | {r['n']} | {r['cycles']} | {_fmt(r['cycle_ms_median'])} ({_fmt(r['cycle_ms_p95'])}) "
              f"| {_fmt(r['per_map_cycle_ms'])} | {_fmt(r['realtime_factor'], '.2f')} "
              f"({_fmt(r['cpu_realtime_factor'], '.2f')}) | {r['peak_rss_mb']:.0f} | {r['robots_merged']}/{r['n']} "
              f"| {_fmt(r['first_merge_s_median'])} | {_fmt(r['first_pair_merge_s_median'])} | {r['false_merges']} |")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
