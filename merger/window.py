"""Rotation *and* translation search, for a common center known only roughly (beyond the thesis).

The thesis (3.3.1) searches only a rotation because the center is shared; it names the imprecise center
as its main failure ("an exact alignment by searching only a rotation is not possible with an
imprecisely given center"). With a window ``W`` the alignment of map j onto map i becomes

    x_i = c_i + t + R(θ)(x_j − c_j),   t = (a, b) · res,  |a|, |b| ≤ K = ⌊W / res⌋,

i.e. the moving map's center lands at ``c_i + t``. The region of interest is centred there (on the
center both maps then share), so a translation is the thesis's rotation problem about the shifted
reference center ``c_i + t`` (:meth:`merger.search.RotationProblem.at`): for W = 0 everything below is
the thesis's search, bit for bit.

**The grid answer** (:func:`reference_window_search`, exhaustive, the yardstick): every translation of
the window in one-cell steps × every coarse angle 0°, 1°, …, 359°; the best (θc, tc) — ties to the
translation first in :func:`translation_offsets` order (nearest the given center first), then the
smallest angle; then the thesis's refinement, 0.1° over θc ± 1° at tc (first maximum): (2K+1)²·360 + 21
evaluations.

**The fast method** (:func:`fast_window_search`) returns exactly that answer — θ, t, score and counts, ties
and plateaus included, for all three measures — with few exact evaluations. It never guesses: a
region of (θ, t) is skipped only when a *true upper bound* shows that it cannot come before the best
alignment already evaluated in the reference's order; everything else is evaluated exactly.

1. *An incumbent, cheaply*: the polar FFT profile of :mod:`merger.polar` about every translation of a
   coarse lattice (max-pooled cells of 10–35 cm, at most ±3 lattice steps; rings inside the ROI's
   inscribed circle), all 360 angles per translation in one FFT product; its best peaks (non-maximum
   suppressed, plus the best one near the half turn) are hill-climbed on the exact coarse grid
   (1° × one cell) with :class:`WindowEvaluator`, which computes the exact values of one angle at many
   translations at once (the rotated moving ROI does not depend on t; the reference ROI is a shifted
   block of the reference grid). The best end is the incumbent: an exact value, usually the answer.
2. *The certificate* (:class:`merger.window_bounds.Certifier`), a branch and bound over (coarse angle,
   box of translations) in two stages, with the order of the reference as the key: (value, −rank of t
   in :func:`translation_offsets`, −θ).

   a. *Sector bounds*, all 360 angles at once, per box of 3 × 3 translations: the polar sectors of
      :mod:`merger.fast` (``SectorBounds``) with the moving map's sector classes grown by the box's
      displacement radius (:class:`merger.window_bounds.BoxBounds`).
   b. *Per surviving angle*, its rotated moving ROI (for ω̃ only bounds of its states, from four
      uncertified warps, :func:`merger.transform.rotated_roi_classes`; exact for the other measures),
      and per surviving box a bound from the reference pooled over the box (Cartographer's fast
      correlative scan matcher's idea: the max of the reference's occupied cells over every shift of
      the box, the min of its free ones); the translations of a box the bound cannot exclude are
      evaluated exactly (with the exact rotated ROI).

   A region is discarded when, for each of its angles, (bound, −the smallest rank in the box, −θ) comes
   no earlier than the incumbent's key: then no (θ, t) in it has a higher value, nor an equal value
   with an earlier translation or, at the same translation, a smaller angle. The incumbent only
   rises, so a region discarded against an earlier incumbent stays discarded. When every region has
   been evaluated or discarded, the incumbent is the reference's (θc, tc). The order in which regions
   are visited decides nothing, only values and ranks do.
3. *The refinement exactly*, as the reference: 21 angles at tc by :class:`merger.sparse.SparseEvaluator`
   (the reference's floats), first maximum.

**Why the bounds hold.** Write R_t for the reference ROI at t and M_θ for the moving ROI rotated by θ:
lattice point k (offsets :func:`merger.sparse.lattice_coords`) of M_θ holds the state of the moving cell
containing c_m + R(−θ)k (unknown outside the moving ROI's square); M_θ does not depend on t. A box of
translations [a0, a1] × [b0, b1] is *consistent* when every R_t is a plain block of the evaluator's padded
reference whose first row and column advance by exactly one cell per cell of translation; then
R_t(k) = Pad(r0 + δ_b + k_i, c0 + δ_a + k_j) with δ = t − (a0, b0). A box that is not (float ties in the
reference lattice: centers on cell borders) gets the sector bounds of a *loose* box — the same argument
with the displacement radius measured on the box's own row and column indices and repeated reads of a
cell weighted (:meth:`merger.window_bounds.BoxBounds._loose`) — or, when its cells do not fit the big
lattice, is cut into single translations. A single translation's box needs no consistency: U = I = its
own ROI (whatever rows and columns of the reference it reads, as the reference reads them) and ρ = 0, so
the sector bounds below are :mod:`merger.fast`'s rotation-only ones for that ROI. The translations of a
box that is not consistent get no box bound in stage (b): they are evaluated exactly at every angle
their sector bound keeps.

* *Sector bounds* (a). Let t_c be the box's center (boxes have odd sides) and s = (s_a, s_b) its
  half-sides. Every lattice point of R_t is a point x = k + δ of the union lattice U (side n + 2s) about
  c_ref + t_c, δ = t − t_c, and its lookup is c_m + R(−θ)k = c_m + R(−θ)x − R(−θ)δ with
  |R(−θ)δ| = |δ| ≤ ρ = ‖s‖·cell. :mod:`merger.fast`'s argument for a whole-degree rotation then holds with
  "the lookup lies in the sector s(x) − θ" replaced by "within ρ of it": *MayOcc_ρ* marks every sector
  that a moving block holding an occupied cell (not outside the square) touches once grown by ρ
  (``grow`` in :func:`merger.fast._polar_boxes`: radii ∓ρ, angular half-width from its half-diagonal + ρ);
  *SureFree_ρ* requires the sector's center in a Fin block and no boundary block of Fin touching it grown
  by ρ — the ρ-neighbourhood of a sector is connected, so the path argument shows every point of it lies
  in a Fin block; *MayFree_ρ*, *SureOcc_ρ* likewise. So for every t in the box: agr̃ ≤ Σ over the
  reference-occupied points of U of MayOcc_ρ; dis ≥ Σ over the reference-occupied points of the
  intersection lattice I (side n − 2s: points of every R_t) of SureFree_ρ (+ reference-free points of I
  against SureOcc_ρ for Birk–Carpin); free/free ≤ Σ over the free points of U of MayFree_ρ. NCC: Σxy = agr̃
  ≤ that bound; Σy(θ) (occupied lookups of the n-lattice) does not depend on t and is bounded by the
  ungrown classes; Σx(t) is exact per t (a summed-area table of the padded reference); the bound is the
  largest of :func:`merger.fast._ncc_upper` over the box's values of Σx. One sector layout, for the
  lattice of side n + 2K, serves every box (U, I and the ROI lattice are its centred sub-blocks, with the
  same coordinates); the counts are circular correlations over the 360 degree shifts, exact integers as
  in :mod:`merger.fast`.
* *Pooled references* (b). With M_θ exact (:func:`merger.transform.rotated_roi_fast`, the reference's
  states) and a consistent box of hb × ha translations: agr̃(θ, t) = Σ_{k ∈ P_θ} Occ(R_t(k)) ≤ Σ_{k ∈ P_θ}
  MaxOcc(r0 + k_i, c0 + k_j), P_θ the occupied lattice points of M_θ and MaxOcc the maximum of the
  occupied indicator over the box's shifts δ (``cv2.dilate`` with an hb × ha kernel anchored at its first
  cell, 0 beyond the padded grid — never read: every R_t lies inside it); dis ≥ Σ_{k ∈ P_θ} MinFree(…)
  + Σ_{k: M_θ free} MinOcc(…) (``cv2.erode``: free, resp. occupied, for every shift); free/free ≤
  Σ_{k: M_θ free} MaxFree(…). NCC: Σy = |P_θ| exactly, Σx(t) exactly, and (Σxy − Σx·Σy/N)/√(vx·vy) grows
  with Σxy: the largest over the box's Σx of :func:`merger.sparse.ncc_from_sums` at Σxy = the bound.
  For ω̃ the exact M_θ is replaced by bounds of its states, lo ≤ M_θ ≤ hi
  (:func:`merger.transform.rotated_roi_classes`, which proves them): agr̃ is bounded over the points
  that *may* be occupied (hi), dis over the points surely occupied (lo) and the points surely free
  (lo = hi = free) — a superset where agr̃ grows, subsets where dis shrinks, so the bound still holds.
* *Counts → scores*: ω̃ = a/(a + d) grows with a and falls with d; integers are exact in float64 and a
  correctly rounded division is monotone, so the float bound is ≥ the reference's float (Birk–Carpin
  with a + free/free likewise). A bound equal to the incumbent's value excludes only regions whose
  translations all rank after it (the tie order), so plateaus of equal scores are decided by the
  ranks and angles, as the reference decides them.
* *Exact values* — the incumbent's and every evaluation's — are :class:`WindowEvaluator`'s, equal as floats
  to the reference's (tested against :meth:`RotationProblem.evaluate` on random grids, centers on cell
  borders, ROIs leaving the grid).

**Evidence.** ``profile`` is an **upper envelope** of the reference's profile (max over t per coarse
angle): per angle, the largest of the bounds that discarded its regions and of its exact values — exact
only where the best translation was evaluated. ``runner_up`` is **approximate**: the best coarse angle
≥ 10° from θ of the approximate table, overwritten by the exact values evaluated (as before this
search was exact); :func:`exact_window_runner_up` computes the reference's runner-up exactly with the
same certificate (costly when the runner-up is at the noise level: few regions can be excluded there).
The guard beyond the window (:func:`beyond_window`) is a heuristic in what it looks at (documented there).

A rotated moving ROI depends only on the moving map, its center and θ: they are kept in a bounded
cache keyed by the map's content (:func:`_rotated`), shared by the searches of a merge cycle and of
the next cycles while the map is unchanged.

**Sub-cell refinement** (:func:`refine_alignment`, on by default): the grid answer is refined below the
grid — θ starts at the middle of a plateau of equal best fine scores, then (θ, t) climb a smooth score
(the reference's occupied cells blurred into a likelihood field, read bilinearly at the moving map's
occupied cells), within ±1° and ±1 cell of the grid answer. A parabola through the grid's own scores
was tried first and rejected: nearest-neighbour scores carry little sub-cell information, and its
offsets lowered the whole-map ν of correct merges below ν_min.
"""

