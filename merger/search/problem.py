"""What a search is asked and what it answers: :class:`RotationProblem` and :class:`Alignment`.

The thesis (3.3.1) searches exhaustively: 1° steps over [0°, 360°), then 0.1° steps over ±1° around
the best coarse angle (360 + 20 = 380 rotations); with a translation window of ±K cells, every one-cell
translation of it too. The grid conventions (angles in [0, 360), the runner-up, the fine angles) live
here; the searches in :mod:`merger.search.engine`.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field, replace

import numpy as np

from ..grid import OccupancyGrid
from ..lattice import extract_roi, roi_cells, rotated_roi
from ..measures import Counts, Similarity, measure_fn
from ..settings import (
    DEFAULT_MEASURE,
    DEFAULT_ROI_M,
    DEFAULT_WINDOW_M,
    check_floor,
    check_measure,
    check_roi,
    check_window,
)


def window_cells(window_m: float, resolution: float) -> int:
    """K: translations of at most K cells each way fit in ±window_m."""
    return int(math.floor(window_m / resolution + 1e-9)) if window_m > 0 else 0


COARSE_STEP_DEG = 1.0
FINE_STEP_DEG = 0.1
FINE_HALF_WIDTH_DEG = 1.0
RUNNER_UP_MIN_SEPARATION_DEG = 10.0


@dataclass(frozen=True, eq=False)
class RotationProblem:
    """One alignment to search: ``moving`` rotated about ``center_moving`` onto ``ref`` at ``center_ref``.

    ``min_support`` (cells, ≥ 0): a placement whose ROI support agr̃ + dis is below it scores 0 (the
    support floor, :mod:`merger.search.measures`), so no optimum rests on a handful of cells; 0 keeps
    the measures as the thesis defines them. ``align`` and merge cycles use :data:`merger.settings.ROI_MIN_SUPPORT`.

    ``roi_m``, ``measure`` and ``window_m`` default to the one default of each (:mod:`merger.settings`:
    ``DEFAULT_ROI_M``, ``DEFAULT_MEASURE``, ``DEFAULT_WINDOW_M``), which ``merger.align`` and
    :class:`merger.team.params.MergeParams` share. ``refine`` (False) and ``min_support`` (0) are not the
    merger's settings but the search's question as the thesis states it: the grid answer of the plain
    measure, the problem every exactness check compares (spec = reference = fast, ``agree_search``).
    Sub-cell refinement and the support floor are policies of a merge, defaulted once in MergeParams
    (``refine`` True, ``roi_min_support`` :data:`merger.settings.ROI_MIN_SUPPORT`); every merge builds its problem from
    those (:func:`merger.team.orders.problem_for`, ``merger.align``) and passes both explicitly.
    """

    ref: OccupancyGrid
    moving: OccupancyGrid
    center_ref: tuple[float, float]
    center_moving: tuple[float, float]
    roi_m: float = DEFAULT_ROI_M
    measure: str = DEFAULT_MEASURE
    window_m: float = DEFAULT_WINDOW_M
    refine: bool = False  # the grid answer: see above
    min_support: int = 0  # no floor: see above

    def __post_init__(self) -> None:
        check_measure(self.measure)
        check_roi(self.roi_m, self.ref.resolution)
        check_window(self.window_m, self.roi_m)
        check_floor(self.min_support)
        for name, c in (("center_ref", self.center_ref), ("center_moving", self.center_moving)):
            if len(c) != 2 or not all(math.isfinite(float(v)) for v in c):
                raise ValueError(f"{name} must be two finite numbers (x, y), got {c}")

    @property
    def window_cells(self) -> int:
        """K: the translation search covers (a, b) cells with |a|, |b| ≤ K (0: rotation only)."""
        return window_cells(self.window_m, self.ref.resolution)

    def offset_m(self, a: int, b: int) -> tuple[float, float]:
        """The translation (metres, reference frame) of ``a``, ``b`` cells."""
        r = self.ref.resolution
        return (a * r, b * r)

    def center_at(self, a: int, b: int) -> tuple[float, float]:
        """Where the moving map's center lands for a translation of ``a``, ``b`` cells: c_ref + t."""
        if a == 0 and b == 0:
            return self.center_ref
        tx, ty = self.offset_m(a, b)
        return (self.center_ref[0] + tx, self.center_ref[1] + ty)

    def at(self, a: int, b: int) -> RotationProblem:
        """The rotation-only problem about the shifted reference center c_ref + t (the thesis's search)."""
        return RotationProblem(self.ref, self.moving, self.center_at(a, b), self.center_moving, self.roi_m,
                               self.measure, 0.0, min_support=self.min_support)

    @property
    def n(self) -> int:
        """ROI side in cells of the reference grid."""
        return roi_cells(self.roi_m, self.ref.resolution)

    def ref_roi(self) -> np.ndarray:
        return extract_roi(self.ref, self.center_ref, self.n)

    def moving_roi(self, theta_deg: float) -> np.ndarray:
        return rotated_roi(self.moving, theta_deg, self.center_moving, self.center_ref, self.n,
                           self.ref.resolution)

    def evaluate(self, theta_deg: float, ref_roi: np.ndarray | None = None):
        """The exact similarity (value and counts) of the ROIs at ``theta_deg``, with the support floor."""
        r = self.ref_roi() if ref_roi is None else ref_roi
        return floored(measure_fn(self.measure)(r, self.moving_roi(theta_deg)), self.min_support)


