"""One problem's searcher: its prepared arrays, the moving ROIs computed so far, and every question a
search asks of them — a branch and bound (:meth:`Searcher.run`), exact values, the polar bounds.

A searcher is a pure function of its problem (kept per problem object by :mod:`merger.caches`); one
search runs at a time on it (a lock: its ROI slots are shared).
"""

from __future__ import annotations

import math
import threading
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from .. import caches
from ..lattice import rotation_entries
from ..measures import Counts, uppers
from .bnb import INCUMBENT, Query, Work, branch_and_bound
from .counts import (
    exact_counts,
    fill_moving,
    moving_points_all,
    sparse_moving,
    values_at,
    values_at_rotations,
)
from .polar import angle_bounds, polar_tables
from .prepared import Prepared

COARSE = np.arange(360.0)
_COARSE_ROT = np.array([rotation_entries(float(a)) for a in COARSE], np.float64)
_NO_INIT = (np.zeros((0, 6), np.int64), np.zeros(0))
_NO_POINTS = np.zeros(0, np.int32)
SLOT_BYTES = 8 * 2**20  # the moving ROIs kept per search (dense states and occupied points) ...
MAX_SLOTS = 32  # ... at most this many angles (a search evaluates few angles exactly)
SECTOR0 = 1  # the branch and bound starts from sectors of this many angles × the whole window (one angle:
# on the windowed bench, ROI 8 m and W 0.5 m, no sector's bound pruned; docs/performance-history.md)
POINTS_BYTES = 32 * 2**20  # the coarse angles' occupied lattice points kept per moving map, at most this size


class Best(NamedTuple):
    """What a branch and bound found: the first maximum in its order, or (``angle`` −1) nothing above
    its starting value."""

    value: float
    angle: int  # index into the search's angles; −1: none
    a: int  # translation, cells
    b: int
    agr: int
    dis: int
    ff: int


def _incumbent(above: float) -> np.ndarray:
    """The starting incumbent: nothing found; −inf, or an element must score strictly above ``above``
    (its tie keys −1: no element's keys come before them)."""
    out = np.zeros(1, INCUMBENT)
    out[0]["value"], out[0]["angle"] = above, -1
    if above != -np.inf:
        out[0]["key_p"] = out[0]["key_s"] = -1
    return out


@lru_cache(maxsize=8)
def _raster(side: int) -> np.ndarray:
    """Tie ranks of the translations in raster order (index b·side + a itself)."""
    out = np.arange(side * side, dtype=np.int64)
    out.flags.writeable = False
    return out


def _is_coarse(angles: np.ndarray) -> bool:
    return angles.shape == COARSE.shape and np.array_equal(angles, COARSE)


def _rot(angles: np.ndarray) -> np.ndarray:
    if _is_coarse(angles):
        return _COARSE_ROT
    return np.array([rotation_entries(float(a)) for a in angles], np.float64).reshape(-1, 4)


