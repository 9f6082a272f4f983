"""The searches: the exhaustive reference (compiled, and its numpy specification) and the fast one.

Both answer the thesis's grid answer (docs/design/search.md §2): over every translation (a, b) of the
window (|a|, |b| ≤ K cells) and every coarse angle 0°, 1°, …, 359° the best value, ties to the
translation first in :func:`merger.search.prepared.translation_offsets` order, then the smallest
angle; then 0.1° over θc ± 1° at that translation, the first maximum. K = 0 is the thesis's search.

* :func:`spec_search` — the definition in numpy (every angle and translation evaluated on whole ROIs
  with :mod:`merger.measures`); slow, for small problems in tests.
* :func:`reference_search` — the same exhaustive loop on the compiled exact counts
  (:func:`merger.search.kernels.exact_counts`): the same floats, at full size.
* :func:`fast_search` — :func:`merger.search.kernels.branch_and_bound` over (sector, box) regions with
  the reference's order as the key (Lemma 5): exactly the reference's answer. Its profile is an upper
  envelope of the reference's (exact where evaluated, never above the best coarse value) and so is its
  runner-up (read off that profile); :func:`exact_runner_up` computes the runner-up exactly and the guard
  beyond the window is exact (on first access), both by the same branch and bound.
"""

from __future__ import annotations

import math
import threading
from dataclasses import replace
from functools import lru_cache

import numpy as np

from ..measures import Counts, measure_fn
from . import caches
from .kernels import (
    branch_and_bound,
    exact_counts,
    exact_counts_sparse,
    fill_moving,
    moving_points_all,
    sparse_moving,
)
from .lattice import rotation_entries
from .measures import NCC, uppers
from .polar import angle_bounds, polar_tables
from .prepared import Prepared, translation_offsets
from .problem import (
    MAX_WINDOW_FRACTION,
    RUNNER_UP_MIN_SEPARATION_DEG,
    Alignment,
    BeyondQuery,
    angle_diff_deg,
    fine_angles,
    floored,
    runner_up,
    wrap_deg,
)

COARSE = np.arange(360.0)
_NO_INIT = (np.zeros((0, 6), np.int64), np.zeros(0))
_NO_POINTS = np.zeros(0, np.int32)
SLOT_BYTES = 8 * 2**20  # the moving ROIs kept per search (dense states and occupied points) ...
MAX_SLOTS = 32  # ... at most this many angles (a search evaluates few angles exactly)
SECTOR0 = 1  # the branch and bound starts from sectors of this many angles × the whole window (one angle:
# on the windowed bench, ROI 8 m and W 0.5 m, no sector's bound pruned; docs/performance-history.md)
FRONTIER_KEEP = 0.12  # the fast search keeps its frontier within this of its incumbent (the ambiguity
# rule's runner-up floor is the answer's score − margin − 0.05, margin 0.05 by default with a window)
POINTS_BYTES = 32 * 2**20  # the coarse angles' occupied lattice points kept per moving map, at most this size
BEYOND_FACTOR = 2.0  # the guard beyond the window looks up to this × the window (≤ a quarter of the ROI)
BEYOND_APART_STEPS = 1.5  # ... for alignments more than one grid step (1°, one cell) from the answer
BEYOND_BUDGET = 40000  # regions the guard may bound (a count: deterministic); best-first, a better placement
# is found early when there is one, the budget cuts the proof that there is none (docs/design/search.md §5)


@lru_cache(maxsize=8)
def _raster(side: int) -> np.ndarray:
    """Tie ranks of the translations in raster order (index b·side + a itself)."""
    out = np.arange(side * side, dtype=np.int64)
    out.flags.writeable = False
    return out


def _rot(angles: np.ndarray) -> np.ndarray:
    if angles.shape == COARSE.shape and np.array_equal(angles, COARSE):
        return _COARSE_ROT
    return np.array([rotation_entries(float(a)) for a in angles], np.float64).reshape(-1, 4)


_COARSE_ROT = np.array([rotation_entries(float(a)) for a in COARSE], np.float64)


