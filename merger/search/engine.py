"""The searches: the exhaustive reference (compiled, and its numpy specification) and the fast one.

All answer the thesis's grid answer (docs/design/search.md §2): over every translation (a, b) of the
window (|a|, |b| ≤ K cells) and every coarse angle 0°, 1°, …, 359° the best value, ties to the
translation first in :func:`merger.search.prepared.translation_offsets` order, then the smallest
angle; then 0.1° over θc ± 1° at that translation, the first maximum. K = 0 is the thesis's search.

* :func:`spec_search` — the definition in numpy (every angle and translation evaluated on whole ROIs
  with :mod:`merger.measures`); slow, for small problems in tests.
* :func:`reference_search` — the same exhaustive loop on the compiled exact counts
  (:mod:`merger.search.counts`): the same floats, at full size.
* :func:`fast_search` — the branch and bound (:mod:`merger.search.bnb`) over (sector, box) regions with
  the reference's order as the key (Lemma 5): exactly the reference's answer. Its profile is an upper
  envelope of the reference's (exact where evaluated, never above the best coarse value) and so is its
  runner-up (read off that profile); :func:`exact_runner_up` computes the runner-up exactly; the guard
  beyond the window (:mod:`merger.search.guard`) is exact too (on first access).
"""

from __future__ import annotations

import numpy as np

from .. import caches
from ..measures import measure_fn
from .guard import BeyondQuery, reference_beyond
from .prepared import translation_offsets
from .problem import (
    RUNNER_UP_MIN_SEPARATION_DEG,
    Alignment,
    angle_diff_deg,
    fine_angles,
    floored,
    runner_up,
    wrap_deg,
)
from .searcher import COARSE, Searcher, searcher_for

FRONTIER_KEEP = 0.12  # the fast search keeps its frontier within this of its incumbent (the ambiguity
# rule's runner-up floor is the answer's score − margin − 0.05, margin 0.05 by default with a window)


def fine_answer(s: Searcher, th_c: float, tc):
    """The thesis's refinement at translation ``tc``: the first maximum of 0.1° over θc ± 1° — (angles, their
    exact scores, index of the answer, its value and counts). Every score is computed (21 exact values at one
    translation cost less than bounding them: on 117 problems of the 16-robot hall a branch and bound over them
    bounded 135 regions in 0.9 ms, the 21 values took 0.33 ms)."""
    angles = fine_angles(th_c)
    vals = s.values_at_angles(angles, tc)
    kf = int(np.argmax(vals))
    value, counts = s.exact(float(angles[kf]), *tc)
    vals[kf] = value
    return angles, vals, kf, value, counts


def fast_search(problem) -> Alignment:
    """The thesis's grid answer by branch and bound (see the module documentation); exact."""
    s = searcher_for(problem)
    # rotation only: every whole-degree angle bounded at once (polar cells), then the best-first search
    best, env = s.run(COARSE, init=s.initial_regions(), keep=FRONTIER_KEEP)
    caches.keep_frontier(problem, (*s.frontier, best.value))
    th_c, tc = float(best.angle), (best.a, best.b)
    angles, fine_vals, kf, value, counts = fine_answer(s, th_c, tc)
    theta = wrap_deg(float(angles[kf]))
    # the profile: an upper envelope of the reference's, never above the best coarse value (Lemma 5), and
    # the runner-up read off it; exact_runner_up computes it exactly, at the cost of a search where few
    # regions can be dropped
    return Alignment(theta, value, counts, problem.measure, "fast", problem.roi_m, env,
                     runner_up(env, theta), window_m=problem.window_m,
                     translation_m=problem.offset_m(*tc), cells=tc, fine=(angles, fine_vals),
                     beyond_query=BeyondQuery(problem, best.value, (th_c, tc)),
                     evidence={"profile": "upper_envelope", "runner_up": "upper_envelope"})


