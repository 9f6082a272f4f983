"""Benchmark: large teams (issue 43) — safety, speed and memory of the team assembly, against a baseline.

Run from the repository root::

    python benchmarks/bench_large_teams.py                                 # the default set below
    python benchmarks/bench_large_teams.py --run lroom12:60:1,2,3 --run hall16:30:1
    python benchmarks/bench_large_teams.py --baseline /tmp/old --run hall16:30:1   # the same runs on another checkout
    python benchmarks/bench_large_teams.py --set merger.teammate_radius_m=0.2 --run lroom12:60:1  # an override
    python benchmarks/bench_large_teams.py --scaling 20    # N = 3 … 32 robots in one world, growth exponents
    python benchmarks/bench_large_teams.py --scaling 30 --sizes 3,4,8,12,16

A run is SCENARIO:SECONDS:SEEDS — a bundled scenario or one of ``benchmarks/scenarios/`` (``lroom12``: 12
robots in an L-shaped wall room written from the README's template, centers 0.2 m off; ``hall16``: 16
robots, 20 × 14 m; ``hall32``: 32 robots, 26 × 20 m, 5 m circle; none tuned on), every merger setting
default; ``scaleN`` is hall16's world with N robots on its circle; ``hall8w`` and ``hall4w`` are the bundled hall8 and hall4 with ``merger.window_m=0.5`` and centers 0.15 m off. Each run is
its own process, one after the other, so its resident memory is its own; ``--baseline DIR`` runs the
same list with the code of the checkout DIR (e.g. ``git worktree add /tmp/old <commit>``) in the same
invocation, so that ratios come from one machine state. Reported per run: false merges by kind (gross /
other / drift-limited), robots that merged every teammate and the last first-merge time, refused correct
cycles, the measurements the assembly rejected (inconsistent / impossible), the realtime factor (simulated
/ wall seconds), the per-robot merge cycle cost (median, ms: what one robot alone would pay) and peak RSS.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "benchmarks" / "scenarios"
DEFAULT_RUNS = ["lroom12:60:1", "hall16:30:1", "hall32:20:1", "hall8w:60:1"]
ALIASES = {"hall8w": ("hall8", ["merger.window_m=0.5", "center_error=0.15"]),
           "hall4w": ("hall4", ["merger.window_m=0.5", "center_error=0.15"])}


SCALING_NS = (3, 4, 8, 12, 16, 32)


def scenario_of(name: str):
    if name.startswith("scale") and name[5:].isdigit():  # hall16's world with N robots on its 3.5 m circle
        n = int(name[5:])
        return str(SCENARIOS / "hall16.yaml"), [f"robots.names=[{','.join(f'S{k:02d}' for k in range(1, n + 1))}]"]
    base, extra = ALIASES.get(name, (name, []))
    path = SCENARIOS / f"{base}.yaml"
    return (str(path) if path.exists() else base), extra


def child(name: str, duration: float, seed: int, sets: list[str] = ()) -> dict:
    from circsim.config.scenario import bundled_scenarios, load_scenario
    from circsim.sim import Simulation

    src, extra = scenario_of(name)
    sc = load_scenario(bundled_scenarios().get(src, src)).with_overrides(
        [f"duration_s={duration}", f"seed={seed}", *extra, *sets])
    t0 = time.perf_counter()
    d = Simulation(sc).run().to_dict()
    wall = time.perf_counter() - t0
    robots = d["robots"].values()
    firsts = [r["first_merge_s"] for r in robots if r["first_merge_s"] is not None]
    rss = 0
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                rss = int(line.split()[1]) // 1024
    cycle = d.get("merge_cycle_ms") or {}
    return {"run": f"{name}:{duration:g}:{seed}", "robots": len(d["robots"]), "false": d["false_merges"],
            "gross": d["gross_merges"], "drift": d["drift_limited_merges"],
            "other": d["false_merges"] - d["gross_merges"] - d["drift_limited_merges"],
            "merged": len(firsts), "first_max_s": max(firsts) if firsts else None,
            "rejected_correct": d["rejected_correct"],
            "inconsistent": sum(r.get("assembly_inconsistent", 0) for r in robots),
            "impossible": sum(r.get("assembly_impossible", 0) for r in robots),
            "realtime": duration / wall, "cycle_ms": cycle.get("median"), "rss_mb": rss}


def run_one(code: Path, spec: str, seed: int, sets: list[str] = ()) -> dict:
    name, dur = spec.split(":")[:2]
    env = dict(os.environ, PYTHONPATH=str(code))
    out = subprocess.run([sys.executable, __file__, "--child", f"{name}:{dur}:{seed}",
                          *(f"--set={s}" for s in sets)], env=env, cwd=code,
                         capture_output=True, text=True, check=False)
    if out.returncode != 0:
        return {"run": f"{name}:{dur}:{seed}", "error": out.stderr.strip().splitlines()[-1:]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def table(rows: list[dict], label: str) -> str:
    head = ("run", "robots", "false", "gross", "other", "drift", "merged", "first_max_s", "rejected_correct",
            "inconsistent", "impossible", "realtime", "cycle_ms", "rss_mb")
    lines = [f"## {label}", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['run']} | error: {r['error']} |")
            continue
        cells = [f"{r[k]:.2f}" if isinstance(r[k], float) else str(r[k]) for k in head]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def scaling_table(rows: list[dict]) -> str:
    """Bench seconds per simulated second and the per-robot cycle cost against N, with the exponent of
    their growth (a least-squares line through log N and the log of each figure)."""
    ok = [r for r in rows if "error" not in r]
    lines = ["## scaling: one world (hall16's 20 x 14 m hall, 3.5 m circle, centers 0.15 m off), N robots",
             "| N | bench s per sim s | per-robot cycle ms (median) | false (gross/other/drift) | merged | RSS MB |",
             "|---|---|---|---|---|---|"]
    for r in ok:
        lines.append(f"| {r['robots']} | {1 / r['realtime']:.2f} | {r['cycle_ms']:.0f} | {r['gross']}/{r['other']}/"
                     f"{r['drift']} | {r['merged']}/{r['robots']} | {r['rss_mb']} |")
    tree = [r for r in ok if r["robots"] >= 4]  # 2-3 robots merge by the thesis's orders (strategy auto)
    if len(tree) >= 2:
        import numpy as np
        n = np.log([r["robots"] for r in tree])
        for label, ys in (("bench s per sim s", [1 / r["realtime"] for r in tree]),
                          ("per-robot cycle ms", [r["cycle_ms"] for r in tree])):
            lines.append(f"growth of {label} (N >= 4, the tree): N^{np.polyfit(n, np.log(ys), 1)[0]:.2f}")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", action="append", help="SCENARIO:SECONDS:SEED[,SEED...] (repeatable)")
    ap.add_argument("--baseline", type=Path, help="another checkout to run the same list with")
    ap.add_argument("--scaling", type=float, metavar="SECONDS",
                    help=f"instead: hall16's world with N = {', '.join(map(str, SCALING_NS))} robots for SECONDS each "
                         "(seed 1), and the growth exponents")
    ap.add_argument("--sizes", default=",".join(map(str, SCALING_NS)), metavar="N,N,...",
                    help="with --scaling: the team sizes (default: all; 32 takes hours at today's cost)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a scenario override for every run, e.g. merger.teammate_radius_m=0.2 (repeatable)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        name, dur, seed = args.child.split(":")
        print(json.dumps(child(name, float(dur), int(seed), args.set)))
        return
    if args.scaling:
        rows = []
        for n in (int(x) for x in args.sizes.split(",")):
            rows.append(run_one(ROOT, f"scale{n}:{args.scaling:g}", 1, args.set))
            print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
        print(scaling_table(rows), flush=True)
        return
    specs = args.run or DEFAULT_RUNS
    codes = [("this checkout", ROOT)] + ([("baseline " + str(args.baseline), args.baseline)] if args.baseline else [])
    for label, code in codes:
        rows = []
        for spec in specs:
            seeds = spec.split(":")[2] if spec.count(":") == 2 else "1"
            for seed in seeds.split(","):
                rows.append(run_one(code, spec, int(seed), args.set))
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
        print(table(rows, label), flush=True)


if __name__ == "__main__":
    main()
