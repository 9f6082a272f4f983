"""Tracking (``merger.research: on_change``) against searching every map version (``every_version``), same run.

    python benchmarks/bench_tracking.py                       # quality: 5 scenarios x 3 seeds x both modes, 60 s
    python benchmarks/bench_tracking.py --speed               # speed: the halls and scene1 windowed, one at a time
    python benchmarks/bench_tracking.py --scenarios hall4 --seeds 1 --duration 20 --jobs 2

Quality (the default): every scenario and seed runs with both settings (``--jobs`` runs side by side, one
merger thread each: the metrics are the same on any schedule, the wall times are not then comparable). It
prints per run the first full merge of every robot under both, the largest lateness of ``on_change``'s
against ``every_version``'s (the target: within one network period), false and gross merges, refused
correct cycles, the latency from a map version to its first verified merge (median, p95), the placement
jump between consecutive held alignments (p95, largest) and the tracker's global searches and local
re-verifications (summed over the robots that used them).

Speed (``--speed``): one run at a time with the machine's threads: wall time, realtime factor and peak RSS
of each mode, and their ratio, on hall8 (W 0.5 m, centers 0.15 m off), the 16-robot hall
(benchmarks/scenarios/hall16.yaml) and scene1 (W 0.5 m, centers 0.25 m off).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SCENARIOS = {  # name → (scenario, overrides): the bundled settings unless said
    "scene1": ("scene1", []),
    "scene2": ("scene2", []),
    "hall4": ("hall4", ["merger.window_m=0.5", "center_error=0.15"]),
    "hall8": ("hall8", ["merger.window_m=0.5", "center_error=0.15"]),
    "newuser5": (str(ROOT / "benchmarks/scenarios/newuser5.yaml"), []),
    "hall16": (str(ROOT / "benchmarks/scenarios/hall16.yaml"), []),
    "scene1-w": ("scene1", ["merger.window_m=0.5", "center_error=0.25"]),
}
MODES = ("every_version", "on_change")


def run(name: str, seed: int, duration: float, mode: str, threads: int | None) -> dict:
    """One ``circsim run`` in its own process; returns its metrics JSON, wall time and peak RSS (MB)."""
    scenario, over = SCENARIOS[name]
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "run.json"
        cmd = [sys.executable, "-m", "circsim.cli", "run", scenario, "--quiet", "--json", str(out),
               "--set", f"seed={seed}", "--set", f"duration_s={duration}", "--set", f"merger.research={mode}"]
        for o in over:
            cmd += ["--set", o]
        env = dict(os.environ)
        if threads is not None:
            env["MERGER_THREADS"] = str(threads)
        t0 = time.perf_counter()
        p = subprocess.run(["/usr/bin/time", "-f", "%M", *cmd], capture_output=True, text=True, env=env, cwd=ROOT)
        wall = time.perf_counter() - t0
        if p.returncode not in (0, 1):
            raise RuntimeError(f"{name} seed {seed} {mode}: exit {p.returncode}: {p.stderr[-2000:]}")
        rss = int(p.stderr.strip().splitlines()[-1]) / 1024.0
        d = json.loads(out.read_text())
    return {"metrics": d, "wall_s": wall, "rss_mb": rss}


def _first(d: dict) -> dict:
    return {n: r["first_merge_s"] for n, r in d["robots"].items()}


def lateness(new: dict, old: dict) -> float | None:
    """The largest (new − old) first merge over the robots (inf: merged under old only; None: neither)."""
    worst = None
    for n, t_old in old.items():
        t_new = new.get(n)
        if t_old is None and t_new is None:
            continue
        late = float("inf") if t_new is None else (float("-inf") if t_old is None else t_new - t_old)
        worst = late if worst is None else max(worst, late)
    return worst


def quality(args) -> int:
    jobs = [(s, seed, m) for s in args.scenarios.split(",") for seed in map(int, args.seeds.split(",")) for m in MODES]
    with ProcessPoolExecutor(max_workers=args.jobs) as ex:
        futs = {j: ex.submit(run, j[0], j[1], args.duration, j[2], 1 if args.jobs > 1 else None) for j in jobs}
        res = {j: f.result() for j, f in futs.items()}
    bad = 0
    print(f"quality: {args.duration:g} s, seeds {args.seeds}; on_change vs every_version (same scenario and seed)")
    for s in args.scenarios.split(","):
        for seed in map(int, args.seeds.split(",")):
            old, new = res[(s, seed, "every_version")]["metrics"], res[(s, seed, "on_change")]["metrics"]
            period = new["params"]["network"]["period_s"]
            late = lateness(_first(new), _first(old))
            ok = late is None or late <= period + 1e-9
            ok &= new["false_merges"] <= old["false_merges"]
            bad += not ok
            tr = new["tracking"]
            print(f"  {s:9s} seed {seed}: first merges every_version {_fmt(_first(old))}")
            print(f"  {'':9s}          on_change     {_fmt(_first(new))}  latest by {_late(late)} (period {period:g} s)"
                  f"{'' if ok else '  <-- MISSED'}")
            for mode, d in (("every_version", old), ("on_change", new)):
                lat, j = d["latency_s"], d["placement_jump"]
                print(f"  {'':9s}          {mode:13s} false {d['false_merges']} (gross {d['gross_merges']}), refused "
                      f"correct {d['rejected_correct']}, latency median {_n(lat['median'])} p95 {_n(lat['p95'])} s, "
                      f"jump p95 {_n(j['deg_p95'], 3)}° / {_n(j['m_p95'], 3)} m (max {_n(j['deg_max'], 2)}° / "
                      f"{_n(j['m_max'], 3)} m)")
            print(f"  {'':9s}          tracker: {tr['global_searches']} global searches, {tr['local_checks']} local "
                  f"re-verifications, {tr['switches']} switches (summed over the robots)")
    print(f"targets missed: {bad}")
    return 0


def speed(args) -> int:
    print(f"speed: one run at a time, {os.cpu_count()} cores, {args.duration:g} s simulated")
    modes = args.modes.split(",")
    for s in args.scenarios.split(","):
        row = {}
        for mode in modes:
            r = run(s, int(args.seeds.split(",")[0]), args.duration, mode, None)
            m = r["metrics"]
            row[mode] = r
            print(f"  {s:9s} {mode:13s}: wall {r['wall_s']:6.1f} s, realtime factor {m['realtime_factor']:5.2f}x, "
                  f"RSS {r['rss_mb']:5.0f} MB, false {m['false_merges']} (gross {m['gross_merges']}), merged "
                  f"{sum(v is not None for v in _first(m).values())}/{len(m['robots'])}, consensus held "
                  f"{m['consensus_held_s']:.1f} s, cycle median {_n(m['merge_cycle_ms']['median'], 0)} ms", flush=True)
        if len(row) == 2:
            a, b = row["every_version"]["metrics"], row["on_change"]["metrics"]
            print(f"  {s:9s} on_change / every_version realtime factor: "
                  f"{b['realtime_factor'] / a['realtime_factor']:.2f}x")
    return 0


def _n(v, digits=2):
    return "–" if v is None else f"{v:.{digits}f}"


def _late(v):
    return "–" if v is None else ("never merged" if v == float("inf") else f"{v:+.1f} s")


def _fmt(first: dict) -> str:
    return " ".join("–" if v is None else f"{v:.1f}" for v in first.values())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speed", action="store_true")
    ap.add_argument("--scenarios", default=None)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--modes", default=",".join(MODES), help="--speed: the settings to run (both by default)")
    ap.add_argument("--jobs", type=int, default=1, help="quality runs side by side (one merger thread each)")
    args = ap.parse_args(argv)
    if args.speed:
        args.scenarios = args.scenarios or "hall8,hall16,scene1-w"
        return speed(args)
    args.scenarios = args.scenarios or "scene1,scene2,hall4,hall8,newuser5"
    return quality(args)


if __name__ == "__main__":
    sys.exit(main())
