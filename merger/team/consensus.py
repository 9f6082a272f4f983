"""The team's placement from mutually consistent pair measurements (issue 43).

Every verified pair of maps is a relative-pose measurement z_ij (map j onto map i, in centered
coordinates y = x − c: y_i = t_ij + R(θ_ij)·y_j, an element of SE(2)) with its evidence (ν, the routes that
confirm it). A spanning tree takes every measurement it needs at its word, so one wrong pair that
verifies places everything beyond it wrongly, and a cluster consistent inside but rotated as a whole
passes every loop check. Here the team is assembled the way multi-robot SLAM's robust front-ends
treat inter-robot loop closures (pairwise consistency maximization, Mangelson et al., ICRA 2018, in
DOOR-SLAM and Kimera-Multi): from the largest sets of measurements that agree with each other, and two
parts of a team are joined only on evidence that is hard to get by chance.

Agglomeration: every map starts as its own cluster. Between two clusters A and B each measurement (a, b)
is a hypothesis for B's frame in A's, and so is each route through a *witness*: a third map c whose
measurements into A all agree on where c lies in A, and into B likewise (its searches are made
independently of the direct ones; a map whose measurements into a cluster disagree witnesses nothing).
Witnesses are asked where fewer than two direct measurements exist, and always before a join is made.
Hypotheses that agree within ``tol_deg`` and ``tol_m`` form a group; a group's *routes* are its
hypotheses, each a separate search or witness. A join is made on the best group when

* **two routes agree** (:data:`MIN_ROUTES`), at least one of them a direct measurement, and the group
  has at least twice the routes of any rival group between the same clusters; or
* **one measurement is strong**: the only route between them, no rival, and its ν ≥ :func:`single_bar`
  — ν_min + :data:`SINGLE_MARGIN` · max(1, log2(H / 3)), a bar that grows with the number H of pairs the
  team tested (the more pairs tried, the more chances a wrong one has to pass ν: 0.55 for the 6 pairs of
  four robots, 0.66 for 28, 0.77 for 120, 0.87 for 496), and the pair was not ambiguous (a pair whose
  search had a rival within the margin, chosen between by whole-map ν, joins only with a second route:
  four robots 90° apart in a bare rectangular hall — a team and a room a half turn maps onto themselves —
  verified the half turn over the truth by ν 0.790 to 0.718, and one robot placed two teammates by it; a
  pair the tracker follows by local searches keeps the record of the choice, :func:`merger.team.tree.merge_tree`);

and the join is **physically possible**: with trajectories (each map's robot path in its own frame,
:class:`merger.team.params.MapInput`), no robot of A and robot of B are placed in the same place at the
same time (:meth:`Paths.conflict`). A wrong rotation by a multiple of the robots' spacing on their circle
puts each robot onto a teammate's path: every map shows the central objects as the teammate's did, the
placement is consistent around every cycle, but two bodies cannot share a place.

The best join (most routes, then Σν) is made first, the measurements of the losing groups between the
two clusters are rejected as inconsistent and named, and the rounds repeat until no join qualifies. A
map that cannot be joined is left out, not guessed: a false rejection is cheap, a false acceptance is not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..jit import njit

SE2 = tuple[float, float, float]  # (θ degrees, tx, ty): y_to = t + R(θ)·y_from, centered coordinates
IDENT: SE2 = (0.0, 0.0, 0.0)
MIN_ROUTES = 2  # independent agreeing routes that join two clusters on their own
RIVAL_FACTOR = 2  # the joining group needs this many times the routes of any rival group
SINGLE_MARGIN = 0.05  # a lone measurement's ν must clear ν_min + this · max(1, log2(H / 3)) (H: pairs tested)
SEPARATION_M = 0.4  # two robots whose median distance over their common history is below this share a place
TOUCH_M = 0.1  # ... or whose distance at some instant is below this (two bodies cannot overlap)
MIN_COMMON = 3  # common trajectory samples needed before the median test speaks
MAX_SAMPLES = 240  # the paths' common time grid, samples at most
_EVALUATE_ONCE = True  # keep each join's evaluation between rounds (False: evaluate afresh; the tests compare)


def compose(a: SE2, b: SE2) -> SE2:
    """a ∘ b: first b, then a."""
    th = math.radians(a[0])
    c, s = math.cos(th), math.sin(th)
    return ((a[0] + b[0]) % 360.0, a[1] + c * b[1] - s * b[2], a[2] + s * b[1] + c * b[2])


def inverse(a: SE2) -> SE2:
    th = math.radians(a[0])
    c, s = math.cos(th), math.sin(th)
    return ((-a[0]) % 360.0, -(c * a[1] + s * a[2]), -(-s * a[1] + c * a[2]))


def apart(a: SE2, b: SE2) -> tuple[float, float]:
    """How far two placements are: (°, m)."""
    d = (a[0] - b[0] + 180.0) % 360.0 - 180.0
    return abs(d), math.hypot(a[1] - b[1], a[2] - b[2])


def single_bar(nu_min: float, tested: int) -> float:
    """The ν a lone measurement needs to join two parts of a team that tested ``tested`` pairs."""
    return nu_min + SINGLE_MARGIN * max(1.0, math.log2(max(tested, 1) / 3.0))


@dataclass(frozen=True)
class Measurement:
    """A verified pair: map j placed onto map i (i < j), its ν and its name for the log. ``ambiguous``: the
    pair's search had a rival within the margin and whole-map ν chose between them
    (:mod:`merger.team.ambiguity`) — a choice between two hypotheses, not a lone measurement's evidence."""

    i: int
    j: int
    z: SE2
    nu: float
    label: str
    ambiguous: bool = False


