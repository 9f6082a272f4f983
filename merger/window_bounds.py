"""The certificate of the windowed fast search: true upper bounds over (angle, box of translations), and
the branch and bound that makes :func:`merger.window.fast_window_search` return exactly the reference's
grid answer.

* :class:`BoxBounds` — upper bounds of the coarse values at all 360 angles over a box of translations:
  :mod:`merger.fast`'s sector bounds about the box's center, the moving map's sector classes grown by
  the box's displacement radius;
* :class:`Certifier` — the branch and bound: sector bounds per box of 3 × 3 translations, then per
  surviving angle its exact rotated ROI with the reference pooled over each surviving box, and exact
  values (:class:`merger.window.WindowEvaluator`) wherever a bound cannot exclude the region.

The argument why each bound holds, and why the result is the reference's answer, ties and plateaus
included, is in :mod:`merger.window`'s documentation.
"""

from __future__ import annotations

import math
import threading

import cv2
import numpy as np
import scipy.fft as sfft

from .fast import SectorBounds, _corr, _hist, _Inexact, _ncc_upper, _row_spectra, sector_grain, sector_layout
from .grid import FREE_S, OCCUPIED_S
from .sparse import ncc_from_sums

SECTOR_HALF = 1  # the sector stage's boxes: 3 × 3 translations (fewer boxes leave many more angles)
BOX_CHUNK = 16  # sector boxes whose histograms share one FFT
_GROW_SLACK = 1e-7  # cells added to a box's displacement radius (≫ every rounding error of the lookups)
_BUF = threading.local()  # a reused histogram buffer per thread (a fresh multi-MB array per group costs page faults)


def _zeroed(size: int) -> np.ndarray:
    """A zeroed float64 array of ``size`` from this thread's reused buffer (grown as needed)."""
    buf = getattr(_BUF, "hist", None)
    if buf is None or buf.size < size:
        buf = _BUF.hist = np.empty(max(size, 1 << 20))
    out = buf[:size]
    out.fill(0.0)
    return out


