"""A problem's arrays, built once per search: the lattice tables, their preimages and the bound tables.

:class:`Prepared` turns a :class:`merger.search.problem.RotationProblem` (with its window of ±K cells)
into the arrays the kernels read, by name (:class:`Tables`):

* ``cols``/``rows`` — :func:`merger.lattice.ref_axes_numpy`: the reference cell each lattice
  column (row) reads at each translation; ``ilo/ihi``, ``jlo/jhi`` — their preimages: the lattice rows
  (columns) reading a reference row (column), a contiguous range because the tables are monotone;
* ``qr, qc`` — the reference's occupied cells that some translation reads, and ``blk``/``lvl_start``
  the same cells pooled in blocks of 2^l cells for the bounds;
* per axis ``(base, dev, mult, lo)`` and ``p1``: how far the tables stray from a plain block (centers on
  cell borders: dev = 1, some cells read twice or not at all) — Lemma 1;
* summed-area tables of the moving map's occupied and free cells;
* ``tsum``: per translation, the reference ROI's occupied (NCC) or free (Birk–Carpin) lattice points.

Everything here is exact integer bookkeeping; the floats of the lookups are those of
:mod:`merger.lattice`.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np

from .. import caches
from ..grid import FREE_S, OCCUPIED_S
from ..jit import njit
from ..lattice import axis_floor, half_side, ref_axes_numpy
from ..measures import OCCUPIED_SUMS, measure

LEVELS = 5  # reference blocks of 1, 2, 4, 8, 16 cells (the region bound's pooled levels)


class Tables(NamedTuple):
    """A problem's arrays as the kernels read them, by name (built by :class:`Prepared`)."""

    n: int  # the ROI lattice: n × n points one reference cell (res) apart
    k: int  # the window: translations −k..k cells each way
    side: int  # 2k + 1
    res: float
    res_m: float  # the moving map's resolution, origin and center
    mox: float
    moy: float
    mcx: float
    mcy: float
    half: float  # n·res/2
    code: int  # the measure (merger.measures): its code, support floor and the counts it needs
    floor: int
    need_ff: bool
    sums: int
    ref: np.ndarray  # the reference's states
    cols: np.ndarray  # (side, n): the reference column (row) each lattice column (row) reads, −1 outside
    rows: np.ndarray
    rlo: int  # the first reference row (column) some translation reads
    clo: int
    ilo: np.ndarray  # (side, rows): the lattice rows [ilo, ihi) reading each reference row; jlo/jhi columns
    ihi: np.ndarray
    jlo: np.ndarray
    jhi: np.ndarray
    axes_r: np.ndarray  # (base, dev, mult, lo) per axis (Lemma 1)
    axes_c: np.ndarray
    qr: np.ndarray  # the reference's occupied cells some translation reads
    qc: np.ndarray
    blk: np.ndarray  # those cells pooled in blocks, levels 0..LEVELS−1 (Prepared._blocks)
    blkf: np.ndarray
    lvl_start: np.ndarray
    wr0: np.ndarray  # per translation, how many lattice rows (columns) read each occupied cell
    wc0: np.ndarray
    ref_sat: np.ndarray  # summed-area table of the readable reference's (occupied << 32 | free)
    mstates: np.ndarray  # the moving map's states, its summed-area table, its occupied cell centres
    cls_sat: np.ndarray
    occ_x: np.ndarray
    occ_y: np.ndarray
    tsum: np.ndarray  # per translation: the reference ROI's count table (NCC occupied, Birk–Carpin free)


def translation_offsets(k: int) -> list[tuple[int, int]]:
    """All (a, b) with |a|, |b| ≤ k, nearest first: by a² + b², then b, then a (the tie order)."""
    return list(_offsets(k))


@lru_cache(maxsize=16)
def _offsets(k: int) -> tuple[tuple[int, int], ...]:
    ts = [(a, b) for b in range(-k, k + 1) for a in range(-k, k + 1)]
    return tuple(sorted(ts, key=lambda t: (t[0] * t[0] + t[1] * t[1], t[1], t[0])))