@dataclass
class Assembly:
    """What the consensus assembly decided.

    place : per placed map index, its placement onto map 0 (the cluster that holds map 0).
    used : the measurements placing them (consistent within the tolerances with ``place``).
    rejected : measurement label → why it was rejected (inconsistent with a stronger group, or impossible).
    left_out : map index → why it was not joined to map 0's cluster.
    joins : one line per join made: which clusters, on what evidence.
    """

    place: dict[int, SE2]
    used: list[Measurement]
    rejected: dict[str, str] = field(default_factory=dict)
    left_out: dict[int, str] = field(default_factory=dict)
    joins: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class AssemblyReport:
    """How a team placement was assembled (:mod:`merger.team.consensus`): the size of the consistent set of
    measurements, the measurements rejected and why ("A|B" → reason), the maps left out and why, and the
    joins made with their evidence."""

    consistent: int = 0
    rejected: dict[str, str] = field(default_factory=dict)
    left_out: dict[str, str] = field(default_factory=dict)
    joins: tuple[str, ...] = ()

    def to_dict(self) -> dict:
        return {"consistent": self.consistent, "rejected": dict(self.rejected), "left_out": dict(self.left_out),
                "joins": list(self.joins)}


class Paths:
    """The robots' paths on one time grid, placed in their clusters' frames: ``same place`` for a whole
    cluster pair at once. ``trajectories``: per map, rows (t, y_x, y_y) in its centered coordinates (or
    None); resampled on a common grid (the finest sample spacing, at most :data:`MAX_SAMPLES` samples)."""

    def __init__(self, trajectories: list[np.ndarray | None]) -> None:
        known = [tr for tr in trajectories if tr is not None and len(tr) > 0]
        self.active = len(known) >= 2
        if not self.active:
            return
        lo = min(float(tr[0, 0]) for tr in known)
        hi = max(float(tr[-1, 0]) for tr in known)
        steps = [float(np.median(np.diff(tr[:, 0]))) for tr in known if len(tr) > 1]
        step = max(min(steps) if steps else 1.0, (hi - lo) / MAX_SAMPLES, 1e-3)
        self.t = lo + step * np.arange(int((hi - lo) / step + 1e-9) + 1)
        self.y = np.full((len(trajectories), len(self.t), 2), np.nan)
        for k, tr in enumerate(trajectories):
            if tr is None or len(tr) == 0:
                continue
            sel = (self.t >= tr[0, 0] - 1e-9) & (self.t <= tr[-1, 0] + 1e-9)
            self.y[k, sel, 0] = np.interp(self.t[sel], tr[:, 0], tr[:, 1])
            self.y[k, sel, 1] = np.interp(self.t[sel], tr[:, 0], tr[:, 2])
        self.placed = self.y.copy()

    def place(self, k: int, p: SE2) -> None:
        self.placed[k] = _apply(p, self.y[k])

    def conflict(self, ka: list[int], kb: list[int], t_ab: SE2, names: list[str]) -> str:
        """Why placing the maps ``kb`` (placed in their cluster's frame) by ``t_ab`` into the frame of the
        maps ``ka`` puts two robots in one place at the same time, or "" (:data:`TOUCH_M`, :data:`SEPARATION_M`).
        The compiled kernel :func:`_closest`; :meth:`conflict_reference` is the same in numpy (the tests
        compare them)."""
        if not self.active:
            return ""
        pa = self.placed[ka]
        pb = _apply(t_ab, self.placed[kb])
        found, dmin, ia, ib, it, close, ja, jb, n = _closest(pa, pb, SEPARATION_M, MIN_COMMON)
        if not found:
            return ""
        if dmin < TOUCH_M:
            return f"it places {names[ka[ia]]} and {names[kb[ib]]} {dmin:.2f} m apart at {float(self.t[it]):.1f} s"
        if close > 0.5:
            return (f"it places {names[ka[ja]]} and {names[kb[jb]]} within {SEPARATION_M:g} m of each other at "
                    f"{close:.0%} of their {n} common instants")
        return ""

    def conflict_reference(self, ka: list[int], kb: list[int], t_ab: SE2, names: list[str]) -> str:
        """:meth:`conflict` in numpy: every distance of every pair of robots at once."""
        if not self.active:
            return ""
        pa = self.placed[ka]
        pb = _apply(t_ab, self.placed[kb])
        d = np.hypot(pa[:, None, :, 0] - pb[None, :, :, 0], pa[:, None, :, 1] - pb[None, :, :, 1])
        valid = ~np.isnan(d)
        n_common = valid.sum(axis=2)
        if not n_common.any():
            return ""
        dmin = np.where(valid, d, np.inf).min(axis=2)
        ia, ib = np.unravel_index(int(np.argmin(dmin)), dmin.shape)
        if dmin[ia, ib] < TOUCH_M:
            at = float(self.t[int(np.argmin(np.where(valid[ia, ib], d[ia, ib], np.inf)))])
            return f"it places {names[ka[ia]]} and {names[kb[ib]]} {dmin[ia, ib]:.2f} m apart at {at:.1f} s"
        # the median distance is below SEPARATION_M exactly when more than half the common instants are
        close = np.where(n_common >= MIN_COMMON, (valid & (d < SEPARATION_M)).sum(axis=2) / np.maximum(n_common, 1), 0.0)
        ia, ib = np.unravel_index(int(np.argmax(close)), close.shape)
        if close[ia, ib] > 0.5:
            return (f"it places {names[ka[ia]]} and {names[kb[ib]]} within {SEPARATION_M:g} m of each other at "
                    f"{close[ia, ib]:.0%} of their {int(n_common[ia, ib])} common instants")
        return ""


