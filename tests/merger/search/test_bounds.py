"""merger.search.bounds: every bound of the search is at least the brute-force maximum over its region.

A region is angles[lo..hi] of a searcher's angle array × a box (a0, a1, b0, b1) of translation indices
(0..2K; cells = index − K). For random small problems (the adversarial kinds of tests.strategies: noise,
a map against its own rotation, walls on the window's edge, near-empty maps, two resolutions; centers
anywhere, on cell centres, on cell corners; every measure; support floor 0 and > 0; window 0 and 1–3
cells) and random regions, each side of the region bound (:func:`bound_of`) — the reference side
(Lemma 3), the moving side (Lemma 3b) and both combined by the branch and bound's own
:func:`merger.search.bounds.region_upper` — gives
agr_hi ≥ every agr̃, dis_lo ≤ every dis and value_hi ≥ every exact value (:meth:`Searcher.exact`) of
the region's elements. The polar bound (Lemma 6, rotation only) is at least the value at each whole
degree; the measures' bound from count bounds (Lemma 4, ``upper_of``) is at least the value of every
count vector inside those bounds.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from merger.measures import upper_of, value_of
from merger.search import RotationProblem, fine_angles, searcher_for
from merger.search.bounds import block_level, moving_bound, region_bound, region_upper, sum_ranges
from tests.strategies import adversarial_problem, random_grid, random_point

MEASURES = ("similarity", "birk_carpin", "ncc")
CODES = {"similarity": 0, "birk_carpin": 1, "ncc": 2}
FLOORS = (0, 3, 25)  # the support floor: off, or biting some placements
KINDS = ("adversarial", "adversarial", "tiny_ref", "tiny_moving")


def examples(n: int) -> settings:
    """``n`` examples, the same on every run (a bound that fails fails in CI, not by chance)."""
    return settings(max_examples=n, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)


def problem(seed: int, measure: str, window: bool, floor: int, kind: str = "adversarial"):
    """An adversarial problem (tests.strategies) with the support floor ``floor``; or, ``tiny_ref`` /
    ``tiny_moving``, one whose reference / moving map is 2–8 cells wide (narrower than the window's box)."""
    if kind == "adversarial":
        return dataclasses.replace(adversarial_problem(seed, measure, window), min_support=floor)
    rng = np.random.default_rng(seed)
    small, big = random_grid(rng, int(rng.integers(2, 9))), random_grid(rng, int(rng.integers(12, 30)))
    g, h = (small, big) if kind == "tiny_ref" else (big, small)
    mode = ("any", "centre", "corner")[seed % 3]
    w = float(rng.choice([0.05, 0.1, 0.15])) if window else 0.0
    return RotationProblem(g, h, random_point(rng, g, mode), random_point(rng, h, mode),
                           float(rng.choice([0.6, 0.8, 1.0])), measure, w, min_support=floor)


def bound_of(searcher, angles, lo: int, hi: int, box, side: str) -> tuple[int, int, float]:
    """(agr_hi, dis_lo, value_hi) over the region angles[lo..hi] × ``box`` of ``searcher``'s problem:
    ``side`` "reference" (:func:`region_bound`), "moving" (:func:`moving_bound`: one angle of a windowed
    problem) or "both" (the counts of both sides combined as Lemma 3b does; the value the branch and
    bound's own :func:`region_upper`)."""
    t = searcher.p.tables
    angles = np.asarray(angles, np.float64)
    searcher.select(angles)
    asum = searcher.angle_sums()
    box = np.asarray(box, np.int64)
    sx_lo, sx_hi, sy_lo, sy_hi = sum_ranges(t, asum, lo, hi, box)
    agr, dis = 1 << 40, 0
    pts = searcher.points_at(angles, lo)
    if side in ("moving", "both"):
        agr, dis = moving_bound(t, pts, box)
    if side in ("reference", "both"):
        half_rad = math.radians((angles[hi] - angles[lo]) / 2.0)
        ra, rd = region_bound(t, (angles[lo] + angles[hi]) / 2.0, half_rad, box, block_level(t, box, half_rad))
        agr, dis = min(agr, ra), dis + rd
    if side == "both":
        return int(agr), int(dis), float(region_upper(t, angles, asum, lo, hi, box, pts, -np.inf))
    return int(agr), int(dis), float(upper_of(t.code, t.floor, agr, dis, sx_lo, sx_hi, sy_lo, sy_hi, t.n * t.n))


def brute(s, angles, lo, hi, box, k):
    """max agr̃, min dis and max exact value over the region's elements."""
    agr, dis, value = -1, math.inf, -math.inf
    for x in range(lo, hi + 1):
        for b in range(box[2], box[3] + 1):
            for a in range(box[0], box[1] + 1):
                v, c = s.exact(float(angles[x]), a - k, b - k)
                agr, dis, value = max(agr, c.agree), min(dis, c.disagree), max(value, v)
    return agr, dis, value


@st.composite
def regions(draw, side: int):
    """An angle array (the coarse search's whole degrees or a refinement's 0.1° steps), a range of it and
    a box of translation indices 0..side − 1."""
    if draw(st.booleans()):
        angles, span = np.arange(360.0), 5
    else:
        angles, span = fine_angles(float(draw(st.integers(0, 359)))), 20
    lo = draw(st.integers(0, angles.size - 1))
    hi = min(angles.size - 1, lo + draw(st.integers(0, span)))
    a0, a1 = sorted(draw(st.tuples(st.integers(0, side - 1), st.integers(0, side - 1))))
    b0, b1 = sorted(draw(st.tuples(st.integers(0, side - 1), st.integers(0, side - 1))))
    return angles, lo, hi, (a0, a1, b0, b1)


@pytest.mark.slow
@examples(300)
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), window=st.booleans(),
       floor=st.sampled_from(FLOORS), kind=st.sampled_from(KINDS), single=st.booleans(), data=st.data())
