"""Exact ROI similarity at many angles, computed only on the cells that can change the counts.

The reference (:func:`merger.search.reference_search`) resamples the whole moving ROI for every angle
(:func:`merger.transform.rotated_roi`) and counts cells on the whole (n, n) lattice. The counts of the
thesis's measures (3.3.1) only involve few cells:

* agr̃ (occupied in both) and the half of dis where the reference is occupied: look up the moving map
  at the reference ROI's *occupied* lattice points only;
* the other half of dis (moving occupied, reference free): the reference-free lattice points whose
  lookup falls in an *occupied moving cell*. Rotation preserves distances, so every such point lies
  within ``√2/2`` cell of that cell's centre mapped forward (x_ref = c_ref + R(θ)(x_mov − c_mov)); the
  lattice points that close to an occupied cell at one of the angles are looked up like the others
  (small ROIs: one candidate set per cluster of nearby angles), or, on large ROIs where a wall sweeps
  many lattice points over 1°, each cell's nb × nb candidates are tested against that cell alone
  (:meth:`SparseEvaluator._moving_occupied_cells`: no candidate set, no de-duplication);
* free/free (Birk–Carpin's agr, and the ``free_agree`` count every result carries): the reference ROI's
  free lattice points;
* NCC's Σy: every lattice point whose lookup is occupied (the same candidates, not only free ones).

A batch of angles is one matrix product (points × angles) and a few vectorized operations. Lookups are
*certified*: coordinates are computed with an error far below 1e-8 cell, and when one is within 1e-8
of a cell border (or a point within 1e-9 m of the moving ROI's square border) that angle is evaluated
by the reference code path instead (:meth:`RotationProblem.moving_roi`). The counts are therefore the
reference's, whatever the floating-point details (BLAS, fused multiply-add) of the machine.

For ω̃ there is also a cheap upper bound (:meth:`SparseEvaluator.upper_bounds`): the moving-occupied half
of dis replaced by a lower bound — occupied cells whose mapped centre lies inside the inscribed circle of
a lattice point's preimage square certainly cover that point — which lets the search skip angles.
"""

from __future__ import annotations

import math

import numpy as np

from .grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid
from .similarity import Counts, Similarity, count_cells, index_from_counts
from .transform import rotated_roi_fast

_TOL_CELL = 1e-8  # certified floor: margin to a cell border, in cells
_TOL_M = 1e-9  # certified square mask: margin to the ROI border, in metres
_CLUSTER_GAP_DEG = 1.5  # angles further apart get their own candidate set (_moving_occupied_union)
_SMALL_CLUSTER = 4  # clusters of at most this many angles share one candidate set
UNION_MAX_CELLS = 480  # ROI side up to which the moving-occupied counts use shared candidate sets
_ANGLE_CHUNK = 32  # angles per batch of lookups (larger (angles, points) arrays fall out of the caches)
_NEAR32 = 1e-5  # float32 positions closer than this (cells) to a cell border are recomputed in float64
_STRADDLE = np.uint8(4)  # crop code flag: the cell straddles the moving ROI's square border


def lattice_coords(n: int, resolution: float) -> np.ndarray:
    """The 1-D offsets of the ROI lattice, exactly as :func:`merger.transform.roi_offsets` builds them."""
    return (np.arange(n) - (n - 1) / 2.0) * resolution


def fast_extract_roi(grid: OccupancyGrid, center, n: int) -> np.ndarray:
    """:func:`merger.transform.extract_roi`, computed separably (same floating-point operations).

    Without rotation the lattice's column only depends on x and its row only on y, so the containing
    cells are two 1-D floors; the ROI is a block of the grid (or a gather of rows and columns), and
    cells outside the grid are unknown.
    """
    k = lattice_coords(n, grid.resolution)
    cols = np.floor((center[0] + k - grid.origin[0]) / grid.resolution).astype(np.int64)
    rows = np.floor((center[1] + k - grid.origin[1]) / grid.resolution).astype(np.int64)
    out = np.zeros((n, n), np.uint8)
    if (np.diff(cols) == 1).all() and (np.diff(rows) == 1).all():  # a plain block (the usual case)
        c0, r0 = int(cols[0]), int(rows[0])
        gc0, gc1 = max(c0, 0), min(c0 + n, grid.width)
        gr0, gr1 = max(r0, 0), min(r0 + n, grid.height)
        if gc0 < gc1 and gr0 < gr1:
            out[gr0 - r0:gr1 - r0, gc0 - c0:gc1 - c0] = grid.states[gr0:gr1, gc0:gc1]
        return out
    padded = np.zeros((grid.height + 2, grid.width + 2), np.uint8)
    padded[1:-1, 1:-1] = grid.states
    return padded[np.ix_(np.clip(rows, -1, grid.height) + 1, np.clip(cols, -1, grid.width) + 1)]


