"""The guard beyond the window: is there a better alignment just outside the translation window?

A center trusted to ±W may be off by more. The guard looks at the coarse alignments in the ring between
the window and ``BEYOND_FACTOR`` × it (at most a quarter of the ROI side) for one that scores above the
answer's best coarse value and lies apart from the answer (docs/design/search.md §5): by the branch and
bound (:func:`beyond_window`, within a budget) or exhaustively (:func:`reference_beyond`, the yardstick).
An :class:`merger.search.problem.Alignment` asks it lazily through its ``beyond_query``, a
:class:`BeyondQuery` holding the question and the guard that answers it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from ..settings import MAX_WINDOW_FRACTION
from .prepared import translation_offsets
from .problem import angle_diff_deg
from .searcher import COARSE, searcher_for

BEYOND_FACTOR = 2.0  # the guard beyond the window looks up to this × the window (≤ a quarter of the ROI)
BEYOND_APART_STEPS = 1.5  # ... for alignments more than one grid step (1°, one cell) from the answer
BEYOND_BUDGET = 40000  # regions the guard may bound (a count: deterministic); best-first, a better placement
# is found early when there is one, the budget cuts the proof that there is none (docs/design/search.md §5)


def _ring(problem):
    """The guard's wider problem, its window (cells) and its searcher; None without a window or a wider
    one. The ring: the wider window's translations outside the problem's window (:func:`_ring_mask`)."""
    k = problem.window_cells
    wide = min(BEYOND_FACTOR * problem.window_m, MAX_WINDOW_FRACTION * problem.roi_m)
    big = replace(problem, window_m=wide, refine=False)
    kb = big.window_cells
    if k == 0 or kb <= k:
        return None
    return big, kb, searcher_for(big)


def _apart(a, b) -> bool:
    """Whether two grid alignments (θ°, (a, b) cells) are more than one grid step apart. A better
    alignment one step beyond the window's edge is the answer's own peak, cut by the edge."""
    if abs(angle_diff_deg(float(a[0]), float(b[0]))) > BEYOND_APART_STEPS:
        return True
    return math.dist(a[1], b[1]) > BEYOND_APART_STEPS


def beyond_window(problem, best_value: float, answer, budget: int = BEYOND_BUDGET):
    """The best coarse alignment outside the window and within ``BEYOND_FACTOR`` × it (at most a quarter
    of the ROI side) that scores above ``best_value`` and is apart from the grid answer ``answer`` =
    (θ°, (a, b) cells): ``(θ°, (tx, ty) m, score)``, or None — by the branch and bound over that ring,
    best-first within ``budget`` bounded regions (0: no limit; then exactly the first in the order θ,
    then the translation order, as :func:`reference_beyond`). What it reports is always a real placement
    scoring above ``best_value``; with the budget spent it may miss one (then None)."""
    ringed = _ring(problem)
    if ringed is None:
        return None
    big, kb, s = ringed
    side = 2 * kb + 1
    th_ans, (a_ans, b_ans) = answer
    # the elements not apart from the answer (_apart): angles within BEYOND_APART_STEPS degrees of it ×
    # translations within BEYOND_APART_STEPS cells of it
    excl_a = np.abs(angle_diff_deg(COARSE, th_ans)) <= BEYOND_APART_STEPS
    tmask = _ring_mask(problem.window_cells, kb)
    bb, aa = np.divmod(np.arange(side * side), side)
    excl_t = tmask & ((aa - kb - a_ans) ** 2 + (bb - kb - b_ans) ** 2 <= BEYOND_APART_STEPS ** 2)
    best, _ = s.run(COARSE, mode=1, tmask=tmask, above=best_value, excl=(excl_a, excl_t), budget=budget,
                    init=_ring_regions(kb))
    if best.angle < 0:
        return None
    return float(best.angle), big.offset_m(best.a, best.b), best.value


@lru_cache(maxsize=16)
def _ring_mask(k: int, kb: int) -> np.ndarray:
    """The ring's translations (beyond ±k cells, within ±kb) as a mask over b·(2kb+1) + a (read-only)."""
    side = 2 * kb + 1
    bb, aa = np.divmod(np.arange(side * side), side)
    out = np.maximum(np.abs(aa - kb), np.abs(bb - kb)) > k
    out.flags.writeable = False
    return out


@lru_cache(maxsize=16)
def _ring_regions(kb: int):
    """The guard's first regions: every coarse angle × the four quadrants of its wide window (±kb cells),
    unbounded (+inf: split on their first visit), so that the first regions bounded are boxes of about
    kb/2 — the problem's own window, for the default wider window of twice it. Bounds of larger boxes
    at one angle (and of sectors of angles) over the wide window stay above any threshold (their
    rectangles hold a wall nearly everywhere) and only cost: on the windowed bench's guards this start
    bounds 4,400–6,000 regions instead of 6,300–8,100 (sectors of 8 angles × the whole window), and
    starting one level finer 17,300 (docs/performance-history.md)."""
    side = 2 * kb + 1
    mid = (side - 1) // 2
    quads = [(a0, a1, b0, b1) for (b0, b1) in ((0, mid), (mid + 1, side - 1)) for (a0, a1) in ((0, mid), (mid + 1, side - 1))
             if a0 <= a1 and b0 <= b1]
    nodes = np.array([(x, x, *q) for x in range(COARSE.size) for q in quads], np.int64)
    return nodes, np.full(len(nodes), np.inf)  # read, never written, by the kernel


def reference_beyond(problem, best_value: float, answer):
    """:func:`beyond_window` exhaustively (the yardstick)."""
    ringed = _ring(problem)
    if ringed is None:
        return None
    big, kb, s = ringed
    k = problem.window_cells
    ring = [(a, b) for (a, b) in translation_offsets(kb) if max(abs(a), abs(b)) > k]
    out = None
    for th in range(360):
        vals = s.values(float(th), ring)
        for t, v in zip(ring, vals, strict=True):
            if v > best_value and (out is None or v > out[2]) and _apart((th, t), answer):
                out = (float(th), big.offset_m(*t), float(v))
    return out


@dataclass(frozen=True, eq=False)
class BeyondQuery:
    """The guard beyond the window, asked but not yet answered — a plain value.

    Is there a coarse alignment outside the problem's translation window (within the guard's wider
    ring) that scores above ``best_value`` and lies apart from the grid ``answer`` = (coarse θ°, (a, b)
    cells)? ``guard`` answers it: :func:`beyond_window` (the branch and bound) or :func:`reference_beyond`
    (exhaustive), or any function with their signature. ``problem_of`` (instead of ``problem``): a function
    that builds the problem again when the question is answered, so that a question kept unanswered does
    not keep its problem's grids (:meth:`merger.search.problem.Alignment.guard_rebuilding`).
    """

    problem: object
    best_value: float
    answer: tuple
    guard: Callable = beyond_window
    problem_of: Callable | None = None  # builds ``problem`` when asked (then ``problem`` is None)

    def answer_now(self) -> tuple[float, tuple[float, float], float] | None:
        """Run the guard: ``(θ°, (tx, ty) m, coarse score)`` or None."""
        problem = self.problem if self.problem_of is None else self.problem_of()
        b = self.guard(problem, self.best_value, self.answer)
        return None if b is None else (float(b[0]), (float(b[1][0]), float(b[1][1])), float(b[2]))
