"""Team merging from verified pairs: a maximum spanning tree of pairwise alignments (issue 10, item 2).

The thesis's procedure (:func:`merger.team.orders.merge_team`, ``strategy: orders``) searches every merge order
again whenever any map changes: N(N−1)/2 orders of N−1 searches each, most of them onto superpositions
that are new every cycle. Here every *pair* of raw maps is searched once per pair of map versions and
verified on its own (ν_ij on the whole maps, in the frame of the map whose name comes first: every robot
searches a pair alike, and a simulation's robots share it, :mod:`merger.team.memo`); a new map from one robot
costs its N−1 pair searches, every other pair is reused from the previous cycle. The team map is then
assembled:

1. the verified pairs are the edges of a graph weighted by ν; its maximum spanning tree (Kruskal, ties to
   the lower indices) links every map that some chain of verified pairs links to map 0 (the merging
   robot's), and each such map's placement onto map 0 is composed along its tree path;
   A tree edge that no loop confirms (a bridge: without it its two maps are not connected by the pose
   graph's edges, :func:`unconfirmed_edges`) holds the maps beyond it on its evidence alone; it is kept
   only with ν ≥ ν_min + ``BRIDGE_MARGIN``, otherwise dropped and the tree spanned again without it (the
   maps beyond are left out until a loop confirms them or the evidence grows). In the 16-robot hall at
   2.6 s a pair of maps 90° off verified with ν 0.500 on 298 cells (the truth: 0.463 on 136) and
   linked two robots to the team alone: 8 gross false merges in 20 s (``verification: whole_map``);
2. every verified pair that is *not* a tree edge is a cycle of the graph: its own alignment must agree
   with the composed placements (within 10° and 0.2 m, the ambiguity rule's distances), otherwise the
   cycle is rejected as inconsistent — a false pair closes a loop that the true pairs do not;
3. with those loops, the placements are adjusted by least squares over every verified pair (a small
   pose graph, :func:`adjust`), and over the pairs that did not verify on their own (too few cells) but
   whose independent search agrees with the tree — weaker loops, weighted by their evidence: a chain's
   small per-pair errors no longer add up along the tree;
4. every two placed maps are verified again on map 0's frame with the composed placements (``checks``,
   the evidence); a tree edge must pass there too. Other pairs are not required to reach ν_min: their
   evidence is the loop consistency of step 2. Two robots on opposite sides of a large circle see
   opposite faces of the same objects and reach ν ≈ ν_min at best even when placed exactly: the thesis's
   rule (every pair ≥ ν_min) rejected every 6-robot cycle of the hall after 15 s, all of them correct,
   and requiring it of the pairs that verified on their own still rejected 4 of 5 (a marginal pair's
   ν moves across ν_min between its own best alignment and the composed one). Under ``verification:
   auto`` a tree edge is checked by the whole rule and the other pairs by ν alone (their checks are
   evidence only; the contrast's checks in the assembly were 45% of the 16-robot hall's merge thread).
5. as with the orders (:func:`merger.team.orders._beyond`), an assembly is refused when a tree edge's search
   found a better alignment beyond the translation window.

Maps that no verified pair links to map 0 are left out: the result places the maps it can (a partial
team); the others are absent from its ``theta_deg``. Composition: with x_i = c_i + t_ij + R(θ_ij)(x_j − c_j) and
x_0 = c_0 + t_0i + R(θ_0i)(x_i − c_i), map j lands at θ_0j = θ_0i + θ_ij, t_0j = t_0i + R(θ_0i)·t_ij.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from ..grid import OccupancyGrid
from ..search import Alignment, angle_diff_deg, search, wrap_deg
from ..search.local import local_search
from ..transform import rotation
from .ambiguity import PairAmbiguity, resolve
from .memo import Memo, map_key
from .orders import (
    AMBIGUOUS_DEG,
    AMBIGUOUS_M,
    Warps,
    _beyond,
    _pair_key,
    compose,
    place_on_frame0,
    problem_for,
    refine_chosen,
    shifted,
)
from .params import ORIGIN, MapInput, MergeParams, OrderResult, Placement, TeamMergeResult
from .pool import parallel_map
from .superpose import fuse
from .track import Tracker, decide
from .verify import Verification, check_pair, no_evidence, pairwise


@dataclass(frozen=True, eq=False)
class PairResult:
    """Map j searched onto map i and verified in i's frame; ``ambiguity``: the pair's runner-up scored
    within the margin (:mod:`merger.team.ambiguity`) — the alignment is the hypothesis whole-map evidence chose,
    or, when it chose none, the best one with a failed ``verification`` naming both (the edge is dropped)."""

    ref: str
    moving: str
    alignment: Alignment
    verification: Verification
    ambiguity: PairAmbiguity | None = None

    @property
    def ambiguous(self) -> bool:
        return self.ambiguity is not None

    def to_dict(self) -> dict:
        return {"ref": self.ref, "moving": self.moving, **self.alignment.to_dict(), "nu": self.verification.nu,
                "passed": self.verification.passed, "reason": self.verification.reason,
                "ambiguous": self.ambiguous,
                "ambiguity": None if self.ambiguity is None else self.ambiguity.to_dict()}


def pair_result(maps: list[MapInput], i: int, j: int, params: MergeParams, warps: Warps,
                around: tuple[float, tuple[int, int]] | None = None) -> PairResult:
    """Search map j onto map i (raw maps) and verify the alignment on the whole maps in i's frame; an
    ambiguous pair is resolved by that verification under both hypotheses (:func:`merger.team.ambiguity.resolve`).
    ``around``: (θ°, (a, b) cells), an earlier answer of the pair — the search is then the exact local search
    about it (:func:`merger.search.local.local_search`, the tracker's re-verification: no runner-up, no guard)."""
    label = f"{maps[i].name}|{maps[j].name}"

    def check(al: Alignment) -> Verification:
        if params.verification != "roi_score":
            return check_pair(maps[i].grid, warps.get(i, j, al.theta_deg, al.translation_m),
                              shifted(maps[i].center, al.translation_m), params, label)
        ok = al.score >= params.score_min
        return Verification(al.score, al.counts, ok, "" if ok else
                            f"score of {maps[j].name} = {al.score:.3f} < score_min {params.score_min:g}")

    prob = problem_for(maps[i].grid, maps[i].center, maps[j], params)
    if around is not None:
        al, amb = local_search(prob, around[0], around[1]), None
    else:
        al, amb = resolve(prob, search(prob, params.method), params.margin, check, maps[i].name, maps[j].name)
    ver = check(al)
    if not al.has_evidence:
        ver = Verification(ver.nu, ver.counts, False, no_evidence(al, params.roi_min_support, label))
    elif amb is not None and not amb.used:
        ver = Verification(ver.nu, ver.counts, False, amb.reason)
    return PairResult(maps[i].name, maps[j].name, al, ver, amb)


def _placement(p: PairResult) -> Placement:
    return (float(p.alignment.theta_deg), (float(p.alignment.translation_m[0]), float(p.alignment.translation_m[1])))


def spanning_tree(n: int, edges: dict[tuple[int, int], float]) -> list[tuple[int, int]]:
    """Maximum spanning forest (Kruskal): edges (i, j), i < j, by decreasing weight, ties to lower indices."""
    parent = list(range(n))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    tree = []
    for (i, j), _ in sorted(edges.items(), key=lambda kv: (-kv[1], kv[0])):
        ri, rj = root(i), root(j)
        if ri != rj:
            parent[rj] = ri
            tree.append((i, j))
    return tree


def relative(al: Alignment, reverse: bool) -> Placement:
    """(θ, t) of a pair's alignment (j onto i); ``reverse``: i onto j, θ_ji = −θ_ij, t_ji = −R(−θ_ij)·t_ij."""
    rel = (float(al.theta_deg), (float(al.translation_m[0]), float(al.translation_m[1])))
    return invert(rel) if reverse else rel


def pair_placement(p: PairResult, names, i: int, j: int) -> Placement:
    """(θ, t) of map j onto map i (``names``: the maps' names by index) from their pair result, whichever
    way it was searched (the pair's reference is the map whose name comes first: :func:`merge_tree`)."""
    return relative(p.alignment, reverse=p.ref != names[i])


def invert(rel: Placement) -> Placement:
    """(θ, t) of i onto j from (θ, t) of j onto i."""
    th, t = rel
    d = -(rotation(-th) @ np.asarray(t, np.float64))
    return wrap_deg(-th), (float(d[0]), float(d[1]))


def chain(p_parent: Placement, rel: Placement) -> Placement:
    """Placement onto map 0 of a map placed ``rel`` onto a map placed ``p_parent`` onto map 0."""
    th0, t0 = p_parent
    d = rotation(th0) @ np.asarray(rel[1], np.float64)
    return wrap_deg(th0 + rel[0]), (float(t0[0] + d[0]), float(t0[1] + d[1]))


def compose_tree(n: int, tree: list[tuple[int, int]], pairs: dict[tuple[int, int], PairResult], names):
    """Placements onto map 0 of every map the tree links to it, in breadth-first order, and the tree edges
    used as (parent, child) pairs."""
    nbrs: dict[int, list[int]] = {k: [] for k in range(n)}
    for i, j in tree:
        nbrs[i].append(j)
        nbrs[j].append(i)
    place: dict[int, Placement] = {0: (0.0, ORIGIN)}
    links: list[tuple[int, int]] = []
    queue = [0]
    for a in queue:
        for b in sorted(nbrs[a]):
            if b in place:
                continue
            i, j = min(a, b), max(a, b)
            rel = pair_placement(pairs[(i, j)], names, i, j)
            place[b] = chain(place[a], rel if a < b else invert(rel))
            links.append((a, b))
            queue.append(b)
    return place, links


def disagreement(place: dict[int, Placement], p: PairResult, names, i: int, j: int) -> tuple[float, float]:
    """How far a pair's own alignment (j onto i) places map j from its composed placement: (°, m)."""
    th_ij, t_ij = pair_placement(p, names, i, j)
    th_i, t_i = place[i]
    th_j, t_j = place[j]
    d = rotation(-th_i) @ (np.asarray(t_j, np.float64) - np.asarray(t_i, np.float64))
    return abs(angle_diff_deg(wrap_deg(th_j - th_i), th_ij)), math.dist((float(d[0]), float(d[1])), t_ij)


def inconsistent_pairs(place: dict[int, Placement], pairs: dict[tuple[int, int], PairResult],
                       tree: list[tuple[int, int]], names) -> list[tuple[int, int, float, float]]:
    """Verified non-tree pairs (i, j) between placed maps whose own alignment disagrees with the composed
    one by more than 10° or 0.2 m, with that disagreement (°, m)."""
    out = []
    in_tree = set(tree)
    for (i, j), p in pairs.items():
        if not p.verification.passed or (i, j) in in_tree or i not in place or j not in place:
            continue
        dth, dt = disagreement(place, p, names, i, j)
        if dth > AMBIGUOUS_DEG or dt > AMBIGUOUS_M:
            out.append((i, j, dth, dt))
    return out


def inconsistencies(place: dict[int, Placement], pairs: dict[tuple[int, int], PairResult],
                    tree: list[tuple[int, int]], maps: list[MapInput]) -> list[str]:
    """Why the assembly is inconsistent: one line per pair of :func:`inconsistent_pairs`."""
    return [f"inconsistent: the verified pair {maps[i].name}|{maps[j].name} places {maps[j].name} "
            f"{dth:.1f}° / {dt:.2f} m away from the spanning tree's placement"
            for i, j, dth, dt in inconsistent_pairs(place, pairs, tree, [m.name for m in maps])]


def loop_pairs(place, pairs, tree, links, names) -> set[tuple[int, int]]:
    """The pairs of the inconsistent loops (:func:`inconsistencies`): each inconsistent verified pair (i, j)
    and the tree edges on the path from i to j."""
    parent = {b: a for a, b in links}

    def up(k):
        path = [k]
        while path[-1] in parent:
            path.append(parent[path[-1]])
        return path

    out = set()
    for i, j, _, _ in inconsistent_pairs(place, pairs, tree, names):
        out.add((i, j))
        pi, pj = up(i), up(j)
        common = next(k for k in pi if k in set(pj))
        for path in (pi[:pi.index(common) + 1], pj[:pj.index(common) + 1]):
            out |= {(min(a, b), max(a, b)) for a, b in zip(path, path[1:], strict=False)}
    return out


def loop_edges(place: dict[int, Placement], pairs: dict[tuple[int, int], PairResult], names,
               params: MergeParams | None = None) -> list[tuple[int, int, Placement, float]]:
    """The pose graph's edges between placed maps: (i, j, placement of j onto i, weight).

    Every verified pair, weighted by its ν. With ``params``, also every pair that did not verify on its own
    but whose search, made independently of the tree, lands within the loop tolerance (10°, 0.2 m) of the
    composed placement with ν ≥ ν_min/2: weighted ν·min(1, support/min_support), it is a weaker loop
    closure. It adjusts the placements only; it never links a map nor accepts anything (the assembly is
    verified as before). On a ring of seven robots 5.7 s into the hall, six pairs verified (one loop) and
    the tree's far end was 2.15° off; ten more pairs between placed maps agreed with the tree but lacked
    min_support cells (ν 0.28–0.66 on 127–198 cells), and with them the largest error was 0.86°."""
    out = []
    for (i, j), p in pairs.items():
        v = p.verification
        if i not in place or j not in place:
            continue
        if v.passed:
            out.append((i, j, pair_placement(p, names, i, j), v.nu))
        elif params is not None and p.ambiguity is None and v.nu >= params.nu_min / 2:
            dth, dt = disagreement(place, p, names, i, j)
            if dth <= AMBIGUOUS_DEG and dt <= AMBIGUOUS_M:
                out.append((i, j, pair_placement(p, names, i, j),
                            v.nu * min(1.0, v.counts.support / max(params.min_support, 1))))
    return out


def adjust(place: dict[int, Placement], pairs: dict[tuple[int, int], PairResult], names,
           params: MergeParams | None = None) -> dict[int, Placement]:
    """Least-squares placements over the pose graph of :func:`loop_edges` (every verified pair between
    placed maps; with ``params``, also the weaker pairs that agree with the tree).

    A tree composes each pair's small error along its path: on a ring of six robots the far end of a
    five-edge chain was off by 2° while every pair was within 0.5°. With the loops closed by other pairs
    (verified ones already found consistent within 10° and 0.2 m), the angles minimise
    Σ w_ij (θ_j − θ_i − θ_ij)² (linearised about the tree's angles, map 0 fixed), then the translations
    Σ w_ij |t_j − t_i − R(θ_i) t_ij|² given the angles. Without loops this is the tree's placement."""
    idx = {k: n for n, k in enumerate(k for k in place if k != 0)}
    edges = loop_edges(place, pairs, names, params)
    if len(edges) <= len(idx) or not idx:  # a tree: nothing to adjust
        return place
    a = np.zeros((len(edges), len(idx)))
    b = np.zeros(len(edges))
    for r, (i, j, (th_ij, _), nu) in enumerate(edges):
        w = math.sqrt(max(nu, 1e-6))
        for k, sign in ((j, 1.0), (i, -1.0)):
            if k in idx:
                a[r, idx[k]] += sign * w
        b[r] = w * angle_diff_deg(th_ij, place[j][0] - place[i][0])  # wrapped residual of the tree
    delta = np.linalg.lstsq(a, b, rcond=None)[0]
    theta = {k: place[k][0] + (delta[idx[k]] if k in idx else 0.0) for k in place}
    at = np.zeros((2 * len(edges), 2 * len(idx)))
    bt = np.zeros(2 * len(edges))
    for r, (i, j, (_, t_ij), nu) in enumerate(edges):
        w = math.sqrt(max(nu, 1e-6))
        for k, sign in ((j, 1.0), (i, -1.0)):
            if k in idx:
                at[2 * r, 2 * idx[k]] += sign * w
                at[2 * r + 1, 2 * idx[k] + 1] += sign * w
        bt[2 * r:2 * r + 2] = w * (rotation(theta[i]) @ np.asarray(t_ij, np.float64))
    tt = np.linalg.lstsq(at, bt, rcond=None)[0]
    return {k: (0.0, ORIGIN) if k == 0 else
            (wrap_deg(theta[k]), (float(tt[2 * idx[k]]), float(tt[2 * idx[k] + 1]))) for k in place}


BRIDGE_MARGIN = 0.05  # a tree edge no loop confirms needs ν ≥ ν_min + this (Cartographer: a global match
# needs global_localization_min_score 0.6, a local one min_score 0.55); docs/limits.md, hall16


def unconfirmed_edges(place, pairs, links, names, params) -> list[tuple[int, int]]:
    """The tree edges (parent, child) that no loop confirms: removing the edge from the graph of the pose
    graph's edges (:func:`loop_edges`: verified pairs and the weaker pairs agreeing with the tree) leaves
    its two maps unconnected — the edge is a bridge, and the maps beyond it rest on its evidence alone."""
    edges = [(i, j) for i, j, _, _ in loop_edges(place, pairs, names, params)]
    out = []
    for a, b in links:
        e = (min(a, b), max(a, b))
        nbrs: dict[int, list[int]] = {}
        for i, j in edges:
            if (i, j) != e:
                nbrs.setdefault(i, []).append(j)
                nbrs.setdefault(j, []).append(i)
        seen, stack = {a}, [a]
        while stack:
            for y in nbrs.get(stack.pop(), ()):
                if y not in seen:
                    seen.add(y)
                    stack.append(y)
        if b not in seen:
            out.append((a, b))
    return out


def merge_tree(maps: list[MapInput], params: MergeParams = MergeParams(), *,  # noqa: B008 (frozen)
               reuse: dict | None = None, memo: Memo | None = None, tracker: Tracker | None = None,
               now: float = 0.0) -> TeamMergeResult:
    """Merge N ≥ 2 maps from verified pairs (see the module notes); results in the frame of ``maps[0]``.

    ``reuse`` (kept by the caller between cycles, e.g. :class:`merger.team.online.TeamMerger`): every pair's
    search and verification, by the versions of its two maps; after the cycle it holds only this cycle's
    pairs. The result has one hypothesis (``orders[0]``): the placed maps in tree order, its ``steps``
    the tree edges' pair searches as (moving map, alignment) — every pair is searched with the map whose
    name comes first as the reference, in that map's frame, so every robot searches it alike — and its
    ``checks`` the placed pairs verified on map 0's frame. ``memo`` (:mod:`merger.team.memo`): pair results shared with the other robots of a simulation (the
    result is the same; its ``charged_ms`` is the computing time of the pairs taken from the memo).
    ``tracker`` (:mod:`merger.team.track`, ``research: on_change``): a pair of new map versions is re-verified
    about its tracked answer by the local search, and searched globally only when the tracker says so
    (``now``: the caller's clock, seconds)."""
    if len(maps) < 2:
        raise ValueError(f"merging needs at least two maps, got {len(maps)}")
    t0 = time.perf_counter()
    if memo is not None:
        memo.take_charged_ms()
    warps = Warps(maps)
    pairs: dict[tuple[int, int], PairResult] = {}
    live = set()
    todo = []
    for i, j in pairwise(maps):
        # every robot searches a pair the same way: the map whose name comes first is the reference (so
        # teammates' results are the same, and shared through the memo)
        r, m = (j, i) if maps[j].name < maps[i].name else (i, j)
        key = _pair_key(maps[r], maps[m], params) if reuse is not None else None
        hit = reuse.get(key) if key is not None else None
        live.add(key)
        if hit is None:
            todo.append(((i, j), r, m, key))
        else:
            pairs[(i, j)] = hit

    def compute(task):
        _, r, m, _ = task
        if memo is None:
            return pair_result(maps, r, m, params, warps)
        return memo.get(("tree-pair", map_key(maps[r]), map_key(maps[m]), params),
                        lambda: pair_result(maps, r, m, params, warps))

    def compute_local(r, m, around):
        """The local search about ``around`` (θ°, cells), shared with teammates through the memo."""
        if memo is None:
            return pair_result(maps, r, m, params, warps, around)
        return memo.get(("tree-pair-local", map_key(maps[r]), map_key(maps[m]), params, around),
                        lambda: pair_result(maps, r, m, params, warps, around))

    def composed(r, m):
        """Where the team placement the robot holds puts map m relative to map r, on the search's grid
        (whole degrees and cells: teammates holding nearly the same placement share the search), or None."""
        tp = tracker.team_place
        if maps[r].name not in tp or maps[m].name not in tp:
            return None
        th, t = compose({0: tp[maps[r].name], 1: tp[maps[m].name]}, 0, 0)[1]
        res = maps[r].grid.resolution
        return (float(round(th) % 360), (int(round(t[0] / res)), int(round(t[1] / res))))

    def tracked(task):
        """The pair's result under the tracker (merger.team.track): local re-verification, global when due."""
        _, r, m, _ = task
        key, sub = f"{maps[r].name}|{maps[m].name}", (maps[r], maps[m])
        tr = tracker.track(key)
        local, local_ok = None, False
        if tr.tracked is None and tr.last is not None and now - tr.global_s < tracker.period_s - 1e-9:
            # never verified, but the team placement links both maps (Cartographer: trajectories already
            # connected are matched locally, from their current relative pose): a local search there,
            # a global one only at the staleness bound; a verified answer there is followed from then on
            at = composed(r, m)
            if at is not None:
                loc = compute_local(r, m, at)
                tr.locals += 1
                if loc.verification.passed:
                    tr.tracked, tr.placement, tr.nu_ref = loc, _placement(loc), loc.verification.nu
                    tracker.accepted(tr, tr.placement)
                tr.last = loc
                return loc
        if tr.tracked is not None:
            local = compute_local(r, m, (tr.tracked.alignment.theta_grid_deg, tr.tracked.alignment.cells))
            local_ok = local.verification.passed and local.verification.nu >= tr.nu_ref - tracker.drop
            if local_ok and not tracker.due(tr, sub, params.roi_m, now):
                tr.locals += 1
                tr.tracked, tr.placement = local, _placement(local)
                out = local
            else:
                out = None
        elif tr.last is not None and not tracker.due(tr, sub, params.roi_m, now):
            return tr.last  # never verified: searched again when its maps change or the period ends
        else:
            out = None
        if out is None:
            glob = compute(task)
            suspect = bool(tr.recheck)
            tracker.searched(tr, sub, params.roi_m, now)
            out = decide(tracker, key, tr, local, local_ok, glob, glob.verification.passed, now, _placement,
                         lambda p: p.verification.nu, suspect)
        if out.verification.passed:
            tracker.accepted(tr, _placement(out))
        tr.last = out
        return out

    # the pairs are independent: searched side by side (merger.team.pool; the same result on any schedule)
    for (ij, _, _, key), hit in zip(todo, parallel_map(compute if tracker is None else tracked, todo), strict=True):
        if key is not None:
            reuse[key] = hit
        pairs[ij] = hit
    pairs = {ij: pairs[ij] for ij in sorted(pairs)}
    if reuse is not None:
        for key in [k for k in reuse if k not in live]:
            del reuse[key]
    edges = {ij: p.verification.nu for ij, p in pairs.items() if p.verification.passed}
    names = [m.name for m in maps]
    weak: dict[tuple[int, int], str] = {}
    for _ in range(len(maps)):  # drop the weak bridges, then span again (each round drops one at least)
        tree = spanning_tree(len(maps), edges)
        place, links = compose_tree(len(maps), tree, pairs, names)
        drop = [e for e in ((min(a, b), max(a, b)) for a, b in unconfirmed_edges(place, pairs, links, names, params))
                if pairs[e].verification.nu < params.nu_min + BRIDGE_MARGIN]
        if not drop:
            break
        for e in drop:
            del edges[e]
            weak[e] = (f"{names[e[0]]}|{names[e[1]]}: only this pair links it and no loop confirms it; ν "
                       f"{pairs[e].verification.nu:.3f} < ν_min + {BRIDGE_MARGIN:g} (a single unconfirmed link)")
    if len(place) == 1:  # no verified pair reaches map 0: report its best pair, rejected
        best = max(range(1, len(maps)), key=lambda k: (pairs[(0, k)].verification.nu, -k))
        place[best] = pair_placement(pairs[(0, best)], names, 0, best)
        links = [(0, best)]
    inconsistent = inconsistencies(place, pairs, tree, maps)
    if not inconsistent:
        place = adjust(place, pairs, names, params)
    order = list(place)  # breadth-first: map 0 first
    sub = [maps[k] for k in order]
    sub_place = {s: place[k] for s, k in enumerate(order)}
    sw = Warps(sub)
    checks, failed = {}, []
    suspects: set[tuple[int, int]] = set()
    linked = {(min(a, b), max(a, b)) for a, b in links}
    # a pair that is no tree edge need not pass (step 4): under "auto" its check is the thesis's ν alone —
    # the contrast rule's rival scan for every such pair was 45% of the 16-robot hall's time
    loose = replace(params, verification="whole_map") if params.verification == "auto" else params
    for a, b in pairwise(sub):
        ij = (min(order[a], order[b]), max(order[a], order[b]))
        v = sw.check(a, sub_place[a], b, sub_place[b], params if ij in linked else loose) \
            if params.verification != "roi_score" else pairs[ij].verification
        checks[f"{sub[a].name}|{sub[b].name}"] = v
        if ij in linked and pairs[ij].verification.passed and not v.passed:  # a tree edge must verify in the assembly
            failed.append(v.reason)
            suspects.add(ij)
    if any(not pairs[ij].verification.passed or ij in weak for ij in linked):  # the fallback pair of an unlinked map 0
        failed += [weak.get(ij) or pairs[ij].verification.reason for ij in linked
                   if not pairs[ij].verification.passed or ij in weak]
    failed += inconsistent
    if inconsistent:  # every pair of an inconsistent loop: the non-tree pair and the tree path it closes
        suspects |= loop_pairs(place, pairs, tree, links, names)
    if tracker is not None:  # a local answer the assembly found wrong is searched globally at the next version
        for ij in suspects:
            p = pairs[ij]
            if p.alignment.method.endswith("-local"):
                tracker.track(f"{p.ref}|{p.moving}").recheck = "the team's assembly found it inconsistent or failing"
    steps = tuple((p.moving, p.alignment) for p in (pairs[(min(a, b), max(a, b))] for a, b in links))
    result = OrderResult(tuple(m.name for m in sub), {maps[k].name: place[k][0] for k in order}, steps, checks,
                         not failed, "; ".join(failed), {maps[k].name: place[k][1] for k in order})
    guard = _beyond(result) if result.accepted else ""  # a tree edge's best alignment beyond the window
    chosen, merged, layers = (result, None, {}) if result.accepted and not guard else (None, None, {})
    if chosen is not None and tracker is not None:
        tracker.team_place = {maps[k].name: place[k] for k in order}
    if chosen is not None:
        chosen, sub_place = refine_chosen(sub, sub_place, sw, params, chosen)
        result = chosen
        lay = place_on_frame0(sub, sub_place, sw)
        merged = OccupancyGrid(fuse([g.states for g in lay]), lay[0].resolution, lay[0].origin)
        layers = {m.name: g for m, g in zip(sub, lay, strict=True)}
    return TeamMergeResult(maps[0].name, (result,), chosen, merged, layers, (time.perf_counter() - t0) * 1e3,
                           guard, tuple(p.ambiguity for p in pairs.values() if p.ambiguity is not None),
                           memo.take_charged_ms() if memo is not None else 0.0)