_UNASKED = object()  # Alignment.beyond not computed yet


def floored(sim: Similarity, floor: int) -> Similarity:
    """``sim`` with value 0 when its support agr̃ + dis is below ``floor`` (measures.value_of)."""
    if sim.counts.support >= floor:
        return sim
    return Similarity(0.0, sim.counts, sim.measure)


@dataclass(frozen=True, eq=False)
class Alignment:
    """Result of a rotation search, with its evidence — a frozen value.

    theta_deg : the rotation of the moving map onto the reference, in [0, 360).
    score : the similarity at ``theta_deg`` on the ROI.
    counts : agr̃, dis and free/free at ``theta_deg`` on the ROI.
    profile : coarse scores at 0°, 1°, ..., 359°.
    runner_up : (runner_up_deg, runner_up_score), the best coarse angle at least 10° away from ``theta_deg``.
    evidence : how exact the profile and the runner-up are — ``{"profile": "exact" | "upper_envelope",
        "runner_up": "exact" | "upper_envelope"}``: the reference gives both exactly; ``fast`` a profile
        that is an upper envelope (exact where evaluated, a true upper bound elsewhere, never above the
        best coarse value) and the runner-up read off it (at least the reference's runner-up score,
        never above the best); :func:`merger.search.exact_runner_up` computes the exact one.
    beyond_query : the guard beyond the translation window, asked and not yet answered
        (:class:`merger.search.guard.BeyondQuery`; None: no guard, e.g. the ``spec`` search).

    One piece of evidence is computed lazily, behind one property: :attr:`beyond` runs the guard of
    ``beyond_query`` once, on first access, under a lock (two threads may ask at once; the search behind
    it is not thread-safe). A merge cycle reads it only for accepted results, so the others do not pay
    for it. Pickling answers it first.
    """

    theta_deg: float
    score: float
    counts: Counts = field(repr=False)
    measure: str
    method: str
    roi_m: float
    profile: np.ndarray = field(repr=False)
    runner_up: tuple[float, float] = field(repr=False)
    window_m: float = 0.0
    translation_m: tuple[float, float] = (0.0, 0.0)
    cells: tuple[int, int] = (0, 0)
    fine: tuple | None = field(default=None, repr=False)
    refined: bool = False
    theta_grid_deg: float | None = None  # θ on the search grid (1° then 0.1°), before sub-cell refinement
    translation_grid_m: tuple[float, float] | None = None  # t on the search grid (whole cells), likewise
    beyond_query: object | None = field(default=None, repr=False)  # a guard.BeyondQuery: answer_now()
    evidence: dict = field(default_factory=lambda: {"profile": "exact", "runner_up": "exact"})

    def __post_init__(self) -> None:
        object.__setattr__(self, "_lock", threading.Lock())
        object.__setattr__(self, "_beyond", _UNASKED)
        object.__setattr__(self, "runner_up", (float(self.runner_up[0]), float(self.runner_up[1])))
        object.__setattr__(self, "translation_m", (float(self.translation_m[0]), float(self.translation_m[1])))
        if self.theta_grid_deg is None:  # the grid answer is the answer until a refinement moves it
            object.__setattr__(self, "theta_grid_deg", self.theta_deg)
        if self.translation_grid_m is None:
            object.__setattr__(self, "translation_grid_m", self.translation_m)

    @property
    def beyond(self) -> tuple[float, tuple[float, float], float] | None:
        """A better alignment found outside the translation window, ``(θ°, (tx, ty) m, coarse score)``,
        or None (see :func:`merger.search.beyond_window`): the answer to ``beyond_query``, computed once,
        on first access, thread-safe."""
        with self._lock:
            if self._beyond is _UNASKED:
                q = self.beyond_query
                object.__setattr__(self, "_beyond", None if q is None else q.answer_now())
            return self._beyond

    def guard_rebuilding(self, problem_of) -> Alignment:
        """This alignment with its unanswered guard asking ``problem_of()`` for its problem when first asked
        (a function that builds the searched problem again, equal in every array): the guard's question
        then holds no grids. Kept unanswered in a simulation's memo, the pairs of a 32-robot hall held each
        pair's own grid this way (1,530 grids, 352 MB after 4 s). ``self`` when there is nothing to ask."""
        if self.beyond_query is None or self._beyond is not _UNASKED:
            return self
        return replace(self, beyond_query=replace(self.beyond_query, problem=None, problem_of=problem_of))

    def __getstate__(self) -> dict:
        beyond = self.beyond
        state = {k: v for k, v in self.__dict__.items() if k != "_lock"}
        state.update(_beyond=beyond, beyond_query=None)  # answered: the problem (both maps) is not carried
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        object.__setattr__(self, "_lock", threading.Lock())

    @property
    def runner_up_deg(self) -> float:
        return self.runner_up[0]

    @property
    def runner_up_score(self) -> float:
        return self.runner_up[1]

    @property
    def has_evidence(self) -> bool:
        """Whether the answer rests on anything: a score above 0 (with the support floor, ω̃ > 0 means at
        least ``min_support`` cells of support and one agreeing cell). An ROI without an occupied cell in
        either map, or without a placement reaching the floor, answers θ = 0, t = 0 with score 0: no
        evidence, not an alignment."""
        return self.score > 0

    @property
    def margin(self) -> float:
        """score − runner-up score: how clearly the best peak stands out."""
        return self.score - self.runner_up_score

    def to_dict(self) -> dict:
        return {
            "theta_deg": self.theta_deg, "translation_m": list(self.translation_m),
            "theta_grid_deg": self.theta_grid_deg, "translation_grid_m": list(self.translation_grid_m),
            "window_m": self.window_m, "refined": self.refined,
            "score": self.score, "measure": self.measure,
            "method": self.method, "roi_m": self.roi_m,
            "agree": self.counts.agree, "disagree": self.counts.disagree,
            "support": self.counts.support,
            "runner_up_deg": self.runner_up_deg, "runner_up_score": self.runner_up_score,
            "evidence": dict(self.evidence),
            "beyond": None if self.beyond is None else {"theta_deg": self.beyond[0],
                                                        "translation_m": list(self.beyond[1]),
                                                        "score": self.beyond[2]},
        }


