"""Verification of an alignment on whole maps (thesis 3.3.1, eq. 3.12, and the online support rule).

An alignment is accepted when ω̃ computed on the whole aligned maps is at least ``nu_min`` *and* its
support ``agr̃ + dis`` is at least ``min_support``: with too few cells the index means nothing, so a
hypothesis is rejected in that case (favouring false negatives over false merges). For maps from
independent runs (real maps), :func:`verify_contrast` asks instead how far the placement's whole-map
fit stands above its rivals' (:mod:`merger.team.evidence`). :func:`check_pair` is the one check of a pair of
placed maps, by the rule ``MergeParams.verification`` names (:mod:`merger.team.defaults`: what each rule runs);
every strategy and ``merger align`` call it. ``auto``, the default, accepts a pair that either rule accepts (docs/merging-real-maps.md: the thesis's rule
where maps agree cell by cell, the contrast rule where they agree only within a few cells).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..grid import OccupancyGrid
from ..measures import Counts, similarity_index
from ..transform import overlap
from .defaults import verification_rule
from .evidence import FIT_AGREE_DEG, REFINE_M, Contrast, contrast, refine


@dataclass(frozen=True)
class Verification:
    nu: float
    counts: Counts
    passed: bool
    reason: str = ""
    contrast: Contrast | None = None  # the contrast evidence (verification "contrast", :mod:`merger.team.evidence`)

    @property
    def support(self) -> int:
        return self.counts.support

    def to_dict(self) -> dict:
        """The evidence as JSON fields: ν, its counts, the verdict and, with the contrast rule, the fit, its
        rival (offset from the placement) and the contrast's support."""
        out = {"nu": self.nu, "agree": self.counts.agree, "disagree": self.counts.disagree,
               "support": self.support, "passed": self.passed, "reason": self.reason}
        k = self.contrast
        if k is not None:
            out.update(contrast=_finite(k.contrast), fit=_finite(k.best), rival_fit=_finite(k.rival),
                       rival_offset_deg=_finite(k.rival_at[0]),
                       contrast_support=k.support,
                       refined_offset={"theta_deg": _finite(k.best_at[0]), "cells": [k.best_at[1], k.best_at[2]]})
        return out


def _finite(v):
    """A figure for JSON: None when it was not computed (NaN)."""
    return None if v is None or np.isnan(v) else float(v)


def verify(a: np.ndarray, b: np.ndarray, *, nu_min: float, min_support: int,
           label: str = "") -> Verification:
    """ω̃ of two aligned whole maps with the acceptance rule; ``reason`` says why it failed."""
    s = similarity_index(a, b)
    name = f"ν({label})" if label else "ν"
    if s.counts.support < min_support:
        return Verification(s.value, s.counts, False,
                            f"support of {name} = {s.counts.support} < min_support {min_support}")
    if s.value < nu_min:
        return Verification(s.value, s.counts, False, f"{name} = {s.value:.3f} < ν_min {nu_min:g}")
    return Verification(s.value, s.counts, True)


def verify_contrast(a: OccupancyGrid, b: OccupancyGrid, pivot, *, tolerance_m: float, contrast_min: float,
                    min_support: int, label: str = "") -> Verification:
    """The contrast rule (:mod:`merger.team.evidence`) for b placed onto a (grids on one lattice, rotations about
    ``pivot``); ``nu`` and ``counts`` are ω̃ on the overlap, as in :func:`verify`, for the record."""
    s = similarity_index(*overlap(a, b))
    k = contrast(a, b, pivot, tolerance_m, min_support=min_support, agree_deg=FIT_AGREE_DEG)
    name = f" of {label}" if label else ""
    if k.support < min_support:
        return Verification(s.value, s.counts, False, f"support{name} = {k.support} occupied cells on known "
                            f"cells < min_support {min_support}", k)
    if abs(k.best_at[0]) > FIT_AGREE_DEG:
        return Verification(s.value, s.counts, False,
                            f"the whole maps{name} fit best {k.best_at[0]:+.1f}° from the placement (more than "
                            f"{FIT_AGREE_DEG:g}°): the ROI's answer is not where the maps agree", k)
    if k.contrast < contrast_min:
        return Verification(s.value, s.counts, False,
                            f"contrast{name} = {k.contrast:.2f} < contrast_min {contrast_min:g} (fit {k.best:.3f}, "
                            f"rival {k.rival:.3f} at {k.rival_at[0]:.0f}°)", k)
    return Verification(s.value, s.counts, True, "", k)


