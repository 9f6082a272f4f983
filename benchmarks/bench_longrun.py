"""Long-run guard (issue 22): minutes of scene1, scene2 and hall4 with the bench SLAM, per minute.

Run from the repository root::

    python benchmarks/bench_longrun.py                         # 10 min each of scene1, scene2, hall4
    python benchmarks/bench_longrun.py --duration 120 --scenes scene1 hall8
    python benchmarks/bench_longrun.py --model odometry_only   # the random-walk stress model
    python benchmarks/bench_longrun.py --slam-only --scenes hall4 hall8   # SLAM pose errors alone, fast

For every scenario it runs ``--duration`` simulated seconds (default 600) with the scenario's settings and
``slam.model`` = ``--model`` (default the scenario's: ``scan_matching``), and prints per simulated minute:

* ``cycles``: merge cycles of all robots (their own, adopted hypotheses not counted);
* ``refused``: cycles not accepted; ``ref.corr``: of those, the ones whose best hypothesis was correct
  and which came after that robot's first correct merge (the issue's "refused correct cycles after the
  first merge", target < 5% of cycles);
* ``false``: false merges (strict: start-frame truth), with ``gross`` (a flip, > 10° or > 0.5 m) and
  ``drift`` (drift-limited: right against the estimated-frame truth) among them;
* ``pose cm`` / ``pose °``: the worst SLAM pose error of any robot within the minute (position, yaw).

then the run's totals, rates per minute and its realtime factor. ``--slam-only`` runs the scenario with maps
published and sent once, at the start, and never again (so the robots merge once; the SLAM does not depend
on merging, so its poses are the same as in the full run) and prints each robot's worst pose error per minute, 10–30× faster than
real time. It is a benchmark, not a test: it asserts
nothing (the issue's targets: 0 false merges, pose error < 1° and 5 cm at every minute with no growth
from lap to lap, refused correct cycles after the first merge < 5% of cycles). Heavy: 10 minutes of one
scenario take several minutes of wall time on two cores.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from circsim.config.scenario import bundled_scenarios, load_scenario  # noqa: E402
from circsim.events import Observer  # noqa: E402
from circsim.sim import Simulation  # noqa: E402

QUIET_S = 1e9  # --slam-only: maps published and sent once, at the start, then never again


class PerMinute(Observer):
    """Buckets a run's merge cycles and SLAM pose errors by simulated minute."""

    def __init__(self) -> None:
        self.rows: dict[int, dict] = defaultdict(lambda: defaultdict(float))
        self.first_correct: dict[str, float] = {}

    def on_tick(self, t, step, ticks) -> None:
        row = self.rows[int(t // 60)]
        for k in ticks:
            (tx, ty, tyaw), (ex, ey, eyaw) = k.true_pose, k.est_pose_world
            row["pose_cm"] = max(row["pose_cm"], 100.0 * math.hypot(ex - tx, ey - ty))
            row["pose_deg"] = max(row["pose_deg"],
                                  abs(math.degrees((eyaw - tyaw + math.pi) % (2 * math.pi) - math.pi)))

    def on_merge_cycle(self, c) -> None:
        row = self.rows[int(c.t // 60)]
        if c.result.accepted and c.false_merge:
            row["false"] += 1
            gross = any(e > 10.0 for e in c.angle_error_deg.values()) \
                or any(e > 0.5 for e in c.translation_error_m.values())
            row["gross"] += gross
            row["drift"] += (not gross) and c.est_correct
        if c.adopted_from:
            return
        row["cycles"] += 1
        if not c.result.accepted:
            row["refused"] += 1
            if c.correct and c.robot in self.first_correct:
                row["refused_correct"] += 1
        if c.first_correct:
            self.first_correct[c.robot] = c.t


def scenario(name: str, duration: float, model: str | None, seed: int | None, extra=()):
    """The bundled scenario ``name`` for ``duration`` simulated seconds, no outputs, with the options' overrides."""
    sets = [f"duration_s={duration}", "output.rrd=null", "output.json=null", *extra]
    if model:
        sets.append(f"slam.model={model}")
    if seed is not None:
        sets.append(f"seed={seed}")
    return load_scenario(bundled_scenarios()[name]).with_overrides(sets)


def run(name: str, duration: float, model: str | None, seed: int | None, extra=()) -> None:
    sc = scenario(name, duration, model, seed, extra)
    obs = PerMinute()
    t0 = time.perf_counter()
    res = Simulation(sc, [obs]).run()
    wall = time.perf_counter() - t0
    print(f"\n{name} (seed {sc.seed}, slam.model {sc.slam.model}, {len(sc.robots.names)} robots): "
          f"{res.sim_s:.0f} s simulated in {wall:.0f} s wall (realtime factor {res.sim_s / wall:.1f})")
    print(f"{'minute':>6} {'cycles':>7} {'refused':>8} {'ref.corr':>8} {'false':>6} {'gross':>6} {'drift':>6} "
          f"{'pose cm':>8} {'pose °':>7}")
    tot = defaultdict(float)
    for k in sorted(obs.rows):
        r = obs.rows[k]
        for key in ("cycles", "refused", "refused_correct", "false", "gross", "drift"):
            tot[key] += r[key]
        tot["pose_cm"] = max(tot["pose_cm"], r["pose_cm"])
        tot["pose_deg"] = max(tot["pose_deg"], r["pose_deg"])
        print(f"{k:>6} {r['cycles']:>7.0f} {r['refused']:>8.0f} {r['refused_correct']:>8.0f} {r['false']:>6.0f} "
              f"{r['gross']:>6.0f} {r['drift']:>6.0f} {r['pose_cm']:>8.2f} {r['pose_deg']:>7.2f}")
    minutes = res.sim_s / 60.0
    firsts = ", ".join(f"{n} {'—' if m.first_merge_s is None else format(m.first_merge_s, '.1f')} s"
                       for n, m in res.robots.items())
    print(f"total: false merges {tot['false']:.0f} ({tot['false'] / minutes:.2f}/min; gross {tot['gross']:.0f}, "
          f"drift-limited {tot['drift']:.0f}), refusals {tot['refused']:.0f} ({tot['refused'] / minutes:.1f}/min), "
          f"refused correct after the first merge {tot['refused_correct']:.0f} "
          f"({100 * tot['refused_correct'] / max(tot['cycles'], 1):.1f}% of {tot['cycles']:.0f} cycles); "
          f"worst SLAM pose error {tot['pose_cm']:.2f} cm / {tot['pose_deg']:.2f}°; first merges {firsts}")
    d = res.to_dict()
    j, lat, tr = d["placement_jump"], d["latency_s"], d["tracking"]
    if j["count"]:
        print(f"placement jumps between held alignments: p95 {j['deg_p95']:.3f}° / {100 * j['m_p95']:.2f} cm, largest "
              f"{j['deg_max']:.2f}° / {100 * j['m_max']:.1f} cm ({j['count']}); map version to verified merge: median "
              f"{lat['median']:.1f} s, p95 {lat['p95']:.1f} s; merger.research {sc.merger.research}: "
              f"{tr['global_searches']} global searches, {tr['local_checks']} local re-verifications, "
              f"{tr['switches']} switches")


class SlamErrors(Observer):
    """Each robot's worst SLAM pose error (cm, degrees) per simulated minute."""

    def __init__(self) -> None:
        self.worst: dict[int, dict[str, list[float]]] = defaultdict(lambda: defaultdict(lambda: [0.0, 0.0]))

    def on_tick(self, t, step, ticks) -> None:
        for k in ticks:
            (tx, ty, tyaw), (ex, ey, eyaw) = k.true_pose, k.est_pose_world
            w = self.worst[int(t // 60)][k.name]
            w[0] = max(w[0], 100.0 * math.hypot(ex - tx, ey - ty))
            w[1] = max(w[1], abs(math.degrees((eyaw - tyaw + math.pi) % (2 * math.pi) - math.pi)))


def run_slam_only(name: str, duration: float, model: str | None, seed: int | None, extra=()) -> None:
    """World, lasers and SLAMs only: each robot's worst SLAM pose error per simulated minute. The run is the
    scenario's with maps published and sent once, at the start (the SLAM does not depend on merging)."""
    sc = scenario(name, duration, model, seed, [*extra, f"slam.publish_period_s={QUIET_S}",
                                                f"network.period_s={QUIET_S}"])
    obs = SlamErrors()
    t0 = time.perf_counter()
    Simulation(sc, [obs]).run()
    wall = time.perf_counter() - t0
    names = list(sc.robots.names)
    print(f"\n{name} SLAM only (seed {sc.seed}, slam.model {sc.slam.model}, {len(names)} robots): "
          f"{sc.duration_s:.0f} s simulated in {wall:.0f} s wall (realtime factor {sc.duration_s / wall:.1f}); "
          f"worst pose error per minute, cm / °")
    print(f"{'minute':>6} " + " ".join(f"{n[:12]:>13}" for n in names) + f" {'worst':>13}")
    top = [0.0, 0.0]
    for m in sorted(obs.worst):
        row = [obs.worst[m][n] for n in names]
        w = [max(c[0] for c in row), max(c[1] for c in row)]
        top = [max(top[0], w[0]), max(top[1], w[1])]
        print(f"{m:>6} " + " ".join(f"{c[0]:6.2f}/{c[1]:5.2f}" for c in row) + f" {w[0]:6.2f}/{w[1]:5.2f}")
    print(f"total: worst SLAM pose error {top[0]:.2f} cm / {top[1]:.2f}°")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--duration", type=float, default=600.0, help="simulated seconds per scenario (600)")
    p.add_argument("--scenes", nargs="+", default=["scene1", "scene2", "hall4"], help="bundled scenarios")
    p.add_argument("--model", choices=("scan_matching", "odometry_only"), default=None,
                   help="slam.model (default: the scenario's)")
    p.add_argument("--seed", type=int, default=None, help="override the scenarios' seeds")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scenario overrides")
    p.add_argument("--slam-only", action="store_true",
                   help="world, lasers and SLAMs only (no merging): each robot's worst pose error per minute")
    a = p.parse_args(argv)
    for name in a.scenes:
        (run_slam_only if a.slam_only else run)(name, a.duration, a.model, a.seed, a.set)
    return 0


if __name__ == "__main__":
    sys.exit(main())