from __future__ import annotations

import hashlib
import math
import threading
from collections import OrderedDict
from functools import lru_cache

import numpy as np
import scipy.fft as sfft

from .grid import FREE_S, OCCUPIED_S
from .polar import PROFILE_LEN, _max_pool, _spectra, polar_layout, polar_spectra, square_crop
from .similarity import Counts, index_from_counts
from .sparse import SparseEvaluator, lattice_coords, ncc_from_sums
from .transform import rotated_roi_classes, rotated_roi_fast

POLAR_POOL_MIN = 2  # the approximate stage pools at least 2× (10 cm cells at 5 cm)
POLAR_TARGET_CELLS = 40  # ... and keeps about this many pooled cells across the ROI
MAX_LATTICE_STEPS = 3  # ... and coarser for wide windows: at most ±3 pooled cells of translation
FREE_CHUNK = 1 << 21  # lookups per batch of the free/free gathers (Birk–Carpin)
WINDOW_CANDIDATES = 5  # approximate peaks climbed exactly (the best end: the certificate's first incumbent)
FIRST_LOOK_STRIDE = 2  # a climb's first look over the start's pooled cell samples every other cell
NMS_DEG = 4  # peaks closer than this (and within one pooled cell) are one peak
OPPOSITE_DEG = 20


def window_cells(window_m: float, resolution: float) -> int:
    """K: translations of at most K cells each way fit in ±window_m."""
    return int(math.floor(window_m / resolution + 1e-9)) if window_m > 0 else 0


def translation_offsets(k: int) -> list[tuple[int, int]]:
    """All (a, b) with |a|, |b| ≤ k, nearest first: by a² + b², then b, then a (the tie order)."""
    ts = [(a, b) for b in range(-k, k + 1) for a in range(-k, k + 1)]
    return sorted(ts, key=lambda t: (t[0] * t[0] + t[1] * t[1], t[1], t[0]))


# --- the exhaustive reference -----------------------------------------------------------------------
def reference_window_search(problem):
    """Exhaustive rotation × translation search (see the module documentation); slow, the yardstick."""
    from .search import Alignment, fine_angles, measure_fn, runner_up, wrap_deg

    fn = measure_fn(problem.measure)
    ts = translation_offsets(problem.window_cells)
    refs = [problem.at(a, b).ref_roi() for a, b in ts]
    table = np.empty((len(ts), 360))
    for th in range(360):
        mov = problem.moving_roi(float(th))
        for i, r in enumerate(refs):
            table[i, th] = fn(r, mov).value
    i_best, th_best = np.unravel_index(int(np.argmax(table)), table.shape)  # first max: t order, then θ
    tc = ts[int(i_best)]
    sub = problem.at(*tc)
    best = None
    angles = fine_angles(float(th_best))
    fine_vals = []
    for a in angles:
        s = fn(refs[int(i_best)], sub.moving_roi(float(a)))
        fine_vals.append(s.value)
        if best is None or s.value > best[1].value:
            best = (float(a), s)
    theta = wrap_deg(best[0])
    profile = table.max(axis=0)
    best_value = float(table[int(i_best), int(th_best)])
    return Alignment(theta, best[1].value, best[1].counts, problem.measure, "reference", problem.roi_m,
                     profile, runner_up(profile, theta), window_m=problem.window_m,
                     translation_m=problem.offset_m(*tc), cells=tc,
                     fine=(np.asarray(angles, np.float64), np.asarray(fine_vals, np.float64)),
                     _beyond=lambda: reference_beyond(problem, best_value, (int(th_best), tc)))


def reference_beyond(problem, best_value: float, answer):
    """Exhaustively, the best coarse (θ, t) outside the window and inside ``BEYOND_FACTOR`` × the window
    (at most a quarter of the ROI side) that scores above ``best_value`` and is apart from the grid answer
    ``answer`` = (θ°, (a, b) cells) (:func:`_apart`): ``(θ°, (tx, ty) m, score)``, else None. The
    yardstick of :func:`beyond_window` (which looks only near approximate peaks)."""
    from .search import measure_fn

    big = _wide(problem)
    k, kb = problem.window_cells, big.window_cells
    if kb <= k:
        return None
    fn = measure_fn(problem.measure)
    ring = [t for t in translation_offsets(kb) if max(abs(t[0]), abs(t[1])) > k]
    refs = [big.at(a, b).ref_roi() for a, b in ring]
    out = None
    for th in range(360):
        mov = big.moving_roi(float(th))
        for t, r in zip(ring, refs, strict=True):
            v = fn(r, mov).value
            if v > best_value and (out is None or v > out[2]) and _apart(problem, (th, t), answer):
                out = (float(th), big.offset_m(*t), float(v))
    return out


