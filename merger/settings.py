"""The search's settings: one default and one rule each, read by every place that takes them.

:class:`merger.search.RotationProblem`, :class:`merger.team.params.MergeParams`, ``merger.align``, the
scenario loader (:mod:`circsim.config.scenario`) and both command lines default a setting to the
constant here and check it with the rule here, naming the setting as their user knows it (``window_m``,
a scenario's ``merger.window_m``, a command line's ``--window``): :class:`SettingError` is that one-line
message. The rules between two settings: the translation window is at most a quarter of the ROI side
(:func:`check_window` with both). The inputs' own limits (a scenario's or a command line's ROI) are
:mod:`merger.limits`.
"""

from __future__ import annotations

import math

import numpy as np

from .limits import MAX_ROI_M, MIN_ROI_CELLS
from .measures import MEASURES

MAX_WINDOW_FRACTION = 0.25  # the translation window may cover at most a quarter of the ROI side
MAX_ROI_CELLS = 4000  # ROI side in cells (100 m at 2.5 cm): the search's tables and OpenCV's 32,767 limits
# The one default of each of the search's settings that a merge, the scenarios and the command lines share
# (RotationProblem's, merger.team.params.MergeParams's and merger.align's defaults are these):
DEFAULT_ROI_M = 8.0  # the ROI side, metres (the thesis's 8 m square)
DEFAULT_WINDOW_M = 0.5  # the translation window, metres (centers trusted to ±0.5 m; 0: the thesis's rotation only)
DEFAULT_MEASURE = "similarity"  # what the search maximizes (the thesis's ω̃, eq. 3.11)
MAX_SUPPORT_FLOOR = 2 ** 40  # cells (check_floor): exact in the kernels' int64 and float64 (an ROI holds <= 1.6e7)
ROI_MIN_SUPPORT = 50  # cells: the support floor of align() and merge cycles (RotationProblem.min_support)


class SettingError(ValueError):
    """A setting its rule refuses. ``key`` names the setting as the caller knows it (``window_m``, a
    scenario's ``merger.window_m``, a command line's ``--window``) and ``rest`` is the rule's words after it:
    the message is ``key + rest``, one line saying what was expected (a caller passes its own name of the
    setting as the rule's ``key``; :func:`circsim.config.validate.refused` reads ``rest``)."""

    def __init__(self, key: str, rest: str) -> None:
        super().__init__(key + rest)
        self.key, self.rest = key, rest


def _metres(value, key: str, rest: str) -> float:
    """``value`` as a float: a real number (not a bool, not text), else SettingError ``key`` + ``rest``."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SettingError(key, rest.format(got=repr(value)))
    return float(value)


def check_window(window_m, roi_m=None, key: str = "window_m", roi_key: str = "the ROI side") -> float:
    """The translation window's rule, the one check of every ``window_m`` (RotationProblem, MergeParams,
    the scenario loader and the command lines call it): a finite number of metres in [0, ``roi_m`` / 4]
    (``roi_m`` None: only >= 0). Returns it as a float; SettingError naming ``key`` (and the ROI side as
    ``roi_key``) and what was expected otherwise."""
    top = None if roi_m is None else MAX_WINDOW_FRACTION * roi_m
    expected = ("expected a number of metres >= 0" if top is None else
                f"expected a number of metres in [0, {top:g}] (at most a quarter of {roi_key}, {roi_m:g} m)")
    w = _metres(window_m, key, " must be a number of metres, got {got}: " + expected)
    if not math.isfinite(w) or w < 0:
        raise SettingError(key, f" must be a finite number >= 0, got {w:g}: {expected}")
    if top is not None and w > top + 1e-12:
        raise SettingError(key, f" = {w:g} m is more than a quarter of {roi_key} ({roi_m:g} m): expected at most "
                                f"{top:g} m (or a larger ROI)")
    return w


def check_roi(roi_m, resolution: float | None = None, key: str = "roi_m", *, limits: bool = False,
              cells_of: str = "") -> float:
    """The ROI side's rule, the one check of every ``roi_m`` (RotationProblem, MergeParams, the scenario
    loader and the command lines call it): a finite number of metres > 0 and, on a grid of ``resolution``,
    at most :data:`MAX_ROI_CELLS` cells a side (the search's tables grow with its square). ``limits``: the
    inputs' limits too (a scenario file, a command line: :mod:`merger.limits`), at most :data:`MAX_ROI_M`
    and at least :data:`MIN_ROI_CELLS` cells a side. Returns it as a float; SettingError naming ``key``
    (``cells_of``: what the resolution is, e.g. a map's path) and what was expected otherwise."""
    span = f"in (0, {MAX_ROI_M:g}]" if limits else "> 0"
    r = _metres(roi_m, key, f": expected a number of metres {span}, got {{got}}")
    if not (math.isfinite(r) and r > 0) or (limits and r > MAX_ROI_M):
        raise SettingError(key, f": expected a number {span}, got {r:g}")
    if resolution is not None:
        n, lo = r / resolution, (MIN_ROI_CELLS if limits else 0)
        if not lo <= n <= MAX_ROI_CELLS:
            top = min(MAX_ROI_M, MAX_ROI_CELLS * resolution) if limits else MAX_ROI_CELLS * resolution
            side = f"{lo} to {MAX_ROI_CELLS}" if limits else f"at most {MAX_ROI_CELLS}"
            of = f" of {cells_of}" if cells_of else ""
            raise SettingError(key, f": expected a side of {side} cells{of} at {resolution:g} m per cell ("
                                    f"{lo * resolution:g} to {top:g} m: a smaller ROI, or a coarser map), got "
                                    f"{r:g} m ({n:.3g} cells)")
    return r


MEASURE_EXPECTED = "one of " + ", ".join(map(repr, MEASURES))  # the measure rule's words


def check_measure(measure, key: str = "measure") -> str:
    """The measure's rule, the one check of every ``measure`` (RotationProblem, MergeParams, the scenario
    loader; the command lines offer the same names): one of :data:`merger.measures.MEASURES`. Returns it;
    SettingError naming ``key`` otherwise."""
    if not isinstance(measure, str) or measure not in MEASURES:
        raise SettingError(key, f" must be {MEASURE_EXPECTED}, got {measure!r}")
    return measure


FLOOR_EXPECTED = "a whole number of cells >= 0 (below 2^40)"  # the floor rule's words


def check_floor(floor, key: str = "min_support") -> int:
    """The support floor's rule, the one check of every floor (RotationProblem's ``min_support``,
    MergeParams's ``roi_min_support``, the scenario loader and the command lines): a whole number of cells
    in [0, :data:`MAX_SUPPORT_FLOOR`). Returns it as an int; SettingError naming ``key`` otherwise."""
    if isinstance(floor, bool) or not isinstance(floor, (int, np.integer)) or not 0 <= floor < MAX_SUPPORT_FLOOR:
        raise SettingError(key, f" must be {FLOOR_EXPECTED}, got {floor!r}")
    return int(floor)
