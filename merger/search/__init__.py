"""Rotation (and translation) search about a shared center — the thesis's section 3.3.1, exact and fast.

Layout (an acyclic core; proofs in docs/design/search.md, cited as Lemma N):

* :mod:`.problem` — :class:`RotationProblem`, :class:`Alignment` (a frozen value; the guard beyond the
  window, :class:`BeyondQuery`, answered lazily by :attr:`Alignment.beyond`);
* :mod:`.lattice` — which cell each ROI lattice point reads (the one place; numpy spec + kernel);
* :mod:`.prepared` — a problem's lattice and bound tables, handed to the kernels by name (``Tables``);
* :mod:`.counts` — compiled exact counts at one element (Lemma 2);
* :mod:`.bounds` — every bound of a region and its tables (Lemmas 3, 3b); :mod:`.polar` — the
  rotation-only bounds of all whole degrees at once (Lemma 6); the measures' own bounds (Lemma 4) are
  :func:`merger.measures.upper_of`;
* :mod:`.bnb` — the branch and bound (Lemma 5); :mod:`.searcher` — one problem's searcher;
* :mod:`.engine` — the searches: ``spec`` (numpy definition), ``reference`` (compiled exhaustive),
  ``fast`` (branch and bound, the same answer) and the exact runner-up; :mod:`.guard` — the guard
  beyond the window; :mod:`.local` — the search about an earlier answer; :mod:`.refine` — sub-cell
  refinement. The caches are :mod:`merger.caches` (``clear_all()``); the settings' defaults and
rules, :mod:`merger.settings`.

A method is a callable ``(problem) -> Alignment`` registered in :data:`SEARCH_METHODS`.
"""

from __future__ import annotations

from collections.abc import Callable

from ..caches import clear_all
from ..settings import MAX_ROI_CELLS, MAX_WINDOW_FRACTION, ROI_MIN_SUPPORT, check_window
from .engine import exact_runner_up, fast_search, reference_search, spec_search
from .guard import BeyondQuery, beyond_window, reference_beyond
from .prepared import translation_offsets
from .problem import (
    COARSE_STEP_DEG,
    FINE_HALF_WIDTH_DEG,
    FINE_STEP_DEG,
    RUNNER_UP_MIN_SEPARATION_DEG,
    Alignment,
    RotationProblem,
    angle_diff_deg,
    fine_angles,
    runner_up,
    window_cells,
    wrap_deg,
)
from .refine import refine_alignment
from .searcher import searcher_for

SearchMethod = Callable[[RotationProblem], Alignment]
SEARCH_METHODS: dict[str, SearchMethod] = {
    "reference": reference_search,  # exhaustive, compiled
    "fast": fast_search,  # branch and bound: the reference's answer
    "spec": spec_search,  # the numpy definition (small problems)
}


def register_method(name: str, fn: SearchMethod) -> None:
    """Register a search method under ``name`` (used by ``search(problem, name)``)."""
    SEARCH_METHODS[name] = fn


def search(problem: RotationProblem, method: str = "reference") -> Alignment:
    """Run a registered search method on ``problem`` (with or without a translation window); a problem
    with ``refine`` gets the sub-cell refinement of the method's grid answer."""
    try:
        fn = SEARCH_METHODS[method]
    except KeyError:
        raise ValueError(f"unknown search method {method!r}; expected one of "
                         f"{', '.join(sorted(SEARCH_METHODS))}") from None
    al = fn(problem)
    if problem.refine and not al.refined:
        al = refine_alignment(problem, al)
    return al


__all__ = [
    "COARSE_STEP_DEG", "FINE_HALF_WIDTH_DEG", "FINE_STEP_DEG", "MAX_ROI_CELLS", "MAX_WINDOW_FRACTION",
    "ROI_MIN_SUPPORT", "RUNNER_UP_MIN_SEPARATION_DEG", "SEARCH_METHODS", "Alignment", "BeyondQuery",
    "RotationProblem",
    "angle_diff_deg", "beyond_window", "check_window", "clear_all", "exact_runner_up",
    "fast_search", "fine_angles",
    "reference_beyond", "reference_search", "refine_alignment", "register_method", "runner_up", "search",
    "searcher_for", "spec_search", "translation_offsets", "window_cells", "wrap_deg",
]