def ncc_from_sums(size: int, sx: float, sy: float, sxy: float) -> float:
    """:func:`merger.similarity.ncc` from its sums (same arithmetic, so the same float)."""
    if size == 0:
        return 0.0
    vx, vy = sx - sx * sx / size, sy - sy * sy / size
    if vx <= 0 or vy <= 0:
        return 0.0
    return float((sxy - sx * sy / size) / np.sqrt(vx * vy))


def _axis_ranges(c0: int, lo: float, hi: float, w: int, tol: float) -> tuple[int, int, int, int]:
    """Along one axis of a crop whose first cell is ``c0``, with the square's borders at continuous cell
    coordinates ``lo`` < ``hi``: (first cell not surely outside, first surely inside, end of surely
    inside, end of not surely outside), as crop indices. A cell c spans [c, c + 1)."""
    tol += 1e-9  # and a margin for the float arithmetic
    a = min(max(math.floor(lo - tol) - c0, 0), w)  # cells before a end at or before lo − tol: outside
    b = min(max(math.ceil(hi + tol) - c0, a), w)  # cells from b start at or after hi + tol: outside
    i = min(max(math.floor(lo + tol) + 1 - c0, a), b)  # cells from i start after lo + tol
    j = min(max(math.ceil(hi - tol) - 1 - c0, i), b)  # cells before j end before hi − tol
    return a, i, j, b


def _rotations(thetas) -> np.ndarray:
    """(T, 2, 2) matrices R(θ) (to within an ulp of :func:`merger.transform.rotation`)."""
    t = np.radians(np.asarray(thetas, np.float64))
    out = np.empty((t.size, 2, 2))
    out[:, 0, 0] = out[:, 1, 1] = np.cos(t)
    out[:, 1, 0] = np.sin(t)
    out[:, 0, 1] = -out[:, 1, 0]
    return out