@lru_cache(maxsize=16)
def rank_table(k: int) -> np.ndarray:
    """rank[(b + k)·(2k+1) + (a + k)]: the position of (a, b) in :func:`translation_offsets` (read-only,
    shared by every problem with this window)."""
    side = 2 * k + 1
    out = np.empty(side * side, np.int64)
    for r, (a, b) in enumerate(_offsets(k)):
        out[(b + k) * side + (a + k)] = r
    out.flags.writeable = False
    return out


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
    # per cell: the most lattice lines reading it at any translation, and whether a translation whose
    # ROI spans it (with dev to spare) skips it (centers on cell borders: float ties)
    wmax = reads.max(axis=0)
    inner = (cells[None, :] >= base + t_idx + dev) & (cells[None, :] <= base + t_idx + n - 1 - dev)
    skipped = ((reads == 0) & inner).any(axis=0)
    return (lo, hi, base, dev, int(wmax.max()), start, end, wmax.astype(np.int64), skipped)


@njit(cache=True, nogil=True)
def class_sat(states, r0, r1, c0, c1):
    """Summed-area table (zero border) of (occupied << 32 | free) over ``states[r0:r1, c0:c1]``: both
    counts of a rectangle in four reads."""
    out = np.zeros((r1 - r0 + 1, c1 - c0 + 1), np.int64)
    for i in range(r1 - r0):
        row = np.int64(0)
        for j in range(c1 - c0):
            s = states[r0 + i, c0 + j]
            if s == 2:
                row += np.int64(1) << 32
            elif s == 1:
                row += 1
            out[i + 1, j + 1] = out[i, j + 1] + row
    return out


@njit(cache=True, nogil=True)
def _occupied_near(ms, ox0, oy0, res, cmx, cmy, half):
    """The centres about c_m (metres) of the occupied cells within ``half`` + one cell of it, row-major."""
    h, w = ms.shape
    xs = np.empty(h * w, np.float64)
    ys = np.empty(h * w, np.float64)
    n = 0
    for r in range(h):
        y = oy0 + (r + 0.5) * res - cmy
        if abs(y) > half + res:
            continue
        for c in range(w):
            if ms[r, c] == 2:
                x = ox0 + (c + 0.5) * res - cmx
                if abs(x) <= half + res:
                    xs[n] = x
                    ys[n] = y
                    n += 1
    return xs[:n].copy(), ys[:n].copy()


def occupied_centres(problem) -> tuple[np.ndarray, np.ndarray]:
    """The centres about c_m (metres, x and y) of the moving map's occupied cells within the ROI's half
    side + one cell of c_m, row-major: the cells a lattice point can read (kept per moving map)."""
    mov = problem.moving
    cm = (float(problem.center_moving[0]), float(problem.center_moving[1]))
    half = half_side(problem.n, problem.ref.resolution)
    return caches.moving_side(mov, ("occupied", cm, half), lambda: _occupied_near(
        np.ascontiguousarray(mov.states), float(mov.origin[0]), float(mov.origin[1]), float(mov.resolution),
        cm[0], cm[1], float(half)))


