"""Similarity measures: one :class:`Measure` object per measure, and the only list of their names.

A measure compares two state-code arrays in the same frame (see :mod:`merger.grid`) on counts:
``agr`` (occupied in both: agr̃ of the thesis), ``dis`` (occupied in one, free in the other), ``ff``
(free in both), ``sx``/``sy`` (occupied — or free — points of the reference / moving ROI), ``N = n²``.

* ``similarity`` — the thesis's modified similarity index (3.11): ω̃ = agr̃ / (agr̃ + dis), 0 without
  support; unknown in either and free/free are ignored.
* ``birk_carpin`` — Birk and Carpin's index (2.21): ω = (agr + ff) / (agr + ff + dis).
* ``ncc`` — normalized cross-correlation of the binary occupied images (the thesis's first method).

Each :class:`Measure` holds its name, its definition on two arrays (numpy, the specification), which
counts its value needs, and its kernel ``code``; the compiled :func:`value_of` (value from counts, the
same floats as the numpy definition) and :func:`upper_of` (an upper bound from bounds on the counts)
are the only places that branch on a measure (docs/design/search.md §3).

The support floor (``floor``, cells): a placement whose support agr + dis is below it scores 0, whatever
the measure, so that no optimum rests on a handful of cells (docs/design/search.md §3; 0: off, the
thesis's measures as defined). Every search method applies it, so they stay equal.

Upper bounds (Lemma 4): ω̃ and ω grow with agr and ff and fall with dis; integers are exact in float64
and a correctly rounded division is monotone, so ``value(agr_hi, dis_lo, ff_hi)`` ≥ every value in the
region, as floats. NCC: numerator ≤ min(agr_hi, sx_hi, sy_hi) − sx_lo·sy_lo/N, denominator ≥ the
smallest of √(vx·vy) over the ranges' ends (vx = sx − sx²/N is concave); a relative slack of 1e-12
covers the rounding of the sqrt and the products.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .grid import FREE_S, OCCUPIED_S
from .jit import njit

SIMILARITY, BIRK_CARPIN, NCC = 0, 1, 2
NO_SUMS, FREE_SUMS, OCCUPIED_SUMS = 0, 1, 2  # the count tables a measure's value reads (sx, sy)


@dataclass(frozen=True)
class Counts:
    """Cell counts behind a similarity value.

    agree : cells occupied in both maps (agr̃ of the thesis).
    disagree : cells occupied in one map and free in the other (dis).
    free_agree : cells free in both maps (counted by Birk–Carpin's agr only).
    """

    agree: int
    disagree: int
    free_agree: int = 0

    @property
    def support(self) -> int:
        """agr̃ + dis: the cells on which ω̃ is based."""
        return self.agree + self.disagree


@dataclass(frozen=True)
class Similarity:
    """A similarity value with its counts."""

    value: float
    counts: Counts
    measure: str = "similarity"


def count_cells(a: np.ndarray, b: np.ndarray) -> Counts:
    """agr̃, dis and free/free counts of two state arrays (unknown in either is ignored)."""
    if a.shape != b.shape:
        raise ValueError(f"shapes differ: {a.shape} vs {b.shape}")
    if a.size == 0:
        return Counts(0, 0, 0)
    if a.ndim != 2:
        a, b = a.reshape(1, -1), b.reshape(1, -1)
    agree, disagree, free_agree = _count_cells(a, b)
    return Counts(int(agree), int(disagree), int(free_agree))


def count_cells_reference(a: np.ndarray, b: np.ndarray) -> Counts:
    """:func:`count_cells` in numpy (the tests compare them)."""
    if a.shape != b.shape:
        raise ValueError(f"shapes differ: {a.shape} vs {b.shape}")
    occ_a, occ_b = a == OCCUPIED_S, b == OCCUPIED_S
    free_a, free_b = a == FREE_S, b == FREE_S
    agree = int(np.count_nonzero(occ_a & occ_b))
    disagree = int(np.count_nonzero(occ_a & free_b) + np.count_nonzero(free_a & occ_b))
    free_agree = int(np.count_nonzero(free_a & free_b))
    return Counts(agree, disagree, free_agree)


@njit(cache=True, nogil=True)
def _count_cells(a, b):
    """agr̃, dis and free/free of two 2-D state arrays in one pass (no temporaries; the GIL released)."""
    agree = disagree = free_agree = 0
    for r in range(a.shape[0]):
        for c in range(a.shape[1]):
            x, y = a[r, c], b[r, c]
            if x == OCCUPIED_S:
                if y == OCCUPIED_S:
                    agree += 1
                elif y == FREE_S:
                    disagree += 1
            elif x == FREE_S:
                if y == OCCUPIED_S:
                    disagree += 1
                elif y == FREE_S:
                    free_agree += 1
    return agree, disagree, free_agree


def index_from_counts(counts: Counts, measure: str = "similarity") -> float:
    """ω̃ (measure="similarity") or Birk–Carpin ω (measure="birk_carpin") from counts; 0 when empty."""
    if measure not in ("similarity", "birk_carpin"):
        raise ValueError(f"counts define 'similarity' and 'birk_carpin', not {measure!r}")
    return value_of(MEASURES_BY_NAME[measure].code, 0, counts.agree, counts.disagree, counts.free_agree, 0, 0, 0)


def similarity_index(a: np.ndarray, b: np.ndarray) -> Similarity:
    """The modified similarity index ω̃ = agr̃ / (agr̃ + dis), thesis eq. (3.11).

    Returns 0 when no cell is occupied-in-both nor occupied-vs-free (no support).
    """
    c = count_cells(a, b)
    return Similarity(index_from_counts(c, "similarity"), c, "similarity")


def birk_carpin(a: np.ndarray, b: np.ndarray) -> Similarity:
    """Birk and Carpin's similarity index ω = agr / (agr + dis), agr counting free/free too (2.21)."""
    c = count_cells(a, b)
    return Similarity(index_from_counts(c, "birk_carpin"), c, "birk_carpin")


def ncc(a: np.ndarray, b: np.ndarray) -> Similarity:
    """Normalized cross-correlation of the binary occupied images of ``a`` and ``b``.

    Every cell of the arrays counts (occupied = 1, free and unknown = 0), as in the thesis's first
    method. Returns 0 when either image is constant.
    """
    if a.shape != b.shape:
        raise ValueError(f"shapes differ: {a.shape} vs {b.shape}")
    x = (a == OCCUPIED_S).astype(np.float64).ravel()
    y = (b == OCCUPIED_S).astype(np.float64).ravel()
    return Similarity(_ncc_binary(x, y), count_cells(a, b), "ncc")


def _ncc_binary(x: np.ndarray, y: np.ndarray) -> float:
    # For 0/1 images: sum((x-mx)(y-my)) = sxy - sx*sy/n ; sum((x-mx)^2) = sx - sx^2/n
    n = x.size
    if n == 0:
        return 0.0
    sx, sy, sxy = x.sum(), y.sum(), float(x @ y)
    vx, vy = sx - sx * sx / n, sy - sy * sy / n
    if vx <= 0 or vy <= 0:
        return 0.0
    return float((sxy - sx * sy / n) / np.sqrt(vx * vy))


@njit(cache=True, nogil=True)
def value_of(code, floor, agr, dis, ff, sx, sy, n_cells):
    """The measure's value from counts — the same floats as the numpy definitions — or 0 when the
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
    every bound here is ≥ 0, so the other bounds stand as they are (Lemma 4a). The bound only falls when
    agr_hi falls or dis_lo rises (Lemma 4b)."""
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


@njit(cache=True, nogil=True, inline=True)
def angle_sum(sums, n_occ, n_free):
    """The per-angle count a measure with count tables ``sums`` reads: the moving ROI's occupied points
    (NCC) or free points (Birk–Carpin)."""
    return n_occ if sums == OCCUPIED_SUMS else n_free


@dataclass(frozen=True)
class Measure:
    """A similarity measure: its name, its definition on two arrays, its kernel code and which counts
    its value needs (``needs_free_agree``: ff, a dense pass over the ROI; ``sums``: the per-translation /
    per-angle count tables its value and bound read)."""

    name: str
    code: int
    needs_free_agree: bool
    sums: int
    fn: Callable[[np.ndarray, np.ndarray], Similarity]

    def value(self, agr: int, dis: int, ff: int = 0, sx: int = 0, sy: int = 0, n_cells: int = 0,
              floor: int = 0) -> float:
        return float(value_of(self.code, floor, agr, dis, ff, sx, sy, n_cells))

    def angle_sum(self, n_occ: int, n_free: int) -> int:
        return int(angle_sum(self.sums, n_occ, n_free))


MEASURES_BY_NAME = {
    "similarity": Measure("similarity", SIMILARITY, False, NO_SUMS, similarity_index),
    "birk_carpin": Measure("birk_carpin", BIRK_CARPIN, True, FREE_SUMS, birk_carpin),  # ff ≤ min(free points)
    "ncc": Measure("ncc", NCC, False, OCCUPIED_SUMS, ncc),  # sx (per translation), sy (per angle)
}
MEASURES = tuple(MEASURES_BY_NAME)  # the only list of measure names


def measure(name: str) -> Measure:
    """The :class:`Measure` called ``name`` (ValueError naming the known ones)."""
    try:
        return MEASURES_BY_NAME[name]
    except KeyError:
        raise ValueError(f"unknown measure {name!r}; expected one of {', '.join(MEASURES)}") from None


def measure_fn(name: str):
    """The function computing measure ``name`` on two state arrays."""
    return measure(name).fn
