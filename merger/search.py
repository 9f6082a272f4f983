"""Rotation search about a shared center: find θ maximizing a similarity on the region of interest.

The thesis (3.3.1) searches exhaustively: 1° steps over [0°, 360°), then 0.1° steps over ±1° around
the best coarse angle (360 + 20 = 380 rotations). :func:`reference_search` does exactly that and is
the yardstick for faster methods. Methods are pluggable: a method is a callable
``(problem: RotationProblem) -> Alignment`` registered in :data:`SEARCH_METHODS` with
:func:`register_method`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .grid import OccupancyGrid
from .similarity import MEASURES, Counts, measure_fn
from .transform import extract_roi, roi_cells, rotated_roi

COARSE_STEP_DEG = 1.0
FINE_STEP_DEG = 0.1
FINE_HALF_WIDTH_DEG = 1.0
RUNNER_UP_MIN_SEPARATION_DEG = 10.0


@dataclass(frozen=True, eq=False)
class RotationProblem:
    """One alignment to search: ``moving`` rotated about ``center_moving`` onto ``ref`` at ``center_ref``."""

    ref: OccupancyGrid
    moving: OccupancyGrid
    center_ref: tuple[float, float]
    center_moving: tuple[float, float]
    roi_m: float = 8.0
    measure: str = "similarity"

    def __post_init__(self) -> None:
        if self.measure not in MEASURES:
            raise ValueError(f"unknown measure {self.measure!r}; expected one of {', '.join(MEASURES)}")
        if not self.roi_m > 0:
            raise ValueError(f"roi_m must be > 0, got {self.roi_m}")

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
        """The exact similarity (value and counts) of the ROIs at ``theta_deg``."""
        r = self.ref_roi() if ref_roi is None else ref_roi
        return measure_fn(self.measure)(r, self.moving_roi(theta_deg))


@dataclass(frozen=True, eq=False)
class Alignment:
    """Result of a rotation search, with its evidence.

    theta_deg : the rotation of the moving map onto the reference, in [0, 360).
    score : the similarity at ``theta_deg`` on the ROI.
    counts : agr̃, dis and free/free at ``theta_deg`` on the ROI.
    profile : coarse scores at 0°, 1°, ..., 359°.
    runner_up_deg, runner_up_score : best coarse angle at least 10° away from ``theta_deg``.

    A search may hand over the counts and the runner-up as callables (arguments ``_counts`` and
    ``_runner_up``), each called once, on first access: a merge cycle decides on θ and the score
    alone, so it does not pay for the rest of the evidence (the free/free count, the runner-up search)
    unless someone reads it. Pickling resolves them.
    """

    theta_deg: float
    score: float
    _counts: Counts | Callable[[], Counts] = field(repr=False)
    measure: str
    method: str
    roi_m: float
    profile: np.ndarray = field(repr=False)
    _runner_up: tuple[float, float] | Callable[[], tuple[float, float]] = field(repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_lock", threading.Lock())

    def _resolve(self, name: str, convert):
        value = getattr(self, name)
        if callable(value):
            with self._lock:  # two threads may ask at once; the search behind it is not thread-safe
                value = getattr(self, name)
                if callable(value):
                    value = convert(value())
                    object.__setattr__(self, name, value)
        return value

    @property
    def counts(self) -> Counts:
        """agr̃, dis and free/free at ``theta_deg`` on the ROI (computed on first access if deferred)."""
        return self._resolve("_counts", lambda c: c)

    @property
    def runner_up(self) -> tuple[float, float]:
        """(runner_up_deg, runner_up_score), computed on first access when the search deferred it."""
        return self._resolve("_runner_up", lambda r: tuple(float(v) for v in r))

    def __getstate__(self) -> dict:
        state = {k: v for k, v in self.__dict__.items() if k != "_lock"}
        state["_counts"], state["_runner_up"] = self.counts, self.runner_up
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
    def margin(self) -> float:
        """score − runner-up score: how clearly the best peak stands out."""
        return self.score - self.runner_up_score

    def to_dict(self) -> dict:
        return {
            "theta_deg": self.theta_deg, "score": self.score, "measure": self.measure,
            "method": self.method, "roi_m": self.roi_m,
            "agree": self.counts.agree, "disagree": self.counts.disagree,
            "support": self.counts.support,
            "runner_up_deg": self.runner_up_deg, "runner_up_score": self.runner_up_score,
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


def reference_search(problem: RotationProblem) -> Alignment:
    """Exhaustive search exactly as the thesis: 360 coarse 1° rotations, then 0.1° over ±1°.

    Every angle rotates the moving ROI with :func:`merger.transform.rotated_roi` and evaluates the
    measure on the whole ROI. Ties go to the smallest angle (first maximum).
    """
    ref_roi = problem.ref_roi()
    fn = measure_fn(problem.measure)
    coarse = np.array([fn(ref_roi, problem.moving_roi(float(a))).value for a in range(360)])
    best_coarse = float(np.argmax(coarse))
    best = None
    for a in fine_angles(best_coarse):
        s = fn(ref_roi, problem.moving_roi(float(a)))
        if best is None or s.value > best[1].value:
            best = (float(a), s)
    theta = wrap_deg(best[0])
    ru_deg, ru_score = runner_up(coarse, theta)
    return Alignment(theta, best[1].value, best[1].counts, problem.measure, "reference",
                     problem.roi_m, coarse, (ru_deg, ru_score))


SearchMethod = Callable[[RotationProblem], Alignment]
SEARCH_METHODS: dict[str, SearchMethod] = {"reference": reference_search}


def register_method(name: str, fn: SearchMethod) -> None:
    """Register a search method under ``name`` (used by ``align(..., method=name)``)."""
    SEARCH_METHODS[name] = fn


def search(problem: RotationProblem, method: str = "reference") -> Alignment:
    try:
        fn = SEARCH_METHODS[method]
    except KeyError:
        raise ValueError(f"unknown search method {method!r}; expected one of "
                         f"{', '.join(sorted(SEARCH_METHODS))}") from None
    return fn(problem)


# The fast method (merger/fast.py) builds on this module and registers itself in SEARCH_METHODS.
from . import fast as _fast  # noqa: E402,F401  (imported last: it imports the names above)