@njit(cache=True, nogil=True)
def _closest(pa, pb, separation, min_common):
    """Over every robot a of ``pa`` (A, T, 2) and b of ``pb`` (B, T, 2) at their common instants (neither
    NaN): whether any pair has one; the smallest distance, its pair (first in a-then-b order) and its first
    instant; the largest share of common instants closer than ``separation`` among pairs with at least
    ``min_common`` of them (0 otherwise), its pair (first) and that pair's common instants."""
    n_a, n_t, n_b = pa.shape[0], pa.shape[1], pb.shape[0]
    found = False
    best, ia, ib, it = np.inf, 0, 0, 0
    share, ja, jb, n_best = -1.0, 0, 0, 0
    for a in range(n_a):
        for b in range(n_b):
            dmin, tmin, n, near = np.inf, 0, 0, 0
            for t in range(n_t):
                d = math.hypot(pa[a, t, 0] - pb[b, t, 0], pa[a, t, 1] - pb[b, t, 1])
                if math.isnan(d):
                    continue
                n += 1
                if d < dmin:
                    dmin, tmin = d, t
                if d < separation:
                    near += 1
            if n > 0:
                found = True
            if dmin < best:
                best, ia, ib, it = dmin, a, b, tmin
            c = near / max(n, 1) if n >= min_common else 0.0
            if c > share:
                share, ja, jb, n_best = c, a, b, n
    return found, best, ia, ib, it, share, ja, jb, n_best


