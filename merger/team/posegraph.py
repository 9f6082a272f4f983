"""The graph of a team's pairs (:mod:`merger.team.tree`): its maximum spanning tree, the placements composed
along it, the loops that check them and the least-squares adjustment over them.

An edge is a :class:`PairResult`: map j searched onto map i (the map whose name comes first is the
reference) and verified in i's frame; a verified pair's weight is its ν. :func:`spanning_tree` is the
maximum spanning forest (Kruskal, ties to the lower indices); :func:`compose_tree` places every map the
tree links to map 0 by chaining the pairs' placements along its path (:func:`chain`, :func:`invert`;
x_0 = c_0 + t_0i + R(θ_0i)(x_i − c_i)); :func:`disagreement` says how far a pair's own alignment lies from
composed placements. :func:`adjust` places the maps by least squares over the pose graph of
:func:`loop_edges` (the verified pairs, and with the merge parameters the weaker pairs that agree with the
placement). Which pairs are consistent and which maps are joined is :mod:`merger.team.consensus`'s
decision; everything here is arithmetic on given pair results: nothing is searched or verified.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..search import Alignment, angle_diff_deg, wrap_deg
from ..transform import rotation
from .ambiguity import PairAmbiguity
from .orders import AMBIGUOUS_DEG, AMBIGUOUS_M
from .params import ORIGIN, MergeParams, Placement
from .verify import Verification


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
    way it was searched (the pair's reference is the map whose name comes first:
    :func:`merger.team.tree.merge_tree`)."""
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