@njit(cache=True, nogil=True)
def _pool_level(qr, qc, s, wr_cell, wc_cell, skip_r, skip_c, rlo, clo):
    """The occupied cells (qr, qc) pooled in blocks of s × s cells, in (block row, block column) order:
    per block its first row and column, its count, the count × the most lattice rows × columns reading
    one of its cells, and 1 when no translation skips one of its rows or columns."""
    br0 = qr.min() // s
    bc0 = qc.min() // s
    nbr = qr.max() // s - br0 + 1
    nbc = qc.max() // s - bc0 + 1
    cnt = np.zeros(nbr * nbc, np.int64)
    wr = np.zeros(nbr * nbc, np.int64)
    wc = np.zeros(nbr * nbc, np.int64)
    for x in range(qr.size):
        b = (qr[x] // s - br0) * nbc + (qc[x] // s - bc0)
        cnt[b] += 1
        wr[b] = max(wr[b], wr_cell[qr[x] - rlo])
        wc[b] = max(wc[b], wc_cell[qc[x] - clo])
    out = np.empty((np.count_nonzero(cnt), 5), np.int64)
    n = 0
    for b in range(nbr * nbc):
        if cnt[b] == 0:
            continue
        r0 = (b // nbc + br0) * s
        c0 = (b % nbc + bc0) * s
        ok = 1
        for d in range(s):
            rr = r0 + d - rlo
            cc = c0 + d - clo
            if (0 <= rr < skip_r.size and skip_r[rr]) or (0 <= cc < skip_c.size and skip_c[cc]):
                ok = 0
        out[n, 0] = r0
        out[n, 1] = c0
        out[n, 2] = cnt[b]
        out[n, 3] = cnt[b] * wr[b] * wc[b]
        out[n, 4] = ok
        n += 1
    return out


def _reference_axes(ref, center_ref, n, k):
    """The lattice tables and both axes' bookkeeping: functions of the reference's geometry alone (its
    origin, resolution and size, the center, n and k), kept per geometry (a robot's center and map
    frame stay put while its map grows; never written to)."""
    key = (center_ref, float(ref.origin[0]), float(ref.origin[1]), float(ref.resolution), ref.width, ref.height,
           n, k)
    return caches.geometry(key, lambda: (
        ref_axes_numpy(ref, center_ref, n, k),
        _axis(axis_floor(center_ref[0], ref.origin[0], ref.resolution, n, k), ref.width),
        _axis(axis_floor(center_ref[1], ref.origin[1], ref.resolution, n, k), ref.height)))


class Prepared:
    """The arrays of one problem (see the module documentation). ``k``: the window in cells."""

    def __init__(self, problem, k: int | None = None) -> None:
        ref, mov = problem.ref, problem.moving
        self.problem = problem
        self.measure = measure(problem.measure)
        self.floor = int(problem.min_support)  # the support floor (measures.value_of)
        self.k = problem.window_cells if k is None else k
        self.n = n = problem.n
        self.res = ref.resolution
        side = 2 * self.k + 1
        self.side = side
        (self.cols, self.rows), ax_c, ax_r = _reference_axes(ref, tuple(map(float, problem.center_ref)), n, self.k)
        self.ref = np.ascontiguousarray(ref.states)
        self.empty_ref = ax_c is None or ax_r is None
        if self.empty_ref:  # no translation reads any reference cell: a dummy axis, no occupied cells
            ax_c = ax_r = (0, 0, 0, 0, 1, np.zeros((side, 1), np.int64), np.zeros((side, 1), np.int64),
                           np.ones(1, np.int64), np.zeros(1, np.bool_))
        clo, chi, cbase, cdev, cmult, self.jlo, self.jhi, self._wc, self._skip_c = ax_c
        rlo, rhi, rbase, rdev, rmult, self.ilo, self.ihi, self._wr, self._skip_r = ax_r
        self.axes_c = np.array([cbase, cdev, cmult, clo], np.int64)
        self.axes_r = np.array([rbase, rdev, rmult, rlo], np.int64)
        self._last = (int(rhi), int(chi))  # the last reference row and column some translation reads
        # the reference side: a function of the reference map, its center, n, k and the measure's sums alone,
        # kept per reference map (a map version is the reference of up to N − 1 pairs, each searched and then
        # re-verified locally: in the 16-robot hall these arrays were 3% of the run)
        (self.qr, self.qc, self.blk, self.blkf, self.lvl_start, self.ref_sat, self.wr0, self.wc0,
         self.tsum) = caches.reference_side(ref, (tuple(map(float, problem.center_ref)), n, self.k,
                                                  self.measure.sums), self._reference_side)
        ms = np.ascontiguousarray(mov.states)
        self.mstates = ms
        half = half_side(n, self.res)
        cm = (float(problem.center_moving[0]), float(problem.center_moving[1]))
        self.cls_sat = caches.moving_side(mov, ("sat",), lambda: class_sat(ms, 0, ms.shape[0], 0, ms.shape[1]))
        self.occ_x, self.occ_y = occupied_centres(problem)
        self.rank = rank_table(self.k)
        self.half = half
        ms_ = self.measure
        self.tables = Tables(
            int(n), int(self.k), int(side), float(self.res), float(mov.resolution), float(mov.origin[0]),
            float(mov.origin[1]), cm[0], cm[1], float(half), int(ms_.code), self.floor, bool(ms_.needs_free_agree),
            int(ms_.sums), self.ref, self.cols, self.rows, int(rlo), int(clo), self.ilo, self.ihi, self.jlo, self.jhi,
            self.axes_r, self.axes_c, self.qr, self.qc, self.blk, self.blkf, self.lvl_start, self.wr0, self.wc0,
            self.ref_sat, ms, self.cls_sat, self.occ_x, self.occ_y, self.tsum)

    @property
    def moving_key(self) -> tuple:
        """The moving side's geometry (resolution, origin, center, half side): a key of its cached arrays."""
        t = self.tables
        return (t.res_m, t.mox, t.moy, t.mcx, t.mcy, t.half)

    def _reference_side(self) -> tuple:
        """The reference side's arrays (never written to): its occupied cells that a translation reads (qr, qc), their
        blocks (:meth:`_blocks`), the readable cells' class summed-area table, the per-translation read counts
        of each occupied cell (wr0, wc0) and the count table per translation (:meth:`_tsum`)."""
        rlo, clo = int(self.axes_r[3]), int(self.axes_c[3])
        rhi, chi = self._last
        if self.empty_ref:
            self.qr = self.qc = np.zeros(0, np.int64)
        else:
            qr, qc = np.nonzero(self.ref[rlo:rhi + 1, clo:chi + 1] == OCCUPIED_S)
            self.qr, self.qc = qr.astype(np.int64) + rlo, qc.astype(np.int64) + clo
        blk, lvl_start, blkf = self._blocks()
        # the readable reference cells' (occupied << 32 | free) summed-area table (the moving side's bound)
        # (rotation only: no box of translations, never read)
        ref_sat = class_sat(self.ref, rlo, rhi + 1, clo, chi + 1) if self.k > 0 and not self.empty_ref \
            else np.zeros((2, 2), np.int64)
        # per translation, how many lattice rows (columns) read each occupied cell: exact weights of small
        # boxes when the ROI is not a plain block (Lemma 3)
        wr0 = np.ascontiguousarray((self.ihi - self.ilo)[:, self.qr - rlo].astype(np.int8))
        wc0 = np.ascontiguousarray((self.jhi - self.jlo)[:, self.qc - clo].astype(np.int8))
        return self.qr, self.qc, blk, blkf, lvl_start, ref_sat, wr0, wc0, self._tsum()

    def _blocks(self):
        """The occupied cells pooled in blocks of 2^l cells, levels 0..LEVELS−1: per block its first row
        and column, its count, the count weighted by the most lattice points reading one of its cells
        (Lemma 3: a bound on agr̃), and 1 when no translation skips one of its rows or columns."""
        parts, starts = [], [0]
        rlo, clo = int(self.axes_r[3]), int(self.axes_c[3])
        levels = 1 if self.k == 0 else LEVELS  # rotation only: the regions are thin (polar.py seeds them)
        for level in range(levels):
            s = 1 << level
            if self.qr.size:
                part = _pool_level(self.qr, self.qc, s, self._wr, self._wc, self._skip_r, self._skip_c, rlo, clo)
            else:
                part = np.zeros((0, 5), np.int64)
            parts.append(part.astype(np.int64))
            starts.append(starts[-1] + part.shape[0])
        blk = np.ascontiguousarray(np.concatenate(parts))
        # per block, its center's lattice coordinates at translation index (0, 0) and their norm (metres)
        half = (blk[:, 2:3] * 0 + (1 << np.repeat(np.arange(levels), np.diff(starts)))[:, None] - 1) / 2.0
        m = (self.n - 1) / 2.0
        bx = ((blk[:, 1:2] + half - self.axes_c[0]) - m) * self.res
        by = ((blk[:, 0:1] + half - self.axes_r[0]) - m) * self.res
        blkf = np.ascontiguousarray(np.concatenate([bx, by, np.hypot(bx, by)], axis=1).astype(np.float64))
        return blk, np.array(starts, np.int64), blkf

    def _tsum(self) -> np.ndarray:
        """Per translation (b·side + a): the reference ROI's occupied (NCC) or free (Birk–Carpin) points."""
        kind = self.measure.sums
        if not kind or self.empty_ref:
            return np.zeros(self.side * self.side, np.int64)
        state = OCCUPIED_S if kind == OCCUPIED_SUMS else FREE_S
        rlo, clo = int(self.axes_r[3]), int(self.axes_c[3])
        # the ROI at (a, b) reads cell (r, c) (ihi − ilo)[b, r] · (jhi − jlo)[a, c] times
        nr = (self.ihi - self.ilo).astype(np.float64)
        nc = (self.jhi - self.jlo).astype(np.float64)
        block = self.ref[rlo:rlo + nr.shape[1], clo:clo + nc.shape[1]] == state
        table = nr @ block.astype(np.float64) @ nc.T  # exact integers (< 2^53)
        return np.rint(table).astype(np.int64).reshape(-1)