def test_each_side_of_the_region_bound_is_at_least_the_brute_force_maximum(seed, measure, window, floor, kind,
                                                                            single, data):
    p = problem(seed, measure, window, floor, kind)
    s = searcher_for(p)
    k = p.window_cells
    angles, lo, hi, box = data.draw(regions(2 * k + 1))
    if single:  # one angle: the moving side applies (with a window)
        hi = lo
    want_agr, want_dis, want_value = brute(s, angles, lo, hi, box, k)
    sides = ("reference", "moving", "both") if k > 0 and lo == hi else ("reference",)
    for side in sides:
        agr_hi, dis_lo, value_hi = bound_of(s, angles, lo, hi, box, side)
        where = (side, kind, float(angles[lo]), float(angles[hi]), box, k)
        assert agr_hi >= want_agr, where
        assert dis_lo <= want_dis, where
        assert value_hi >= want_value, where


@pytest.mark.slow
@examples(60)
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), floor=st.sampled_from(FLOORS),
       kind=st.sampled_from(KINDS))
def test_the_polar_bound_is_at_least_the_value_at_every_whole_degree(seed, measure, floor, kind):
    p = problem(seed, measure, False, floor, kind)
    s = searcher_for(p)
    bound = s.polar_bounds()
    assert bound.shape == (360,)
    values = np.array([s.exact(float(d), 0, 0)[0] for d in range(360)])
    bad = np.flatnonzero(bound < values)
    assert bad.size == 0, [(int(d), float(bound[d]), float(values[d])) for d in bad[:5]]


