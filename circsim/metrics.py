"""Metrics against ground truth, and the plain serializable record of a run (DESIGN.md, "Metrics").

* ``first_merge_s[robot]`` — simulated seconds to that robot's first accepted, correct merge of all maps
  (every teammate correctly placed).
* ``first_pair_merge_s[robot]`` — simulated seconds to its first accepted, correct merge of any two or
  more maps (a partial team: its own and at least one teammate's); never later than ``first_merge_s``.
* ``teammates_placed[robot]`` — over time, how many teammates the alignment it holds places correctly:
  ``[[t, count], ...]``, one entry per change (``teammates_placed_final``: the count at the end).
* ``first_merge_arc_deg[robot]`` — degrees it had travelled on its circle by then.
* ``false_merges`` — accepted alignments that are not correct (any angle error > ``correct_tol_deg`` or
  any translation error > ``correct_tol_m``).
* ``rejected_correct`` — merge cycles whose best hypothesis was correct but rejected.
* ``merge_cycle_ms`` — cost of one merge cycle (all orders + verification): median and p95 of its wall time
  plus the computing time of the pair results it took from the robots' shared memo (:mod:`merger.team.memo`): what
  the cycle costs a robot computing alone.
* ``realtime_factor`` — simulated seconds per wall second of the run.
* ``consensus_s`` — simulated seconds to the first time every robot holds the same global alignment: each
  holds a placement of every map, and expressed in one frame (:func:`merger.team.frames.compose`) all of them
  agree within ``CONSENSUS_TOL_DEG`` (0.1°) and one cell (the SLAM grid's resolution); None if never.
  ``consensus_final``: whether they still do at the end; ``consensus_held_s``: for how many simulated
  seconds in all they did. With shared hypotheses
  (``merger.share_hypotheses``) an adopted hypothesis is held like an accepted merge: it counts for
  ``first_merge_s``, ``false_merges`` and ``teammates_placed`` (not for ``cycles`` or ``merge_cycle_ms``);
  per robot ``hypotheses_received`` / ``hypotheses_adopted``.

Telling a wrong placement from a drift-limited one (issue 22). Every accepted alignment is also judged
against the *estimated-frame* truth: the alignment the maps as their SLAMs built them call for (the
transform between the SLAMs' map frames as estimated when the held maps were published,
:func:`circsim.sim.estimated_truth`). ``false_merges`` stays the strict count (start-frame truth); of
those, ``gross_merges`` are a flip or more than ``GROSS_DEG`` (10°) or ``GROSS_M`` (0.5 m) off for some
map, and ``drift_limited_merges`` are within the tolerances of the estimated-frame truth and not gross: the
merger placed the maps as built; the SLAM's drift made that wrong. ``false_merge_log`` lists every false
merge: when, which robot and which maps, how far off against both truths, and its kind (``gross``,
``drift_limited`` or ``other``). Per robot, ``accepted_error_max`` holds the worst angle and translation
error of its accepted alignments against each truth.

SLAM pose error: per robot, ``slam_pose_error`` samples the distance (m) and yaw difference (°) between
its SLAM's pose estimate and its true pose (both in its map frame) at every whole simulated second,
``[[t, m, deg], ...]``; ``slam_pose_error_max`` is the worst over every tick, ``{"m": ..., "deg": ...}``.

Beyond DESIGN.md, per robot: ``final_angle_error_deg`` and ``final_translation_error_m`` (per map, of the
alignment held at the end) and ``first_merge_translation_error_m`` (the largest translation error of the
first correct merge). Angle and translation errors, and what is correct, are :mod:`circsim.judge`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from merger.search import angle_diff_deg
from merger.team.frames import compose
from merger.team.params import Placement
from merger.team.track import jump_summary, placement_jump

from .events import MergeCycle, Observer
from .judge import JUDGE_EPS_DEG, JUDGE_EPS_M

GROSS_DEG = 10.0  # a false merge this far off in angle (or GROSS_M in translation) for some map is gross
GROSS_M = 0.5
CONSENSUS_TOL_DEG = 0.1


@dataclass
class RobotMetrics:
    first_merge_s: float | None = None
    first_merge_arc_deg: float | None = None
    first_pair_merge_s: float | None = None
    first_pair_merge_arc_deg: float | None = None
    teammates_placed: list = field(default_factory=list)  # [[t, count], ...] at every change
    partial_cycles: int = 0  # cycles over a partial team (not every teammate's map held)
    cycles: int = 0
    accepted: int = 0
    false_merges: int = 0
    rejected_correct: int = 0
    final_angle_error_deg: dict[str, float] | None = None  # of the alignment held at the end
    final_translation_error_m: dict[str, float] | None = None  # of the alignment held at the end
    first_merge_translation_error_m: float | None = None  # largest over the maps, at the first correct merge
    maps_published: int = 0
    maps_received: int = 0  # teammates' maps taken (newer than the one held)
    maps_stale: int = 0  # teammates' maps dropped: not newer than the one held (out of order, repeated)
    hypotheses_received: int = 0  # teammates' hypotheses weighed (shared hypotheses)
    hypotheses_adopted: int = 0
    gross_merges: int = 0  # false merges a flip, > GROSS_DEG or > GROSS_M off for some map
    drift_limited_merges: int = 0  # false merges right against the estimated-frame truth, not gross
    final_est_angle_error_deg: dict[str, float] | None = None  # held at the end, vs the estimated-frame truth
    final_est_translation_error_m: dict[str, float] | None = None
    accepted_error_max: dict = field(default_factory=dict)  # {"start"|"estimated": {"deg": .., "m": ..}}
    slam_pose_error: list = field(default_factory=list)  # [[t, metres, degrees], ...] every whole second
    slam_pose_error_max: dict = field(default_factory=lambda: {"m": 0.0, "deg": 0.0})
    # the tree's consensus assembly (merger.team.consensus), summed over cycles: measurements rejected as
    # inconsistent with a stronger group, as impossible (two robots in one place), and maps left out
    assembly_inconsistent: int = 0
    assembly_impossible: int = 0
    assembly_left_out: int = 0
    consistent_set: list = field(default_factory=list)  # [[t, measurements in the consistent set], ...] at every change

    @property
    def teammates_placed_final(self) -> int:
        return self.teammates_placed[-1][1] if self.teammates_placed else 0

    def to_dict(self) -> dict:
        d = dict(self.__dict__)
        d["teammates_placed"] = [list(p) for p in self.teammates_placed]
        d["slam_pose_error"] = [list(p) for p in self.slam_pose_error]
        d["consistent_set"] = [list(p) for p in self.consistent_set]
        d["teammates_placed_final"] = self.teammates_placed_final
        return d


@dataclass
class RunResult:
    """Everything a run measured; ``to_dict()`` is the metrics JSON (plain, serializable)."""

    scenario: str
    seed: int
    params: dict
    robots: dict[str, RobotMetrics]
    cycle_ms: list[float] = field(default_factory=list)
    sim_s: float = 0.0
    wall_s: float = 0.0
    interrupted: bool = False
    outputs: dict = field(default_factory=dict)
    consensus_s: float | None = None
    consensus_final: bool = False
    consensus_held_s: float = 0.0
    false_merge_log: list = field(default_factory=list)  # one dict per false merge (see the module doc)
    latency_s: list = field(default_factory=list)  # per map version: its first accepted merge's time − its stamp
    placement_jumps: list = field(default_factory=list)  # [Δθ°, Δt m] of a teammate between held alignments
    tracking: dict = field(default_factory=dict)  # per robot, per pair: merger.team.track.Tracker.stats()

    @property
    def false_merges(self) -> int:
        return sum(r.false_merges for r in self.robots.values())

    @property
    def gross_merges(self) -> int:
        return sum(r.gross_merges for r in self.robots.values())

    @property
    def drift_limited_merges(self) -> int:
        return sum(r.drift_limited_merges for r in self.robots.values())

    @property
    def rejected_correct(self) -> int:
        return sum(r.rejected_correct for r in self.robots.values())

    @property
    def realtime_factor(self) -> float:
        return self.sim_s / self.wall_s if self.wall_s > 0 else math.inf

    def merge_cycle_ms(self) -> dict:
        if not self.cycle_ms:
            return {"median": None, "p95": None, "count": 0}
        a = np.asarray(self.cycle_ms)
        return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)), "count": int(a.size)}

    def all_merged(self) -> bool:
        return all(r.first_merge_s is not None for r in self.robots.values())

    def to_dict(self) -> dict:
        return {
            "scenario": self.scenario, "seed": self.seed, "params": self.params,
            "robots": {n: r.to_dict() for n, r in self.robots.items()},
            "false_merges": self.false_merges, "gross_merges": self.gross_merges,
            "drift_limited_merges": self.drift_limited_merges, "false_merge_log": self.false_merge_log,
            "rejected_correct": self.rejected_correct,
            "merge_cycle_ms": self.merge_cycle_ms(),
            "realtime_factor": None if math.isinf(self.realtime_factor) else self.realtime_factor,
            "sim_s": self.sim_s, "wall_s": self.wall_s, "interrupted": self.interrupted,
            "all_merged": self.all_merged(), "outputs": self.outputs,
            "consensus_s": self.consensus_s, "consensus_final": self.consensus_final,
            "consensus_held_s": self.consensus_held_s,
            "latency_s": _quantiles(self.latency_s), "placement_jump": self.jump_summary(),
            "tracking": self.tracking_summary(),
        }

    def jump_summary(self) -> dict:
        """How far a teammate's placement moved between consecutive alignments a robot held: p95 and
        largest, angle (°) and translation (m), over every robot and teammate."""
        return jump_summary(self.placement_jumps)

    def tracking_summary(self) -> dict:
        """The tracker's work (``merger.research: on_change``): per robot and pair the global searches it
        used, its local re-verifications, the new map versions that kept its answer (held), the changed
        versions of a never-verified pair re-verified at its answer instead of searched (waited) and switches (a
        pair's global search is computed once for the team and counted for every robot that used it), and the
        totals."""
        tot = {"global_searches": 0, "local_checks": 0, "held": 0, "waited": 0, "switches": 0}
        for pairs in self.tracking.values():
            for s in pairs.values():
                for k in tot:
                    tot[k] += s.get(k, 0)
        return {**tot, "per_robot": self.tracking}


def _quantiles(values) -> dict:
    if not len(values):
        return {"count": 0, "median": None, "p95": None, "max": None}
    a = np.asarray(values, np.float64)
    return {"count": int(a.size), "median": float(np.median(a)), "p95": float(np.percentile(a, 95)),
            "max": float(a.max())}


def false_merge_kind(cycle: MergeCycle) -> str:
    """"gross" (a flip, > GROSS_DEG or > GROSS_M off for some map, start-frame truth), "drift_limited"
    (within the tolerances of the estimated-frame truth) or "other"."""
    if any(e > GROSS_DEG for e in cycle.angle_error_deg.values()) \
            or any(e > GROSS_M for e in cycle.translation_error_m.values()):
        return "gross"
    return "drift_limited" if cycle.est_correct else "other"


def false_merge_entry(cycle: MergeCycle, kind: str, tol_deg: float, tol_m: float) -> dict:
    """A false merge for the JSON: when, which robot, its kind, and per misplaced map (beyond ``tol_deg``
    or ``tol_m`` against the start-frame truth) how far off against both truths."""
    maps = {}
    for k, e in cycle.angle_error_deg.items():
        te = cycle.translation_error_m.get(k, 0.0)
        if e > tol_deg + JUDGE_EPS_DEG or te > tol_m + JUDGE_EPS_M:
            maps[k] = {"angle_error_deg": e, "translation_error_m": te,
                       "est_angle_error_deg": cycle.est_angle_error_deg.get(k),
                       "est_translation_error_m": cycle.est_translation_error_m.get(k)}
    return {"t": cycle.t, "robot": cycle.robot, "kind": kind, "adopted_from": cycle.adopted_from or None,
            "maps": maps}


def _worst(into: dict, key: str, deg: dict, m: dict) -> None:
    w = into.setdefault(key, {"deg": 0.0, "m": 0.0})
    w["deg"] = max(w["deg"], max(deg.values(), default=0.0))
    w["m"] = max(w["m"], max(m.values(), default=0.0))


def false_merge_lines(d: dict, limit: int = 10) -> list[str]:
    """The false merges of a metrics dict (``RunResult.to_dict()``) for a summary: counts by kind, then
    one line each (at most ``limit``; the JSON has them all)."""
    log = d.get("false_merge_log") or []
    if not log:
        return []
    out = [f"false merges: {d['false_merges']} ({d['gross_merges']} gross: a flip, > {GROSS_DEG:g}° or > "
           f"{GROSS_M:g} m; {d['drift_limited_merges']} drift-limited: right for the maps as their SLAMs "
           f"built them)"]
    for e in log[:limit]:
        what = "; ".join(f"{k} off {v['angle_error_deg']:.2f}° / {100 * v['translation_error_m']:.1f} cm "
                         f"(vs SLAM frames {v['est_angle_error_deg']:.2f}° / {100 * v['est_translation_error_m']:.1f} cm)"
                         for k, v in e["maps"].items())
        out.append(f"  {e['t']:7.1f} s  {e['robot']}: {e['kind']}: {what}")
    if len(log) > limit:
        out.append(f"  … {len(log) - limit} more in the JSON (false_merge_log)")
    return out


def slam_lines(d: dict) -> list[str]:
    """Each robot's worst SLAM pose error, for a summary."""
    parts = [f"{n} {r['slam_pose_error_max']['m'] * 100:.1f} cm / {r['slam_pose_error_max']['deg']:.2f}°"
             for n, r in d["robots"].items() if r.get("slam_pose_error_max")]
    model = (d.get("params") or {}).get("slam_model", "")
    return [f"SLAM ({model}) worst pose error: " + ", ".join(parts)] if parts else []


def spread(held: dict[str, dict[str, Placement]], team) -> tuple[float, float] | None:
    """How far apart the robots' global alignments are: every robot's placements (onto its own frame, per
    map name) expressed in the first robot's frame, the largest angle and translation difference from that
    robot's over all maps; None unless every robot of ``team`` holds a placement of every map."""
    team = list(team)
    if any(r not in held or any(k not in held[r] for k in team) for r in team):
        return None
    base = team[0]
    ref = held[base]
    d_deg = d_m = 0.0
    for r in team[1:]:
        p = compose(held[r], r, base)
        for k in team:
            d_deg = max(d_deg, abs(float(angle_diff_deg(p[k][0], ref[k][0]))))
            d_m = max(d_m, math.dist(p[k][1], ref[k][1]))
    return d_deg, d_m


def in_consensus(held: dict[str, dict[str, Placement]], team, tol_deg: float = CONSENSUS_TOL_DEG,
                 tol_m: float = 0.05) -> bool:
    """Whether every robot holds the same global alignment, within ``tol_deg`` and ``tol_m`` (one cell)."""
    s = spread(held, team)
    return s is not None and s[0] <= tol_deg + JUDGE_EPS_DEG and s[1] <= tol_m + JUDGE_EPS_M


class MetricsObserver(Observer):
    """Accumulates :class:`RunResult` figures from the run's events; ``cell_m``: the consensus's
    translation tolerance (one cell of the robots' grids); ``tol_deg``, ``tol_m``: the correctness
    tolerances (``merger.correct_tol_deg`` / ``correct_tol_m``), to name a false merge's misplaced maps."""

    def __init__(self, result: RunResult, arc_of, *, cell_m: float = 0.05, tol_deg: float = 2.0,
                 tol_m: float = 0.1) -> None:
        self.result = result
        self.tol_deg, self.tol_m = float(tol_deg), float(tol_m)
        self._arc_of = arc_of  # (robot, t) -> degrees travelled
        self.cell_m = float(cell_m)
        self.held: dict[str, dict[str, Placement]] = {}  # per robot, the placements of the alignment it holds
        self._merged_versions: set = set()  # (robot, map, stamp) already merged: latency counted once
        self._agree_since: float | None = None  # when the current consensus began (None: none now)
        self._next_sample_s: float | None = None  # the next whole second of the SLAM pose error

    def on_tick(self, t, step, ticks) -> None:
        sample = self._next_sample_s is None or t + 1e-9 >= self._next_sample_s
        if sample:
            self._next_sample_s = math.floor(t + 1e-9) + 1.0
        for k in ticks:
            (tx, ty, tyaw), (ex, ey, eyaw) = k.true_pose, k.est_pose_world
            m_err = math.hypot(ex - tx, ey - ty)
            deg = abs(math.degrees((eyaw - tyaw + math.pi) % (2.0 * math.pi) - math.pi))
            r = self.result.robots[k.name]
            mx = r.slam_pose_error_max
            mx["m"], mx["deg"] = max(mx["m"], m_err), max(mx["deg"], deg)
            if sample:
                r.slam_pose_error.append([t, m_err, deg])

    def on_hypothesis(self, t, recipient, adoption) -> None:
        m = self.result.robots[recipient]
        m.hypotheses_received += 1
        m.hypotheses_adopted += bool(adoption.adopted)

    def _hold(self, cycle: MergeCycle) -> None:
        c = cycle.result.chosen
        if c is None:
            return
        before = self.held.get(cycle.robot, {})
        now = {k: (c.theta_deg[k], c.translation(k)) for k in c.theta_deg}
        for k, p in now.items():
            if k != cycle.robot and k in before:
                self.result.placement_jumps.append(list(placement_jump(p, before[k])))
            stamp = cycle.map_stamps.get(k)
            if stamp is not None and (cycle.robot, k, stamp) not in self._merged_versions:
                self._merged_versions.add((cycle.robot, k, stamp))
                self.result.latency_s.append(cycle.t - stamp)
        self.held[cycle.robot] = now
        agree = in_consensus(self.held, self.result.robots, tol_m=self.cell_m)
        self.result.consensus_final = agree
        if agree and self.result.consensus_s is None:
            self.result.consensus_s = cycle.t
        if agree and self._agree_since is None:
            self._agree_since = cycle.t
        elif not agree and self._agree_since is not None:
            self.result.consensus_held_s += cycle.t - self._agree_since
            self._agree_since = None

    def on_end(self, result) -> None:
        if self._agree_since is not None:
            self.result.consensus_held_s += max(self.result.sim_s - self._agree_since, 0.0)
            self._agree_since = None

    def on_map_published(self, t, robot, grid, center_given, center_true) -> None:
        self.result.robots[robot].maps_published += 1

    def on_map_received(self, t, recipient, sender, sent_s, stale=False) -> None:
        m = self.result.robots[recipient]
        if stale:
            m.maps_stale += 1
        else:
            m.maps_received += 1

    def on_merge_cycle(self, cycle: MergeCycle) -> None:
        m = self.result.robots[cycle.robot]
        if not cycle.adopted_from:  # an adopted hypothesis is held, but it is no cycle of the robot's
            m.cycles += 1
            m.partial_cycles += not cycle.complete
            self.result.cycle_ms.append(cycle.result.cost_ms)
        if cycle.teammates_placed != m.teammates_placed_final:
            m.teammates_placed.append([cycle.t, cycle.teammates_placed])
        asm = getattr(cycle.result, "assembly", None)
        if asm is not None and not cycle.adopted_from:
            m.assembly_inconsistent += sum(r.startswith("inconsistent") for r in asm.rejected.values())
            m.assembly_impossible += sum(r.startswith("impossible") for r in asm.rejected.values())
            m.assembly_left_out += len(asm.left_out)
            if not m.consistent_set or m.consistent_set[-1][1] != asm.consistent:
                m.consistent_set.append([cycle.t, asm.consistent])
        if cycle.first_pair_correct:
            m.first_pair_merge_s = cycle.t
            m.first_pair_merge_arc_deg = self._arc_of(cycle.robot, cycle.t)
        if cycle.result.accepted:
            self._hold(cycle)
            m.accepted += 1
            m.final_angle_error_deg = dict(cycle.angle_error_deg)
            m.final_translation_error_m = dict(cycle.translation_error_m)
            m.final_est_angle_error_deg = dict(cycle.est_angle_error_deg)
            m.final_est_translation_error_m = dict(cycle.est_translation_error_m)
            _worst(m.accepted_error_max, "start", cycle.angle_error_deg, cycle.translation_error_m)
            _worst(m.accepted_error_max, "estimated", cycle.est_angle_error_deg, cycle.est_translation_error_m)
            if cycle.false_merge:
                m.false_merges += 1
                kind = false_merge_kind(cycle)
                m.gross_merges += kind == "gross"
                m.drift_limited_merges += kind == "drift_limited"
                self.result.false_merge_log.append(false_merge_entry(cycle, kind, self.tol_deg, self.tol_m))
            elif cycle.complete and m.first_merge_s is None:
                m.first_merge_s = cycle.t
                m.first_merge_arc_deg = self._arc_of(cycle.robot, cycle.t)
                m.first_merge_translation_error_m = max(cycle.translation_error_m.values(), default=0.0)
        elif cycle.correct:
            m.rejected_correct += 1