def wrap_deg(a):
    """Angle(s) in [0, 360)."""
    if np.ndim(a):
        return np.mod(np.round(np.mod(np.round(np.asarray(a, np.float64), 9), 360.0), 9), 360.0)
    return float(round(round(a, 9) % 360.0, 9) % 360.0)  # 360 − 279.3 is 80.69999999999999: round again


def angle_diff_deg(a, b):
    """Signed smallest difference a − b in (−180, 180]."""
    d = (np.asarray(a, np.float64) - np.asarray(b, np.float64) + 180.0) % 360.0 - 180.0
    return np.where(d == -180.0, 180.0, d) if np.ndim(d) else (180.0 if d == -180.0 else float(d))


def runner_up(profile: np.ndarray, theta_deg: float,
              min_sep_deg: float = RUNNER_UP_MIN_SEPARATION_DEG) -> tuple[float, float]:
    """Best coarse angle at least ``min_sep_deg`` away from ``theta_deg`` (1° profile)."""
    angles = np.arange(profile.size) * (360.0 / profile.size)
    far = np.abs(angle_diff_deg(angles, theta_deg)) >= min_sep_deg
    if not far.any():
        return float("nan"), float("nan")
    idx = np.flatnonzero(far)[np.argmax(profile[far])]
    return float(angles[idx]), float(profile[idx])


def fine_angles(coarse_deg: float) -> np.ndarray:
    """The refinement angles: ``coarse ± 1°`` in 0.1° steps (21 angles, the centre included)."""
    k = int(round(FINE_HALF_WIDTH_DEG / FINE_STEP_DEG))
    return coarse_deg + np.arange(-k, k + 1) * FINE_STEP_DEG
