"""Similarity measures between two state-code arrays in the same frame.

All functions take two equally shaped uint8 arrays of state codes (see :mod:`merger.grid`).

* :func:`similarity_index` — the thesis's modified similarity index (3.11)
  ``ω̃ = agr̃ / (agr̃ + dis)`` with ``agr̃`` = cells occupied in both maps, ``dis`` = cells occupied in
  one map and free in the other; unknown in either and free/free are ignored.
* :func:`birk_carpin` — the original Birk–Carpin index (2.21): ``agr`` also counts free/free.
* :func:`ncc` — normalized cross-correlation of the binary occupied images (the thesis's first method).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .grid import FREE_S, OCCUPIED_S

MEASURES = ("similarity", "birk_carpin", "ncc")


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
    occ_a, occ_b = a == OCCUPIED_S, b == OCCUPIED_S
    free_a, free_b = a == FREE_S, b == FREE_S
    agree = int(np.count_nonzero(occ_a & occ_b))
    disagree = int(np.count_nonzero(occ_a & free_b) + np.count_nonzero(free_a & occ_b))
    free_agree = int(np.count_nonzero(free_a & free_b))
    return Counts(agree, disagree, free_agree)


def index_from_counts(counts: Counts, measure: str = "similarity") -> float:
    """ω̃ (measure="similarity") or Birk–Carpin ω (measure="birk_carpin") from counts; 0 when empty."""
    if measure == "similarity":
        num, den = counts.agree, counts.agree + counts.disagree
    elif measure == "birk_carpin":
        num = counts.agree + counts.free_agree
        den = num + counts.disagree
    else:
        raise ValueError(f"counts define 'similarity' and 'birk_carpin', not {measure!r}")
    return num / den if den else 0.0


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


def measure_fn(measure: str):
    """The function computing ``measure`` on two state arrays."""
    try:
        return {"similarity": similarity_index, "birk_carpin": birk_carpin, "ncc": ncc}[measure]
    except KeyError:
        raise ValueError(f"unknown measure {measure!r}; expected one of {', '.join(MEASURES)}") from None
