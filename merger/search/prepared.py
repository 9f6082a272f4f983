"""A problem's arrays, built once per search: the lattice tables, their preimages and the bound tables.

:class:`Prepared` turns a :class:`merger.search.problem.RotationProblem` (with its window of ±K cells)
into the arrays the kernels read (:mod:`merger.search.kernels`):

* ``cols``/``rows`` — :func:`merger.search.lattice.ref_axes_numpy`: the reference cell each lattice
  column (row) reads at each translation; ``ilo/ihi``, ``jlo/jhi`` — their preimages: the lattice rows
  (columns) reading a reference row (column), a contiguous range because the tables are monotone;
* ``qr, qc`` — the reference's occupied cells that some translation reads, and ``blk``/``lvl_start``
  the same cells pooled in blocks of 2^l cells for the bounds;
* per axis ``(base, dev, mult, lo)`` and ``p1``: how far the tables stray from a plain block (centers on
  cell borders: dev = 1, some cells read twice or not at all) — Lemma 1;
* summed-area tables of the moving map's occupied and free cells;
* ``tsum``: per translation, the reference ROI's occupied (NCC) or free (Birk–Carpin) lattice points.

Everything here is exact integer bookkeeping; the floats of the lookups are those of
:mod:`merger.search.lattice`.
"""

from __future__ import annotations

import numpy as np

from ..grid import FREE_S, OCCUPIED_S
from .kernels import LEVELS
from .lattice import lattice_offsets, ref_axes_numpy
from .measures import measure


def translation_offsets(k: int) -> list[tuple[int, int]]:
    """All (a, b) with |a|, |b| ≤ k, nearest first: by a² + b², then b, then a (the tie order)."""
    ts = [(a, b) for b in range(-k, k + 1) for a in range(-k, k + 1)]
    return sorted(ts, key=lambda t: (t[0] * t[0] + t[1] * t[1], t[1], t[0]))


def rank_table(k: int) -> np.ndarray:
    """rank[(b + k)·(2k+1) + (a + k)]: the position of (a, b) in :func:`translation_offsets`."""
    side = 2 * k + 1
    out = np.empty(side * side, np.int64)
    for r, (a, b) in enumerate(translation_offsets(k)):
        out[(b + k) * side + (a + k)] = r
    return out


def _raw_axis(center: float, origin: float, res: float, n: int, k: int) -> np.ndarray:
    off = lattice_offsets(n, res)
    tab = np.empty((2 * k + 1, n), np.float64)
    for a in range(-k, k + 1):
        c = center + a * res if a else center
        tab[a + k] = np.floor(((c + off) - origin) / res)
    return tab


def _axis(raw: np.ndarray, size: int):
    """Bookkeeping of one axis from its raw (unclipped, monotone) floor table (2k+1, n)."""
    side, n = raw.shape
    valid = (raw >= 0) & (raw < size)
    if not valid.any():
        return None
    lo = int(raw[valid].min())
    hi = int(raw[valid].max())
    span = hi - lo + 1
    t_idx = np.arange(side)[:, None]
    i_idx = np.arange(n)[None, :]
    nominal = raw - t_idx - i_idx
    base = int(np.round(np.median(nominal[valid])))
    dev = int(np.abs(nominal[valid] - base).max())
    cells = np.arange(lo, hi + 1, dtype=np.float64)
    start = np.empty((side, span), np.int64)
    end = np.empty((side, span), np.int64)
    for t in range(side):
        start[t] = np.searchsorted(raw[t], cells, side="left")
        end[t] = np.searchsorted(raw[t], cells, side="right")
    reads = end - start
    p1 = np.zeros((side + 1, span), np.int64)
    p1[1:] = np.cumsum(reads >= 1, axis=0)
    mult = int(reads.max())
    return (lo, hi, base, dev, mult, start, end, p1)


def _sat(mask: np.ndarray) -> np.ndarray:
    out = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), np.int64)
    out[1:, 1:] = np.cumsum(np.cumsum(mask, axis=0, dtype=np.int64), axis=1)
    return out