class SparseEvaluator:
    """Exact counts of a :class:`~merger.search.RotationProblem` at batches of angles.

    Parameters
    ----------
    problem : the rotation problem; its ``measure`` decides which counts :meth:`scores` needs.

    Notes
    -----
    Per angle the evaluator keeps the counts of :func:`merger.similarity.count_cells` on
    ``(problem.ref_roi(), problem.moving_roi(θ))``, part by part as they are needed (see ``_PARTS``).
    :meth:`scores` returns the measure's values, equal as floats to ``problem.evaluate(θ).value``;
    :meth:`similarity` the whole :class:`Similarity` (value and counts); :meth:`upper_bounds` cheap
    bounds for ω̃; :meth:`prepare` evaluates values and bounds for many angles in few batches.
    """

    def __init__(self, problem) -> None:
        self.problem = problem
        n = self.n = problem.n
        self.res = problem.ref.resolution
        self.k = lattice_coords(n, self.res)
        self.half = n * self.res / 2.0
        self.ref_roi = fast_extract_roi(problem.ref, problem.center_ref, n)
        flat = self.ref_roi.reshape(-1)
        self.ref_occ_flat = flat == OCCUPIED_S
        self.occ_idx = np.flatnonzero(self.ref_occ_flat)  # the reference-occupied lattice points (flat)
        self.occ_h = self._homogeneous(self.occ_idx)
        self._ref_free_flat = None
        self._free_h = None  # lazily: free lattice points (free/free counts)
        self.sx = float(self.occ_h.shape[1])
        self.cm = np.asarray(problem.center_moving, np.float64)
        self._crop(problem.moving)
        self._index: dict[float, int] = {}  # angle -> row of _rows
        self._angles: list[float] = []
        self._rows = np.full((64, 6), -1, np.int64)
        self._full: dict[float, np.ndarray] = {}
        self._padded = None  # the reference ROI's classes on a padded lattice (see _lattice_masks)
        self._free_pad1 = None  # the reference-free lattice points, padded by one (see _disagree_lower)

    @property
    def ref_free_flat(self) -> np.ndarray:
        """The reference-free lattice points (flat mask; computed when first needed)."""
        if self._ref_free_flat is None:
            self._ref_free_flat = self.ref_roi.reshape(-1) == FREE_S
        return self._ref_free_flat

    def _homogeneous(self, lattice_flat: np.ndarray) -> np.ndarray:
        """(3, m) columns (kx, ky, 1) of lattice points given by flat index ``i * n + j``."""
        i, j = np.divmod(lattice_flat, self.n)
        out = np.empty((3, j.size))
        self.k.take(j, out=out[0])
        self.k.take(i, out=out[1])
        out[2] = 1.0
        return out

    # --- the moving map around its ROI, the square border baked in ------------------------------------
    def _crop(self, mov: OccupancyGrid) -> None:
        """Codes of the moving cells a lattice lookup can reach: the state inside the moving ROI's square,
        unknown outside it, and a flag on the cells that straddle the square's border."""
        mres, (ox, oy) = mov.resolution, mov.origin
        self.mres = mres
        uc = (self.cm - np.array([ox, oy])) / mres
        reach = self.half * math.sqrt(2) / mres + 2  # the ROI lattice's corners are √2·half away
        x0, y0 = (int(math.floor(v - reach)) for v in uc)
        w = self.w = int(math.ceil(2 * reach)) + 2
        crop = np.zeros((w, w), np.uint8)
        # per crop column (row): outside the square for sure, straddling its border, or inside for sure
        (xa, xi, xj, xb), (ya, yi, yj, yb) = (_axis_ranges(c0, (cmv - self.half - o) / mres,
                                                           (cmv + self.half - o) / mres, w, _TOL_M / mres)
                                              for c0, o, cmv in ((x0, ox, self.cm[0]), (y0, oy, self.cm[1])))
        gx0, gx1 = max(x0 + xa, 0), min(x0 + xb, mov.width)
        gy0, gy1 = max(y0 + ya, 0), min(y0 + yb, mov.height)
        if gx0 < gx1 and gy0 < gy1:
            block = mov.states[gy0:gy1, gx0:gx1]
            crop[gy0 - y0:gy1 - y0, gx0 - x0:gx1 - x0] = block
            qr, qc = np.divmod(np.flatnonzero(block == OCCUPIED_S), gx1 - gx0)
            qr += gy0 - y0
            qc += gx0 - x0
        else:
            qr = qc = np.empty(0, np.intp)
        for c in (*range(xa, xi), *range(xj, xb)):  # a column or two on each side
            crop[:, c] |= _STRADDLE
        for r in (*range(ya, yi), *range(yj, yb)):
            crop[r, :] |= _STRADDLE
        self.code = crop.reshape(-1)
        self.base = uc - np.array([x0, y0])  # crop coordinates: u = (c_m + d − origin)/res_m − (x0, y0)
        # occupied moving cells: the only cells whose preimage can be occupied in the moving ROI
        self.q_strad = (qc < xi) | (qc >= xj) | (qr < yi) | (qr >= yj)
        self.q_h = q_h = np.empty((3, qr.size))
        np.multiply(qc, mres, out=q_h[0])
        q_h[0] += (x0 + 0.5) * mres + ox - self.cm[0]
        np.multiply(qr, mres, out=q_h[1])
        q_h[1] += (y0 + 0.5) * mres + oy - self.cm[1]
        q_h[2] = 1.0
        self.q_rel = q_h[:2]  # (2, Q): cell centres relative to the moving center, metres
        self.scale = self.res / mres  # one lattice step, in moving cells
        self.rad = math.sqrt(0.5) / self.scale + 1e-6  # preimage radius of a cell, in lattice steps
        self._nb = int(math.floor(2 * self.rad)) + 1  # lattice points per axis within rad of a point
        self._pad = self._nb + 1
        self.qcol, self.qrow = qc.astype(np.float64), qr.astype(np.float64)  # occupied cells, crop indices
        self._q_inner32 = q_h[:, ~self.q_strad].astype(np.float32)  # those surely inside the square
        self._q_strad_any = bool(self.q_strad.any())

    # --- certified lookups ----------------------------------------------------------------------------
    def _states(self, pts_h: np.ndarray, rots: np.ndarray, bad: np.ndarray) -> np.ndarray:
        """Moving-ROI states (T, m) at lattice points ``pts_h`` (3, m) for rotations ``rots`` (T, 2, 2)
        (``d = R @ (kx, ky)``). Angles where a point is too close to a cell border, or to the square's
        border, are flagged in ``bad``."""
        nt = rots.shape[0]
        g = np.empty((2 * nt, 3))
        g[:nt, :2], g[nt:, :2] = rots[:, 0, :] / self.mres, rots[:, 1, :] / self.mres
        g[:nt, 2], g[nt:, 2] = self.base
        u = g @ pts_h  # (2T, m): crop x per angle, then crop y per angle (always > 1: the crop's margin)
        f = np.floor(u)
        u -= f
        if u.min() < _TOL_CELL or u.max() > 1.0 - _TOL_CELL:
            amb = ((u < _TOL_CELL) | (u > 1.0 - _TOL_CELL)).any(axis=1)
            bad |= amb[:nt] | amb[nt:]
        f[nt:] *= self.w
        f[nt:] += f[:nt]  # exact: integers far below 2⁵³
        code = self.code.take(f[nt:].astype(np.intp))
        if code.max(initial=0) >= _STRADDLE:
            t_idx, m_idx = np.divmod(np.flatnonzero(code >= _STRADDLE), code.shape[1])
            d = np.einsum("am,mba->mb", pts_h[:2, m_idx], rots[t_idx])
            out, amb2 = self._outside(d)
            code[t_idx, m_idx] = np.where(out, UNKNOWN_S, code[t_idx, m_idx] & 3)
            bad[t_idx[amb2]] = True
        return code

    def _outside(self, d: np.ndarray):
        """Points (m, 2) in metres: outside the moving ROI's square? too close to its border to tell?"""
        a = np.abs(d)
        return (a >= self.half).any(axis=1), (np.abs(a - self.half) < _TOL_M).any(axis=1)

    def _lattice_masks(self):
        """The reference-free lattice points, and the not-occupied ones, on the lattice padded by ``pad``
        points on every side (padding: neither)."""
        if self._padded is None:
            n, pad = self.n, self._pad
            free = np.zeros((n + 2 * pad, n + 2 * pad), bool)
            free[pad:pad + n, pad:pad + n] = self.ref_roi == FREE_S
            nocc = np.zeros_like(free)
            nocc[pad:pad + n, pad:pad + n] = self.ref_roi != OCCUPIED_S
            self._padded = (free.reshape(-1), nocc.reshape(-1))
        return self._padded

    def _near_walls(self, angles, keep: np.ndarray) -> np.ndarray:
        """Lattice points (flat, within ``keep``) whose lookup can land in an occupied moving cell at one
        of ``angles``: the lattice points within ``rad`` of a cell centre mapped forward (x_ref =
        c_ref + R(θ)(x_mov − c_mov)), i.e. a superset of the occupied cells' preimages."""
        n = self.n
        fr = _rotations(angles) / self.res
        nb = int(math.floor(2 * self.rad)) + 1  # lattice points per axis within rad of a point
        w = n + 2 * nb
        ns = fr.shape[0]
        g = np.empty((2 * ns, 3))
        g[:ns, :2], g[ns:, :2] = fr[:, 0, :], fr[:, 1, :]
        g[:, 2] = (n - 1) / 2.0 - self.rad + nb
        lo = np.ceil(g @ self.q_h)  # (2T, Q): first lattice point per axis, padded by nb
        np.maximum(lo, 0, out=lo)
        np.minimum(lo, w - nb, out=lo)
        lo[ns:] *= w
        lo[ns:] += lo[:ns]
        # mark each nb × nb block of candidates by its first point, then widen the marks into blocks
        first = np.zeros((w, w), bool)
        first.reshape(-1)[lo[ns:].astype(np.intp).reshape(-1)] = True
        mask = first.copy()
        for dy in range(nb):
            for dx in range(nb):
                if dy or dx:
                    mask[dy:, dx:] |= first[:w - dy, :w - dx]
        return np.flatnonzero(mask[nb:nb + n, nb:nb + n] & keep.reshape(n, n))

    def _moving_occupied_union(self, thetas, rots, bad, out, *, need_sy: bool) -> None:
        """:meth:`_moving_occupied` by candidate sets shared by nearby angles (small ROIs).

        The angles are grouped in clusters (gaps ≤ 1.5°): a cluster of many angles gets its own candidate
        set (:meth:`_near_walls`), the small ones share one. Candidates are looked up exactly like the
        reference-occupied points; each lattice point is counted once per angle.
        """
        ths = np.asarray(thetas)
        order = np.argsort(ths, kind="stable")
        cuts = np.flatnonzero(np.diff(ths[order]) > _CLUSTER_GAP_DEG) + 1
        clusters = np.split(order, cuts)
        groups = [c for c in clusters if len(c) > _SMALL_CLUSTER]
        small = [c for c in clusters if len(c) <= _SMALL_CLUSTER]
        if small:
            groups.append(np.concatenate(small))
        keep = ~self.ref_occ_flat if need_sy else self.ref_free_flat
        for grp in groups:
            pts = self._near_walls(ths[grp], keep)
            if not pts.size:
                continue
            flagged = np.zeros(len(grp), bool)
            occ = self._states(self._homogeneous(pts), rots[grp], flagged) == OCCUPIED_S
            bad[grp] |= flagged
            if need_sy:
                out[grp, 1] += np.count_nonzero(occ, axis=1)
                occ &= self.ref_free_flat.take(pts)
            out[grp, 0] += np.count_nonzero(occ, axis=1)

    def _moving_occupied(self, thetas, rots, bad, out, *, need_sy: bool) -> None:
        """Lattice points whose lookup is an occupied moving cell: ``out[:, 0]`` += those where the
        reference is free (disagree), ``out[:, 1]`` += those where it is not occupied (if ``need_sy``).
        Two exact ways, the cheaper one by ROI size: candidate sets shared by nearby angles
        (:meth:`_moving_occupied_union`: ROIs up to UNION_MAX_CELLS, where a wall sweeps few lattice
        points over 2°) or cell by cell (:meth:`_moving_occupied_cells`)."""
        if self.n <= UNION_MAX_CELLS:
            self._moving_occupied_union(thetas, rots, bad, out, need_sy=need_sy)
        else:
            self._moving_occupied_cells(thetas, rots, bad, out, need_sy=need_sy)

    def _moving_occupied_cells(self, thetas, rots, bad, out, *, need_sy: bool) -> None:
        """Lattice points whose lookup is an occupied moving cell: ``out[:, 0]`` += those where the
        reference is free (disagree), ``out[:, 1]`` += those where it is not occupied (if ``need_sy``).

        Cell by cell: a lattice point whose lookup lies in the occupied cell C lies within ``rad`` of C's
        centre mapped forward (x_ref = c_ref + R(θ)(x_mov − c_mov); rotations keep distances), so among
        the nb × nb lattice points from ``ceil(m − rad)`` per axis. Each candidate is counted when its
        lookup lies in C, i.e. when its position v = u − (C + ½) relative to C's centre, in moving cells,
        has |v_x|, |v_y| < ½: every lattice point's lookup lies in one cell, so it is counted once, with
        no de-duplication. v is computed in float32 (error < 1e-6 cell for the candidates near C); where
        max(|v_x|, |v_y|) is within 1e-5 of ½ it is recomputed in float64 (error far below 1e-8 cell) and
        certified like :meth:`_states` (closer than 1e-8: the angle takes the reference code path).
        Lookups in cells straddling the square's border are tested against the square like
        :meth:`_states`.
        """
        q = self.q_h.shape[1]
        if not q:
            return
        n, pad, nb = self.n, self._pad, self._nb
        wp = n + 2 * pad
        free_p, nocc_p = self._lattice_masks()
        dx, dy = np.meshgrid(np.arange(nb, dtype=np.float64), np.arange(nb, dtype=np.float64))
        dx, dy = dx.reshape(-1), dy.reshape(-1)
        offs = (dy * wp + dx).astype(np.intp)  # (O,)
        c = (n - 1) / 2.0
        chunk = max(1, int(2_000_000 // (dx.size * q)))
        for s0 in range(0, len(thetas), chunk):
            sl = slice(s0, s0 + chunk)
            rot = rots[sl]  # R(−θ): d = rot @ k
            nt = rot.shape[0]
            fr = _rotations(np.asarray(thetas[sl], np.float64)) / self.res  # forward, lattice steps
            g = np.empty((2 * nt, 3))
            g[:nt, :2], g[nt:, :2] = fr[:, 0, :], fr[:, 1, :]
            g[:, 2] = c - self.rad
            lo = np.ceil(g @ self.q_h)  # (2T, Q): the first candidate per axis (lattice index)
            np.clip(lo, -pad, n, out=lo)  # a candidate block wholly outside the lattice stays outside
            lx, ly = lo[:nt], lo[nt:]
            # v = u − (C + ½) in moving cells, u = (c_m + R(−θ)k − origin)/res_m: linear in the lattice index
            a = rot * (self.res / self.mres)  # (T, 2, 2): moving cells per lattice step
            cx = (self.base[0] - 0.5 - (a[:, 0, 0] + a[:, 0, 1]) * c)[:, None] - self.qcol
            cy = (self.base[1] - 0.5 - (a[:, 1, 0] + a[:, 1, 1]) * c)[:, None] - self.qrow
            ux = a[:, 0, 0, None] * lx + a[:, 0, 1, None] * ly + cx  # (T, Q), float64
            uy = a[:, 1, 0, None] * lx + a[:, 1, 1, None] * ly + cy
            sx = a[:, 0, 0, None] * dx + a[:, 0, 1, None] * dy  # (T, O): a candidate's offset
            sy = a[:, 1, 0, None] * dx + a[:, 1, 1, None] * dy
            vx = ux.astype(np.float32)[:, None, :] + sx.astype(np.float32)[:, :, None]  # (T, O, Q)
            vy = uy.astype(np.float32)[:, None, :] + sy.astype(np.float32)[:, :, None]
            np.abs(vx, out=vx)
            np.abs(vy, out=vy)
            m = np.maximum(vx, vy, out=vx)
            m -= np.float32(0.5)  # < 0: the lookup lies in C
            hit = m < 0
            base = ((ly + pad) * wp + lx + pad).astype(np.intp)  # (T, Q) padded flat index
            idx = base[:, None, :] + offs[None, :, None]
            nocc = nocc_p.take(idx)
            np.abs(m, out=m)
            if m.min() < _NEAR32:  # near C's border in float32: decide in float64
                near = np.flatnonzero(m < _NEAR32)
                near = near[nocc.reshape(-1).take(near)]
                t_i, o_i, q_i = np.unravel_index(near, m.shape)
                if t_i.size:
                    wx = np.abs(ux[t_i, q_i] + sx[t_i, o_i])
                    wy = np.abs(uy[t_i, q_i] + sy[t_i, o_i])
                    m64 = np.maximum(wx, wy) - 0.5
                    hit[t_i, o_i, q_i] = m64 < 0
                    bad[s0 + t_i[np.abs(m64) < _TOL_CELL]] = True
            hs = hit & nocc
            if self._q_strad_any:  # lookups in cells straddling the square's border: inside the square?
                sh = hs & self.q_strad[None, None, :]
                if sh.any():
                    t_i, o_i, q_i = np.nonzero(sh)
                    kx = (lx[t_i, q_i] + dx[o_i] - c) * self.res
                    ky = (ly[t_i, q_i] + dy[o_i] - c) * self.res
                    d = np.stack([rot[t_i, 0, 0] * kx + rot[t_i, 0, 1] * ky,
                                  rot[t_i, 1, 0] * kx + rot[t_i, 1, 1] * ky], axis=1)
                    outside, amb2 = self._outside(d)
                    hs[t_i[outside], o_i[outside], q_i[outside]] = False
                    bad[s0 + t_i[amb2]] = True
            if need_sy:
                out[sl, 1] += np.count_nonzero(hs.reshape(nt, -1), axis=1)
            hs &= free_p.take(idx)
            out[sl, 0] += np.count_nonzero(hs.reshape(nt, -1), axis=1)

    # --- counts, per angle and per part ---------------------------------------------------------------
    # row (one per angle, ``_rows[_index[θ]]``): agree, disagree where the reference is occupied (a),
    # disagree where the moving map is occupied (b), free/free (c), moving-occupied cells where the
    # reference is not occupied (b, NCC only), a lower bound of (b) (l); −1 = not computed yet. An angle
    # that fell back to the reference path holds its complete row.
    _PARTS = {"a": (0, 1), "b": (2, 4), "c": (3,), "l": (5,)}

    def _ids(self, thetas) -> np.ndarray:
        """Row indices of ``thetas`` (floats), new rows for new angles."""
        index, out = self._index, []
        for t in thetas:
            i = index.get(t)
            if i is None:
                i = index[t] = len(self._angles)
                self._angles.append(t)
            out.append(i)
        if len(self._angles) > self._rows.shape[0]:
            grown = np.full((2 * len(self._angles), 6), -1, np.int64)
            grown[:self._rows.shape[0]] = self._rows
            self._rows = grown
        return np.asarray(out, np.intp)

    def _ensure(self, thetas, parts: str) -> np.ndarray:
        """Compute the missing ``parts`` of the rows of ``thetas`` (floats), each part in one batch; returns
        their row indices."""
        ids = self._ids(thetas)
        if not ids.size:
            return ids
        for part in parts:
            col = self._PARTS[part][0]
            todo_ids = ids[self._rows[ids, col] < 0]
            if not todo_ids.size:
                continue
            if todo_ids.size > 1:
                todo_ids = np.unique(todo_ids)
            todo = [self._angles[i] for i in todo_ids.tolist()]
            rots = _rotations([-t for t in todo])  # d = R(−θ) @ (kx, ky), as rotated_roi
            bad = np.zeros(len(todo), bool)
            vals = np.zeros((len(todo), 2), np.int64)
            if part == "a" and self.occ_h.shape[1]:
                for s0 in range(0, len(todo), _ANGLE_CHUNK):  # chunks keep the (angles, points) arrays in cache
                    sl = slice(s0, s0 + _ANGLE_CHUNK)
                    b_sl = bad[sl]
                    st = self._states(self.occ_h, rots[sl], b_sl)
                    bad[sl] = b_sl
                    vals[sl, 0] = np.count_nonzero(st == OCCUPIED_S, axis=1)
                    vals[sl, 1] = np.count_nonzero(st == FREE_S, axis=1)
            elif part == "b" and self.q_h.shape[1]:
                self._moving_occupied(todo, rots, bad, vals, need_sy=self.problem.measure == "ncc")
            elif part == "c":
                vals[:, 0] = self._free_agree(rots, bad)
            elif part == "l" and self.q_h.shape[1]:
                for s0 in range(0, len(todo), _ANGLE_CHUNK):
                    vals[s0:s0 + _ANGLE_CHUNK, 0] = self._disagree_lower(todo[s0:s0 + _ANGLE_CHUNK])
            cols = list(self._PARTS[part])
            self._rows[todo_ids[:, None], cols] = vals[:, :len(cols)]
            if bad.any():  # too close to a cell border to certify: the reference code path decides
                for i in todo_ids[bad].tolist():
                    self._rows[i] = self.full_counts(self._angles[i])
        return ids

    def _disagree_lower(self, thetas) -> np.ndarray:
        """Per angle, a lower bound of the moving-occupied/reference-free count: occupied cells whose
        centre, mapped forward, lies within the inscribed radius (less a margin) of a lattice point —
        that point is certainly their preimage (each point has one cell, so none is counted twice).

        Computed in float32: a mapped coordinate is a sum of terms whose magnitudes add up to less than
        2.5·n lattice steps (|R(θ)q| ≤ 0.71·n + 2, plus (n + 1)/2), so rounding g and q to float32 and the
        float32 product err by less than 10·2⁻²⁴·n < 6e-7·n steps; the radius is shrunk by 2e-6·n + 1e-3
        — a cell passing the test lies within the inscribed radius in exact arithmetic (the margin only
        ever drops cells: still a lower bound)."""
        n, nt = self.n, len(thetas)
        q_in = self._q_inner32
        if not q_in.shape[1] or n > 8000:
            return np.zeros(nt, np.int64)
        fr = _rotations(thetas) / self.res
        g = np.empty((2 * nt, 3), np.float32)
        g[:nt, :2], g[nt:, :2] = fr[:, 0, :], fr[:, 1, :]
        g[:, 2] = (n - 1) / 2.0 + 1.0  # lattice coordinates (j, then i) on the lattice padded by one point
        v = g @ q_in  # (2T, Q)
        r = np.rint(v)
        v -= r
        v *= v
        radius = 0.5 / self.scale - 1e-6 - (2e-6 * n + 1e-3)
        if radius <= 0:
            return np.zeros(nt, np.int64)
        ok = v[:nt] + v[nt:] < np.float32(radius * radius)
        np.clip(r, 0, n + 1, out=r)  # beyond the lattice: its padding (not free)
        ri = r.astype(np.intp)
        ri[nt:] *= n + 2
        ri[nt:] += ri[:nt]
        if self._free_pad1 is None:  # the reference-free lattice points, on the lattice padded by one point
            free_pad = np.zeros((n + 2, n + 2), bool)
            free_pad[1:-1, 1:-1] = self.ref_free_flat.reshape(n, n)
            self._free_pad1 = free_pad.reshape(-1)
        ok &= self._free_pad1.take(ri[nt:])
        return np.count_nonzero(ok, axis=1)

    def _free_agree(self, rots, bad) -> np.ndarray:
        if self._free_h is None:
            self._free_h = self._homogeneous(np.flatnonzero(self.ref_free_flat))
        if not self._free_h.shape[1]:
            return np.zeros(rots.shape[0], np.int64)
        return np.count_nonzero(self._states(self._free_h, rots, bad) == FREE_S, axis=1)

    def full_counts(self, theta: float) -> np.ndarray:
        """A complete row at θ from the whole rotated ROI: the reference's states
        (:meth:`RotationProblem.moving_roi`), computed by :func:`merger.transform.rotated_roi_fast` (the same
        states; it takes the reference's own code path where a lookup is too close to a border to call)."""
        key = float(theta)
        if key not in self._full:
            p = self.problem
            m = rotated_roi_fast(p.moving, key, p.center_moving, p.n, p.ref.resolution)
            c = count_cells(self.ref_roi, m)
            self._full[key] = [c.agree, c.disagree, 0, c.free_agree,
                               int(np.count_nonzero(m == OCCUPIED_S)) - c.agree, 0]
        return self._full[key]

    # --- measure values ---------------------------------------------------------------------------------
    def _exact_parts(self) -> str:
        return "abc" if self.problem.measure == "birk_carpin" else "ab"

    def scores(self, thetas) -> np.ndarray:
        """Values of the problem's measure at ``thetas`` (floats equal to ``problem.evaluate(θ).value``)."""
        ids = self._ensure([float(t) for t in thetas], self._exact_parts())
        rows = self._rows[ids]
        if self.problem.measure == "similarity":  # index_from_counts, vectorized (the same IEEE division)
            agree, den = rows[:, 0], rows[:, 0] + rows[:, 1] + rows[:, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(den > 0, agree / np.maximum(den, 1), 0.0)
        return np.array([self._value(r) for r in rows.tolist()], np.float64)

    def known(self, thetas) -> np.ndarray:
        """Whether the values at ``thetas`` are already computed (:meth:`scores` would not evaluate)."""
        index = self._index
        ids = np.array([index.get(float(t), -1) for t in thetas], np.intp)
        rows = self._rows[np.maximum(ids, 0)]
        out = ids >= 0
        for p in self._exact_parts():
            out &= rows[:, self._PARTS[p][0]] >= 0
        return out

    def prepare(self, exact=(), bounds=(), first_part=()) -> None:
        """Evaluate, in as few batches as possible, the values at ``exact`` and the bounds at ``bounds``
        (and the part the bounds share with the values at ``first_part``)."""
        exact, bounds = [float(t) for t in exact], [float(t) for t in bounds]
        self._ensure(list(dict.fromkeys(exact + bounds + [float(t) for t in first_part])), "a")
        if self.problem.measure == "similarity":
            self._ensure(bounds, "l")
        self._ensure(exact, self._exact_parts())

    def upper_bounds(self, thetas) -> np.ndarray:
        """Upper bounds of the values at ``thetas`` from the reference-occupied points only (cheap).

        For ω̃: agr̃ / (agr̃ + dis) with the moving-occupied half of dis replaced by a lower bound
        (:meth:`_disagree_lower`); exact where the value is known. Other measures get +inf (no bound).
        """
        if self.problem.measure != "similarity":
            return np.full(len(thetas), np.inf)
        ids = self._ensure([float(t) for t in thetas], "al")
        rows = self._rows[ids]
        exact = rows[:, 2] >= 0
        agree = rows[:, 0]
        den = agree + rows[:, 1] + np.where(exact, rows[:, 2], rows[:, 5])
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(den > 0, agree / np.maximum(den, 1), 0.0)

    def _value(self, row) -> float:
        agree, disagree, measure = row[0], row[1] + row[2], self.problem.measure
        if measure == "similarity":  # index_from_counts, inlined
            return agree / (agree + disagree) if agree + disagree else 0.0
        if measure == "ncc":
            return ncc_from_sums(self.n * self.n, self.sx, float(agree + row[4]), float(agree))
        return index_from_counts(Counts(agree, disagree, row[3]), measure)

    def similarity(self, theta: float) -> Similarity:
        """The full :class:`Similarity` at θ (value and all counts), as ``problem.evaluate(θ)``."""
        ids = self._ensure([float(theta)], "abc")
        row = self._rows[ids[0]].tolist()
        return Similarity(self._value(row), Counts(int(row[0]), int(row[1] + row[2]), int(row[3])),
                          self.problem.measure)