class BoxBounds:
    """Upper bounds of v(θ, t) for θ = 0°, 1°, …, 359° and t in a box of translations, for one windowed
    problem (its :class:`merger.window.WindowEvaluator` ``ev`` supplies the reference's ROI geometry).

    A box is ``(a_c, b_c, s_a, s_b)``: translations (a, b) cells with |a − a_c| ≤ s_a, |b − b_c| ≤ s_b.
    """

    def __init__(self, problem, ev) -> None:
        self.problem, self.ev = problem, ev
        n, k = problem.n, problem.window_cells
        self.n, self.k, self.res = n, k, problem.ref.resolution
        self.big = big = n + 2 * k  # the lattice of the whole window about its center (parity of n)
        self.lay = sector_layout(big, self.res, sector_grain(n))
        self.measure = problem.measure
        self._mov: dict[float, dict] = {}
        self._single = None  # ((a, b), the reference ROI of that single translation): the last one read
        self._loose_cache: dict = {}  # box -> its geometry when its ROIs are not plain blocks (_loose)
        (cols_t, cb, cf, _), (rows_t, rb, rf, _) = ev._axes_table()
        self.reach = ev.reach
        self.cb, self.cf, self.rb, self.rf = cb, cf, rb, rf
        self._steps = []
        for blk, first in ((cb, cf), (rb, rf)):
            g = np.zeros(blk.size, np.int64)
            g[1:] = blk[1:] & blk[:-1] & (np.diff(first) == 1)
            self._steps.append((blk.tolist(), np.concatenate([[0], np.cumsum(g)]).tolist()))
        pad = ev._pad
        # the padded reference's cells that any box's union of ROIs can hold
        r0, r1 = int(rf.min()) - k, int(rf.max()) + n + k
        c0, c1 = int(cf.min()) - k, int(cf.max()) + n + k
        hp, wp = pad.shape
        sub = pad[max(r0, 0):max(min(r1, hp), 0), max(c0, 0):max(min(c1, wp), 0)]
        oy, ox = max(r0, 0), max(c0, 0)
        r, c = np.nonzero(sub == OCCUPIED_S)
        self.occ = (r + oy, c + ox)
        if self.measure == "birk_carpin":
            r, c = np.nonzero(sub == FREE_S)
            self.free = (r + oy, c + ox)
        if self.measure == "ncc":
            # Σy does not depend on t: bounds from the ROI lattice (the big layout's central block)
            i, j = np.divmod(np.arange(n * n), n)
            allp = (i + k) * big + (j + k)
            self._n_all = _row_spectra(self.lay, _hist(self.lay, allp))
            # Σx(t) = the reference-occupied cells of ROI(t), exactly: a summed-area table of the padded grid
            occ = (pad == OCCUPIED_S).astype(np.int64)
            self._sat = np.zeros((hp + 1, wp + 1), np.int64)
            self._sat[1:, 1:] = occ.cumsum(0).cumsum(1)

    # --- the moving map's sector classes, grown by a displacement radius -------------------------------
    def _moving(self, grow_cells: float) -> dict:
        key = float(grow_cells)
        hit = self._mov.get(key)
        if hit is None:
            sb = SectorBounds.__new__(SectorBounds)
            sb.lay, sb.measure, sb.problem = self.lay, self.measure, self.problem
            sb.grow = (grow_cells + _GROW_SLACK) * self.res if grow_cells > 0 else 0.0
            hit = self._mov[key] = sb._moving_sectors(self.problem)
        return hit

    # --- the reference side -----------------------------------------------------------------------------
    def consistent(self, box) -> bool:
        """Whether every ROI of the box is a plain block of the padded reference, each one cell on from
        the previous (then the box's ROIs are sub-blocks of one lattice)."""
        a_c, b_c, s_a, s_b = box
        return self.consistent_rect(a_c - s_a, a_c + s_a, b_c - s_b, b_c + s_b)

    def consistent_rect(self, a0: int, a1: int, b0: int, b1: int) -> bool:
        """:meth:`consistent` of the box [a0, a1] × [b0, b1] (prefix counts of the translation indices
        whose block continues the previous one by one cell)."""
        kk = self.reach
        for lo, hi, (blk, cum) in ((a0 + kk, a1 + kk, self._steps[0]), (b0 + kk, b1 + kk, self._steps[1])):
            if not blk[lo] or cum[hi + 1] - cum[lo + 1] != hi - lo:
                return False
        return True

    def boundable(self, box) -> bool:
        """Whether the sector stage bounds the box: a consistent one, a single translation (its ROI, a
        plain block or not, is then the lattice itself: :meth:`_single_roi`), or a box whose ROIs are not
        plain blocks but whose cells all fit the big lattice (:meth:`_loose`)."""
        return (box[2] == 0 and box[3] == 0) or self.consistent(box) or self._loose(box) is not None

    def grow_of(self, box) -> float:
        """The displacement radius (cells) of a boundable box's sector bounds: ‖(s_a, s_b)‖ for a
        consistent box, 0 for a single translation, the measured one of a loose box (:meth:`_loose`)."""
        a_c, b_c, s_a, s_b = box
        if s_a == 0 and s_b == 0:
            return 0.0
        if self.consistent(box):
            return math.hypot(s_a, s_b)
        loose = self._loose(box)
        if loose is None:
            raise ValueError(f"box {box} has no sector bound: cut it into single translations")
        return loose["grow"]

    def _loose(self, box):
        """A box of translations whose ROIs are not plain blocks (centers on cell borders: a ROI reads
        some reference row or column twice and skips another), bounded as a box all the same.

        Per axis (rows; columns alike), translation b of the box reads padded rows R_b[i], i = 0..n−1.
        Place padded row r at big-lattice row pos(r) = r − (rf(b_c) − K), as for a consistent box. Lattice
        row i of translation b sits at big row p = i + K + (b − b_c) (its offset from c_ref + t is
        kbig[p] − δ), and the cell it reads sits at pos(R_b[i]) = p + dev_b(i). So its lookup offset is
        kbig[pos] − (dev_b(i) + δ)·cell: within ρ' = ‖(max |dev + δ_b|, max |dev + δ_a|)‖ cells of the
        cell's own position — the consistent box's argument with ρ replaced by ρ'. A cell read at
        translation t by several lattice points (a repeated row or column) counts that many times in
        agr̃ (and free/free): the union's cells are weighted by the largest such number over the box
        (row count × column count). The intersection (cells every ROI of the box reads: the rows all the
        R_b hold × the columns all the C_a hold) counts once per cell — distinct cells are read by
        distinct lattice points — which bounds dis from below. None when a cell's position falls off the
        big lattice (then the box is cut into single translations)."""
        key = tuple(box)
        if key in self._loose_cache:
            return self._loose_cache[key]
        a_c, b_c, s_a, s_b = box
        kk, k, big = self.reach, self.k, self.big
        (cols_t, _, _, _), (rows_t, _, _, _) = self.ev._axes_table()
        out = {}
        for name, tab, first, c, s in (("r", rows_t, self.rf, b_c, s_b), ("c", cols_t, self.cf, a_c, s_a)):
            base = int(first[c + kk]) - k
            sub = tab[c - s + kk:c + s + kk + 1]  # (2s + 1, n): the padded rows of each translation
            p = np.arange(self.n)[None, :] + k + np.arange(-s, s + 1)[:, None]  # the lattice rows' big rows
            pos = sub - base
            if pos.min() < 0 or pos.max() >= big:
                self._loose_cache[key] = None
                return None
            disp = int(np.abs(pos - p + np.arange(-s, s + 1)[:, None]).max())  # max |dev + δ|
            lo = int(sub.min())
            mult = np.zeros((sub.shape[0], int(sub.max()) - lo + 1), np.int64)
            np.add.at(mult, (np.repeat(np.arange(sub.shape[0]), self.n), (sub - lo).reshape(-1)), 1)
            out[name] = (base, lo, mult.max(axis=0), (mult > 0).all(axis=0), disp)
        out["grow"] = math.hypot(out["r"][4], out["c"][4])
        self._loose_cache[key] = out
        return out

    def _loose_ids(self, pts, box, inner: bool):
        """(big-layout ids, weights) of the reference cells ``pts`` in a loose box's union (weighted by
        their largest read count) or intersection (weight 1): :meth:`_loose`."""
        g = self._loose(box)
        keep = np.ones(pts[0].size, bool)
        w = np.ones(pts[0].size)
        for v, (_, lo, mult, every, _) in zip(pts, (g["r"], g["c"]), strict=True):
            j = v - lo
            ok = (j >= 0) & (j < mult.size)
            jj = np.where(ok, j, 0)
            keep &= ok & (every[jj] if inner else mult[jj] > 0)
            w *= mult[jj]
        rr, cc = pts[0][keep] - g["r"][0], pts[1][keep] - g["c"][0]
        return rr * self.big + cc, (None if inner else w[keep])

    def _single_roi(self, a: int, b: int) -> np.ndarray:
        """The reference ROI at translation (a, b) cells, as the reference reads it (per-axis indices
        into the padded reference: :meth:`merger.window.WindowEvaluator._axis`); the last one is kept (a
        box's classes are read one after the other; keeping all would cost n² bytes per translation)."""
        if self._single is None or self._single[0] != (a, b):
            rows, cols, _ = self.ev._axis(a, b)
            self._single = ((a, b), self.ev._pad[np.ix_(rows, cols)])
        return self._single[1]

    def _box_ids(self, pts, box, inner: bool):
        """(big-layout sector ids, weights or None for 1) of the reference cells ``pts`` in a boundable
        box's union of ROIs (``inner``: in their intersection): :meth:`_ids` for a consistent box, the
        lattice points of its own ROI for a single translation, :meth:`_loose_ids` for a loose box."""
        a_c, b_c, s_a, s_b = box
        if self.consistent(box):
            return self._ids(pts, box, inner), None
        if s_a == 0 and s_b == 0:
            # one translation whose ROI is not a plain block: its lattice points of the class of ``pts``
            # (union = intersection = the ROI), the central n × n block of the big lattice about c_ref + t
            i, j = np.nonzero(self._single_roi(a_c, b_c) == (OCCUPIED_S if pts is self.occ else FREE_S))
            return (i + self.k) * self.big + (j + self.k), None
        return self._loose_ids(pts, box, inner)

    def _ids(self, pts, box, inner: bool):
        """Big-layout sector ids of the reference cells ``pts`` in a consistent box's union of ROIs
        (``inner``: in the intersection of its ROIs), placed about the box's center."""
        a_c, b_c, s_a, s_b = box
        kk, n, k = self.reach, self.n, self.k
        rr = pts[0] - (int(self.rf[b_c + kk]) - k)  # rows of the big lattice about c_ref + t_c
        cc = pts[1] - (int(self.cf[a_c + kk]) - k)
        if inner:
            ok = (rr >= k + s_b) & (rr < k + n - s_b) & (cc >= k + s_a) & (cc < k + n - s_a)
        else:
            ok = (rr >= k - s_b) & (rr < k + n + s_b) & (cc >= k - s_a) & (cc < k + n + s_a)
        return rr[ok] * self.big + cc[ok]

    def _hist_spec(self, ids_list):
        return _row_spectra(self.lay, np.stack([_hist(self.lay, ids) for ids in ids_list]))

    def sx_values(self, a0: int, a1: int, b0: int, b1: int) -> np.ndarray:
        """The distinct values over a boundable box [a0, a1] × [b0, b1] of Σx(t), the reference-occupied
        lattice points of ROI(t) (NCC), exactly: a summed-area table of the padded reference for a
        consistent box; otherwise, per translation, each occupied cell times the lattice points that read
        it (:meth:`merger.window.WindowEvaluator._inverse_axes`)."""
        kk, n = self.reach, self.n
        if not self.consistent_rect(a0, a1, b0, b1):
            rf0, rl0, cf0, cl0 = self.ev._inverse_axes()
            qr, qc = self.ev._q_rc
            mr = rl0[np.arange(b0, b1 + 1) + kk][:, qr] - rf0[np.arange(b0, b1 + 1) + kk][:, qr]
            mc = cl0[np.arange(a0, a1 + 1) + kk][:, qc] - cf0[np.arange(a0, a1 + 1) + kk][:, qc]
            return np.unique(mr @ mc.T)
        r = self.rf[np.arange(b0, b1 + 1) + kk].astype(np.intp)
        c = self.cf[np.arange(a0, a1 + 1) + kk].astype(np.intp)
        sat = self._sat
        v = sat[r[:, None] + n, c[None, :] + n] - sat[r[:, None], c[None, :] + n] \
            - sat[r[:, None] + n, c[None, :]] + sat[r[:, None], c[None, :]]
        return np.unique(v)

    def bounds_many(self, boxes: list) -> list[np.ndarray]:
        """Upper bounds of max_{t in box} v(θ, t) for θ = 0..359, for each (consistent) box: the
        histograms of boxes with the same half-sides in one pass, one FFT, one product (no bound — +inf —
        if a correlation does not come out integral: never seen)."""
        out: list = [None] * len(boxes)
        groups: dict = {}
        for i, box in enumerate(boxes):
            groups.setdefault(self.grow_of(box), []).append(i)
        for grow, members in groups.items():
            for c0 in range(0, len(members), BOX_CHUNK):
                part = members[c0:c0 + BOX_CHUNK]
                try:
                    vals = self._bounds_group([boxes[i] for i in part], grow)
                except _Inexact:
                    vals = np.full((len(part), 360), np.inf)
                for i, v in zip(part, vals, strict=True):
                    out[i] = v
        return out

    def _bounds_group(self, boxes: list, grow: float) -> np.ndarray:
        lay, m = self.lay, self.measure
        mov = self._moving(grow)
        size = lay.rows * 360
        nb = len(boxes)
        kinds = [(self.occ, False)] + ([] if m == "ncc" else [(self.occ, True)])
        if m == "birk_carpin":
            kinds += [(self.free, False), (self.free, True)]
        nk = len(kinds)
        ids, weights = [], []
        for box in boxes:
            for pts, inner in kinds:
                i, w = self._box_ids(pts, box, inner)
                ids.append(i)
                weights.append(np.ones(i.size) if w is None else w)
        offs = np.repeat(np.arange(nb * nk) * size, [x.size for x in ids])
        allids = np.concatenate(ids) if ids else np.empty(0, np.intp)
        hist = _zeroed(nb * nk * size)  # counts, exact in float64
        np.add.at(hist, lay.lattice_row_id.take(allids) + offs, np.concatenate(weights) if weights else 1.0)
        spec = sfft.rfft(hist.reshape(nb, nk, lay.rows, 360), axis=-1)

        def corr(j, name):
            x = sfft.irfft(np.einsum("brk,rk->bk", spec[:, j], np.conj(mov[name])), n=360, axis=-1)
            r = np.rint(x)
            if not np.abs(x - r).max(initial=0.0) < 0.1:
                raise _Inexact
            return r

        a = corr(0, "may_occ")
        if m == "ncc":
            m0 = self._moving(0.0)
            y_hi = _corr(self._n_all, m0["may_occ"])
            y_lo = _corr(self._n_all, m0["sure_occ"]) if "sure_occ" in m0 else np.zeros(360)
            out = np.zeros((nb, 360))
            for i, (a_c, b_c, s_a, s_b) in enumerate(boxes):
                for sx in self.sx_values(a_c - s_a, a_c + s_a, b_c - s_b, b_c + s_b).tolist():
                    np.maximum(out[i], _ncc_upper(a[i], y_lo, y_hi, self.n * self.n, int(sx)), out=out[i])
            return out
        d = corr(1, "sure_free")
        if m == "birk_carpin":
            if "sure_occ" in mov:
                d = d + corr(3, "sure_occ")
            a = a + corr(2, "may_free")
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(a > 0, a / (a + d), 0.0)

    def bounds(self, box) -> np.ndarray:
        """:meth:`bounds_many` of one box."""
        return self.bounds_many([box])[0]