class Prepared:
    """The arrays of one problem (see the module documentation). ``k``: the window in cells."""

    def __init__(self, problem, k: int | None = None) -> None:
        ref, mov = problem.ref, problem.moving
        self.problem = problem
        self.measure = measure(problem.measure)
        self.k = problem.window_cells if k is None else k
        self.n = n = problem.n
        self.res = ref.resolution
        side = 2 * self.k + 1
        self.side = side
        self.cols, self.rows = ref_axes_numpy(ref, problem.center_ref, n, self.k)
        ax_c = _axis(_raw_axis(problem.center_ref[0], ref.origin[0], ref.resolution, n, self.k), ref.width)
        ax_r = _axis(_raw_axis(problem.center_ref[1], ref.origin[1], ref.resolution, n, self.k), ref.height)
        self.ref = np.ascontiguousarray(ref.states)
        self.empty_ref = ax_c is None or ax_r is None
        if self.empty_ref:  # no translation reads any reference cell: a dummy axis, no occupied cells
            ax_c = ax_r = (0, 0, 0, 0, 1, np.zeros((side, 1), np.int64), np.zeros((side, 1), np.int64),
                           np.zeros((side + 1, 1), np.int64))
        clo, chi, cbase, cdev, cmult, self.jlo, self.jhi, self.p1c = ax_c
        rlo, rhi, rbase, rdev, rmult, self.ilo, self.ihi, self.p1r = ax_r
        self.axes_c = np.array([cbase, cdev, cmult, clo], np.int64)
        self.axes_r = np.array([rbase, rdev, rmult, rlo], np.int64)
        if self.empty_ref:
            self.qr = self.qc = np.zeros(0, np.int64)
        else:
            qr, qc = np.nonzero(self.ref[rlo:rhi + 1, clo:chi + 1] == OCCUPIED_S)
            self.qr, self.qc = qr.astype(np.int64) + rlo, qc.astype(np.int64) + clo
        self.blk, self.lvl_start = self._blocks()
        ms = np.ascontiguousarray(mov.states)
        self.mstates = ms
        self.occ_sat = _sat(ms == OCCUPIED_S)
        self.free_sat = _sat(ms == FREE_S)
        self.rank = rank_table(self.k)
        self.tsum = self._tsum()
        half = n * self.res / 2.0
        self.ctx_f = np.array([self.res, mov.resolution, mov.origin[0], mov.origin[1],
                               float(problem.center_moving[0]), float(problem.center_moving[1]), half])

    def _blocks(self):
        """(row, col, count) of the occupied cells pooled in blocks of 2^l cells, levels 0..LEVELS−1."""
        parts, starts = [], [0]
        for level in range(LEVELS):
            s = 1 << level
            if self.qr.size:
                br, bc = self.qr // s, self.qc // s
                key = br * (1 << 31) + bc
                uk, cnt = np.unique(key, return_counts=True)
                part = np.stack([(uk >> 31) * s, (uk & ((1 << 31) - 1)) * s, cnt], axis=1)
            else:
                part = np.zeros((0, 3), np.int64)
            parts.append(part.astype(np.int64))
            starts.append(starts[-1] + part.shape[0])
        return np.ascontiguousarray(np.concatenate(parts)), np.array(starts, np.int64)

    def _tsum(self) -> np.ndarray:
        """Per translation (b·side + a): the reference ROI's occupied (NCC) or free (Birk–Carpin) points."""
        kind = self.measure.sums
        if kind == 0 or self.empty_ref:
            return np.zeros(self.side * self.side, np.int64)
        state = OCCUPIED_S if kind == 2 else FREE_S
        rlo, clo = int(self.axes_r[3]), int(self.axes_c[3])
        # the ROI at (a, b) reads cell (r, c) (ihi − ilo)[b, r] · (jhi − jlo)[a, c] times
        nr = (self.ihi - self.ilo).astype(np.float64)
        nc = (self.jhi - self.jlo).astype(np.float64)
        block = self.ref[rlo:rlo + nr.shape[1], clo:clo + nc.shape[1]] == state
        table = nr @ block.astype(np.float64) @ nc.T  # exact integers (< 2^53)
        return np.rint(table).astype(np.int64).reshape(-1)