def _wide(problem):
    """The problem with the guard's wider window (rotation and translation grid only)."""
    from dataclasses import replace

    from .search import MAX_WINDOW_FRACTION

    wide = min(BEYOND_FACTOR * problem.window_m, MAX_WINDOW_FRACTION * problem.roi_m)
    return replace(problem, window_m=wide, refine=False)


# --- exact evaluation of one angle at many translations ---------------------------------------------
class WindowEvaluator:
    """Exact values of a windowed problem at (θ, t) — equal as floats to the reference's.

    For one angle the moving ROI rotated by θ (:meth:`RotationProblem.moving_roi`) is the same for every
    translation; it is computed once (:func:`merger.transform.rotated_roi_fast`: OpenCV's warp, with
    the lookups near a cell border recomputed, the same states as the reference's). The reference ROI at t is the reference grid
    sampled on the lattice about ``c_ref + t`` with the reference's own arithmetic (per-axis cell indices,
    :func:`merger.sparse.fast_extract_roi`), so the counts are gathers: the moving-occupied lattice points
    against the reference (agr̃, half of dis) and the reference-occupied cells against the moving ROI's free
    cells (the other half of dis).
    """

    def __init__(self, problem) -> None:
        self.problem = problem
        n = self.n = problem.n
        self.res = problem.ref.resolution
        self.k = lattice_coords(n, self.res)
        ref = problem.ref
        self.reach = problem.window_cells + 1  # translations evaluated: |a|, |b| ≤ reach (the window and
        self._tab = None                       # one cell beyond, for the refinement at its edge)
        # the part of the reference that the windows' ROIs read, padded with unknown cells so that every
        # window's ROI lies inside: a shifted block of it is then a plain slice (no clipping); its size
        # follows the ROI and the window, not the map's (a 200 m map costs what a 10 m one does)
        (_, _, _, (sx, lx)), (_, _, _, (sy, ly)) = self._axes_table()
        self._pad = np.zeros((ly, lx), np.uint8)
        y0, y1 = max(sy, 0), min(sy + ly, ref.height)
        x0, x1 = max(sx, 0), min(sx + lx, ref.width)
        if y0 < y1 and x0 < x1:
            self._pad[y0 - sy:y1 - sy, x0 - sx:x1 - sx] = ref.states[y0:y1, x0:x1]
        self._padO = (self._pad == OCCUPIED_S).reshape(-1)
        self._padflat = self._pad.reshape(-1)
        self._q = None
        self._margin = 0
        self._mov: dict[float, np.ndarray] = {}
        self._movb: dict[float, tuple] = {}  # per angle: bound classes (moving_bounds)
        self._lut = None
        self._blocks = None  # (_similarity_blocks' tables)
        self._dig = None
        self._inv = None  # (_inverse_axes' tables)
        self.values: dict[float, np.ndarray] = {}  # per angle: values by (b, a) + reach (NaN: not yet)

    def _digest(self) -> bytes:
        if self._dig is None:
            self._dig = grid_digest(self.problem.moving)
        return self._dig

    def _axes_table(self):
        """Per translation index −K..K: the padded reference columns (rows) of the ROI lattice about
        c_ref + t, with the reference's own arithmetic (:meth:`RotationProblem.center_at`, extract_roi),
        whether they form plain blocks, their first ones, and the padded part (the grid's first cell in
        it, its length): every index one cell or more from its ends (cells outside the grid are unknown,
        as extract_roi reads them; integer shifts of the reference's own indices)."""
        if self._tab is None:
            ref, kk = self.problem.ref, self.reach
            steps = np.arange(-kk, kk + 1) * ref.resolution  # a · res, as offset_m
            cx, cy = self.problem.center_ref
            out = []
            for c, o in ((cx, ref.origin[0]), (cy, ref.origin[1])):
                cs = c + steps
                cs[kk] = c  # t = 0 is the given center itself
                idx = np.floor((cs[:, None] + self.k[None, :] - o) / ref.resolution).astype(np.int64)
                block = (np.diff(idx, axis=1) == 1).all(axis=1)
                shift = int(idx.min()) - 1  # grid cell of padded index 0
                idx -= shift
                out.append((idx, block, idx[:, 0], (shift, int(idx.max()) + 2)))
            self._tab = out
        return self._tab

    def _axis(self, a: int, b: int):
        """Padded reference row and column indices of the ROI lattice about c_ref + t (as extract_roi),
        and the first ones when they are plain blocks (None otherwise)."""
        (cols, cb, cf, _), (rows, rb, rf, _) = self._axes_table()
        kk = self.reach
        i, j = a + kk, b + kk
        if not (0 <= i < cols.shape[0] and 0 <= j < rows.shape[0]):
            raise ValueError(f"translation ({a}, {b}) cells is outside the window ±{kk}")
        first = (int(rf[j]), int(cf[i])) if cb[i] and rb[j] else None
        return rows[j], cols[i], first

    def _occupied_cells(self):
        """Occupied cells of the padded reference that any window's ROI can hold, as flat indices in the
        padded moving-free image's width (see :meth:`_counts`), and that image's margin; as padded
        (rows, columns) in ``_q_rc``."""
        if self._q is None:
            n = self.n
            (cols_t, _, _, _), (rows_t, _, _, _) = self._axes_table()
            # the rows and columns any window reads: [r0, r1) × [c0, c1), inside the padded part
            r0, r1 = int(rows_t.min()), int(rows_t.max()) + 1
            c0, c1 = int(cols_t.min()), int(cols_t.max()) + 1
            m = self._margin = max(r1 - r0, c1 - c0) - n + 2
            qr, qc = np.nonzero(self._padO.reshape(self._pad.shape)[r0:r1, c0:c1])
            qr += r0
            qc += c0
            self._q_rc = (qr, qc)
            self._q = qr * (n + 2 * m) + qc
            inside = np.zeros((n + 2 * m, n + 2 * m), bool)
            inside[m:m + n, m:m + n] = True
            self._inside = inside.reshape(-1)
        return self._q

    def moving(self, thetas) -> None:
        """Compute (and keep) the rotated moving ROIs of ``thetas``: per angle the moving-occupied
        lattice points and the moving-free indicator, padded for the translation gathers."""
        todo = [float(t) for t in dict.fromkeys(thetas) if float(t) not in self._mov]
        if not todo:
            return
        self._occupied_cells()
        n, m = self.n, self._margin
        w = n + 2 * m
        wp = self._pad.shape[1]
        p = self.problem
        for t in todo:
            mov = _rotated(p.moving, self._digest(), t, p.center_moving, n, self.res)
            pi, pj = np.divmod(np.flatnonzero(mov == OCCUPIED_S), n)
            mfp = np.zeros((w, w), bool)
            mfp[m:m + n, m:m + n] = (mov == FREE_S).reshape(n, n)
            # moving-occupied lattice points (i, j), and as flat offsets i·wp + j from the ROI's first cell
            self._mov[t] = ((pi, pj, pi * wp + pj), mfp.reshape(-1), mov)

    def moving_bounds(self, theta: float):
        """For bounds only (ω̃): ``(P⁺, P⁻, MF⁻)`` at angle θ — the flat offsets (as :meth:`moving`'s) of
        the lattice points whose rotated moving state may be / surely is occupied, and the padded
        indicator of those surely free (:func:`merger.transform.rotated_roi_classes`: four uncertified
        warps, cheaper than the exact ROI); the exact classes when θ's exact ROI is already known or
        the warps cannot be used."""
        theta = float(theta)
        hit = self._movb.get(theta)
        if hit is not None:
            return hit
        cls = None
        if theta not in self._mov:
            p = self.problem
            cls = rotated_roi_classes(p.moving, theta, p.center_moving, self.n, self.res)
        if cls is None:
            self.moving([theta])
            (_, _, pflat), mfp, _ = self._mov[theta]
            return pflat, pflat, mfp
        self._occupied_cells()
        n, m = self.n, self._margin
        w = n + 2 * m
        lut = self._lut
        if lut is None:  # lattice flat index -> offset i·wp + j from the ROI's first padded cell
            i, j = np.divmod(np.arange(n * n), n)
            lut = self._lut = i * self._pad.shape[1] + j
        lo, hi = cls
        mfp = np.zeros((w, w), bool)
        mfp[m:m + n, m:m + n] = ((lo == FREE_S) & (hi == FREE_S)).reshape(n, n)
        hit = self._movb[theta] = (lut[np.flatnonzero(hi == OCCUPIED_S)], lut[np.flatnonzero(lo == OCCUPIED_S)],
                                   mfp.reshape(-1))
        return hit

    def evaluate(self, theta: float, ts) -> np.ndarray:
        """Values at angle θ and translations ``ts`` [(a, b), ...] (cells)."""
        ts = np.asarray(ts, np.intp).reshape(-1, 2)
        return self.evaluate_ab(theta, ts[:, 0], ts[:, 1])

    def evaluate_ab(self, theta: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Values at angle θ and translations (a[i], b[i]) cells (arrays)."""
        theta = float(theta)
        tab = self.values.get(theta)
        if tab is None:
            tab = self.values[theta] = np.full((2 * self.reach + 1, 2 * self.reach + 1), np.nan)
        ia, ib = a + self.reach, b + self.reach
        if ia.size and (min(ia.min(), ib.min()) < 0 or max(ia.max(), ib.max()) > 2 * self.reach):
            # checked before the table is read: a negative index would wrap to another translation's value
            raise ValueError(f"a translation of {np.stack([a, b], axis=1).tolist()} cells is outside the "
                             f"evaluator's reach ±{self.reach}")
        out = tab[ib, ia]
        miss = np.isnan(out)
        if miss.any():
            self.moving([theta])
            todo = np.stack([a[miss], b[miss]], axis=1)  # distinct: callers pass distinct translations
            tab[ib[miss], ia[miss]] = self._values(theta, todo)
            out = tab[ib, ia]
        return out

    def _similarity_blocks(self, theta: float, ia: np.ndarray, ib: np.ndarray):
        """ω̃ at angle θ and translation indices (``ia``, ``ib``) = (a, b) + reach (checked in reach) when
        every window is a plain block of the padded reference (the usual case; None otherwise):
        :meth:`_counts`'s gathers, fewer steps — per-evaluator tables (each window's first padded cell,
        its offset in the moving-free image) and one gather of a code image (occupied 1, free 2³²: agr̃
        and the moving-occupied half of dis in one sum). The floats are
        :func:`merger.similarity.index_from_counts`'s: integer counts, one correctly rounded division."""
        if self._blocks is None:
            (_, cb, cf, _), (_, rb, rf, _) = self._tab
            self._occupied_cells()
            m, wp = self._margin, self._pad.shape[1]
            code = np.zeros(256, np.int64)
            code[OCCUPIED_S], code[FREE_S] = 1, 1 << 32
            self._blocks = (rb[:, None] & cb[None, :], rf[:, None] * wp + cf[None, :],
                            (rf[:, None] - m) * (self.n + 2 * m) + (cf[None, :] - m), code[self._pad].reshape(-1))
        ok, base, shift, padcode = self._blocks
        if not ok[ib, ia].all():
            return None
        (_, _, pflat), mfp, _ = self._mov[theta]
        s = padcode[base[ib, ia][:, None] + pflat[None, :]].sum(axis=1)
        agr = s & 0xFFFFFFFF
        tot = agr + (s >> 32)
        if self._q.size:  # the reference-occupied cells of each window against the moving free cells
            tot += np.count_nonzero(mfp[self._q[None, :] - shift[ib, ia][:, None]], axis=1)
        return np.where(tot > 0, agr / np.maximum(tot, 1), 0.0)

    def counts(self, theta: float, t) -> Counts:
        self.moving([theta])
        c = self._counts(float(theta), [tuple(t)])
        return Counts(int(c[0][0]), int(c[1][0] + c[2][0]), int(c[3][0]))

    def _counts(self, theta: float, ts, free_agree: bool = True):
        """Per translation: agr̃, dis where the moving map is occupied, dis where the reference is,
        free/free (if asked), the reference ROI's occupied count; and the moving ROI's occupied count."""
        n = self.n
        (cols_t, cb, cf, _), (rows_t, rb, rf, _) = self._axes_table()
        ia, ib = self._indices(ts)
        (pi, pj, pflat), mfp, mov = self._mov[theta]
        wp = self._pad.shape[1]
        block = cb[ia] & rb[ib]
        nt = ia.size
        if block.all():  # plain blocks (of the padded grid): shifted flat indices
            idx = (rf[ib] * wp + cf[ia])[:, None] + pflat[None, :]
        else:
            idx = rows_t[ib][:, pi] * wp + cols_t[ia][:, pj]
        st = self._pad.reshape(-1)[idx]  # (T, |P|): reference states under the moving-occupied points
        agr = np.count_nonzero(st == OCCUPIED_S, axis=1)
        d_mo = np.count_nonzero(st == FREE_S, axis=1)
        d_ro = np.zeros(nt, np.int64)
        sx = np.zeros(nt, np.int64)
        ff = np.zeros(nt, np.int64)
        qflat = self._q
        if block.any() and qflat.size:  # each window's reference-occupied cells against the moving free cells
            m = self._margin
            w = n + 2 * m
            flat = qflat[None, :] - ((rf[ib[block]] - m) * w + (cf[ia[block]] - m))[:, None]
            d_ro[block] = np.count_nonzero(mfp[flat], axis=1)
            if self.problem.measure == "ncc":
                sx[block] = np.count_nonzero(self._inside[flat], axis=1)
        if free_agree and block.any():  # free/free: the moving-free lattice points against each block
            fi, fj = np.divmod(np.flatnonzero(mov == FREE_S), n)
            fflat = fi * wp + fj
            rows = np.flatnonzero(block)
            step = max(1, FREE_CHUNK // max(fflat.size, 1))
            for c0 in range(0, rows.size, step):
                rr = rows[c0:c0 + step]
                st = self._padflat[(rf[ib[rr]] * wp + cf[ia[rr]])[:, None] + fflat[None, :]]
                ff[rr] = np.count_nonzero(st == FREE_S, axis=1)
        if not block.all():  # not plain blocks (float ties in the lattice: centers on cell borders)
            self._counts_general(theta, ia, ib, ~block, d_ro, ff, sx, free_agree)
        return agr, d_mo, d_ro, ff, sx, pflat.size

    def _inverse_axes(self):
        """Per translation index and axis, for every padded reference row (column) r: the lattice indices
        [first, last) whose ROI row (column) is r. The ROI's rows are floors of increasing values —
        correctly rounded sums and quotients are monotone — so they never decrease, and the lattice points
        that read the padded cell (r, c) at translation t are exactly the rectangle [first_r, last_r) ×
        [first_c, last_c) (empty when t's ROI does not hold the cell)."""
        if self._inv is None:
            (cols_t, _, _, _), (rows_t, _, _, _) = self._axes_table()
            hp, wp = self._pad.shape
            out = []
            for idx, size in ((rows_t, hp), (cols_t, wp)):
                if (np.diff(idx, axis=1) < 0).any():  # cannot happen (monotone arithmetic); kept as a guard
                    raise AssertionError("the reference ROI's cell indices decrease along an axis")
                r = np.arange(size + 1)
                out.append((np.stack([np.searchsorted(row, r, "left") for row in idx]),
                            np.stack([np.searchsorted(row, r, "right") for row in idx])))
            (rf0, rl0), (cf0, cl0) = out
            self._inv = (rf0, rl0, cf0, cl0)
            self._occupied_cells()  # _q_rc: the occupied cells any window's ROI can hold
        return self._inv

    def _counts_general(self, theta: float, ia, ib, rows_sel, d_ro, ff, sx, free_agree: bool) -> None:
        """:meth:`_counts` for the translations ``rows_sel`` whose reference ROI is not a plain block: the
        reference-occupied cells against the moving free ones by a summed-area table of the moving-free
        lattice (each padded cell is read by a rectangle of lattice points, :meth:`_inverse_axes`), the
        free/free count by gathers over the moving-free points (integers: the reference's counts)."""
        n = self.n
        rf0, rl0, cf0, cl0 = self._inverse_axes()
        qr, qc = self._q_rc
        (cols_t, _, _, _), (rows_t, _, _, _) = self._axes_table()
        (_, _, _), _, mov = self._mov[theta]
        mf = (mov == FREE_S).reshape(n, n)
        sat = np.zeros((n + 1, n + 1), np.int64)
        sat[1:, 1:] = mf.cumsum(0).cumsum(1)
        satf = sat.reshape(-1)
        wp = self._pad.shape[1]
        sel = np.flatnonzero(rows_sel)
        step = max(1, FREE_CHUNK // max(qr.size, 1))
        for c0 in range(0, sel.size, step):
            rr = sel[c0:c0 + step]
            i0, i1 = rf0[ib[rr]][:, qr], rl0[ib[rr]][:, qr]
            j0, j1 = cf0[ia[rr]][:, qc], cl0[ia[rr]][:, qc]
            d_ro[rr] = (satf[i1 * (n + 1) + j1] - satf[i0 * (n + 1) + j1] - satf[i1 * (n + 1) + j0]
                        + satf[i0 * (n + 1) + j0]).sum(axis=1)
            if self.problem.measure == "ncc":
                sx[rr] = ((i1 - i0) * (j1 - j0)).sum(axis=1)
        if free_agree:
            fi, fj = np.divmod(np.flatnonzero(mf.reshape(-1)), n)
            step = max(1, FREE_CHUNK // max(fi.size, 1))
            for c0 in range(0, sel.size, step):
                rr = sel[c0:c0 + step]
                st = self._padflat[rows_t[ib[rr]][:, fi] * wp + cols_t[ia[rr]][:, fj]]
                ff[rr] = np.count_nonzero(st == FREE_S, axis=1)

    def _indices(self, ts):
        """Indices into the axes table of translations ``ts`` [(a, b), ...] cells (checked in reach)."""
        kk = self.reach
        ts = np.asarray(ts, np.intp).reshape(-1, 2)
        ia, ib = ts[:, 0] + kk, ts[:, 1] + kk
        if ia.min() < 0 or ib.min() < 0 or ia.max() > 2 * kk or ib.max() > 2 * kk:
            raise ValueError(f"a translation of {ts.tolist()} cells is outside the evaluator's reach ±{kk}")
        return ia, ib

    def _values(self, theta: float, ts) -> list[float]:
        m = self.problem.measure
        if m == "similarity":
            fast = self._similarity_blocks(theta, *self._indices(ts))
            if fast is not None:
                return fast
        agr, d_mo, d_ro, ff, sx, sy = self._counts(theta, ts, free_agree=m == "birk_carpin")
        if m == "similarity":  # index_from_counts, inlined (Python ints: the same floats)
            return np.array([a / (a + d) if a + d else 0.0
                             for a, d in zip(agr.tolist(), (d_mo + d_ro).tolist(), strict=True)], np.float64)
        out = []
        for r in range(len(ts)):
            a, d = int(agr[r]), int(d_mo[r] + d_ro[r])
            if m == "ncc":
                out.append(ncc_from_sums(self.n * self.n, float(sx[r]), float(sy), float(a)))
            else:
                out.append(index_from_counts(Counts(a, d, int(ff[r])), m))
        return np.array(out, np.float64)


_HANDOFF = threading.local()  # this thread's last windowed search: (problem, its evaluator)


def evaluator_for(problem) -> WindowEvaluator:
    """A :class:`WindowEvaluator` of ``problem``: the one this thread's last windowed search of that very
    problem object used (taken once: its rotated ROIs and exact values serve the rivals of
    :mod:`merger.ambiguity`, which evaluate the same problem right after it), else a new one. Its
    values are the same floats either way (exact, deterministic)."""
    last = getattr(_HANDOFF, "last", None)
    _HANDOFF.last = None
    if last is not None and last[0] is problem:
        return last[1]
    return WindowEvaluator(problem)


# --- rotated moving ROIs, shared between searches --------------------------------------------------
_ROT: OrderedDict = OrderedDict()
_ROT_BYTES = [0]
ROT_CACHE_BYTES = 48 * 2**20  # the cache's bound
_ROT_LOCK = threading.Lock()


def grid_digest(grid) -> bytes:
    """A content key of a grid: its states, shape, resolution and origin."""
    h = hashlib.blake2b(np.ascontiguousarray(grid.states).data, digest_size=16)
    h.update(repr((grid.shape, grid.resolution, grid.origin)).encode())
    return h.digest()


def clear_rotation_cache() -> None:
    with _ROT_LOCK:
        _ROT.clear()
        _ROT_BYTES[0] = 0


def _rotated(moving, digest: bytes, theta: float, center, n: int, res: float) -> np.ndarray:
    """:func:`merger.transform.rotated_roi_fast` (flat), from a bounded cache keyed by content: a map is
    the moving map of several searches of a merge cycle, and of the next cycles while it is unchanged."""
    key = (digest, float(center[0]), float(center[1]), n, res, theta)
    with _ROT_LOCK:
        hit = _ROT.get(key)
        if hit is not None:
            _ROT.move_to_end(key)
            return hit
    out = rotated_roi_fast(moving, theta, center, n, res).reshape(-1)
    out.setflags(write=False)
    with _ROT_LOCK:
        if key not in _ROT:
            _ROT[key] = out
            _ROT_BYTES[0] += out.nbytes
            while _ROT_BYTES[0] > ROT_CACHE_BYTES and _ROT:
                _ROT_BYTES[0] -= _ROT.popitem(last=False)[1].nbytes
    return out


# --- the approximate stage ----------------------------------------------------------------------------
def window_pool(n: int, k: int) -> int:
    """The approximate stage's pooling factor for an ROI of n cells and a window of ±k cells."""
    return max(POLAR_POOL_MIN, int(round(n / POLAR_TARGET_CELLS)), int(math.ceil(k / MAX_LATTICE_STEPS)))


def approximate_window_table(problem, k: int, pool: int | None = None):
    """Approximate values for every angle (1°) at translations of a coarse lattice.

    Returns ``(ts, table)``: translations in cells [(a, b), ...] (multiples of the pooling factor, the
    window's edges included) and a (len(ts), 360) array."""
    n, res = problem.n, problem.ref.resolution
    if pool is None:
        pool = window_pool(n, k)
    lay = polar_layout(n, res, pool, True)
    mov = polar_spectra(problem.moving, problem.center_moving, lay)
    kp = max(1, int(round(k / pool)))  # lattice steps of one pooled cell, covering about ±k
    ts = [(x * pool, y * pool) for y in range(-kp, kp + 1) for x in range(-kp, kp + 1)]
    # the reference's pooled crop about c_ref, wide enough for every shift
    cx, cy = problem.center_ref
    crop, (ox, oy) = square_crop(problem.ref, (cx, cy),
                                 n * res / 2.0 * math.sqrt(2) + 2 * res * pool + kp * pool * res, pool)
    pooled = _max_pool(crop, pool)
    ps = pooled.shape[0]
    pres = res * pool
    ix = np.clip(np.floor((lay.x + (cx - ox)) / pres).astype(np.intp), kp, ps - 1 - kp)
    iy = np.clip(np.floor((lay.y + (cy - oy)) / pres).astype(np.intp), kp, ps - 1 - kp)
    base = np.where(lay.mask, iy * ps + ix, -1)
    shifts = np.array([(b // pool) * ps + a // pool for a, b in ts], np.intp)
    flat = np.append(pooled.reshape(-1), np.uint8(0))  # index −1 (outside the ROI square): unknown
    idx = base[None, :] + shifts[:, None]
    idx[:, base < 0] = -1
    s = flat[idx]
    values = np.stack([s == OCCUPIED_S, s == FREE_S], axis=1).astype(np.float32)
    spec = _spectra(lay, values.reshape(-1, values.shape[-1])).reshape(len(ts), 2, -1, mov.shape[-1])
    bc = np.conj(mov)
    pairs = [spec[:, 0] * bc[0], spec[:, 0] * bc[1] + spec[:, 1] * bc[0]]
    if problem.measure == "birk_carpin":
        pairs.append(spec[:, 1] * bc[1])
    elif problem.measure == "ncc":
        pairs += [np.broadcast_to(lay.mask_spec[0] * bc[0], spec[:, 0].shape),
                  spec[:, 0] * np.conj(lay.mask_spec[0])[None]]
    sp = np.stack([p.sum(axis=1) for p in pairs], axis=1)  # (T, P, 181)
    corr = sfft.irfft(sp, n=PROFILE_LEN, axis=-1)
    agr, dis = corr[:, 0], corr[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        if problem.measure == "similarity":
            val = agr / (agr + dis)
        elif problem.measure == "birk_carpin":
            val = (agr + corr[:, 2]) / (agr + corr[:, 2] + dis)
        else:
            size_c = float(n / pool) ** 2
            sx, sy = corr[:, 3][:, :1], corr[:, 2]
            vx, vy = sx - sx * sx / size_c, sy - sy * sy / size_c
            val = (agr - sx * sy / size_c) / np.sqrt(np.maximum(vx * vy, 1e-12))
    return ts, np.nan_to_num(val, nan=0.0, posinf=0.0, neginf=0.0), pool


def _peaks(ts, table, pool: int, limit: int):
    """The approximate table's best entries, one per peak (suppressing neighbours within NMS_DEG and a
    pooled cell), plus the best within OPPOSITE_DEG of the top's half turn."""
    from .search import angle_diff_deg

    flat_t = table.reshape(-1)
    m = min(50 * limit, flat_t.size - 1)
    top_idx = np.argpartition(-flat_t, m)[: m + 1]
    order = top_idx[np.lexsort((top_idx, -flat_t[top_idx]))]
    picked: list[tuple[int, int, int]] = []
    for flat in order:
        i, th = divmod(int(flat), 360)
        a, b = ts[i]
        if any(abs(angle_diff_deg(th, p[0])) <= NMS_DEG and abs(a - p[1]) <= pool and abs(b - p[2]) <= pool
               for p in picked):
            continue
        picked.append((th, a, b))
        if len(picked) >= limit:
            break
    top = picked[0]
    opp = np.abs(angle_diff_deg(np.arange(360.0), top[0] + 180.0)) <= OPPOSITE_DEG
    sub = np.where(opp[None, :], table, -np.inf)
    i, th = np.unravel_index(int(np.argmax(sub)), sub.shape)
    cand = (int(th), *ts[int(i)])
    if all(abs(angle_diff_deg(cand[0], p[0])) > NMS_DEG for p in picked):
        picked.append(cand)
    return picked


@lru_cache(maxsize=16)
def _tie_rank(k: int) -> np.ndarray:
    """The reference's tie order over translations (nearest first), as a rank per (b + k, a + k)."""
    rank = np.empty((2 * k + 1, 2 * k + 1), np.int64)
    ts = np.array(translation_offsets(k), np.int64).reshape(-1, 2)
    rank[ts[:, 1] + k, ts[:, 0] + k] = np.arange(len(ts))
    rank.setflags(write=False)
    return rank


class _Climber:
    """Hill climbs on the exact coarse grid (1° × one cell) within ±k cells, with ``ev``'s values."""

    def __init__(self, ev: WindowEvaluator, k: int) -> None:
        self.ev, self.k, self.rank = ev, k, _tie_rank(k)
        self.walked: set = set()  # points a climb stepped from (r = 1): from there it is the same climb

    def best_in(self, th: int, a: int, b: int, r: int, stride: int = 1):
        """The best (value, −rank, −θ) of θ ± 1° × the box of half side r about (a, b), in the window,
        on the cells of the box ``stride`` apart (a, b itself included)."""
        k, rank = self.k, self.rank
        xs = np.arange(a - (a - max(-k, a - r)) // stride * stride, min(k, a + r) + 1, stride)
        ys = np.arange(b - (b - max(-k, b - r)) // stride * stride, min(k, b + r) + 1, stride)
        gy, gx = np.divmod(np.arange(xs.size * ys.size), xs.size)
        gx = xs[gx]
        gy = ys[gy]
        rk = rank[gy + k, gx + k]
        best = None
        for x in ((th - 1) % 360, th, (th + 1) % 360):
            v = self.ev.evaluate_ab(float(x), gx, gy)
            j = int(np.lexsort((rk, -v))[0])  # the best value, then the lowest rank
            key = (float(v[j]), -int(rk[j]), -x)
            if best is None or key > best[0]:
                best = (key, x, (int(gx[j]), int(gy[j])))
        return best

    def climb(self, th: int, t: tuple[int, int], r: int):
        """Climb from (θ, t), first looking over the box of half side r; returns (key, θ, t) of the
        local maximum, or None when the climb joins an earlier one (whose end is already known)."""
        key = None
        for _ in range(1000):
            if r == 1 and (th, t) in self.walked:
                return None
            if r == 1:
                self.walked.add((th, t))
            key, x, tt = self.best_in(th, *t, r, FIRST_LOOK_STRIDE if r > 1 else 1)
            if (x, tt) == (th, t) and r == 1:
                break
            th, t, r = x, tt, 1
        return key, th, t


def fast_window_search(problem, certify: bool = True):
    """The fast rotation × translation search: exactly the reference's grid answer (see the module
    documentation). ``certify=False`` (method ``"climb"``, :func:`climb_window_search`): the incumbent
    of the climbs without the certificate — about 2.4× cheaper, not exact (it misses the reference's
    answer where the approximate stage misses the best peak, e.g. on random-noise grids)."""
    from .search import Alignment, fine_angles, runner_up, wrap_deg
    from .window_bounds import Certifier

    k = problem.window_cells
    ts_c, table, pool = approximate_window_table(problem, k)
    starts = _peaks(ts_c, table, pool, WINDOW_CANDIDATES)
    ev = WindowEvaluator(problem)
    climber = _Climber(ev, k)
    ends = []
    for th0, a0, b0 in starts:
        end = climber.climb(th0, (a0, b0), max(1, pool // 2))  # first look: the pooled cell around the start
        if end is not None:
            ends.append(end)
    incumbent = max(ends, key=lambda e: e[0])
    if certify:
        cert = Certifier(problem, ev, climber.rank)
        best = cert.run(incumbent)  # the incumbent certified, or beaten
    else:
        best = incumbent
    _, th_c, tc = best
    sub = problem.at(*tc)
    sev = SparseEvaluator(sub)
    fine = [float(a) for a in fine_angles(float(th_c))]
    values = sev.scores(fine)
    kf = int(np.argmax(values))
    theta = wrap_deg(fine[kf])
    approx = table.max(axis=0)  # the runner-up's profile: approximate, exact where evaluated
    for x, tab in ev.values.items():
        tab = tab[1:-1, 1:-1]  # the window (the evaluator reaches one cell beyond)
        if float(x).is_integer() and 0 <= x < 360 and not np.isnan(tab).all():
            approx[int(x)] = np.nanmax(tab)
    # certified: an upper envelope of the reference's profile (exact where evaluated); climbs: approximate
    profile = cert.env.copy() if certify else approx.copy()

    best_value = best[0][0]
    _HANDOFF.last = (problem, ev)
    al = Alignment(theta, float(values[kf]), lambda: sev.similarity(fine[kf]).counts, problem.measure,
                   "fast" if certify else "climb", problem.roi_m, profile, lambda: runner_up(approx, theta),
                   window_m=problem.window_m, translation_m=problem.offset_m(*tc), cells=tc,
                   fine=(np.asarray(fine), np.asarray(values, np.float64)),
                   _beyond=lambda: beyond_window(problem, best_value, (th_c, tc)),
                   evidence={"profile": "upper_envelope" if certify else "approximate", "runner_up": "approximate"})
    return refine_alignment(problem, al, ev) if problem.refine else al


def climb_window_search(problem):
    """Method ``"climb"`` with a window: :func:`fast_window_search` without the certificate (approximate)."""
    return fast_window_search(problem, certify=False)


RUNNER_UP_STARTS = 2  # approximate peaks among the far angles climbed for the exact runner-up's first incumbent


def exact_window_runner_up(problem, theta_deg: float) -> tuple[float, float]:
    """The reference's runner-up of a windowed problem exactly — the first maximum, over the coarse angles
    at least 10° from ``theta_deg``, of the best value over the window's translations — by the
    certifier of :func:`fast_window_search` (ties: the smallest angle): ``(θ°, score)``, NaNs when no
    angle is that far. Costly when the runner-up scores near the noise level (few regions can be
    excluded): the windowed fast search's own ``runner_up`` is the approximate one."""
    from .search import RUNNER_UP_MIN_SEPARATION_DEG, angle_diff_deg
    from .window_bounds import Certifier

    far = np.abs(angle_diff_deg(np.arange(360.0), theta_deg)) >= RUNNER_UP_MIN_SEPARATION_DEG
    if not far.any():
        return float("nan"), float("nan")
    k = problem.window_cells
    ts, table, pool = approximate_window_table(problem, k)
    ev = WindowEvaluator(problem)
    climber = _Climber(ev, k)
    sub = np.where(far[None, :], table, -np.inf)
    for th, a, b in _peaks(ts, sub, pool, RUNNER_UP_STARTS):
        if far[th]:
            climber.climb(th, (a, b), max(1, pool // 2))
    inc = ((-math.inf, 0, 0), None, None)
    for x, tab in ev.values.items():
        tab = tab[1:-1, 1:-1]  # the window (the evaluator reaches one cell beyond)
        if float(x).is_integer() and 0 <= x < 360 and far[int(x)] and not np.isnan(tab).all():
            key = (float(np.nanmax(tab)), 0, -int(x))
            if key > inc[0]:
                inc = (key, int(x), None)
    (v, _, _), th, _ = Certifier(problem, ev, climber.rank).run(inc, far, use_rank=False)
    return float(th), float(v)


BEYOND_FACTOR = 2.0  # the guard looks for better alignments up to this × the window ...
BEYOND_SLACK = 0.15  # ... climbing from approximate peaks outside it within this of the best inside
BEYOND_CANDIDATES = 3
BEYOND_APART_STEPS = 1.5  # a rival is more than one grid step (1°, one cell, or one diagonal cell) away


def _apart(problem, a, b) -> bool:
    """Whether two grid alignments (θ°, (a, b) cells) are more than one grid step apart: further than
    BEYOND_APART_STEPS degrees or cells. A better alignment one step beyond the window's edge is the
    in-window answer's own peak, cut by the edge; one further away is another alignment (a truth the
    window does not reach, or a rival), and the in-window answer is off by more than a step."""
    from .search import angle_diff_deg

    if abs(angle_diff_deg(float(a[0]), float(b[0]))) > BEYOND_APART_STEPS:
        return True
    return math.dist(a[1], b[1]) > BEYOND_APART_STEPS


def beyond_window(problem, best_value: float, answer):
    """The best exact local maximum found outside the window, up to ``BEYOND_FACTOR`` × the window (at
    most a quarter of the ROI side), that scores above ``best_value`` and is apart from the grid answer
    ``answer`` = (θ°, (a, b) cells): ``(θ°, (tx, ty) m, score)``, or None. Within one grid step of the
    answer it is the answer's own peak, cut by the window's edge (:func:`_apart`).

    When the center error exceeds the window's reach the true alignment lies outside it, and the best
    alignment inside can be a rival (in a symmetric room, the half turn). The guard computes the
    approximate table (:func:`approximate_window_table`) over the wider window, and climbs exactly
    (1° × one cell) from its best peaks outside the window that come within ``BEYOND_SLACK`` of its best
    value inside. What it finds is evidence against the in-window answer, never an answer. It is a
    heuristic in what it looks at (it can miss a peak the approximate table ranks low) but exact in
    what it reports: a reported alignment is a real one, scoring more than the in-window answer."""
    k = problem.window_cells
    big = _wide(problem)
    kb = big.window_cells
    if kb <= k:
        return None
    ts, table, pool = approximate_window_table(big, kb)
    outside = np.array([max(abs(a), abs(b)) > k for a, b in ts])
    if not outside.any() or outside.all():
        return None
    floor = float(table[~outside].max()) - BEYOND_SLACK
    ring = np.where(outside[:, None], table, -np.inf)
    # inside entries are −inf in the ring, below the (finite) floor: every start lies outside
    starts = [p for p in _peaks(ts, ring, pool, BEYOND_CANDIDATES) if ring[ts.index((p[1], p[2])), p[0]] >= floor]
    if not starts:
        return None
    climber = _Climber(WindowEvaluator(big), kb)
    out = None
    for th, a, b in starts:
        end = climber.climb(th, (a, b), max(1, pool // 2))
        if end is None:
            continue
        (v, _, _), th_e, t_e = end
        if (max(abs(t_e[0]), abs(t_e[1])) > k and v > best_value and (out is None or v > out[2])
                and _apart(problem, (th_e, t_e), answer)):
            out = (float(th_e), big.offset_m(*t_e), float(v))
    return out


# --- sub-cell refinement -----------------------------------------------------------------------------
REFINE_SIGMA_CELLS = 1.0  # the smoothing of the reference's occupied cells (a likelihood field)
REFINE_MAX_DEG = 1.0  # the refinement stays within the thesis's fine window (±1°) of the grid angle ...
REFINE_MAX_CELLS = 1.0  # ... and within one cell of the grid translation (and inside the window)


def _plateau_middle(angles: np.ndarray, vals: np.ndarray, i: int) -> float:
    """The middle of the run of fine angles around index ``i`` whose score equals the best one."""
    top = vals[i]
    lo = hi = i
    while lo > 0 and vals[lo - 1] == top:
        lo -= 1
    while hi < vals.size - 1 and vals[hi + 1] == top:
        hi += 1
    return float(angles[lo] + angles[hi]) / 2.0


def refine_alignment(problem, al, evaluator=None):
    """The alignment refined below the search grid; the grid answer stays in ``theta_grid_deg`` and
    ``translation_grid_m``.

    1. Ties first: where several fine angles share the best score (a plateau), θ starts at its middle.
    2. Then a continuous local optimisation of a smooth score: the reference's occupied cells blurred
       (Gaussian, σ = 1 cell) into a likelihood field, read bilinearly at the moving ROI's occupied cell
       centres placed by (θ, t); a pattern search (steps halved down to 0.005° and 1/32 cell) within
       ±1° of the start and ±1 cell of the grid translation (and inside the window). The field and
       the points are real-valued, so the optimum lies between grid values; a symmetric score (a map
       against itself) does not move the start. With no window only θ moves.
    """
    from dataclasses import replace

    from .search import fine_angles, wrap_deg

    theta_g = al.theta_grid_deg
    a0, b0 = al.cells
    if al.fine is not None and np.any(np.isclose(wrap_deg(al.fine[0]), theta_g, atol=1e-9)):
        angles, vals = al.fine
    else:
        angles = fine_angles(theta_g)
        vals = SparseEvaluator(problem.at(a0, b0)).scores([float(x) for x in angles])
    angles = np.asarray(angles, np.float64)
    vals = np.asarray(vals, np.float64)
    i = int(np.flatnonzero(np.isclose(wrap_deg(angles), theta_g, atol=1e-9))[0])
    theta0 = _plateau_middle(angles, vals, i)
    t0 = problem.offset_m(a0, b0)
    theta, t = _smooth_refine(problem, theta0, t0)
    return replace(al, theta_deg=wrap_deg(round(theta, 9)), translation_m=t, refined=True)


def _smooth_refine(problem, theta0: float, t0) -> tuple[float, tuple[float, float]]:
    import cv2

    ref, mov = problem.ref, problem.moving
    res = ref.resolution
    n = problem.n
    half = n * res / 2.0
    w_m = problem.window_m if problem.window_cells > 0 else 0.0
    # moving ROI's occupied cell centres, relative to the moving center (metres)
    cm = np.asarray(problem.center_moving, np.float64)
    rm = mov.resolution
    c0 = max(int(math.floor((cm[0] - half * math.sqrt(2) - mov.origin[0]) / rm)), 0)
    c1 = min(int(math.ceil((cm[0] + half * math.sqrt(2) - mov.origin[0]) / rm)), mov.width)
    r0 = max(int(math.floor((cm[1] - half * math.sqrt(2) - mov.origin[1]) / rm)), 0)
    r1 = min(int(math.ceil((cm[1] + half * math.sqrt(2) - mov.origin[1]) / rm)), mov.height)
    if c0 >= c1 or r0 >= r1:
        return theta0, (float(t0[0]), float(t0[1]))
    rr, cc = np.nonzero(mov.states[r0:r1, c0:c1] == OCCUPIED_S)
    p = np.stack([mov.origin[0] + (cc + c0 + 0.5) * rm, mov.origin[1] + (rr + r0 + 0.5) * rm], axis=1) - cm
    p = p[(np.abs(p) < half).all(axis=1)]  # inside the moving ROI's square
    if p.shape[0] < 3:
        return theta0, (float(t0[0]), float(t0[1]))
    # the reference's occupied cells around c_ref, blurred
    cr = np.asarray(problem.center_ref, np.float64)
    crop, org = square_crop(ref, cr, half * math.sqrt(2) + w_m + 4 * res)
    field = cv2.GaussianBlur((crop == OCCUPIED_S).astype(np.float32), (0, 0), REFINE_SIGMA_CELLS)
    org = np.asarray(org, np.float64)

    def scores(cands):
        """Mean field value at the moving points for each (θ, tx, ty)."""
        c = np.asarray(cands, np.float64)
        th = np.radians(c[:, 0])
        cs, sn = np.cos(th)[:, None], np.sin(th)[:, None]
        base = cr - org
        mx = ((cs * p[:, 0] - sn * p[:, 1]) + (base[0] + c[:, 1:2])) / res - 0.5  # crop pixel coordinates
        my = ((sn * p[:, 0] + cs * p[:, 1]) + (base[1] + c[:, 2:3])) / res - 0.5
        out = cv2.remap(field, mx.astype(np.float32), my.astype(np.float32), cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        return out.astype(np.float64).mean(axis=1)

    x = np.array([theta0, float(t0[0]), float(t0[1])])
    lo = np.array([theta0 - REFINE_MAX_DEG, t0[0] - REFINE_MAX_CELLS * res, t0[1] - REFINE_MAX_CELLS * res])
    hi = np.array([theta0 + REFINE_MAX_DEG, t0[0] + REFINE_MAX_CELLS * res, t0[1] + REFINE_MAX_CELLS * res])
    if w_m > 0:
        lo[1:] = np.maximum(lo[1:], -w_m)
        hi[1:] = np.minimum(hi[1:], w_m)
    else:
        lo[1:] = hi[1:] = 0.0
    step = np.array([0.1, 0.25 * res, 0.25 * res])
    dims = [0] if w_m == 0 else [0, 1, 2]
    best = scores([x])[0]
    for _ in range(200):
        cands = []
        for d in dims:
            for sgn in (-1.0, 1.0):
                y = x.copy()
                y[d] = min(max(y[d] + sgn * step[d], lo[d]), hi[d])
                if y[d] != x[d]:
                    cands.append(y)
        v = scores(cands) if cands else np.empty(0)
        j = int(np.argmax(v)) if v.size else -1
        if j >= 0 and v[j] > best * (1 + 1e-9) + 1e-12:
            x, best = cands[j], float(v[j])
            continue
        step /= 2.0
        if step[0] < 0.005 and step[1] < res / 32:
            break
    return float(x[0]), (float(x[1]), float(x[2]))
