"""The fast rotation search: exactly the reference's answer, by branch and bound over the 360 coarse angles.

:func:`fast_search` returns what :func:`merger.search.reference_search` returns — the thesis's search
(3.3.1): the first maximum of the 360 coarse 1° scores, refined at 0.1° over ±1° (first maximum) — and
the same runner-up, for every input and all three measures. It never guesses: an angle is skipped only
when a *true upper bound* of its score shows it cannot win; every other angle is evaluated exactly.

1. **Upper bounds for all 360 coarse angles at once** (:class:`SectorBounds`). The plane around each
   center is cut into polar *sectors*: bands of width ``wb`` and, in band i, ``360·B_i`` equal angular
   bins (so a rotation by a whole degree maps every sector exactly onto another of the same band). Every
   reference ROI lattice point p falls in one sector s(p); at a coarse angle θ its lookup point
   c_m + R(−θ)p lies in the moving-frame sector s(p) − θ (same band, bins shifted by B_i·θ). Per moving
   sector we know, conservatively, whether a lookup there *may* be occupied, is *surely* free (inside
   the moving ROI's square) or *surely* occupied. The bound counts are then circular correlations over
   the 360 degree shifts (one FFT product per sector row, summed; integers, rounded):

   * ``A(θ)  = Σ_p [ref occupied at p] · MayOcc(s(p) − θ)``            ≥ agr̃(θ)
   * ``D(θ)  = Σ_p [ref occupied] · SureFree(s(p) − θ) + [ref free] · SureOcc(s(p) − θ)`` ≤ dis(θ)
   * ``F(θ)  = Σ_p [ref free] · MayFree(s(p) − θ)``                     ≥ free/free(θ)  (Birk–Carpin)
   * ``Y⁺(θ) = Σ_p MayOcc(s(p) − θ)``, ``Y⁻(θ) = Σ_p SureOcc(s(p) − θ)``: Y⁻ ≤ Σy(θ) ≤ Y⁺ (NCC)

   and the score bounds: ω̃ ≤ A / (A + D) (0 when A = 0); Birk–Carpin ω ≤ (A + F) / (A + F + D);
   NCC ≤ the largest value (sxy − c·sy)/√(vx·vy(sy)) can take with sxy ≤ min(A, sy), Y⁻ ≤ sy ≤ Y⁺
   (:func:`_ncc_upper`), with 0 included (the degenerate cases).
2. **Best-first exact evaluation** (:class:`merger.sparse.SparseEvaluator`, which reproduces the
   reference's counts exactly). Angles are taken in decreasing order of bound. For ω̃ an angle first
   gets a tighter *per-angle* bound from the evaluator (:meth:`SparseEvaluator.upper_bounds`, cheap:
   no whole-ROI pass), and is evaluated exactly only if that bound still lets it win. The loop stops
   when every unevaluated angle j has ``bound(j) < best`` or ``bound(j) == best and j > best angle``:
   then none can beat the best one in the reference's order (higher score, then the first angle), and
   the best evaluated angle is the reference's coarse angle — ties and plateaus included, identical maps
   too (the order of evaluation never decides, only scores and indices do). The first exact batch
   carries the refinement angles of its angle (usually the answer: no second pass) — all 21 of them up
   to ROI side FINE_EXACT_MAX; on larger ROIs (ω̃) those whose per-angle bound is within FINE_GAP of
   the best one, the bounds computed with the coarse angles' (a guess of which angles step 3 needs).
3. **The refinement, exactly**: the 21 angles ``coarse ± 1°`` at 0.1° (the same floats as the
   reference's). Its answer is their first maximum: the best-first argument of step 2 over the 21
   angles (:class:`_FineValues`: per-angle bounds, exact where evaluated) decides it, evaluating exactly
   only the angles whose bound reaches the best exact score (all of them for the measures without a
   per-angle bound); θ's score and counts equal ``problem.evaluate(θ)``. The other refinement scores
   (``Alignment.fine``) are computed, exactly, when first read.
4. **The runner-up** (best coarse angle ≥ 10° from θ, first maximum) by the same best-first loop over
   the far zone: exact. It is computed when first read (deferred, :class:`merger.search.Alignment`); a
   far zone of noise-level scores needs most of its angles' per-angle bounds, so it costs several
   searches.

**Why the bounds hold.**

* *Sectors.* Band i is ``[i·wb, (i+1)·wb]``, bin j of band i is ``[j, j+1] / B_i`` degrees (closed;
  bands and bins are widened by a margin ``δ`` — 1e-7 cell in radius, 1e-9 rad plus 1e-7 cell of arc —
  that exceeds every floating-point error below by orders of magnitude). A lattice point p with polar
  coordinates (r, φ) about the reference center is put in the sector holding (r, φ) as computed; its
  lookup point at the whole-degree angle θ is c_m + R(−θ)p, at polar coordinates (r, φ − θ) about the
  moving center up to rounding (≪ δ), hence inside the (widened) moving sector s(p) − θ: the bins of
  band i shift by exactly B_i·θ. The reference resolves that point to the moving cell containing it
  (floor), and to *unknown* outside the moving ROI's square.
* *Blocks.* The moving map is read in q × q blocks of cells (q ≈ a third of a sector, a quarter from
  ROI side LARGE_ROI on, where sectors are 10 cells; 1 for small ROIs). A block *may* hold a class when one of its cells does and *surely* holds it when all do; blocks
  tile the plane as cells do, so the arguments below hold for blocks word for word.
* *Touching.* A block touches a sector when its closed square meets the widened sector. We mark every
  sector whose polar box meets the block's polar box — radius from the nearest to the farthest point of
  the square; angle within ``asin(ρ/|c|)`` of the direction of its centre c (every point of the square
  lies within its half-diagonal ρ of c), the whole circle when |c| ≤ ρ — a superset.
* *MayOcc* = touched by a block holding an occupied cell and not entirely outside the square (with
  margin). If p's lookup is occupied and inside the square, its block is such a block and touches the
  sector: A ≥ agr̃.
* *SureFree(s)* = the sector's center point lies in a block of class Fin (all cells free, block entirely
  inside the square, with margin) **and** no block of the boundary of Fin's complement (a non-Fin block
  with an 8-neighbour in Fin) touches s. Then every point of s lies in a Fin block: otherwise a path
  inside the (connected) sector from its center to that point passes from a Fin block to a non-Fin
  block through a shared edge or corner, and that non-Fin block is a boundary block touching s. So a
  lookup in s is free and inside the square: a ref-occupied p counts in dis. *SureOcc* is the same with
  Oin (all cells occupied, inside the square); a ref-free p whose lookup is surely occupied counts in
  dis, and in Σy. The two parts of D count disjoint sets of lattice points (ref occupied / ref free):
  D ≤ dis. (For ω̃ the SureOcc part is left out — it bounds next to nothing — which only lowers D.)
* *MayFree(s)* = the center lies in a Fany block (holding a free cell, not entirely outside the square)
  **or** a boundary Fany block (with an 8-neighbour not in Fany) touches s; by the same path argument a
  lookup in s that is free and inside the square makes MayFree(s) true: F ≥ free/free.
* *The crop.* Only blocks meeting the moving ROI's square can hold a lookup that is not unknown; the crop
  is that square and two blocks around it, whose outer ring lies outside the square (non-Fin, non-Oin,
  non-Fany) like every block beyond it, and a sector center beyond the crop is read in that ring.
* *Counts → scores.* ω̃ = a/(a+d) grows with a and falls with d; integers are exact in float64 and
  correctly rounded division is monotone, so the float A/(A+D) ≥ the float the reference computes.
  Birk–Carpin likewise with a + f. NCC's bound is monotonicity on two intervals of sy (see
  :func:`_ncc_upper`), inflated by 1e-9 relative to cover rounding.
* *Correlations.* Each count is Σ_rows of a length-360 circular correlation of non-negative integers,
  at most the number of lattice points (≤ 1.6·10⁷: bounds are used for ROIs up to 4000 cells a side). A float64 FFT
  correlation errs by at most a few ε·log₂360 times Σ_rows ‖N_row‖₂‖M_row‖₂ ≤ 10⁻⁵ here, far below ½,
  so ``rint`` returns the exact integers (and :func:`_corr` checks every value lies within 0.1 of an
  integer; if not, it gives up pruning — every angle is then evaluated).
* *Per-angle bound* (ω̃, :meth:`SparseEvaluator.upper_bounds`): agr̃ and the reference-occupied half of
  dis are exact; the other half is replaced by the number of occupied moving cells, not straddling the
  square, whose centre maps (x_ref = c_ref + R(θ)(x_mov − c_mov)) within the inscribed radius of a
  reference-free lattice point: that point's lookup lies in that cell (rotations keep distances), and
  each lattice point has one cell, so that count ≤ the true half; the same monotonicity applies. The
  count is taken in float32 with the radius shrunk by more than twice the float32 error (proved in
  :meth:`SparseEvaluator._disagree_lower`): a cell it counts covers its point in exact arithmetic.
* *Exact values* (what every pruning is compared against) come from
  :class:`merger.sparse.SparseEvaluator`, whose counts are the reference's: certified lookups (an angle
  with a lookup within 1e-8 cell of a cell border takes the reference code path); on large ROIs the
  moving-occupied half of dis is counted cell by cell, in float32 where a lookup is farther than 1e-5
  cell from the cell's border (float32 errs by < 1e-6 there) and in float64, certified, elsewhere.

Everything about the sectors and the lattice depends only on (n, cell size, sector size) and is cached;
a moving map's sector spectra are kept across the searches of a merge cycle (bounded, checked against
the whole crop before use; :func:`clear_cache`). The returned ``profile`` is an **upper envelope**:
exact at the coarse angles evaluated, an upper bound of the exact score elsewhere (:func:`exact_profile`
gives the reference's profile, evaluating every angle). The counts (Birk–Carpin's free/free part) and
the runner-up are handed over deferred: a merge cycle reads θ and the score only.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
import scipy.fft as sfft

from .cache import BoundedCache
from .grid import FREE_S, OCCUPIED_S
from .polar import crop_cells
from .search import (
    RUNNER_UP_MIN_SEPARATION_DEG,
    Alignment,
    RotationProblem,
    angle_diff_deg,
    fine_angles,
    register_method,
    wrap_deg,
)
from .sparse import SparseEvaluator, lattice_coords

POOL_DIV = 3.0  # blocks of the moving map ≈ a sector / POOL_DIV (POOL_DIV_LARGE from ROI side LARGE_ROI on)
POOL_DIV_LARGE = 4.0
FIRST_BATCH = 20  # best sector bounds given the per-angle bound before the first exact evaluation
EXACT_BATCH = 4  # exact evaluations per batch after the first (best bounds first); batches then double
MAX_BATCH = 48
FINE_EXTRA = 21  # at most this many refinement angles evaluated with the first coarse angle (ω̃) ...
FINE_GAP = 0.06  # ... those whose per-angle bound is within this of the best one
FINE_EXACT_MAX = 480  # up to this ROI side all 21 refinement angles ride with the first (one cheap batch)
LARGE_ROI = 480  # from this ROI side on: coarser sectors (10 cells), larger blocks, more angles tightened
TIGHTEN_BATCH = 32  # angles given the evaluator's per-angle bound at a time (ω̃)
_DELTA_CELL = 1e-7  # margin of sectors and square tests, in moving cells (≫ every rounding error)
_DELTA_RAD = 1e-9
_FULL_CIRCLE_R = 1e-6  # a cell closer than this (cells) to the center touches every angle
_NCC_INFLATE = 1e-9
MAX_BOUND_CELLS = 4000  # ROI side (cells) up to which the sector bounds are used
_MOVING_CACHE = BoundedCache(32, 32 << 20)  # moving maps' sector spectra (a merge cycle reuses them)


def clear_cache() -> None:
    """Forget the moving maps' sector spectra (benchmarks time cold searches)."""
    _MOVING_CACHE.clear()