class Searcher:
    """One problem's prepared arrays and the moving ROIs computed so far (per angle array)."""

    def __init__(self, problem, k: int | None = None) -> None:
        self.p = Prepared(problem, k)
        n = self.p.n
        self._angles: np.ndarray | None = None
        n_slots = int(min(MAX_SLOTS, max(2, SLOT_BYTES // (5 * n * n))))
        self.slots_dense = np.empty((n_slots, n * n), np.uint8)  # read only where slot_angle says filled
        self.slots_pocc = np.empty((n_slots, n * n), np.int32)
        self.slot_counts = np.zeros((n_slots, 2), np.int64)
        self.slot_angle = np.full(n_slots, -1, np.int64)
        self.mark = np.zeros(n * n, np.int32)  # lattice points seen by sparse_moving, by generation
        self.gen = np.zeros(1, np.int64)
        self.stats = {"bounds": 0, "exact": 0}
        self.lock = threading.RLock()  # one search at a time per searcher (its ROI slots are shared)

    def _use(self, angles: np.ndarray):
        if self._angles is None or self._angles.shape != angles.shape or not np.array_equal(self._angles, angles):
            self._angles = angles.copy()
            self._rot = _rot(angles)
            self.slot_angle[:] = -1
            self._asum = None
        return self._rot

    def angle_sums(self) -> np.ndarray:
        """Per angle of the current array: the moving ROI's occupied (NCC) or free (Birk–Carpin) points."""
        if self._asum is None:
            p = self.p
            out = np.zeros(self._angles.size, np.int64)
            if p.measure.sums:
                dense = np.empty(p.n * p.n, np.uint8)
                pocc = np.empty(p.n * p.n, np.int32)
                for x in range(self._angles.size):
                    if p.measure.code == NCC:  # occupied points only: without the dense ROI
                        self.gen[0] += 1
                        out[x] = sparse_moving(p.mstates, *p.ctx_f[1:6], p.n, p.res, *self._rot[x], p.occ_x,
                                               p.occ_y, self.mark, self.gen[0], pocc)
                    else:
                        out[x] = fill_moving(p.mstates, *p.ctx_f[1:6], p.n, p.res, *self._rot[x], dense, pocc)[1]
            self._asum = out
        return self._asum

    def run(self, angles: np.ndarray, *, mode: int = 0, amask=None, tmask=None, inc=None, excl=None,
            sector0: int = SECTOR0, budget: int = 0, init=None, raster: bool = False, keep: float = -1.0):
        """Branch and bound over ``angles`` × the window; returns (incumbent array, envelope). With a
        ``budget`` of bounded regions, ``self.complete`` says whether the search finished within it.
        ``raster``: translations tie in raster order (b, then a) instead of the nearest-first order.
        ``keep`` ≥ 0: ``self.frontier`` holds the regions dropped (elements evaluated) within ``keep`` of the
        incumbent of their moment, as (regions, bounds) — see :func:`exact_runner_up`."""
        with self.lock:
            return self._run(angles, mode, amask, tmask, inc, excl, sector0, budget, init, raster, keep)

    def first_max(self, angles, ts) -> tuple[float, int, tuple[int, int]] | None:
        """The first maximum of the exact values over ``angles`` (in that order) × translations ``ts``
        (cells, in raster order: b, then a) — what a loop over the angles taking each angle's first
        ``argmax`` of :meth:`values` and keeping an angle only when strictly better gives — as (value,
        index into ``angles``, (a, b)); None when ``angles`` or ``ts`` is empty. By the branch and bound."""
        angles = np.asarray(angles, np.float64)
        if angles.size == 0 or len(ts) == 0:
            return None
        # one first region per angle: the angles need not be ascending (they may wrap at 360°)
        inc, _ = self.run(angles, mode=1, tmask=self.translation_mask(ts), sector0=1, raster=True)
        return float(inc[0]), int(inc[3]), (int(inc[4]), int(inc[5]))

    def _run(self, angles, mode, amask, tmask, inc, excl, sector0, budget, init, raster=False, keep=-1.0):
        p = self.p
        angles = np.asarray(angles, np.float64)
        rot = self._use(angles)
        side = p.side
        amask = np.ones(angles.size, np.bool_) if amask is None else np.asarray(amask, np.bool_)
        tmask = np.ones(side * side, np.bool_) if tmask is None else np.asarray(tmask, np.bool_)
        excl_a, excl_t = (np.zeros(angles.size, np.bool_), np.zeros(side * side, np.bool_)) if excl is None else excl
        inc = np.array([-np.inf, 0, 0, -1, 0, 0, 0, 0, 0], np.float64) if inc is None else inc
        env = np.full(angles.size, -np.inf)
        ctx_i = np.array([p.n, p.k, p.measure.code, mode, int(p.measure.needs_free_agree), sector0, budget,
                          p.floor], np.int64)
        nb, ne, self.complete, fr_nodes, fr_vals = branch_and_bound(p.ctx_f, ctx_i, p.ref, p.cols, p.rows, p.qr, p.qc, p.ilo, p.ihi, p.jlo, p.jhi,
                                  p.axes_r, p.axes_c, p.blk, p.blkf, p.lvl_start, p.wr0, p.wc0, p.mstates, p.cls_sat,
                                  angles, rot, amask, tmask, _raster(side) if raster else p.rank, p.tsum,
                                  self.angle_sums(),
                                  excl_a, excl_t, self.slots_dense, self.slots_pocc, self.slot_angle,
                                  self.slot_counts, inc, env,
                                  *(_NO_INIT if init is None else init), p.occ_x, p.occ_y,
                                  self.mark, self.gen, p.ref_sat, *self._points(angles), float(keep))
        self.frontier = (fr_nodes, fr_vals)
        self.stats["bounds"] += int(nb)
        self.stats["exact"] += int(ne)
        return inc, env

    def _points(self, angles: np.ndarray):
        """The moving ROI's occupied lattice points at every angle of ``angles`` (start, count, buffer) for
        the coarse angles of a windowed search, kept per moving map (every search of a cycle with this map
        moving reads them; a windowed search bounds nearly every angle alone); rotation only, for other
        angles, or when they would be large, none (the kernel computes the few angles it needs)."""
        if self.p.k == 0 or not (angles.shape == COARSE.shape and np.array_equal(angles, COARSE)) or \
                self.p.occ_x.size * 2 * COARSE.size * 4 > POINTS_BYTES:
            return np.full(angles.size, -1, np.int64), np.zeros(angles.size, np.int64), _NO_POINTS
        p = self.p
        return caches.moving_side(
            p.problem.moving, ("points", tuple(p.ctx_f[1:7]), p.n, p.res),
            lambda: moving_points_all(p.mstates, *p.ctx_f[1:6], p.n, p.res, _COARSE_ROT, p.occ_x, p.occ_y))

    def exact(self, theta_deg: float, a: int, b: int) -> tuple[float, Counts]:
        """The exact value and counts (free/free included) at one (θ, t) in cells."""
        p = self.p
        rot = rotation_entries(theta_deg)
        dense = np.empty(p.n * p.n, np.uint8)
        pocc = np.empty(p.n * p.n, np.int32)
        no, nf = fill_moving(p.mstates, *p.ctx_f[1:6], p.n, p.res, *rot, dense, pocc)
        ai, bi = a + p.k, b + p.k
        agr, dis, ff = exact_counts(dense, pocc, no, p.ref, p.cols, p.rows, ai, bi, p.qr, p.qc, p.axes_r[3],
                                    p.axes_c[3], p.ilo, p.ihi, p.jlo, p.jhi, p.n, True)
        sx = p.tsum[bi * p.side + ai]
        sy = no if p.measure.code == NCC else nf
        return p.measure.value(agr, dis, ff, int(sx), int(sy), p.n * p.n, p.floor), Counts(int(agr), int(dis), int(ff))

    def values(self, theta_deg: float, ts) -> np.ndarray:
        """Exact values at one angle for translations ``ts`` ((a, b) cells, within the window)."""
        with self.lock:
            return self._values(theta_deg, ts)

    def _values(self, theta_deg: float, ts) -> np.ndarray:
        p = self.p
        rot = rotation_entries(theta_deg)
        pocc = np.empty(p.n * p.n, np.int32)
        dense = None
        if p.measure.needs_free_agree:  # free/free: the dense ROI
            dense = np.empty(p.n * p.n, np.uint8)
            no, nf = fill_moving(p.mstates, *p.ctx_f[1:6], p.n, p.res, *rot, dense, pocc)
        else:
            self.gen[0] += 1
            no = sparse_moving(p.mstates, *p.ctx_f[1:6], p.n, p.res, *rot, p.occ_x, p.occ_y, self.mark,
                               self.gen[0], pocc)
            nf = 0
        out = np.empty(len(ts))
        for x, (a, b) in enumerate(ts):
            ai, bi = a + p.k, b + p.k
            if dense is not None:
                agr, dis, ff = exact_counts(dense, pocc, no, p.ref, p.cols, p.rows, ai, bi, p.qr, p.qc,
                                            p.axes_r[3], p.axes_c[3], p.ilo, p.ihi, p.jlo, p.jhi, p.n, True)
            else:
                agr, dis = exact_counts_sparse(pocc, no, p.ref, p.cols, p.rows, ai, bi, p.qr, p.qc, p.axes_r[3],
                                               p.axes_c[3], p.ilo, p.ihi, p.jlo, p.jhi, p.n, p.mstates,
                                               *p.ctx_f[1:6], p.res, *rot)
                ff = 0
            sx = p.tsum[bi * p.side + ai]
            sy = no if p.measure.code == NCC else nf
            out[x] = p.measure.value(agr, dis, ff, int(sx), int(sy), p.n * p.n, p.floor)
        return out

    def _polar(self):
        """The moving map's polar tables about c_m (cached per map) and their ring width."""
        p = self.p
        ring_w = p.res
        half = float(p.ctx_f[6])
        n_rings = int(math.ceil(half * math.sqrt(2.0) / ring_w)) + 2
        tables = caches.moving_side(
            p.problem.moving, ("polar", tuple(p.ctx_f[1:7]), ring_w, n_rings),
            lambda: polar_tables(p.cls_sat, p.mstates.shape[0], p.mstates.shape[1], *p.ctx_f[1:6], half, ring_w,
                                 n_rings))
        return tables, ring_w

    def polar_bounds(self) -> np.ndarray:
        """Rotation only: an upper bound of the value at every whole-degree angle (Lemma 6, polar.py)."""
        p = self.p
        self._use(COARSE)
        (may, nf), ring_w = self._polar()
        # the reference ROI's occupied lattice points (each reads one cell; a cell may be read by 1–4)
        rlo, clo = int(p.axes_r[3]), int(p.axes_c[3])
        i0 = p.ilo[p.k, p.qr - rlo]
        ni = p.ihi[p.k, p.qr - rlo] - i0
        j0 = p.jlo[p.k, p.qc - clo]
        nj = p.jhi[p.k, p.qc - clo] - j0
        ii, jj = [], []
        for di in range(int(ni.max(initial=0))):
            for dj in range(int(nj.max(initial=0))):
                sel = (di < ni) & (dj < nj)
                ii.append(i0[sel] + di)
                jj.append(j0[sel] + dj)
        m = (p.n - 1) / 2.0
        ii = np.concatenate(ii) if ii else np.zeros(0, np.int64)
        jj = np.concatenate(jj) if jj else np.zeros(0, np.int64)
        agr, dis = angle_bounds((jj - m) * p.res, (ii - m) * p.res, may, nf, ring_w)
        sx = int(p.tsum[p.k * p.side + p.k])
        return uppers(p.measure.code, p.floor, agr, dis, sx, sx, self.angle_sums(), p.n * p.n)

    def initial_regions(self):
        """The first regions of the coarse search with their bounds: rotation only, one per whole degree
        (Lemma 6); with a window None (sectors: per-box polar bounds were tried, docs/performance-history.md)."""
        if self.p.k != 0:
            return None
        nodes = np.zeros((360, 6), np.int64)
        nodes[:, 0] = nodes[:, 1] = np.arange(360)
        with self.lock:  # selects the coarse angles and fills the per-angle sums: searcher state
            return nodes, self.polar_bounds()

    def values_at_angles(self, angles, t) -> np.ndarray:
        """Exact values at one translation ``t`` (cells) for each of ``angles``."""
        return np.array([self.values(float(a), [t])[0] for a in angles], np.float64)

    def translation_mask(self, ts) -> np.ndarray:
        m = np.zeros(self.p.side * self.p.side, np.bool_)
        for a, b in ts:
            m[(b + self.p.k) * self.p.side + (a + self.p.k)] = True
        return m


def searcher_for(problem, k: int | None = None) -> Searcher:
    """The searcher of ``problem`` (kept per problem object, see :mod:`merger.search.caches`)."""
    return caches.searcher(problem, k, Searcher)


# --- answers -------------------------------------------------------------------------------------------
def _fine(s: Searcher, th_c: float, tc) -> tuple[np.ndarray, np.ndarray, int]:
    """The thesis's refinement at translation ``tc``: the first maximum of 0.1° over θc ± 1°."""
    angles = fine_angles(th_c)
    inc, env = s.run(angles, tmask=s.translation_mask([tc]), sector0=angles.size)
    return angles, env, int(inc[3])


def fast_search(problem) -> Alignment:
    """The thesis's grid answer by branch and bound (see the module documentation); exact."""
    s = searcher_for(problem)
    # rotation only: every whole-degree angle bounded at once (polar cells), then the best-first search
    inc, env = s.run(COARSE, init=s.initial_regions(), keep=FRONTIER_KEEP)
    caches.keep_frontier(problem, (*s.frontier, float(inc[0])))
    th_c, tc = float(inc[3]), (int(inc[4]), int(inc[5]))
    angles, fine_env, kf = _fine(s, th_c, tc)
    value, counts = s.exact(float(angles[kf]), *tc)
    # the fine scores: exact wherever a bound reaches the best (a plateau of equal scores is exact),
    # elsewhere bounds below it (the sub-cell refinement reads only the plateau)
    fine_vals = fine_env.copy()
    fine_vals[kf] = value
    for x in np.flatnonzero(fine_env >= value):
        if x != kf:
            fine_vals[x] = s.values(float(angles[x]), [tc])[0]
    theta = wrap_deg(float(angles[kf]))
    profile = np.minimum(env, max(float(inc[0]), 0.0)) if problem.measure == "ncc" else env
    best_value = float(inc[0])
    # the runner-up from the envelope: an upper bound of the reference's (never above the best coarse
    # value); exact_runner_up computes it exactly, at the cost of a search where few regions can be dropped
    return Alignment(theta, value, counts, problem.measure, "fast", problem.roi_m, profile,
                     runner_up(profile, theta), window_m=problem.window_m,
                     translation_m=problem.offset_m(*tc), cells=tc, fine=(angles, fine_vals),
                     beyond_query=BeyondQuery(problem, best_value, (th_c, tc)),
                     evidence={"profile": "upper_envelope", "runner_up": "upper_envelope"})


def exact_runner_up(problem, theta_deg: float, floor: float | None = None, budget: int = 0,
                    envelope=None) -> tuple[float, float]:
    """The reference's runner-up exactly: over the coarse angles at least 10° from ``theta_deg``, the
    first maximum (smallest angle) of the best value over the window (NaNs when no angle is that far).
    With ``floor``, only a runner-up scoring at least ``floor`` is looked for (NaNs when there is none):
    regions bounded below it are dropped at once. With a ``budget`` of bounded regions the answer is
    the best exact value found within it (exact when the search completed; a real placement always).
    ``envelope``: per coarse angle an upper bound of its values over the window (the fast search's
    profile, Lemma 5): the search starts from one region per angle with that bound, so angles whose
    bound is below ``floor`` are never searched. Better, when the fast search of this very problem
    object ran and ``floor`` is within ``FRONTIER_KEEP`` of its best coarse value: the search starts from
    that search's frontier — the regions it dropped and the elements it evaluated with a bound at least
    its incumbent − FRONTIER_KEEP (every element scoring ≥ floor lies in one of them, Lemma 5b)."""
    far = np.abs(angle_diff_deg(COARSE, theta_deg)) >= RUNNER_UP_MIN_SEPARATION_DEG
    if not far.any():
        return float("nan"), float("nan")
    inc = None if floor is None else np.array([np.nextafter(floor, -np.inf), -1, -1, -1, 0, 0, 0, 0, 0])
    s = searcher_for(problem)
    init = None
    fr = caches.frontier(problem) if floor is not None else None
    if fr is not None and floor >= fr[2] - FRONTIER_KEEP:
        sel = fr[1] >= floor
        if not sel.any():
            return float("nan"), float("nan")
        init = (np.ascontiguousarray(fr[0][sel]), np.ascontiguousarray(fr[1][sel]))
    elif envelope is not None:
        side = s.p.side
        nodes = np.zeros((COARSE.size, 6), np.int64)
        nodes[:, 0] = nodes[:, 1] = np.arange(COARSE.size)
        nodes[:, 3] = nodes[:, 5] = side - 1
        init = (nodes, np.asarray(envelope, np.float64))
    inc, _ = s.run(COARSE, mode=1, amask=far, inc=inc, budget=budget, init=init)
    if inc[3] < 0:
        return float("nan"), float("nan")
    return float(inc[3]), float(inc[0])


def _wide(problem):
    wide = min(BEYOND_FACTOR * problem.window_m, MAX_WINDOW_FRACTION * problem.roi_m)
    return replace(problem, window_m=wide, refine=False)


def _ring(problem):
    """The guard's wider problem, its window (cells) and its searcher; None without a window or a wider
    one. The ring: the wider window's translations outside the problem's window (:func:`_ring_mask`)."""
    k = problem.window_cells
    big = _wide(problem)
    kb = big.window_cells
    if k == 0 or kb <= k:
        return None
    return big, kb, searcher_for(big)


def _apart(a, b) -> bool:
    """Whether two grid alignments (θ°, (a, b) cells) are more than one grid step apart. A better
    alignment one step beyond the window's edge is the answer's own peak, cut by the edge."""
    if abs(angle_diff_deg(float(a[0]), float(b[0]))) > BEYOND_APART_STEPS:
        return True
    return math.dist(a[1], b[1]) > BEYOND_APART_STEPS


def beyond_window(problem, best_value: float, answer, budget: int = BEYOND_BUDGET):
    """The best coarse alignment outside the window and within ``BEYOND_FACTOR`` × it (at most a quarter
    of the ROI side) that scores above ``best_value`` and is apart from the grid answer ``answer`` =
    (θ°, (a, b) cells): ``(θ°, (tx, ty) m, score)``, or None — by the branch and bound over that ring,
    best-first within ``budget`` bounded regions (0: no limit; then exactly the first in the order θ,
    then the translation order, as :func:`reference_beyond`). What it reports is always a real placement
    scoring above ``best_value``; with the budget spent it may miss one (then None)."""
    ringed = _ring(problem)
    if ringed is None:
        return None
    big, kb, s = ringed
    side = 2 * kb + 1
    th_ans, (a_ans, b_ans) = answer
    # the elements not apart from the answer (_apart): angles within BEYOND_APART_STEPS degrees of it ×
    # translations within BEYOND_APART_STEPS cells of it
    excl_a = np.abs(angle_diff_deg(COARSE, th_ans)) <= BEYOND_APART_STEPS
    tmask = _ring_mask(problem.window_cells, kb)
    bb, aa = np.divmod(np.arange(side * side), side)
    excl_t = tmask & ((aa - kb - a_ans) ** 2 + (bb - kb - b_ans) ** 2 <= BEYOND_APART_STEPS ** 2)
    inc = np.array([best_value, -1, -1, -1, 0, 0, 0, 0, 0], np.float64)  # strictly above best_value
    inc, _ = s.run(COARSE, mode=1, tmask=tmask, inc=inc, excl=(excl_a, excl_t), budget=budget,
                   init=_ring_regions(kb))
    if inc[3] < 0:
        return None
    return float(inc[3]), big.offset_m(int(inc[4]), int(inc[5])), float(inc[0])


@lru_cache(maxsize=16)
def _ring_mask(k: int, kb: int) -> np.ndarray:
    """The ring's translations (beyond ±k cells, within ±kb) as a mask over b·(2kb+1) + a (read-only)."""
    side = 2 * kb + 1
    bb, aa = np.divmod(np.arange(side * side), side)
    out = np.maximum(np.abs(aa - kb), np.abs(bb - kb)) > k
    out.flags.writeable = False
    return out


@lru_cache(maxsize=16)
def _ring_regions(kb: int):
    """The guard's first regions: every coarse angle × the four quadrants of its wide window (±kb cells),
    unbounded (+inf: split on their first visit), so that the first regions bounded are boxes of about
    kb/2 — the problem's own window, for the default wider window of twice it. Bounds of larger boxes
    at one angle (and of sectors of angles) over the wide window stay above any threshold (their
    rectangles hold a wall nearly everywhere) and only cost: on the windowed bench's guards this start
    bounds 4,400–6,000 regions instead of 6,300–8,100 (sectors of 8 angles × the whole window), and
    starting one level finer 17,300 (docs/performance-history.md)."""
    side = 2 * kb + 1
    mid = (side - 1) // 2
    quads = [(a0, a1, b0, b1) for (b0, b1) in ((0, mid), (mid + 1, side - 1)) for (a0, a1) in ((0, mid), (mid + 1, side - 1))
             if a0 <= a1 and b0 <= b1]
    nodes = np.array([(x, x, *q) for x in range(COARSE.size) for q in quads], np.int64)
    return nodes, np.full(len(nodes), np.inf)  # read, never written, by the kernel


def reference_search(problem) -> Alignment:
    """The exhaustive search on compiled exact counts: every coarse angle × every translation."""
    s = searcher_for(problem)
    p = s.p
    ts = translation_offsets(p.k)
    table = np.empty((len(ts), 360))
    for th in range(360):
        table[:, th] = s.values(float(th), ts)
    i_best, th_best = np.unravel_index(int(np.argmax(table)), table.shape)  # first max: t order, then θ
    tc = ts[int(i_best)]
    angles = fine_angles(float(th_best))
    fine_vals = np.array([s.values(float(a), [tc])[0] for a in angles])
    kf = int(np.argmax(fine_vals))
    theta = wrap_deg(float(angles[kf]))
    value, counts = s.exact(float(angles[kf]), *tc)
    profile = table.max(axis=0)
    best_value = float(table[int(i_best), int(th_best)])
    return Alignment(theta, value, counts, problem.measure, "reference", problem.roi_m, profile,
                     runner_up(profile, theta), window_m=problem.window_m, translation_m=problem.offset_m(*tc),
                     cells=tc, fine=(angles, fine_vals),
                     beyond_query=BeyondQuery(problem, best_value, (int(th_best), tc), "reference"),
                     evidence={"profile": "exact", "runner_up": "exact"})


def reference_beyond(problem, best_value: float, answer):
    """:func:`beyond_window` exhaustively (the yardstick)."""
    ringed = _ring(problem)
    if ringed is None:
        return None
    big, kb, s = ringed
    k = problem.window_cells
    ring = [(a, b) for (a, b) in translation_offsets(kb) if max(abs(a), abs(b)) > k]
    out = None
    for th in range(360):
        vals = s.values(float(th), ring)
        for t, v in zip(ring, vals, strict=True):
            if v > best_value and (out is None or v > out[2]) and _apart((th, t), answer):
                out = (float(th), big.offset_m(*t), float(v))
    return out


def spec_search(problem) -> Alignment:
    """The definition in numpy: every angle × translation on whole ROIs (:mod:`merger.measures`)."""
    measure = measure_fn(problem.measure)

    def fn(a, b):
        return floored(measure(a, b), problem.min_support)
    ts = translation_offsets(problem.window_cells)
    refs = [problem.at(a, b).ref_roi() for a, b in ts]
    table = np.empty((len(ts), 360))
    for th in range(360):
        mov = problem.moving_roi(float(th))
        for i, r in enumerate(refs):
            table[i, th] = fn(r, mov).value
    i_best, th_best = np.unravel_index(int(np.argmax(table)), table.shape)
    tc = ts[int(i_best)]
    angles = fine_angles(float(th_best))
    sims = [fn(refs[int(i_best)], problem.moving_roi(float(a))) for a in angles]  # floored
    vals = np.array([x.value for x in sims])
    kf = int(np.argmax(vals))
    theta = wrap_deg(float(angles[kf]))
    profile = table.max(axis=0)
    return Alignment(theta, float(vals[kf]), sims[kf].counts, problem.measure, "spec", problem.roi_m, profile,
                     runner_up(profile, theta), window_m=problem.window_m, translation_m=problem.offset_m(*tc),
                     cells=tc, fine=(angles, vals))