def check_pair(a: OccupancyGrid, b: OccupancyGrid, pivot, params, label: str = "") -> Verification:
    """Verification of b placed onto a (grids on one lattice; rotations about ``pivot``, where b's center
    lands) by the rule ``params.verification`` names (:data:`merger.team.defaults.VERIFICATIONS_BY_NAME`):
    the thesis's (``nu``: "whole_map", ω̃ ≥ ν_min on the overlap), the contrast rule (``contrast``:
    "contrast", :func:`verify_contrast`) or both ("auto"): the thesis's rule, and when it refuses, the
    contrast rule (accepted when either accepts; the reason of a refusal names both). ``params``: a
    :class:`MergeParams` (read by attribute: ``verification``, ``nu_min``, ``min_support``, ``tolerance_m``,
    ``contrast_min``)."""
    rule = verification_rule(params.verification)
    if not rule.whole_maps:
        raise ValueError(f"check_pair: verification {rule.name!r} is not a whole-map rule")
    if rule.nu:
        v = verify(*overlap(a, b), nu_min=params.nu_min, min_support=params.min_support, label=label)
        # the contrast's support (b's occupied cells on a's known cells) is at most agr̃ + dis: below
        # min_support here, the contrast rule refuses too, and is not computed
        if not rule.contrast or v.passed or v.counts.support < params.min_support:
            return v
    k = verify_contrast(a, b, pivot, tolerance_m=params.tolerance_m, contrast_min=params.contrast_min,
                        min_support=params.min_support, label=label)
    if not rule.nu or k.passed:
        return k
    return Verification(v.nu, v.counts, False, f"{v.reason}; {k.reason}", k.contrast)


def refine_limit_m(params) -> float:
    """How far the whole-map refinement may move a placement on each axis: ``REFINE_M`` (1 m), at most twice
    the search's window (the center error it assumes is up to half the window: ±2W covers the search's
    answer off by as much again); 0 for a rotation-only search, whose centers are exact by assumption."""
    return min(REFINE_M, 2.0 * float(params.window_m))


def refined_placement(a: OccupancyGrid, b: OccupancyGrid, pivot, theta: float, t, params):
    """Whole-map refinement of a placement (θ, t) of b onto a (b already placed by it, about ``pivot`` =
    where b's center lands): the best fit near it (:func:`merger.team.evidence.refine`, tolerance
    ``params.tolerance_m``, translations within :func:`refine_limit_m`) as a placement of the same form,
    (θ + δθ, t + δ); rotating the placed map by δθ about the pivot and shifting it by δ is that placement."""
    _, (dth, dx, dy) = refine(a, b, pivot, params.tolerance_m, refine_limit_m(params))
    return theta + dth, (float(t[0]) + dx * a.resolution, float(t[1]) + dy * a.resolution)


def no_evidence(al, floor: int, label: str = "") -> str:
    """Why an alignment without evidence (``al.has_evidence`` false) is not an answer."""
    what = f" for {label}" if label else ""
    c = al.counts
    return (f"no evidence{what}: no placement in the {al.roi_m:g} m ROI reaches {floor} cells of support "
            f"(agr̃ + dis) with an agreeing cell (best: agree {c.agree}, disagree {c.disagree}); the search sees "
            f"only the {al.roi_m:g} m square about each center: choose a common center with walls of both maps "
            f"within {al.roi_m / 2:g} m of it, or a larger ROI (--roi, merger.roi_m; real maps: 16 m)")


def pairwise(layers: list[np.ndarray]) -> list[tuple[int, int]]:
    """Index pairs (i, j), i < j, of a list of aligned layers."""
    n = len(layers)
    return [(i, j) for i in range(n) for j in range(i + 1, n)]

