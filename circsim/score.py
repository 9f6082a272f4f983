"""``circsim score RUN``: judge any merger's answers against a run's ground truth, with the run's metrics.

RUN is a bag written by ``circsim run --bag RUN`` (:mod:`circsim.record.bag`); its ``circsim_truth.yaml``
holds the truth. An *estimate* is what a merger holds at a time for one robot's frame: the pose of every
map it placed in that robot's map frame. ``--transforms FILE`` reads estimates from a CSV (or YAML: a list
of the same rows, or ``{transforms: [...]}``) with the columns

    t_s, robot, map, yaw_deg, x_m, y_m [, estimate]

one row per placed map: at ``t_s`` (simulated seconds = the bag's clock), the pose of frame ``map``/map
in frame ``robot``/map, x_robot = R(yaw)·x_map + (x, y) — the tf transform between the two map frames.
Rows with the same ``estimate`` id (or, without that column, the same ``t_s`` and ``robot``) are one
estimate. ``--merged-bag`` derives estimates from a merged ``/map`` topic (:mod:`circsim.locate`).

Every estimate is judged as the run judges an accepted merge (:func:`circsim.judge.judge_placement`):
the alignment about the given centers, θ = yaw and t = p + R(θ)·c_j − c_i, against the start-frame truth
θ*_ij, t*_ij within the run's tolerances. Per robot: ``first_merge_s`` (first correct estimate placing
every teammate), ``first_pair_merge_s`` (first correct one placing any), ``estimates``, ``false_merges``
(incorrect estimates) and of those ``gross_merges`` (a flip, > 10° or > 0.5 m off), the final errors, and
``first_merge_translation_error_m``. The bench's own merges (``RUN/circsim_merges.csv``) score exactly
as the run did (same first merges, same false merges: tests/circsim/test_score.py).
Not judged here: the estimated-frame truth (drift-limited merges) and arcs, which need the run itself.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from merger.limits import MAX_YAML_BYTES, load_yaml, one_line, read_input

from .judge import JUDGE_EPS_DEG, JUDGE_EPS_M, judge_placement
from .metrics import GROSS_DEG, GROSS_M

TRUTH_FILE = "circsim_truth.yaml"  # the same names as circsim.record.bag (which needs rosbags to import)
MERGES_FILE = "circsim_merges.csv"
COLUMNS = ("t_s", "robot", "map", "yaw_deg", "x_m", "y_m")


MAX_TRANSFORMS_BYTES = 256 << 20


class ScoreError(ValueError):
    """A bad RUN or estimates file: one line naming the file, the key or row, and what was expected."""


def _text(path: Path, limit: int) -> str:
    """The UTF-8 text of the regular file ``path``: a folder, FIFO or device is named as such (ValueError)."""
    try:
        return read_input(path, limit, "file").decode()
    except UnicodeDecodeError:
        raise ScoreError(f"{path}: expected a UTF-8 text file") from None


def _yaml(path: Path, limit: int):
    try:
        return load_yaml(_text(path, limit))
    except yaml.YAMLError as e:
        raise ScoreError(f"{path}: not valid YAML ({one_line(str(e))})") from None


@dataclass(frozen=True)
class Truth:
    robots: tuple[str, ...]
    centers: dict  # robot -> given center (its map frame)
    theta_deg: dict  # [i][j]: θ*_ij
    t_m: dict  # [i][j]: t*_ij about the given centers
    rigid: dict  # [i][j]: (yaw_deg, x, y), the pose of j/map in i/map
    tol_deg: float
    tol_m: float
    map_topics: dict = field(default_factory=dict)  # robot -> its map topic in the bag
    source: str = ""
    sim_s: float | None = None  # the run's length: estimates are stamped within [0, sim_s]


@dataclass(frozen=True)
class Estimate:
    t: float
    robot: str
    placements: dict  # map -> (yaw_deg, x, y): the pose of map/map in robot/map
    where: str = ""


def load_truth(run) -> Truth:
    """The ground truth of a run: ``run`` is the bag folder (or its ``circsim_truth.yaml``)."""
    run = Path(run)
    path = run / TRUTH_FILE if run.is_dir() else run
    if not path.is_file():
        raise ScoreError(f"{run}: no {TRUTH_FILE} here: expected a bag written by `circsim run --bag`")
    d = _yaml(path, MAX_YAML_BYTES)

    def num(v, key):
        x = _number(v)
        if x is None:
            raise ScoreError(f"{path}: {key}: expected a finite number, got {one_line(repr(v))}")
        return x

    def nums(v, key, n):
        if not isinstance(v, list | tuple) or len(v) != n:
            raise ScoreError(f"{path}: {key}: expected {n} finite numbers, got {one_line(repr(v))}")
        return tuple(num(x, key) for x in v)

    try:
        robots = tuple(d["robots"])
        centers = {n: nums(d["robots"][n]["center_given"], f"robots.{n}.center_given", 2) for n in robots}
        topics = {n: str(d["robots"][n]["map_topic"]) for n in robots}
        theta, t_m, rigid = {}, {}, {}
        for i in robots:
            theta[i], t_m[i], rigid[i] = {i: 0.0}, {i: (0.0, 0.0)}, {i: (0.0, 0.0, 0.0)}
            for j in robots:
                if j != i:
                    p, k = d["truth"][i][j], f"truth.{i}.{j}"
                    theta[i][j] = num(p["theta_deg"], f"{k}.theta_deg")
                    t_m[i][j] = nums(p["t_m"], f"{k}.t_m", 2)
                    rigid[i][j] = tuple(num(p[c], f"{k}.{c}") for c in ("yaw_deg", "x_m", "y_m"))
        tol = d["tolerance"]
        tol_deg, tol_m = num(tol["deg"], "tolerance.deg"), num(tol["m"], "tolerance.m")
        if tol_deg < 0 or tol_m < 0:
            raise ScoreError(f"{path}: tolerance: expected numbers >= 0, got {tol_deg:g} deg, {tol_m:g} m")
        sim_s = num(d["sim_s"], "sim_s") if "sim_s" in d else None
        if sim_s is not None and sim_s < 0:
            raise ScoreError(f"{path}: sim_s: expected a run's length >= 0 s, got {sim_s:g}")
        return Truth(robots, centers, theta, t_m, rigid, tol_deg, tol_m, topics, str(path), sim_s)
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        if isinstance(e, ScoreError):
            raise
        raise ScoreError(f"{path}: not a circsim truth file (missing or bad key: {one_line(str(e))})") from None


def _number(v) -> float | None:
    """``v`` as a finite float (a number, or a CSV cell's text), or None: YAML's true/false are not numbers."""
    if isinstance(v, bool):
        return None
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def read_transforms(path, truth: Truth) -> list[Estimate]:
    """Estimates from a CSV or YAML file of rows (module docstring), in time order (stable)."""
    path = Path(path)
    if not os.path.lexists(path):
        raise ScoreError(f"{path}: no such transforms file")  # a folder, FIFO or device: named by _text
    if path.suffix.lower() in (".yaml", ".yml"):
        d = _yaml(path, MAX_TRANSFORMS_BYTES)
        rows = d.get("transforms") if isinstance(d, dict) else d
        if not isinstance(rows, list):
            raise ScoreError(f"{path}: expected a list of rows with keys {', '.join(COLUMNS)} (or transforms: [...])")
        where = [f"{path}: transforms[{k}]" for k in range(len(rows))]
    else:
        reader = csv.DictReader(_text(path, MAX_TRANSFORMS_BYTES).splitlines())
        missing = [c for c in COLUMNS if c not in (reader.fieldnames or [])]
        if missing:
            raise ScoreError(f"{path}: header: expected the columns {', '.join(COLUMNS)} [, estimate], "
                             f"missing {', '.join(missing)}")
        rows = list(reader)
        where = [f"{path}: line {k + 2}" for k in range(len(rows))]
    groups: dict = {}
    for row, w in zip(rows, where, strict=True):
        if not isinstance(row, dict):
            raise ScoreError(f"{w}: expected a row with keys {', '.join(COLUMNS)}")
        try:
            t, yaw, x, y = (_number(row[k]) for k in ("t_s", "yaw_deg", "x_m", "y_m"))
            robot, m = str(row["robot"]), str(row["map"])
        except KeyError as e:
            raise ScoreError(f"{w}: missing {e}") from None
        bad = [k for k, v in zip(("t_s", "yaw_deg", "x_m", "y_m"), (t, yaw, x, y), strict=True) if v is None]
        if bad:
            raise ScoreError(f"{w}: {', '.join(bad)}: expected finite numbers, got "
                             + ", ".join(one_line(repr(row[k])) for k in bad))
        if t < 0 or (truth.sim_s is not None and t > truth.sim_s + 1e-6):
            span = f"[0, {truth.sim_s:g}] s (the run's length)" if truth.sim_s is not None else ">= 0 s"
            raise ScoreError(f"{w}: t_s: expected a time of the run, in {span}, got {t:g}")
        for key, name in (("robot", robot), ("map", m)):
            if name not in truth.robots:
                raise ScoreError(f"{w}: {key}: {name!r} is no robot of the run ({', '.join(truth.robots)})")
        est = row.get("estimate")
        key = (robot, str(est)) if est not in (None, "") else (robot, t)
        g = groups.setdefault(key, [t, robot, {}, w])
        if g[0] != t:
            raise ScoreError(f"{w}: estimate {est}: its rows have different times ({g[0]} and {t})")
        if m in g[2]:
            raise ScoreError(f"{w}: map {m}: placed twice in one estimate of {robot} (at {t:g} s; first at "
                             f"{g[2][m][3].rsplit(': ', 1)[-1]}): expected one row per map")
        if m != robot:
            g[2][m] = (yaw, x, y, w)
    out = [Estimate(t, r, {m: v[:3] for m, v in p.items()}, w) for t, r, p, w in groups.values() if p]
    return sorted(out, key=lambda e: e.t)


def judge_estimate(truth: Truth, e: Estimate):
    """Angle errors, translation errors and correctness of an estimate, about the given centers as the run
    judges a merge (the robot's own map at θ = 0, t = 0)."""
    i = e.robot
    ci = truth.centers[i]
    theta, t = {i: 0.0}, {i: (0.0, 0.0)}
    for j, (yaw, x, y) in e.placements.items():
        a = math.radians(yaw)
        c, s = math.cos(a), math.sin(a)
        cj = truth.centers[j]
        theta[j] = yaw % 360.0
        t[j] = (x + c * cj[0] - s * cj[1] - ci[0], y + s * cj[0] + c * cj[1] - ci[1])
    return judge_placement(theta, t, {k: truth.theta_deg[i][k] for k in theta},
                           {k: truth.t_m[i][k] for k in theta}, truth.tol_deg, truth.tol_m)


def score(truth: Truth, estimates: list[Estimate]) -> dict:
    """The run's metrics of a merger's estimates (module docstring); plain and serializable."""
    robots = {n: {"first_merge_s": None, "first_pair_merge_s": None, "first_merge_translation_error_m": None,
                  "estimates": 0, "false_merges": 0, "gross_merges": 0, "final_angle_error_deg": None,
                  "final_translation_error_m": None} for n in truth.robots}
    log = []
    for e in estimates:
        r = robots[e.robot]
        a_err, t_err, correct = judge_estimate(truth, e)
        complete = set(e.placements) | {e.robot} == set(truth.robots)
        r["estimates"] += 1
        r["final_angle_error_deg"], r["final_translation_error_m"] = a_err, t_err
        if not correct:
            r["false_merges"] += 1
            gross = any(v > GROSS_DEG for v in a_err.values()) or any(v > GROSS_M for v in t_err.values())
            r["gross_merges"] += gross
            log.append({"t": e.t, "robot": e.robot, "kind": "gross" if gross else "other",
                        "maps": {k: {"angle_error_deg": a_err[k], "translation_error_m": t_err[k]} for k in a_err
                                 if a_err[k] > truth.tol_deg + JUDGE_EPS_DEG or t_err[k] > truth.tol_m + JUDGE_EPS_M}})
            continue
        if r["first_pair_merge_s"] is None:
            r["first_pair_merge_s"] = e.t
        if complete and r["first_merge_s"] is None:
            r["first_merge_s"] = e.t
            r["first_merge_translation_error_m"] = max(t_err.values(), default=0.0)
    return {"truth": truth.source, "robots": robots, "estimates": len(estimates),
            "false_merges": sum(r["false_merges"] for r in robots.values()),
            "gross_merges": sum(r["gross_merges"] for r in robots.values()), "false_merge_log": log,
            "all_merged": all(r["first_merge_s"] is not None for r in robots.values()),
            "tolerance": {"deg": truth.tol_deg, "m": truth.tol_m}}


def summary(d: dict, what: str) -> str:
    """A table of :func:`score`'s result, as ``circsim run`` prints a run's."""
    lines = [f"scored {what} against {d['truth']} (tolerances {d['tolerance']['deg']:g}° / "
             f"{100 * d['tolerance']['m']:g} cm)", "",
             f"{'robot':<10} {'first merge s':>13} {'first pair s':>12} {'estimates':>9} {'false':>6} {'gross':>6}  "
             "final errors per teammate (angle deg / translation cm)"]
    for n, r in d["robots"].items():
        def f(v):
            return "—" if v is None else f"{v:.1f}"
        errs = r["final_angle_error_deg"] or {}
        terr = r["final_translation_error_m"] or {}
        e = ", ".join(f"{k} {v:.2f}° / {100 * terr[k]:.1f} cm" for k, v in errs.items() if k != n) or "—"
        lines.append(f"{n:<10} {f(r['first_merge_s']):>13} {f(r['first_pair_merge_s']):>12} {r['estimates']:>9} "
                     f"{r['false_merges']:>6} {r['gross_merges']:>6}  {e}")
    lines += ["", f"false merges {d['false_merges']} ({d['gross_merges']} gross)   estimates {d['estimates']}   "
                  f"every robot merged: {'yes' if d['all_merged'] else 'no'}"]
    for e in d["false_merge_log"][:10]:
        lines.append(f"  {e['t']:7.1f} s  {e['robot']}: {e['kind']}: " + "; ".join(
            f"{k} off {v['angle_error_deg']:.2f}° / {100 * v['translation_error_m']:.1f} cm" for k, v in e["maps"].items()))
    return "\n".join(lines)