def sector_grain(n: int) -> float:
    """Sector size (band width, and arc of a bin at the band's outer edge) in ROI cells for an (n, n) ROI:
    coarser sectors cost less (∝ (n / grain)²) and bound less tightly, so that more angles need their
    per-angle bound (a few µs each); 3.2 cells at 128, 6.4 at 256, 10 from 400 on (measured best on
    generated rooms: the sector stage costs 0.55, 0.75 and 1.9 ms at ROI 128, 256 and 800, and leaves
    15–40 angles above the answer's score)."""
    return min(max(2.0, n / 64.0), 7.0) if n <= LARGE_ROI else 10.0


@dataclass(frozen=True, eq=False)
class SectorLayout:
    """The polar sectors of an (n, n) ROI lattice of cell size ``res`` (see the module documentation).

    Sectors are stored two ways: *natural* (band by band, bin by bin; ``noff[i] + j``) and *rows*
    (``(R, 360)``: row ``roff[i] + j mod B_i``, column ``j // B_i``) where a whole-degree rotation is a
    circular shift of every row. ``lattice_row_id`` is the rows-layout sector (``row * 360 + col``) of
    every lattice point (flat ``i * n + j``); ``to_rows`` gathers a natural-layout array into rows;
    ``cx, cy`` are the sectors' center points (metres from the center, natural layout)."""

    n: int
    res: float
    wb: float
    bins: np.ndarray  # B_i per band
    noff: np.ndarray
    roff: np.ndarray
    total: int
    rows: int
    lattice_row_id: np.ndarray
    to_rows: np.ndarray
    cx: np.ndarray
    cy: np.ndarray
    n_all_spec: np.ndarray
    rows_identity: bool = False