class Searcher:
    """One problem's prepared arrays and the moving ROIs computed so far (per angle array)."""

    def __init__(self, problem, k: int | None = None) -> None:
        self.p = Prepared(problem, k)
        nn = self.p.n * self.p.n
        n_slots = int(min(MAX_SLOTS, max(2, SLOT_BYTES // (5 * nn))))
        self.work = Work(np.empty((n_slots, nn), np.uint8), np.empty((n_slots, nn), np.int32),
                         np.full(n_slots, -1, np.int64), np.zeros((n_slots, 2), np.int64), np.zeros(nn, np.int32),
                         np.zeros(1, np.int64), np.empty(nn, np.int32))
        self._angles: np.ndarray | None = None
        self.stats = {"bounds": 0, "exact": 0}
        self.lock = threading.RLock()  # one search at a time per searcher (its ROI slots are shared)

    def select(self, angles: np.ndarray) -> np.ndarray:
        """Make ``angles`` the searcher's angle array (its slots forgotten when it changes); their R(−θ)."""
        if self._angles is None or self._angles.shape != angles.shape or not np.array_equal(self._angles, angles):
            self._angles = angles.copy()
            self._rot = _rot(angles)
            self.work.slot_angle[:] = -1
            self._asum = None
        return self._rot

    def angle_sums(self) -> np.ndarray:
        """Per angle of the current array: the moving ROI's occupied (NCC) or free (Birk–Carpin) points."""
        if self._asum is None:
            p, w = self.p, self.work
            out = np.zeros(self._angles.size, np.int64)
            if p.measure.sums:
                dense = np.empty(p.n * p.n, np.uint8)
                for x in range(self._angles.size):
                    if p.measure.needs_free_agree:
                        out[x] = fill_moving(p.tables, self._rot[x], dense, w.tmp)[1]
                    else:  # occupied points only: without the dense ROI
                        w.gen[0] += 1
                        out[x] = sparse_moving(p.tables, self._rot[x], w.mark, w.gen[0], w.tmp)
            self._asum = out
        return self._asum

    def run(self, angles: np.ndarray, *, mode: int = 0, amask=None, tmask=None, above: float = -np.inf,
            excl=None, sector0: int = SECTOR0, budget: int = 0, init=None, raster: bool = False,
            keep: float = -1.0) -> tuple[Best, np.ndarray]:
        """Branch and bound over ``angles`` × the window; returns (:class:`Best`, envelope); ``above``: only
        an element scoring strictly above it is looked for. With a
        ``budget`` of bounded regions, ``self.complete`` says whether the search finished within it.
        ``raster``: translations tie in raster order (b, then a) instead of the nearest-first order.
        ``keep`` ≥ 0: ``self.frontier`` holds the regions dropped (elements evaluated) within ``keep`` of the
        incumbent of their moment, as (regions, bounds) — see :func:`merger.search.engine.exact_runner_up`."""
        with self.lock:
            p = self.p
            angles = np.asarray(angles, np.float64)
            rot = self.select(angles)
            n_t = p.side * p.side
            excl = (np.zeros(angles.size, np.bool_), np.zeros(n_t, np.bool_)) if excl is None else excl
            q = Query(angles, rot, _mask(amask, angles.size), _mask(tmask, n_t), _raster(p.side) if raster else p.rank,
                      self.angle_sums(), *excl, *(_NO_INIT if init is None else init),
                      *self._points(angles, few=amask is not None and 4 * int(np.count_nonzero(amask)) < angles.size),
                      int(mode), int(sector0), int(budget), float(keep))
            inc = _incumbent(above)
            env = np.full(angles.size, -np.inf)
            nb, ne, self.complete, *self.frontier = branch_and_bound(p.tables, self.work, q, inc, env)
            self.stats["bounds"] += int(nb)
            self.stats["exact"] += int(ne)
            r = inc[0]
            return Best(float(r["value"]), int(r["angle"]), int(r["a"]), int(r["b"]), int(r["agr"]), int(r["dis"]),
                        int(r["ff"])), env

    def first_max(self, angles, ts) -> tuple[float, int, tuple[int, int]] | None:
        """The first maximum of the exact values over ``angles`` (in that order) × translations ``ts``
        (cells, in raster order: b, then a) — what a loop over the angles taking each angle's first
        ``argmax`` of :meth:`values` and keeping an angle only when strictly better gives — as (value,
        index into ``angles``, (a, b)); None when ``angles`` or ``ts`` is empty. By the branch and bound."""
        angles = np.asarray(angles, np.float64)
        if angles.size == 0 or len(ts) == 0:
            return None
        # one first region per angle: the angles need not be ascending (they may wrap at 360°)
        best, _ = self.run(angles, mode=1, tmask=self.translation_mask(ts), sector0=1, raster=True)
        return best.value, best.angle, (best.a, best.b)

    def _points(self, angles: np.ndarray, few: bool = False):
        """The moving ROI's occupied lattice points at every angle of ``angles`` (start, count, buffer) for
        the coarse angles of a windowed search, kept per moving map (every search of a cycle with this map
        moving reads them; a windowed search bounds nearly every angle alone); rotation only, for other
        angles, or when they would be large, none (the kernel computes the few angles it needs). ``few``:
        the search reads few of the angles (a local search's 7 of 360), so they are not computed for all
        of them unless they are kept already (the kernel computes the same points: the same answer)."""
        p = self.p
        none = np.full(angles.size, -1, np.int64), np.zeros(angles.size, np.int64), _NO_POINTS
        if p.k == 0 or not _is_coarse(angles) or p.occ_x.size * 2 * COARSE.size * 4 > POINTS_BYTES:
            return none
        key = ("points", p.moving_key, p.n, p.res)
        if few:
            kept = caches.moving_side_kept(p.problem.moving, key)
            return none if kept is None else kept
        return caches.moving_side(p.problem.moving, key, lambda: moving_points_all(p.tables, _COARSE_ROT))

    def points_at(self, angles: np.ndarray, x: int) -> np.ndarray:
        """The moving ROI's occupied lattice points at ``angles[x]`` (what the moving side's bound reads)."""
        start, cnt, buf = self._points(np.asarray(angles, np.float64))
        if start[x] >= 0:
            return buf[start[x]:start[x] + cnt[x]]
        w = self.work
        w.gen[0] += 1
        c = sparse_moving(self.p.tables, np.array(rotation_entries(float(angles[x]))), w.mark, w.gen[0], w.tmp)
        return w.tmp[:c].copy()

    def exact(self, theta_deg: float, a: int, b: int) -> tuple[float, Counts]:
        """The exact value and counts (free/free included) at one (θ, t) in cells."""
        p = self.p
        dense = np.empty(p.n * p.n, np.uint8)
        pocc = np.empty(p.n * p.n, np.int32)
        no, nf = fill_moving(p.tables, np.array(rotation_entries(theta_deg)), dense, pocc)
        agr, dis, ff = exact_counts(p.tables, dense, pocc, no, a + p.k, b + p.k, True)
        return self._value(agr, dis, ff, a, b, no, nf), Counts(int(agr), int(dis), int(ff))

    def _value(self, agr, dis, ff, a, b, no, nf) -> float:
        p = self.p
        sx = int(p.tsum[(b + p.k) * p.side + a + p.k])
        return p.measure.value(agr, dis, ff, sx, p.measure.angle_sum(no, nf), p.n * p.n, p.floor)

    def values(self, theta_deg: float, ts) -> np.ndarray:
        """Exact values at one angle for translations ``ts`` ((a, b) cells, within the window)."""
        with self.lock:
            p, w = self.p, self.work
            rot = np.array(rotation_entries(theta_deg))
            pocc = np.empty(p.n * p.n, np.int32)
            dense = np.empty(p.n * p.n if p.measure.needs_free_agree else 0, np.uint8)
            if p.measure.needs_free_agree:  # free/free: the dense ROI
                no, nf = fill_moving(p.tables, rot, dense, pocc)
            else:
                w.gen[0] += 1
                no, nf = sparse_moving(p.tables, rot, w.mark, w.gen[0], pocc), 0
            idx = np.array(ts, np.int64).reshape(-1, 2) + p.k
            out = np.empty(idx.shape[0])
            values_at(p.tables, dense, pocc, no, nf, idx[:, 0].copy(), idx[:, 1].copy(), rot, out)
            return out

    def values_at_angles(self, angles, t) -> np.ndarray:
        """Exact values at one translation ``t`` (cells) for each of ``angles``: :meth:`values` at each, in one
        compiled call."""
        angles = np.asarray(angles, np.float64).reshape(-1)
        with self.lock:
            p, w = self.p, self.work
            rots = _rot(angles)
            pocc = np.empty(p.n * p.n, np.int32)
            dense = np.empty(p.n * p.n if p.measure.needs_free_agree else 0, np.uint8)
            out = np.empty(angles.size)
            values_at_rotations(p.tables, rots, w.mark, w.gen, dense, pocc, np.array([t[0] + p.k], np.int64),
                                np.array([t[1] + p.k], np.int64), out)
            return out

    def polar_bounds(self) -> np.ndarray:
        """Rotation only: an upper bound of the value at every whole-degree angle (Lemma 6)."""
        p = self.p
        with self.lock:  # selects the coarse angles and fills the per-angle sums: searcher state
            self.select(COARSE)
            ring_w = p.res
            n_rings = int(math.ceil(p.half * math.sqrt(2.0) / ring_w)) + 2
            may, nf = caches.moving_side(
                p.problem.moving, ("polar", p.moving_key, ring_w, n_rings),
                lambda: polar_tables(p.tables, ring_w, n_rings))
            # the reference ROI's occupied lattice points (each reads one cell; a cell may be read by 1–4)
            i0 = p.ilo[p.k, p.qr - p.tables.rlo]
            ni = p.ihi[p.k, p.qr - p.tables.rlo] - i0
            j0 = p.jlo[p.k, p.qc - p.tables.clo]
            nj = p.jhi[p.k, p.qc - p.tables.clo] - j0
            ii, jj = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
            for di in range(int(ni.max(initial=0))):
                for dj in range(int(nj.max(initial=0))):
                    sel = (di < ni) & (dj < nj)
                    ii.append(i0[sel] + di)
                    jj.append(j0[sel] + dj)
            m = (p.n - 1) / 2.0
            agr, dis = angle_bounds((np.concatenate(jj) - m) * p.res, (np.concatenate(ii) - m) * p.res, may, nf,
                                    ring_w)
            sx = int(p.tsum[p.k * p.side + p.k])
            return uppers(p.measure.code, p.floor, agr, dis, sx, sx, self.angle_sums(), p.n * p.n)

    def initial_regions(self):
        """The first regions of the coarse search with their bounds: rotation only, one per whole degree
        (Lemma 6); with a window None (sectors: per-box polar bounds were tried, docs/performance-history.md)."""
        if self.p.k != 0:
            return None
        nodes = np.zeros((360, 6), np.int64)
        nodes[:, 0] = nodes[:, 1] = np.arange(360)
        return nodes, self.polar_bounds()

    def translation_mask(self, ts) -> np.ndarray:
        m = np.zeros(self.p.side * self.p.side, np.bool_)
        for a, b in ts:
            m[(b + self.p.k) * self.p.side + (a + self.p.k)] = True
        return m


def _mask(mask, size: int) -> np.ndarray:
    return np.ones(size, np.bool_) if mask is None else np.asarray(mask, np.bool_)


def searcher_for(problem, k: int | None = None) -> Searcher:
    """The searcher of ``problem`` (kept per problem object, see :mod:`merger.caches`)."""
    return caches.searcher(problem, k, Searcher)
