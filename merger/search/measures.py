"""Similarity measures as objects: which counts each needs, its value from counts, its upper bound from
count bounds (docs/design/search.md §3). One :class:`Measure` per measure; kernels take its ``code``.

Counts on an ROI pair: ``agr`` (occupied in both), ``dis`` (occupied in one, free in the other), ``ff``
(free in both), ``sx``/``sy`` (occupied lattice points of the reference / moving ROI), ``N = n²``.

* ``similarity`` (thesis 3.11): ω̃ = agr / (agr + dis), 0 without support.
* ``birk_carpin`` (2.21): ω = (agr + ff) / (agr + ff + dis).
* ``ncc``: normalized cross-correlation of the binary occupied images (the thesis's first method).

The support floor (``floor``, cells): a placement whose support agr + dis is below it scores 0, whatever
the measure, so that no optimum rests on a handful of cells (docs/design/search.md §3; 0: off, the
thesis's measures as defined). Every method applies it, so they stay equal.

Upper bounds (Lemma 4): ω̃ and ω grow with agr and ff and fall with dis; integers are exact in float64
and a correctly rounded division is monotone, so ``value(agr_hi, dis_lo, ff_hi)`` ≥ every value in the
region, as floats. NCC: numerator ≤ min(agr_hi, sx_hi, sy_hi) − sx_lo·sy_lo/N, denominator ≥ the
smallest of √(vx·vy) over the ranges' ends (vx = sx − sx²/N is concave); a relative slack of 1e-12
covers the rounding of the sqrt and the products.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..jit import njit

SIMILARITY, BIRK_CARPIN, NCC = 0, 1, 2


@njit(cache=True, nogil=True)
def value_of(code, floor, agr, dis, ff, sx, sy, n_cells):
    """The measure's value from counts — the same floats as :mod:`merger.measures` — or 0 when the
    support agr + dis is below ``floor``."""
    if agr + dis < floor:
        return 0.0
    if code == NCC:
        if n_cells == 0:
            return 0.0
        fx, fy, nn = float(sx), float(sy), float(n_cells)
        vx = fx - fx * fx / nn
        vy = fy - fy * fy / nn
        if vx <= 0 or vy <= 0:
            return 0.0
        return (float(agr) - fx * fy / nn) / math.sqrt(vx * vy)
    num = agr + ff if code == BIRK_CARPIN else agr
    den = num + dis
    return num / den if den else 0.0


@njit(cache=True, nogil=True)
def _v(s, nn):
    return s - s * s / nn


@njit(cache=True, nogil=True)
def upper_of(code, floor, agr_hi, dis_lo, sx_lo, sx_hi, sy_lo, sy_hi, n_cells):
    """An upper bound of the measure over a region whose counts satisfy agr ≤ agr_hi, dis ≥ dis_lo and
    whose count tables lie in [sx_lo, sx_hi] (per translation) and [sy_lo, sy_hi] (per angle): occupied
    points for NCC, free points for Birk–Carpin (ff ≤ both) (Lemma 4). With a support floor F, ω̃ ≤
    agr_hi / max(agr_hi + dis_lo, F) (increasing in agr_hi); the floor only lowers values to 0, and
    every bound here is ≥ 0, so the other bounds stand as they are."""
    if code == SIMILARITY:
        if agr_hi <= 0:
            return 0.0
        return agr_hi / max(agr_hi + dis_lo, floor)
    if code == BIRK_CARPIN:
        return value_of(code, 0, agr_hi, dis_lo, min(sx_hi, sy_hi), 0, 0, n_cells)
    nn = float(n_cells)
    a = min(agr_hi, sx_hi, sy_hi)
    num = a - float(sx_lo) * float(sy_lo) / nn
    if num <= 0.0:
        return 0.0
    # only sx, sy in [1, N − 1] give a non-zero value; vx is concave, smallest at an end of the range
    x0, x1 = max(sx_lo, 1), min(sx_hi, n_cells - 1)
    y0, y1 = max(sy_lo, 1), min(sy_hi, n_cells - 1)
    if x0 > x1 or y0 > y1:
        return 0.0
    vx = min(_v(float(x0), nn), _v(float(x1), nn))
    vy = min(_v(float(y0), nn), _v(float(y1), nn))
    if vx <= 0 or vy <= 0:
        return 0.0
    return num / math.sqrt(vx * vy) * (1.0 + 1e-12) + 1e-12


@njit(cache=True, nogil=True)
def uppers(code, floor, agr_hi, dis_lo, sx_lo, sx_hi, sy, n_cells):
    """:func:`upper_of` per angle: count bounds ``agr_hi``, ``dis_lo`` and ``sy`` per angle, ``sx`` in
    [sx_lo, sx_hi]."""
    out = np.empty(agr_hi.size)
    for x in range(agr_hi.size):
        out[x] = upper_of(code, floor, agr_hi[x], dis_lo[x], sx_lo, sx_hi, sy[x], sy[x], n_cells)
    return out


@dataclass(frozen=True)
class Measure:
    """A similarity measure: its name, kernel code and which counts its value needs."""

    name: str
    code: int
    needs_free_agree: bool  # ff: a dense pass over the ROI
    sums: int  # the per-translation / per-angle count tables its bound uses: 0 none, 1 free, 2 occupied

    def value(self, agr: int, dis: int, ff: int = 0, sx: int = 0, sy: int = 0, n_cells: int = 0,
              floor: int = 0) -> float:
        return float(value_of(self.code, floor, agr, dis, ff, sx, sy, n_cells))


MEASURES_BY_NAME = {
    "similarity": Measure("similarity", SIMILARITY, False, 0),
    "birk_carpin": Measure("birk_carpin", BIRK_CARPIN, True, 1),  # ff ≤ min(free points of either ROI)
    "ncc": Measure("ncc", NCC, False, 2),  # sx (per translation), sy (per angle)
}


def measure(name: str) -> Measure:
    try:
        return MEASURES_BY_NAME[name]
    except KeyError:
        raise ValueError(f"unknown measure {name!r}; expected one of {', '.join(MEASURES_BY_NAME)}") from None