@lru_cache(maxsize=16)
def sector_layout(n: int, res: float, grain: float) -> SectorLayout:
    wb = grain * res
    k = lattice_coords(n, res)
    rmax = float(np.hypot(k[0], k[0]))
    nb = int(math.floor(rmax / wb)) + 1  # every lattice point's band is < nb
    outer = (np.arange(nb) + 1) * wb
    bins = np.maximum(1, np.ceil(2 * math.pi * outer / (360.0 * wb) - 1e-9)).astype(np.int64)
    lengths = 360 * bins
    noff = np.concatenate([[0], np.cumsum(lengths)])
    roff = np.concatenate([[0], np.cumsum(bins)])
    total, rows = int(noff[-1]), int(roff[-1])
    # natural id -> rows-layout id
    band = np.repeat(np.arange(nb), lengths)
    j = np.arange(total) - noff[band]
    rows_id = (roff[band] + j % bins[band]) * 360 + j // bins[band]
    to_rows = np.empty(total, np.intp)
    to_rows[rows_id] = np.arange(total)
    # sector centers
    r_mid = (band + 0.5) * wb
    phi = np.radians((j + 0.5) / bins[band])
    cx, cy = r_mid * np.cos(phi), r_mid * np.sin(phi)
    # lattice points
    kx, ky = np.meshgrid(k, k)
    r = np.hypot(kx, ky).ravel()
    ph = np.mod(np.degrees(np.arctan2(ky, kx)).ravel(), 360.0)
    bd = np.minimum((r / wb).astype(np.int64), nb - 1)
    bn = np.minimum((ph * bins[bd]).astype(np.int64), lengths[bd] - 1)
    lat = (roff[bd] + bn % bins[bd]) * 360 + bn // bins[bd]
    lay = SectorLayout(n, res, wb, bins, noff, roff, total, rows, lat.astype(np.intp), to_rows, cx, cy,
                       np.empty(0), bool((to_rows == np.arange(total)).all()))
    object.__setattr__(lay, "n_all_spec", _row_spectra(lay, _hist(lay, None)))
    return lay