@st.composite
def count_vectors(draw, max_cells: int = 400):
    """(N, agr, dis, ff, sx, sy) of some ROI pair of N lattice points: sx, sy the reference's and the
    moving ROI's occupied points (NCC) or free points (Birk–Carpin: ff ≤ both)."""
    n_cells = draw(st.integers(1, max_cells))
    occ_x, occ_y = draw(st.integers(0, n_cells)), draw(st.integers(0, n_cells))
    free_x, free_y = draw(st.integers(0, n_cells - occ_x)), draw(st.integers(0, n_cells - occ_y))
    agr = draw(st.integers(0, min(occ_x, occ_y)))
    dis = draw(st.integers(0, most_dis(agr, occ_x, occ_y, free_x, free_y)))
    ff = draw(st.integers(0, max(0, min(free_x, free_y, n_cells - agr - dis))))
    return n_cells, agr, dis, ff, (occ_x, occ_y), (free_x, free_y)


def most_dis(agr, occ_x, occ_y, free_x, free_y):
    """Disagreements: occupied in one map and free in the other, beside the agr̃ occupied in both."""
    return min(occ_x - agr, free_y) + min(occ_y - agr, free_x)


def sums_of(measure, occ, free):
    return occ if measure == "ncc" else free if measure == "birk_carpin" else (0, 0)


@pytest.mark.slow
@examples(3000)
@given(measure=st.sampled_from(MEASURES), vec=count_vectors(), floor=st.sampled_from((0, 1, 3, 25, 120)),
       slack=st.tuples(*[st.integers(0, 50)] * 6))
def test_the_measures_bound_is_at_least_the_value_inside_its_count_bounds(measure, vec, floor, slack):
    n_cells, agr, dis, ff, occ, free = vec
    sx, sy = sums_of(measure, occ, free)
    code = CODES[measure]
    agr_hi, dis_lo = agr + slack[0], max(0, dis - slack[1])
    sx_lo, sx_hi = max(0, sx - slack[2]), min(n_cells, sx + slack[3])
    sy_lo, sy_hi = max(0, sy - slack[4]), min(n_cells, sy + slack[5])
    value = value_of(code, floor, agr, dis, ff, occ[0], occ[1], n_cells)
    ub = upper_of(code, floor, agr_hi, dis_lo, sx_lo, sx_hi, sy_lo, sy_hi, n_cells)
    assert ub >= value, (measure, vec, floor, (agr_hi, dis_lo, sx_lo, sx_hi, sy_lo, sy_hi), ub, value)
    assert ub >= 0.0


@examples(200)
@given(measure=st.sampled_from(MEASURES), n_cells=st.integers(1, 6), floor=st.sampled_from((0, 1, 2, 4)),
       bounds=st.tuples(*[st.integers(0, 6)] * 6))
def test_the_measures_bound_is_at_least_the_maximum_over_every_count_vector_of_its_bounds(
        measure, n_cells, floor, bounds):
    """Small ROIs: every count vector (agr̃, dis, ff, sx, sy) of N ≤ 6 lattice points inside the bounds."""
    code = CODES[measure]
    agr_hi, dis_lo = bounds[0], bounds[1]
    sx_lo, sx_hi = sorted(min(b, n_cells) for b in bounds[2:4])
    sy_lo, sy_hi = sorted(min(b, n_cells) for b in bounds[4:6])
    ub = upper_of(code, floor, agr_hi, dis_lo, sx_lo, sx_hi, sy_lo, sy_hi, n_cells)
    rng = range(n_cells + 1)
    best = -math.inf
    for occ_x, occ_y, free_x, free_y in itertools.product(rng, rng, rng, rng):
        if occ_x + free_x > n_cells or occ_y + free_y > n_cells:
            continue
        sx, sy = sums_of(measure, (occ_x, occ_y), (free_x, free_y))
        if measure != "similarity" and not (sx_lo <= sx <= sx_hi and sy_lo <= sy <= sy_hi):
            continue
        for agr in range(min(agr_hi, occ_x, occ_y) + 1):
            for dis in range(dis_lo, most_dis(agr, occ_x, occ_y, free_x, free_y) + 1):
                for ff in range(min(free_x, free_y, n_cells - agr - dis) + 1):
                    best = max(best, value_of(code, floor, agr, dis, ff, occ_x, occ_y, n_cells))
    assert ub >= best, (measure, n_cells, floor, bounds, ub, best)
