"""The local search: the thesis's grid answer restricted to a region around an earlier answer.

A merge cycle that tracks an accepted alignment (:mod:`merger.team.track`) does not search every map
version globally: it first searches the *region* of the earlier answer — the coarse angles within
``half_deg`` of its coarse angle × the translations within ``half_cells`` of its translation (clipped
to the problem's window) — exactly, with the same measure, support floor, tie order, 0.1° step and
sub-cell refinement as the global search:

* the coarse answer is the first maximum over the region's elements in the reference's order
  (translation tie rank, then angle; :mod:`merger.search.engine`), by the same branch and bound with
  the region as its angle and translation masks (mode 0);
* then 0.1° over θc ± 1° at that translation, the first maximum (the thesis's refinement);
* then, with ``problem.refine``, the sub-cell refinement (:func:`merger.search.refine_alignment`).

:func:`reference_local` computes the same answer exhaustively (every element of the region evaluated
exactly); ``benchmarks/agree_search.py --local`` and the tests compare the two. A local answer carries no
runner-up and no guard beyond the window (``evidence = {"profile": "local", ...}``): those belong to the
global search, which the tracker runs when the local evidence is not enough.
"""

from __future__ import annotations

import numpy as np

from .engine import fine_answer, grid_answer
from .prepared import translation_offsets
from .problem import Alignment, angle_diff_deg, wrap_deg
from .refine import refine_alignment
from .searcher import COARSE, searcher_for

LOCAL_HALF_DEG = 3  # coarse degrees each side of the earlier answer's coarse angle
LOCAL_HALF_CELLS = 3  # cells each side of the earlier answer's translation (clipped to the window)
_NO_RUNNER_UP = (float("nan"), float("nan"))
_EVIDENCE = {"profile": "local", "runner_up": "none"}


def region(problem, theta_deg: float, cells: tuple[int, int], half_deg: int = LOCAL_HALF_DEG,
           half_cells: int = LOCAL_HALF_CELLS):
    """The region about an earlier grid answer (θ°, (a, b) cells): (coarse angle mask over 0..359,
    translations (a, b) in the reference's order). The coarse centre is θ rounded to a whole degree."""
    th0 = float(round(float(theta_deg)) % 360)
    amask = np.abs(angle_diff_deg(COARSE, th0)) <= half_deg + 1e-9
    a0, b0 = int(cells[0]), int(cells[1])
    ts = [(a, b) for (a, b) in translation_offsets(problem.window_cells)
          if abs(a - a0) <= half_cells and abs(b - b0) <= half_cells]
    if not ts:  # an earlier answer outside this problem's window: the window's nearest translation
        k = problem.window_cells
        ts = [(min(max(a0, -k), k), min(max(b0, -k), k))]
    return amask, ts


def _alignment(problem, method: str, theta, value, counts, tc, angles, fine_vals, profile) -> Alignment:
    al = Alignment(wrap_deg(theta), value, counts, problem.measure, method, problem.roi_m, profile,
                   _NO_RUNNER_UP, window_m=problem.window_m, translation_m=problem.offset_m(*tc), cells=tc,
                   fine=(angles, fine_vals), beyond_query=None, evidence=dict(_EVIDENCE))
    return refine_alignment(problem, al) if problem.refine else al


def local_search(problem, theta_deg: float, cells: tuple[int, int], half_deg: int = LOCAL_HALF_DEG,
                 half_cells: int = LOCAL_HALF_CELLS) -> Alignment:
    """The grid answer of ``problem`` restricted to the region about (``theta_deg``, ``cells``) (see the
    module documentation), refined when the problem asks; by the branch and bound."""
    s = searcher_for(problem)
    amask, ts = region(problem, theta_deg, cells, half_deg, half_cells)
    best, env = s.run(COARSE, amask=amask, tmask=s.translation_mask(ts))
    tc = (best.a, best.b)
    angles, fine_vals, kf, value, counts = fine_answer(s, float(best.angle), tc)
    profile = np.where(amask, env, -np.inf)
    return _alignment(problem, "fast-local", float(angles[kf]), value, counts, tc, angles, fine_vals, profile)


def reference_local(problem, theta_deg: float, cells: tuple[int, int], half_deg: int = LOCAL_HALF_DEG,
                    half_cells: int = LOCAL_HALF_CELLS) -> Alignment:
    """:func:`local_search` exhaustively: every element of the region evaluated exactly (the yardstick)."""
    s = searcher_for(problem)
    amask, ts = region(problem, theta_deg, cells, half_deg, half_cells)
    ths = np.flatnonzero(amask)
    table = np.empty((len(ts), ths.size))
    for x, th in enumerate(ths):
        table[:, x] = s.values(float(th), ts)
    _, _, tc, angles, fine_vals, kf, value, counts = grid_answer(
        table, ts, ths, lambda a, t: s.values(a, [t])[0], lambda a, t: s.exact(a, *t))
    profile = np.full(COARSE.size, -np.inf)
    profile[ths] = table.max(axis=0)
    return _alignment(problem, "reference-local", float(angles[kf]), value, counts, tc, angles, fine_vals, profile)