def _hist(lay: SectorLayout, points) -> np.ndarray:
    """(R, 360) count of lattice points per sector (those of flat indices ``points``, or all)."""
    ids = lay.lattice_row_id if points is None else lay.lattice_row_id.take(points)
    return np.bincount(ids, minlength=lay.rows * 360).reshape(lay.rows, 360).astype(np.float64)


def _pool(a: np.ndarray, q: int, op) -> np.ndarray:
    """Block reduction (``np.maximum`` or ``np.minimum``) of a square array over q × q blocks."""
    if q == 1:
        return a
    rows = a[0::q].copy()
    for i in range(1, q):
        op(rows, a[i::q], out=rows)
    out = rows[:, 0::q].copy()
    for j in range(1, q):
        op(out, rows[:, j::q], out=out)
    return out


def _row_spectra(lay: SectorLayout, rows_array: np.ndarray) -> np.ndarray:
    return sfft.rfft(rows_array, axis=-1)


class _Inexact(Exception):
    """An FFT correlation did not come out (near) integral: no bounds for this problem."""


def _corr(ref_spec: np.ndarray, mov_spec: np.ndarray) -> np.ndarray:
    """Σ_rows Σ_a ref[row, a] · mov[row, (a − θ) mod 360] for θ = 0..359, as exact integers (float64)."""
    x = sfft.irfft(np.einsum("rk,rk->k", ref_spec, np.conj(mov_spec)), n=360)
    r = np.rint(x)
    if not np.abs(x - r).max(initial=0.0) < 0.1:
        raise _Inexact
    return r


def _polar_boxes(x0, y0, size, grow: float = 0.0):
    """Polar boxes of squares [x0, x0+size] × [y0, y0+size] (metres from the center): rmin, rmax (nearest
    and farthest point), and the angles (radians) ac ∓ asin(ρ/|c|) about the direction ac of the
    square's centre c, ρ = size/√2 its half-diagonal — every point of the square lies within ρ of c, so
    within that angle of ac; the interval is set to ±π (the whole circle) when |c| ≤ ρ.

    ``grow`` > 0: the polar boxes of the squares grown by a disk of that radius (every point within
    ``grow`` of the square): radii widened by ``grow``, ρ by ``grow`` (:mod:`merger.window_bounds`)."""
    x1, y1 = x0 + size, y0 + size
    dx = np.maximum(np.maximum(x0, -x1), 0.0)
    dy = np.maximum(np.maximum(y0, -y1), 0.0)
    rmin = np.maximum(np.hypot(dx, dy) - grow, 0.0)
    rmax = np.hypot(np.maximum(np.abs(x0), np.abs(x1)), np.maximum(np.abs(y0), np.abs(y1))) + grow
    xc, yc = x0 + size / 2, y0 + size / 2
    ac = np.arctan2(yc, xc)
    rho = size * math.sqrt(0.5) + grow
    dc = np.hypot(xc, yc)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(dc > rho * (1 + 1e-9), np.arcsin(np.minimum(rho / dc, 1.0)), math.pi)
    return rmin, rmax, ac - w, ac + w