def exact_runner_up(problem, theta_deg: float, floor: float | None = None, budget: int = 0,
                    envelope=None) -> tuple[float, float]:
    """The reference's runner-up exactly: over the coarse angles at least 10° from ``theta_deg``, the
    first maximum (smallest angle) of the best value over the window (NaNs when no angle is that far).
    With ``floor``, only a runner-up scoring at least ``floor`` is looked for (NaNs when there is none):
    regions bounded below it are dropped at once. With a ``budget`` of bounded regions the answer is
    the best exact value found within it (exact when the search completed; a real placement always).
    ``envelope``: per coarse angle an upper bound of its values over the window (the fast search's
    profile, Lemma 5): the search starts from one region per angle with that bound (Lemma 5c), so angles whose
    bound is below ``floor`` are never searched. Better, when the fast search of this very problem
    object ran and ``floor`` is within ``FRONTIER_KEEP`` of its best coarse value: the search starts from
    that search's frontier — the regions it dropped and the elements it evaluated with a bound at least
    its incumbent − FRONTIER_KEEP (every element scoring ≥ floor lies in one of them, Lemma 5b)."""
    far = np.abs(angle_diff_deg(COARSE, theta_deg)) >= RUNNER_UP_MIN_SEPARATION_DEG
    if not far.any():
        return float("nan"), float("nan")
    s = searcher_for(problem)
    init = None
    fr = caches.frontier(problem) if floor is not None else None
    if fr is not None and floor >= fr[2] - FRONTIER_KEEP:
        sel = fr[1] >= floor
        if not sel.any():
            return float("nan"), float("nan")
        init = (np.ascontiguousarray(fr[0][sel]), np.ascontiguousarray(fr[1][sel]))
    elif envelope is not None:
        nodes = np.zeros((COARSE.size, 6), np.int64)
        nodes[:, 0] = nodes[:, 1] = np.arange(COARSE.size)
        nodes[:, 3] = nodes[:, 5] = s.p.side - 1
        init = (nodes, np.asarray(envelope, np.float64))
    above = -np.inf if floor is None else np.nextafter(floor, -np.inf)  # at least floor
    best, _ = s.run(COARSE, mode=1, amask=far, above=above, budget=budget, init=init)
    if best.angle < 0:
        return float("nan"), float("nan")
    return float(best.angle), best.value


def grid_answer(table: np.ndarray, ts, coarse, values_at, exact_at):
    """The grid answer from an exhaustive ``table`` of values (translations ``ts`` × ``coarse`` angles): its
    first maximum (translation order, then θ), then the fine angles' first maximum by ``values_at(θ, t)``;
    ``exact_at(θ, t)`` gives the answer's (value, counts). Returns (coarse θ, its value, t, fine angles,
    their values, index of the answer, value, counts)."""
    i_best, x_best = np.unravel_index(int(np.argmax(table)), table.shape)  # first max: t order, then θ
    tc, th_c = ts[int(i_best)], float(coarse[int(x_best)])
    angles = fine_angles(th_c)
    fine_vals = np.array([values_at(float(a), tc) for a in angles])
    kf = int(np.argmax(fine_vals))
    value, counts = exact_at(float(angles[kf]), tc)
    return th_c, float(table[int(i_best), int(x_best)]), tc, angles, fine_vals, kf, value, counts


def _exhaustive(problem, method: str, table: np.ndarray, ts, values_at, exact_at, beyond_query=None) -> Alignment:
    """The grid answer (:func:`grid_answer`) of the exhaustive ``table`` over the 360 coarse angles."""
    th_c, best, tc, angles, fine_vals, kf, value, counts = grid_answer(table, ts, COARSE, values_at, exact_at)
    theta = wrap_deg(float(angles[kf]))
    profile = table.max(axis=0)
    query = None if beyond_query is None else beyond_query(best, (int(th_c), tc))
    return Alignment(theta, value, counts, problem.measure, method, problem.roi_m, profile,
                     runner_up(profile, theta), window_m=problem.window_m, translation_m=problem.offset_m(*tc),
                     cells=tc, fine=(angles, fine_vals), beyond_query=query)


def reference_search(problem) -> Alignment:
    """The exhaustive search on compiled exact counts: every coarse angle × every translation."""
    s = searcher_for(problem)
    ts = translation_offsets(s.p.k)
    table = np.empty((len(ts), 360))
    for th in range(360):
        table[:, th] = s.values(float(th), ts)
    return _exhaustive(problem, "reference", table, ts, lambda a, t: s.values(a, [t])[0],
                       lambda a, t: s.exact(a, *t),
                       lambda best, answer: BeyondQuery(problem, best, answer, reference_beyond))


def spec_search(problem) -> Alignment:
    """The definition in numpy: every angle × translation on whole ROIs (:mod:`merger.measures`)."""
    measure = measure_fn(problem.measure)
    ts = translation_offsets(problem.window_cells)
    refs = {t: problem.at(*t).ref_roi() for t in ts}

    def sim(theta, t):
        return floored(measure(refs[t], problem.moving_roi(theta)), problem.min_support)

    table = np.empty((len(ts), 360))
    for th in range(360):
        mov = problem.moving_roi(float(th))
        for i, t in enumerate(ts):
            table[i, th] = floored(measure(refs[t], mov), problem.min_support).value
    return _exhaustive(problem, "spec", table, ts, lambda a, t: sim(a, t).value,
                       lambda a, t: (sim(a, t).value, sim(a, t).counts))