# --- branch and bound over (angle, box of translations) -------------------------------------------
def odd_parts(lo: int, hi: int, size: int) -> list[tuple[int, int]]:
    """[lo, hi] (an odd number of cells) cut into an odd number of consecutive runs of odd lengths, at
    most ``size`` long where possible, as (center, half-length) pairs."""
    length = hi - lo + 1
    m = min(max(1, -(-length // size)) | 1, length)  # odd: odd lengths summing to an odd total
    sizes = [1] * m
    for i in range((length - m) // 2):
        sizes[i % m] += 2
    sizes.sort(key=lambda x: -x)  # longest first, then keep the runs symmetric about the middle
    order = sorted(range(m), key=lambda i: abs(i - m // 2), reverse=True)
    lengths = [0] * m
    for i, x in zip(order, sizes, strict=True):
        lengths[i] = x
    out, a = [], lo
    for x in lengths:
        out.append((a + x // 2, x // 2))
        a += x
    return out


class Certifier:
    """Branch and bound over (coarse angle, box of translations) for a windowed problem: the best grid
    alignment in the reference's order, exactly (see :mod:`merger.window`, "exact by construction").

    ``rank`` is the reference's tie order over translations (``(2K+1, 2K+1)`` by (b + K, a + K)); with
    ``use_rank=False`` ties go to the smallest angle only (the runner-up's order). Every exact value comes
    from the evaluator ``ev``; bounds prune only where they show that a region cannot beat — or tie in
    the order — the best alignment evaluated so far (the *incumbent*).
    """

    def __init__(self, problem, ev, rank: np.ndarray) -> None:
        self.problem, self.ev, self.rank = problem, ev, rank
        self.k = problem.window_cells
        self.n = problem.n
        self.sectors = BoxBounds(problem, ev)
        self._sector_cache: dict = {}
        self._pooled: dict = {}
        self._free_pts: dict = {}
        self._rects: dict = {}
        ev._occupied_cells()
        self.env = np.full(360, -np.inf)  # per angle: an upper bound of the best value (the profile)
        self.stats = {"sector_boxes": 0, "angles": 0, "boxes": 0, "leaves": 0}

    # --- keys: (value, −rank, −θ), compared as tuples ----------------------------------------------
    def _minrank(self, a0, a1, b0, b1) -> int:
        k = self.k
        return int(self.rank[b0 + k:b1 + k + 1, a0 + k:a1 + k + 1].min()) if self.use_rank else 0

    def _can_win(self, ub, r, theta) -> np.ndarray:
        """Whether a region whose values are ≤ ``ub`` (per angle ``theta``) and whose translations rank at
        best ``r`` may hold an alignment that comes before the incumbent in the reference's order (and
        reaches the floor)."""
        v, nr, nth = self.best[0]
        win = (ub > v) | ((ub == v) & ((-r > nr) | ((-r == nr) & (-np.asarray(theta) > nth))))
        return win & (ub >= self.floor)

    def _wins(self, ub: float, r: int, theta: int) -> bool:
        """:meth:`_can_win` for one region (Python scalars)."""
        return ub >= self.floor and (ub, -r, -theta) > self.best[0]

    def _offer(self, theta: int, a, b, vals) -> None:
        """Exact values at (θ, (a[i], b[i])): the incumbent becomes the best of them if it comes first."""
        k = self.k
        vals = np.asarray(vals, np.float64)
        np.maximum.at(self.env, theta, vals.max(initial=-np.inf))
        r = self.rank[np.asarray(b) + k, np.asarray(a) + k] if self.use_rank else np.zeros(len(vals), np.int64)
        j = int(np.lexsort((r, -vals))[0])
        key = (float(vals[j]), -int(r[j]), -int(theta))
        if key > self.best[0]:
            self.best = (key, int(theta), (int(a[j]), int(b[j])))

    # --- stage A: sector bounds for all angles over boxes of translations --------------------------
    def _sectors(self, boxes: list) -> list[np.ndarray]:
        """Sector bounds of the boxes (kept: the runner-up's search reuses them); +inf where a box has
        none (neither consistent nor a single translation — :meth:`run` cuts those — or a correlation
        that did not come out integral)."""
        todo = [b for b in dict.fromkeys(boxes) if b not in self._sector_cache]
        ok = [b for b in todo if self.sectors.boundable(b)]
        for b, v in zip(ok, self.sectors.bounds_many(ok), strict=True):
            self._sector_cache[b] = v
        self.stats["sector_boxes"] += len(ok)
        for b in todo:
            self._sector_cache.setdefault(b, np.full(360, np.inf))
        return [self._sector_cache[b] for b in boxes]

    def run(self, best, allowed: np.ndarray | None = None, use_rank: bool = True, floor: float = -np.inf):
        """The best (key, θ, (a, b)) over the allowed coarse angles and every translation, starting from
        the incumbent ``best`` = (key, θ, t) (an exact evaluation, or key (−inf, 0, 0) with θ, t None).

        With a ``floor`` the search skips every region whose bound is below it: the answer is exact when
        its value reaches the floor; otherwise every value is below the floor and the answer is only the
        best one evaluated."""
        self.best, self.use_rank, self.floor = best, use_rank, floor
        allowed = np.ones(360, bool) if allowed is None else allowed
        k = self.k
        thetas = np.arange(360)
        todo: dict[int, list] = {}  # angle -> boxes (a0, a1, b0, b1) to search with its exact rotation
        top: dict[int, float] = {}
        parts = odd_parts(-k, k, 2 * SECTOR_HALF + 1)
        boxes = []
        for box in [(ac, bc, sa, sb) for bc, sb in parts for ac, sa in parts]:
            a_c, b_c, s_a, s_b = box
            if (s_a or s_b) and not self.sectors.boundable(box):  # (float ties in the lattice) one by one
                boxes += [(a, b, 0, 0) for b in range(b_c - s_b, b_c + s_b + 1) for a in range(a_c - s_a, a_c + s_a + 1)]
            else:
                boxes.append(box)
        for box, ub in zip(boxes, self._sectors(boxes), strict=True):
            a_c, b_c, s_a, s_b = box
            rect = (a_c - s_a, a_c + s_a, b_c - s_b, b_c + s_b)
            alive = allowed & self._can_win(ub, self._minrank(*rect), thetas)
            dead = allowed & ~alive
            self.env[dead] = np.maximum(self.env[dead], ub[dead])
            for th in np.flatnonzero(alive).tolist():
                todo.setdefault(th, []).append(rect)
                top[th] = max(top.get(th, -np.inf), float(ub[th]))
        # --- stage B: per angle, its exact rotated ROI and pooled references over the boxes ---------
        for th in sorted(todo, key=lambda t: -top[t]):
            self._angle(th, todo[th])
        return self.best

    # --- stage B: translation boxes at one angle, Cartographer's bounds -----------------------------
    def _pool(self, hb: int, ha: int):
        """The padded reference pooled over every offset of an hb × ha box of translations (first block
        corner at the cell): max of occupied (and of free), min of free and of occupied (as cells of the
        evaluator's reference-occupied image)."""
        key = (hb, ha)
        hit = self._pooled.get(key)
        if hit is None:
            ev = self.ev
            pad = ev._pad
            kern = np.ones((hb, ha), np.uint8)
            occ = (pad == OCCUPIED_S).view(np.uint8)
            free = (pad == FREE_S).view(np.uint8)

            def dil(x):
                return cv2.dilate(x, kern, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT, borderValue=0)

            def ero(x):
                return cv2.erode(x, kern, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT, borderValue=0)

            max_occ = dil(occ).reshape(-1).astype(bool)
            min_free = ero(free).reshape(-1).astype(bool)
            max_free = dil(free).reshape(-1).astype(bool) if self.problem.measure == "birk_carpin" else None
            # cells occupied for every offset, in the evaluator's moving-free image coordinates
            min_occ = ero(occ)
            (_, _, cf, _), (_, _, rf, _) = ev._axes_table()
            n, m = self.n, ev._margin
            r0, r1 = int(rf.min()), int(rf.max()) + n
            c0, c1 = int(cf.min()), int(cf.max()) + n
            hp, wp = pad.shape
            sub = min_occ[max(r0, 0):max(min(r1, hp), 0), max(c0, 0):max(min(c1, wp), 0)]
            qr, qc = np.nonzero(sub)
            q = (qr + max(r0, 0)) * (n + 2 * m) + (qc + max(c0, 0))
            hit = self._pooled[key] = (max_occ, min_free, max_free, q)
        return hit

    def _consistent(self, a0, a1, b0, b1) -> bool:
        return self.sectors.consistent_rect(a0, a1, b0, b1)

    def _rect_bounds(self, theta: float, rects: list) -> np.ndarray:
        """Upper bounds of v(θ, t) over each consistent box of ``rects``, with θ's rotated ROI (the pooled
        references gathered at the moving-occupied lattice points, and so on: see :mod:`merger.window`;
        for ω̃ bounds of the rotated states, :meth:`merger.window.WindowEvaluator.moving_bounds`)."""
        ev, s = self.ev, self.sectors
        kk, n, m = s.reach, self.n, ev._margin
        wp, w = ev._pad.shape[1], n + 2 * ev._margin
        measure = self.problem.measure
        if measure == "similarity":  # may-occupied points for agr̃, surely occupied / free ones for dis
            p_may, pflat, mfp = ev.moving_bounds(theta)
        else:
            (_, _, pflat), mfp, mov = ev._mov[theta]
            p_may = pflat
        out = np.empty(len(rects))
        groups: dict = {}
        for i, (a0, a1, b0, b1) in enumerate(rects):
            groups.setdefault((b1 - b0 + 1, a1 - a0 + 1), []).append(i)
        for (hb, ha), members in groups.items():
            max_occ, min_free, max_free, q = self._pool(hb, ha)
            rr = np.array([rects[i] for i in members], np.intp)
            r = s.rf[rr[:, 2] + kk].astype(np.intp)
            c = s.cf[rr[:, 0] + kk].astype(np.intp)
            base = r * wp + c
            agr = np.count_nonzero(max_occ[base[:, None] + p_may[None, :]], axis=1)
            idx = base[:, None] + pflat[None, :]
            if measure == "ncc":
                sy = float(pflat.size)
                for j, i in enumerate(members):
                    a0, a1, b0, b1 = rects[i]
                    out[i] = max(ncc_from_sums(n * n, float(sx), sy, float(agr[j]))
                                 for sx in s.sx_values(a0, a1, b0, b1).tolist())
                continue
            dis = np.count_nonzero(min_free[idx], axis=1)
            if q.size:
                dis += np.count_nonzero(mfp[q[None, :] - ((r - m) * w + (c - m))[:, None]], axis=1)
            if measure == "birk_carpin":
                fp = self._free_pts.get(theta)
                if fp is None:
                    fi, fj = np.divmod(np.flatnonzero(mov == FREE_S), n)
                    fp = self._free_pts[theta] = fi * wp + fj
                agr = agr + np.count_nonzero(max_free[base[:, None] + fp[None, :]], axis=1)
            # the floats of index_from_counts (integer counts, one correctly rounded division)
            out[members] = [a / (a + d) if a + d else 0.0 for a, d in zip(agr.tolist(), dis.tolist(), strict=True)]
        return out

    def _angle(self, th: int, rects) -> None:
        """Every translation of the boxes ``rects`` at the coarse angle θ: each box is bounded with θ's
        rotated ROI (for ω̃ bounds of its states, no certified rotation), and its translations are
        evaluated exactly (with the exact rotated ROI) unless the bound excludes them."""
        theta = float(th)
        if self.problem.measure != "similarity":  # ω̃'s box bounds need only bound classes (moving_bounds)
            self.ev.moving([theta])
        self.stats["angles"] += 1
        info = [self._rect_info(r) for r in rects]
        ok = [i for i, x in enumerate(info) if x[0]]
        keep = [i for i, x in enumerate(info) if not x[0]]  # (float ties in the lattice) no bound
        if ok:
            ub = self._rect_bounds(theta, [rects[i] for i in ok])
            self.stats["boxes"] += len(ok)
            for i, u in zip(ok, ub.tolist(), strict=True):
                if self._wins(u, info[i][1] if self.use_rank else 0, th):
                    keep.append(i)
                elif u > self.env[th]:
                    self.env[th] = u
        if keep:
            a = np.concatenate([info[i][2] for i in keep])
            b = np.concatenate([info[i][3] for i in keep])
            self.stats["leaves"] += a.size
            self._offer(th, a, b, self.ev.evaluate_ab(theta, a, b))

    def _rect_info(self, rect):
        """(consistent, smallest rank, translations a, translations b) of a box (kept)."""
        hit = self._rects.get(rect)
        if hit is None:
            a0, a1, b0, b1 = rect
            k = self.k
            a, b = np.meshgrid(np.arange(a0, a1 + 1), np.arange(b0, b1 + 1))
            hit = self._rects[rect] = (self._consistent(*rect), int(self.rank[b0 + k:b1 + k + 1, a0 + k:a1 + k + 1].min()),
                                       a.reshape(-1), b.reshape(-1))
        return hit