class SectorBounds:
    """Upper bounds of a problem's coarse scores at 0°, 1°, …, 359° (see the module documentation)."""

    grow = 0.0  # the touching test's extra radius (metres; > 0 only in merger.window_bounds)

    def __init__(self, problem: RotationProblem, ref_roi: np.ndarray, sx: int, occ_idx=None) -> None:
        self.problem = problem
        n, res = problem.n, problem.ref.resolution
        self.lay = lay = sector_layout(n, res, sector_grain(n))
        self.measure = problem.measure
        flat = ref_roi.reshape(-1)
        self.sx = sx
        spec = dict(self._moving_sectors(problem))
        hists = {"n_occ": _hist(lay, np.flatnonzero(flat == OCCUPIED_S) if occ_idx is None else occ_idx)}
        if self.measure == "birk_carpin":
            hists["n_free"] = _hist(lay, np.flatnonzero(flat == FREE_S))
        spec.update(zip(hists, _row_spectra(lay, np.stack(list(hists.values()))), strict=True))
        n_occ = spec["n_occ"]
        a = _corr(n_occ, spec["may_occ"])
        if self.measure == "ncc":
            y_hi = _corr(lay.n_all_spec, spec["may_occ"])
            y_lo = _corr(lay.n_all_spec, spec["sure_occ"]) if "sure_occ" in spec else np.zeros(360)
            self.values = _ncc_upper(a, y_lo, y_hi, n * n, sx)
            return
        n_free = spec.get("n_free")
        d = _corr(n_occ, spec["sure_free"])
        if "sure_occ" in spec and n_free is not None:
            d = d + _corr(n_free, spec["sure_occ"])
        if self.measure == "birk_carpin":
            a = a + _corr(n_free, spec["may_free"])
        with np.errstate(divide="ignore", invalid="ignore"):
            self.values = np.where(a > 0, a / (a + d), 0.0)

    def _moving_sectors(self, problem: RotationProblem) -> dict[str, np.ndarray]:
        """Row spectra of the (R, 360) 0/1 arrays MayOcc, SureFree, SureOcc (and MayFree for Birk–Carpin)
        of the moving map (cached, :data:`_MOVING_CACHE`).

        The moving map is read in blocks of q × q cells (q ≈ a sector / POOL_DIV): a block *may* hold a class
        when one of its cells does, *surely* holds it when all do; blocks tile the plane like cells, so
        the touching and path arguments (module documentation) hold for blocks unchanged."""
        lay = self.lay
        mov, mres = problem.moving, problem.moving.resolution
        q = max(1, int(lay.wb / mres / (POOL_DIV_LARGE if problem.n > LARGE_ROI else POOL_DIV)))
        cmx, cmy = problem.center_moving
        half = problem.n * lay.res / 2.0
        # only cells that meet the moving ROI's square matter (outside it a lookup is unknown): the crop is
        # the square and two blocks around it; blocks beyond are outside the square, as its outer ring
        reach = half + 2 * q * mres
        crop, c0, r0 = crop_cells(mov, (cmx, cmy), reach, q)
        size = crop.shape[0]
        # a map is the moving map of several searches of a merge cycle: its sector spectra are kept, keyed
        # by the geometry and a cheap sample of the crop, and served only if the whole crop is equal
        key = (lay.n, lay.res, lay.wb, q, self.measure, self.grow, mres, cmx - mov.origin[0] - c0 * mres,
               cmy - mov.origin[1] - r0 * mres, size, hash(crop[::5, ::3].tobytes()))
        hit = _MOVING_CACHE.get(key)
        if hit is not None and np.array_equal(hit[0], crop):
            return dict(zip(hit[1], hit[2], strict=True))
        pmax, pmin = _pool(crop, q, np.maximum), _pool(crop, q, np.minimum)
        ps, bs = size // q, q * mres  # blocks per side, block side (metres)
        # block corners relative to the moving center, metres
        xs = mov.origin[0] + (c0 + q * np.arange(ps)) * mres - cmx
        ys = mov.origin[1] + (r0 + q * np.arange(ps)) * mres - cmy
        dm = _DELTA_CELL * mres
        in_x = (xs > -half + dm) & (xs + bs < half - dm)
        in_y = (ys > -half + dm) & (ys + bs < half - dm)
        out_x = (xs + bs < -half - dm) | (xs > half + dm)
        out_y = (ys + bs < -half - dm) | (ys > half + dm)
        inside = in_y[:, None] & in_x[None, :]
        outside = out_y[:, None] | out_x[None, :]
        kernel = np.ones((3, 3), np.uint8)

        def dil(m):
            return cv2.dilate(m.view(np.uint8), kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0).view(bool)

        # the sectors' center points: their blocks
        cc = np.floor((cmx - mov.origin[0] + lay.cx) / mres).astype(np.intp) - c0
        cr = np.floor((cmy - mov.origin[1] + lay.cy) / mres).astype(np.intp) - r0
        np.clip(cc, 0, size - 1, out=cc)  # a center beyond the crop: a block of its outer ring (outside)
        np.clip(cr, 0, size - 1, out=cr)
        center = (cr // q) * ps + cc // q

        def boundary(cls):  # the blocks of cls's complement with an 8-neighbour in cls
            return dil(cls) & ~cls

        # every touched set in one raster: [class name, blocks] in order
        sets = [("may_occ", (pmax == OCCUPIED_S) & ~outside)]
        sure = []  # (name, class): sure_x = class at the sector's center and no boundary block touches it
        oin = (pmin == OCCUPIED_S) & inside
        if self.measure != "similarity" and oin.any():  # ω̃'s bound gains next to nothing from it
            sure.append(("sure_occ", oin))
        if self.measure != "ncc":
            sure.append(("sure_free", (pmin == FREE_S) & (pmax == FREE_S) & inside))
        sets += [(name, boundary(cls)) for name, cls in sure]
        fany = None
        if self.measure == "birk_carpin":
            fany = (_pool(crop == FREE_S, q, np.maximum) if q > 1 else crop == FREE_S) & ~outside
            sets.append(("may_free", fany & dil(~fany)))
        touched = dict(zip([name for name, _ in sets], self._raster([b for _, b in sets], ps, xs, ys, bs),
                           strict=True))
        out = {"may_occ": touched["may_occ"]}
        for name, cls in sure:
            out[name] = cls.reshape(-1).take(center) & ~touched[name]
        if fany is not None:
            out["may_free"] = fany.reshape(-1).take(center) | touched["may_free"]
        names = list(out)
        rows = np.stack([out[k] for k in names]).astype(np.float64)
        if not lay.rows_identity:
            rows = rows[:, lay.to_rows]
        rows = rows.reshape(len(names), lay.rows, 360)
        spectra = _row_spectra(lay, rows)
        _MOVING_CACHE.put(key, (crop, tuple(names), spectra))
        return dict(zip(names, spectra, strict=True))

    def _raster(self, sets: list[np.ndarray], size: int, xs, ys, mres) -> list[np.ndarray]:
        """Natural-layout masks of the sectors touched by each given set of crop blocks (boolean arrays
        over the crop's blocks), in one pass."""
        lay = self.lay
        total = lay.total + 1
        cells_of = [np.flatnonzero(b) for b in sets]
        k = len(sets)
        cells = np.concatenate(cells_of)
        if cells.size == 0:
            return [np.zeros(lay.total, bool) for _ in sets]
        owner = np.repeat(np.arange(k) * total, [c.size for c in cells_of])
        r, c = np.divmod(cells, size)
        rmin, rmax, lo, hi = _polar_boxes(xs[c], ys[r], mres, self.grow)
        dr = _DELTA_CELL * mres
        nb = len(lay.bins)
        i0 = np.maximum(np.ceil((rmin - dr) / lay.wb).astype(np.int64) - 1, 0)
        i1 = np.minimum(np.floor((rmax + dr) / lay.wb).astype(np.int64), nb - 1)
        keep = i0 <= i1
        full = (rmin < _FULL_CIRCLE_R * mres) | (hi - lo >= 2 * math.pi - 1e-9)
        with np.errstate(divide="ignore"):
            margin = _DELTA_RAD + np.where(full, 0.0, dr / np.maximum(rmin, 1e-300))
        lo_deg, hi_deg = np.degrees(lo - margin), np.degrees(hi + margin)
        i0, i1, lo_deg, hi_deg, full, owner = (i0[keep], i1[keep], lo_deg[keep], hi_deg[keep], full[keep],
                                               owner[keep])
        cnt = i1 - i0 + 1
        cell = np.repeat(np.arange(cnt.size), cnt)
        band = i0[cell] + np.arange(cell.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        b = lay.bins[band]
        length = 360 * b
        j0 = np.ceil(lo_deg[cell] * b).astype(np.int64) - 1
        j1 = np.floor(hi_deg[cell] * b).astype(np.int64)
        whole = full[cell] | (j1 - j0 + 1 >= length)
        span = np.where(whole, length - 1, np.maximum(j1 - j0, 0))
        j0 = np.where(whole, 0, np.mod(j0, length))
        base = lay.noff[band] + owner[cell]
        end = j0 + span  # inclusive, may pass the band's end: split
        starts = [base + j0]
        stops = [base + np.minimum(end, length - 1) + 1]
        wrap = end >= length
        if wrap.any():
            starts.append(base[wrap])
            stops.append(base[wrap] + end[wrap] - length[wrap] + 1)
        hit = np.bincount(np.concatenate(starts), minlength=k * total)
        hit -= np.bincount(np.concatenate(stops), minlength=k * total)
        hit = np.cumsum(hit.reshape(k, total), axis=1)[:, :-1] > 0
        return list(hit)


def _ncc_upper(a: np.ndarray, y_lo: np.ndarray, y_hi: np.ndarray, size: int, sx: int) -> np.ndarray:
    """Upper bounds of NCC = (sxy − c·sy)/√(vx·h(sy)), h(s) = s − s²/N, c = sx/N, given sxy ≤ a, sxy ≤ sy,
    y_lo ≤ sy ≤ y_hi (all per angle). Values with sy ∈ {0, N} or vx ≤ 0 are 0 (the measure's rule), so 0
    is always included. For s ≤ a the best sxy is s and (1 − c)·√s / √(vx(1 − s/N)) grows with s: its
    bound is at s = min(a, hi). For s ≥ a the numerator a − c·s falls with s and h is concave: the bound
    is (a − c·s₀) / √(vx · min(h(s₀), h(hi))) with s₀ = max(a, lo), when positive."""
    n = float(size)
    vx = sx - sx * sx / n
    if vx <= 0:
        return np.zeros(a.shape)
    c = sx / n
    lo = np.maximum(y_lo, 1.0)
    hi = np.minimum(y_hi, n - 1)

    def h(s):
        return np.maximum(s - s * s / n, 1e-300)

    out = np.zeros(a.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        s1 = np.minimum(a, hi)
        ok1 = (lo <= s1) & (s1 >= 1)
        g1 = np.where(ok1, (s1 - c * s1) / np.sqrt(vx * h(s1)), 0.0)
        s0 = np.maximum(a, lo)
        ok2 = s0 <= hi
        num = a - c * s0
        g2 = np.where(ok2 & (num > 0), num / np.sqrt(vx * np.minimum(h(s0), h(hi))), 0.0)
    np.maximum(out, g1, out=out)
    np.maximum(out, g2, out=out)
    return out * (1 + _NCC_INFLATE) + 1e-12


class _Coarse:
    """Exact coarse scores on demand (batched), with upper bounds for the rest, in the reference's order.

    ``bounds`` start as the sector bounds; for ω̃ an angle that could still win gets the evaluator's
    per-angle bound first (:meth:`SparseEvaluator.upper_bounds`: agr̃ and the reference-occupied half of
    dis exact, the other half of dis replaced by a lower bound — cheap, no whole-ROI pass), and is
    evaluated exactly only if that bound still lets it win.
    """

    def __init__(self, ev: SparseEvaluator, bounds: np.ndarray) -> None:
        self.ev = ev
        self.bounds = bounds
        self.values: dict[int, float] = {}
        self.tightened = np.zeros(360, bool)
        self.can_tighten = ev.problem.measure == "similarity"

    def evaluate(self, idx, extra=()) -> None:
        """Exact scores at the coarse angles ``idx``, and at the angles ``extra`` in the same batch (the
        evaluator keeps them; those that are whole degrees in [0, 360) count as coarse values)."""
        todo = [int(i) for i in dict.fromkeys(idx) if int(i) not in self.values]
        extra = [float(a) for a in extra]
        if todo or extra:
            vals = self.ev.scores([float(i) for i in todo] + extra).tolist()
            got = dict(zip(todo, vals, strict=False))
            got.update({int(a): v for a, v in zip(extra, vals[len(todo):], strict=True)
                        if 0.0 <= a < 360.0 and a == int(a)})
            got = {i: v for i, v in got.items() if i not in self.values}
            self.values.update(got)
            self.bounds[list(got)] = list(got.values())
            self.tightened[list(got)] = True

    def tighten(self, idx, extra=(), first_part=()) -> None:
        """Per-angle bounds at the coarse angles ``idx`` (and, in the same batches, at the angles
        ``extra``, and the first exact part at ``first_part``: the evaluator keeps them for later)."""
        todo = [int(i) for i in idx if not self.tightened[i]]
        extra = [float(a) for a in extra]
        if todo or extra:
            self.ev.prepare((), [float(i) for i in todo] + extra, [float(a) for a in first_part])
        if todo:
            ub = self.ev.upper_bounds([float(i) for i in todo])
            self.bounds[todo] = np.minimum(self.bounds[todo], ub)
            self.tightened[todo] = True

    def best(self, allowed: np.ndarray | None = None, with_fine: bool = False) -> int | None:
        """The first maximum of the exact coarse profile over ``allowed`` (a mask over 0..359): evaluates
        angles in decreasing order of bound until no other angle can beat the best one evaluated.
        ``with_fine``: the first angle evaluated is usually the answer, so its refinement angles ride in
        its batches — their per-angle bounds (ω̃), and the exact scores of the FINE_EXTRA best bounded
        (ω̃) or of all of them (the other measures, which have no per-angle bound)."""
        idx = np.arange(360)
        mask = np.ones(360, bool) if allowed is None else allowed.copy()
        if not mask.any():
            return None
        batch = EXACT_BATCH
        while True:
            known = [i for i in self.values if mask[i]]
            best = max(known, key=lambda i: (self.values[i], -i)) if known else None
            open_ = mask.copy()
            open_[list(self.values)] = False
            if best is not None:
                bv = self.values[best]
                open_ &= (self.bounds > bv) | ((self.bounds == bv) & (idx < best))
            cand = np.flatnonzero(open_)
            if cand.size == 0:
                return best
            cand = cand[np.lexsort((cand, -self.bounds[cand]))]  # best bound first, then smallest angle
            if best is None:  # a first exact value: the best bound of the first few, once tightened
                extra = []
                if self.can_tighten:
                    top = cand[:FIRST_BATCH if self.ev.n <= LARGE_ROI else 32]
                    # the answer's refinement angles ride along: those of the two best sector bounds
                    # (the best tightened bound is nearly always one of them)
                    if with_fine and self.ev.n > FINE_EXACT_MAX:  # their bounds: the refinement's certificate
                        self.tighten(top, fine_angles(float(top[0])))
                    else:
                        self.tighten(top)
                    cand = top[np.lexsort((top, -self.bounds[top]))]
                first = int(cand[0])
                if with_fine:
                    fine = [float(a) for a in fine_angles(float(first))]
                    if self.can_tighten and self.ev.n > FINE_EXACT_MAX:
                        self.tighten((), fine)  # nothing to do when the guess was right
                        ub = self.ev.upper_bounds(fine)
                        # exact with the first angle: the refinement angles whose bound is near the best
                        # (a guess of which ones the refinement needs; the refinement checks it exactly)
                        order = np.lexsort((np.arange(len(fine)), -ub))
                        near = order[ub[order] >= ub[order[0]] - FINE_GAP][:FINE_EXTRA]
                        extra = [fine[i] for i in near]
                    else:
                        extra = fine
                self.evaluate([first], extra)
                continue
            if self.can_tighten and not self.tightened[cand[:TIGHTEN_BATCH]].all():
                self.tighten(cand[:TIGHTEN_BATCH])  # the best bounds first; the order may change
                continue
            self.evaluate(cand[:batch])
            batch = min(2 * batch, MAX_BATCH)


def _prepare(problem: RotationProblem):
    ev = SparseEvaluator(problem)
    bounds = np.full(360, np.inf)  # without bounds every angle is evaluated (still exact)
    if problem.n <= MAX_BOUND_CELLS:  # the FFT error bound (module documentation) covers these ROIs
        try:
            bounds = SectorBounds(problem, ev.ref_roi, int(ev.sx), ev.occ_idx).values
        except _Inexact:  # never seen
            pass
    return ev, _Coarse(ev, np.array(bounds, np.float64))


def fast_search(problem: RotationProblem) -> Alignment:
    """Rotation search returning exactly the reference's answer (see the module documentation).

    Parameters
    ----------
    problem : the rotation problem (maps, centers, ROI side, measure); ``window_m`` is not looked at
        (:func:`merger.search.search` sends windowed problems to :mod:`merger.window`).

    Returns
    -------
    Alignment with ``method="fast"``: ``theta_deg``, ``score``, ``counts``, ``runner_up_deg`` and
    ``runner_up_score`` equal to :func:`merger.search.reference_search`'s (counts and runner-up computed
    on first access); ``profile`` is an **upper envelope** of the reference's profile — exact at every
    coarse angle evaluated, a true upper bound elsewhere (:func:`exact_profile` completes it).
    """
    ev, coarse = _prepare(problem)
    best = coarse.best(with_fine=True)
    fine = [float(a) for a in fine_angles(float(best))]
    lock = threading.Lock()  # the deferred evidence shares the evaluator, which is not thread-safe
    values = _FineValues(ev, fine, lock)
    k = values.first_max()  # the first maximum, as the reference's strict '>' scan
    theta = wrap_deg(fine[k])
    score = values.exact[k]
    profile = coarse.bounds.copy()
    for i, v in coarse.values.items():
        profile[i] = v

    def runner_up():
        with lock:
            return _runner_up(coarse, theta)

    def counts():
        with lock:
            return ev.similarity(fine[k]).counts

    return Alignment(theta, score, counts, problem.measure, "fast", problem.roi_m, profile, runner_up,
                     fine=values, evidence={"profile": "upper_envelope", "runner_up": "exact"})


class _FineValues:
    """The refinement's ``(angles, scores)`` pair of an :class:`Alignment` (``fine``), exact.

    :meth:`first_max` finds the reference's fine answer — the first maximum of the 21 exact scores —
    evaluating exactly only the angles that can be it: best per-angle upper bound first
    (:meth:`SparseEvaluator.upper_bounds`, exact where known), until every unevaluated angle j has
    ``bound(j) < best`` or ``bound(j) == best and j > best index`` (the argument of the coarse loop).
    The scores of the other angles are computed when ``fine`` is first read (indexing, unpacking or
    pickling: a pickled copy is a plain tuple)."""

    def __init__(self, ev: SparseEvaluator, angles: list[float], lock) -> None:
        self.ev, self.lock = ev, lock
        self.angles = np.asarray(angles, np.float64)
        self._list = [float(a) for a in angles]
        self.exact = np.full(len(angles), -np.inf)
        self.done = np.zeros(len(angles), bool)
        self._resolved = None

    def _evaluate(self, idx) -> None:
        idx = [int(i) for i in idx if not self.done[i]]
        if idx:
            self.exact[idx] = self.ev.scores([self._list[i] for i in idx])
            self.done[idx] = True

    def first_max(self) -> int:
        ev, n = self.ev, len(self._list)
        known = ev.known(self._list)
        if known.all():  # the usual case for small ROIs: all of them came with the first coarse angle
            self.exact[:] = ev.scores(self._list)
            self.done[:] = True
            return int(np.argmax(self.exact))
        self._evaluate(np.flatnonzero(known))
        ub = np.full(n, np.inf)
        rest = np.flatnonzero(~self.done)
        if rest.size:
            ub[rest] = ev.upper_bounds([self._list[i] for i in rest])
        pos = np.arange(n)
        while True:
            if self.done.any():
                bk = int(np.argmax(np.where(self.done, self.exact, -np.inf)))  # first maximum
                bv = self.exact[bk]
                open_ = ~self.done & ((ub > bv) | ((ub == bv) & (pos < bk)))
            else:
                open_ = ~self.done
            cand = np.flatnonzero(open_)
            if cand.size == 0:
                return bk
            self._evaluate(cand)  # all of them in one batch (a batch costs more than an angle)

    def _values(self) -> np.ndarray:
        if self._resolved is None:
            with self.lock:
                self._evaluate(np.flatnonzero(~self.done))
                self._resolved = self.exact.copy()
        return self._resolved

    def __len__(self) -> int:
        return 2

    def __getitem__(self, i):
        if isinstance(i, int) and i in (0, -2):
            return self.angles
        return (self.angles, self._values())[i]

    def __iter__(self):
        return iter((self.angles, self._values()))

    def __reduce__(self):
        return (tuple, ((self.angles, self._values()),))


def _runner_up(coarse: _Coarse, theta: float) -> tuple[float, float]:
    """The reference's runner-up: the first maximum of the coarse profile at least 10° from θ."""
    angles = np.arange(360) * 1.0
    far = np.abs(angle_diff_deg(angles, theta)) >= RUNNER_UP_MIN_SEPARATION_DEG
    r = coarse.best(far)
    if r is None:
        return float("nan"), float("nan")
    return float(angles[r]), coarse.values[r]


def exact_profile(problem: RotationProblem) -> np.ndarray:
    """The reference's coarse profile (all 360 exact scores at 0°, 1°, …, 359°), by the exact evaluator."""
    return SparseEvaluator(problem).scores([float(a) for a in range(360)])


register_method("fast", fast_search)