def _apply(p: SE2, y: np.ndarray) -> np.ndarray:
    """Placement p applied to points y (..., 2)."""
    th = math.radians(p[0])
    c, s = math.cos(th), math.sin(th)
    out = np.empty_like(y)
    out[..., 0] = p[1] + c * y[..., 0] - s * y[..., 1]
    out[..., 1] = p[2] + s * y[..., 0] + c * y[..., 1]
    return out


def _mean(hyps: list[tuple[SE2, float]]) -> SE2:
    """Weighted mean of agreeing placements (angles about the first: they lie within the tolerance)."""
    ref = hyps[0][0][0]
    w = sum(h[1] for h in hyps)
    dth = sum(((p[0] - ref + 180.0) % 360.0 - 180.0) * wt for p, wt in hyps) / w
    return ((ref + dth) % 360.0, sum(p[1] * wt for p, wt in hyps) / w, sum(p[2] * wt for p, wt in hyps) / w)


def assemble(n: int, meas: list[Measurement], *, tested: int, nu_min: float, names: list[str],
             trajectories: list[np.ndarray | None] | None = None, tol_deg: float = 10.0,
             tol_m: float = 0.2) -> Assembly:
    """Place the team from mutually consistent measurements (see the module notes). ``trajectories``: per
    map, its robot's path as rows (t, y_x, y_y) in the map's centered coordinates, or None."""
    cluster = list(range(n))  # map → cluster id
    members: dict[int, list[int]] = {k: [k] for k in range(n)}
    pose: list[SE2] = [IDENT] * n  # map's placement in its cluster's frame
    adj: dict[int, dict[int, Measurement]] = {k: {} for k in range(n)}
    for m in meas:
        adj[m.i][m.j] = m
        adj[m.j][m.i] = m
    rejected: dict[str, str] = {}
    joins: list[str] = []
    why_not: dict[frozenset, str] = {}  # the last round's reasons, by pair of clusters
    bar = single_bar(nu_min, tested)

    def rel(m: Measurement, frm: int) -> SE2:
        """Placement of the other map of m onto map ``frm``."""
        return m.z if frm == m.i else inverse(m.z)

    paths = Paths(trajectories) if trajectories is not None else None
    seen: dict[tuple, str] = {}

    def impossible(ca: int, cb: int, t_ab: SE2) -> str:
        if paths is None or not paths.active:
            return ""
        key = (tuple(members[ca]), tuple(members[cb]), round(t_ab[0] * 2), round(t_ab[1] * 100), round(t_ab[2] * 100))
        if key not in seen:
            seen[key] = paths.conflict(members[ca], members[cb], t_ab, names)
        return seen[key]

    def group(hyps: list) -> list[list]:
        """Hypotheses (placement, weight, edges, direct?) grouped by agreement with each group's first."""
        hyps.sort(key=lambda h: (-h[3], -h[1], h[2]))
        groups: list[list] = []
        for h in hyps:
            for g in groups:
                dth, dt = apart(h[0], g[0][0])
                if dth <= tol_deg and dt <= tol_m:
                    g.append(h)
                    break
            else:
                groups.append([h])
        return groups

    def witnesses(ca: int, cb: int) -> list:
        """Routes through every third map c that measurements tie to both clusters: c's placement in each,
        as all its measurements into that cluster agree on it (a map whose measurements into a cluster
        disagree witnesses nothing); one route per witness."""
        out = []
        for c in range(n):
            if cluster[c] in (ca, cb):
                continue
            votes = {ca: [], cb: []}
            for a, m in adj[c].items():
                if cluster[a] in votes and m.label not in rejected:
                    votes[cluster[a]].append((compose(pose[a], rel(m, a)), m.nu, (m.label,), True))
            if votes[ca] and votes[cb]:
                ga, gb = group(votes[ca]), group(votes[cb])
                if len(ga) > 1 or len(gb) > 1:
                    continue  # its own measurements disagree on where it lies: no witness
                va, vb = ga[0], gb[0]
                out.append((compose(_mean([(h[0], h[1]) for h in va]), inverse(_mean([(h[0], h[1]) for h in vb]))),
                            min(va[0][1], vb[0][1]), (f"via {names[c]}",), False))
        return out

    def evaluate(ca: int, cb: int, direct: list[Measurement], full: bool):
        """The join of clusters ca and cb on their direct measurements (and, with ``full`` or fewer than
        two of them, the routes through witnesses): (routes, Σν, t_ab, groups, evidence) or a reason."""
        hyps = []
        for m in direct:
            a, b = (m.i, m.j) if cluster[m.i] == ca else (m.j, m.i)
            hyps.append((compose(compose(pose[a], rel(m, a)), inverse(pose[b])), m.nu, (m.label,), True))
        if full or len(direct) < MIN_ROUTES:
            hyps += witnesses(ca, cb)
        scored = sorted(((len(g), sum(h[1] for h in g if h[3]), g) for g in group(hyps)),
                        key=lambda s: (-s[0], -s[1]))
        possible = []  # groups checked and possible; a group too weak to matter is never checked
        for sc in scored:
            if possible and sc[0] * RIVAL_FACTOR <= possible[0][0][0]:
                break  # it cannot block the best group (and the best cannot be weaker)
            t_ab = _mean([(h[0], h[1]) for h in sc[2]])
            why = impossible(ca, cb, t_ab)
            if why:
                for h in sc[2]:
                    if h[3]:
                        rejected[h[2][0]] = f"impossible: {why}"
            else:
                possible.append((sc, t_ab))
        if not possible:
            return "every placement its measurements give is impossible"
        (routes, wsum, g), t_ab = possible[0]
        rival = max((sc[0] for sc, _ in possible[1:]), default=0)
        n_direct = sum(1 for h in g if h[3])
        lone = routes == 1 and n_direct == 1
        chosen = lone and any(m.ambiguous and m.label == g[0][2][0] for m in direct)  # over a rival, by ν
        if routes >= MIN_ROUTES and n_direct >= 1 and routes >= RIVAL_FACTOR * rival:
            evidence = f"{routes} agreeing routes ({n_direct} direct)" + (f", rival {rival}" if rival else "")
        elif lone and rival == 0 and len(direct) == 1 and g[0][1] >= bar and not chosen:
            evidence = f"one measurement, ν {g[0][1]:.3f} >= {bar:.3f} (H = {tested} pairs tested)"
        else:
            return (f"{routes} agreeing route(s) ({n_direct} direct)"
                    + (f" against {rival} placing it elsewhere" if rival else "")
                    + ("; a lone ambiguous pair (chosen over its rival by whole-map ν) needs a second route"
                       if chosen else f"; a lone measurement needs ν >= {bar:.3f}" if lone else ""))
        return routes, wsum, t_ab, possible, evidence

    ends = {m.label: (m.i, m.j) for m in meas}
    answers: dict[tuple, object] = {}

    def evaluate_once(ca: int, cb: int, direct: list[Measurement], full: bool):
        """:func:`evaluate`, each answer computed once: it depends only on the two clusters (their members,
        whose placements change only when their cluster grows), the direct measurements and the rejections
        of measurements that touch the two clusters; a round's join leaves every other pair of clusters as
        it was, so only the pairs with the grown cluster are evaluated again. An evaluation that rejected a
        measurement (impossible) is not kept: its side effect is part of its answer."""
        mem = set(members[ca]) | set(members[cb])
        rej = frozenset((k, v) for k, v in rejected.items() if ends[k][0] in mem or ends[k][1] in mem)
        key = (ca, cb, full, tuple(members[ca]), tuple(members[cb]), tuple(m.label for m in direct), rej)
        hit = answers.get(key) if _EVALUATE_ONCE else None
        if hit is not None:
            return hit
        before = dict(rejected)
        got = evaluate(ca, cb, direct, full)
        if rejected == before:
            answers[key] = got
        return got

    while True:
        why_not = {}
        between: dict[tuple[int, int], list[Measurement]] = {}
        for m in meas:
            if m.label in rejected:
                continue
            ca, cb = cluster[m.i], cluster[m.j]
            if ca != cb:
                between.setdefault((min(ca, cb), max(ca, cb)), []).append(m)
        cands = []
        for (ca, cb), direct in sorted(between.items()):
            got = evaluate_once(ca, cb, direct, full=False)
            if isinstance(got, str):
                why_not[frozenset((ca, cb))] = got
            else:
                cands.append((-got[0], -got[1], ca, cb))
        best = None
        for _, _, ca, cb in sorted(cands):  # the strongest first, confirmed with every witness's route
            got = evaluate_once(ca, cb, between[(ca, cb)], full=True)
            if isinstance(got, str):
                why_not[frozenset((ca, cb))] = got
            else:
                best = (ca, cb, *got[2:])
                break
        if best is None:
            break
        ca, cb, t_ab, possible, evidence = best
        win = {h[2][0] for h in possible[0][0][2] if h[3]}
        for (_, _, g), _ in possible[1:]:
            for h in g:
                if h[3] and h[2][0] not in win:
                    rejected[h[2][0]] = (f"inconsistent: {h[0][0] - t_ab[0]:+.1f}° / "
                                         f"{math.hypot(h[0][1] - t_ab[1], h[0][2] - t_ab[2]):.2f} m from the placement "
                                         f"that {evidence} agree on")
        joins.append(f"{'+'.join(names[k] for k in members[ca])} with {'+'.join(names[k] for k in members[cb])}: "
                     f"{evidence}")
        for b in members[cb]:
            pose[b] = compose(t_ab, pose[b])
            cluster[b] = ca
            if paths is not None and paths.active:
                paths.place(b, pose[b])
        members[ca] += members.pop(cb)
    home = cluster[0]
    inv0 = inverse(pose[0])
    place = {k: compose(inv0, pose[k]) for k in sorted(members[home], key=lambda k: (k != 0, k))}
    used = []
    for m in meas:
        if m.i in place and m.j in place and m.label not in rejected:
            dth, dt = apart(compose(place[m.i], m.z), place[m.j])
            if dth <= tol_deg and dt <= tol_m:
                used.append(m)
            else:
                rejected[m.label] = f"inconsistent: {dth:.1f}° / {dt:.2f} m from the team's placement"
    left = {}
    for k in range(n):
        if k not in place:
            reasons = [why_not[key] for key in why_not if cluster[k] in key and home in key]
            left[k] = ("not joined: " + (reasons[0] if reasons else "no verified pair links it to the team"))
    return Assembly(place, used, rejected, left, joins)
