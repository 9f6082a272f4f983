"""Sub-cell refinement of a grid answer (on by default): θ and t below the search's 1°/0.1°/one-cell grid.

1. Ties first: where several fine angles share the best score (a plateau), θ starts at its middle.
2. Then a continuous local optimisation of a smooth score: the reference's occupied cells blurred
   (Gaussian, σ = 1 cell) into a likelihood field, read bilinearly at the moving ROI's occupied cell
   centres placed by (θ, t); a pattern search within ±1° of the start and ±1 cell of the grid
   translation (and inside the window). A parabola through the grid's own scores was tried first and
   rejected: nearest-neighbour scores carry little sub-cell information, and its offsets lowered the
   whole-map ν of correct merges below ν_min.
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
from numba import types
from numba.core.extending import intrinsic

from ..grid import OCCUPIED_S
from ..jit import njit
from ..lattice import half_side
from .prepared import occupied_centres
from .problem import fine_angles, wrap_deg

SUM_BLOCK = 32_000  # the reads are summed in blocks of this many points (as when cv2.remap read them: it takes
# fewer than 32,767 columns, issue 26), each block pairwise in float64 and the blocks in order


def _block_means(reads: np.ndarray) -> np.ndarray:
    """Row means of the float32 ``reads`` (candidates × points), summed as :data:`SUM_BLOCK` says."""
    total = np.zeros(reads.shape[0], np.float64)
    for j in range(0, reads.shape[1], SUM_BLOCK):
        total += reads[:, j:j + SUM_BLOCK].astype(np.float64).sum(axis=1)
    return total / reads.shape[1]


@intrinsic
def _fma32(typingctx, a, b, c):
    """a·b + c rounded once (float32): LLVM's fma, a fused instruction where the CPU has one, else libm's."""
    def codegen(context, builder, signature, args):
        return builder.fma(*args)
    return types.float32(types.float32, types.float32, types.float32), codegen


@njit(cache=True, nogil=True, inline="always")
def _read(field, px, py, c, s, bx, by, res):
    """One read of :func:`_field_reads`: point (px, py) under the candidate (c, s, bx, by)."""
    h, w = field.shape
    x = np.float32(((c * px - s * py) + bx) / res - 0.5)
    y = np.float32(((s * px + c * py) + by) / res - 0.5)
    fx, fy = math.floor(x), math.floor(y)
    ax, ay = np.float32(x - np.float32(fx)), np.float32(y - np.float32(fy))
    ix, iy = int(fx), int(fy)
    v00 = v01 = v10 = v11 = np.float32(0.0)
    if 0 <= iy < h:
        if 0 <= ix < w:
            v00 = field[iy, ix]
        if 0 <= ix + 1 < w:
            v01 = field[iy, ix + 1]
    if 0 <= iy + 1 < h:
        if 0 <= ix < w:
            v10 = field[iy + 1, ix]
        if 0 <= ix + 1 < w:
            v11 = field[iy + 1, ix + 1]
    top = _fma32(ax, np.float32(v01 - v00), v00)
    bottom = _fma32(ax, np.float32(v11 - v10), v10)
    return _fma32(ay, np.float32(bottom - top), top)


@njit(cache=True, nogil=True)
def _field_reads(field, px, py, cs, sn, bx, by, res):
    """The refinement's reads of ``field`` (float32) for each candidate k and point j: bilinear at the pixel
    coordinates computed in float64 and rounded to float32, x = ((cs_k·px_j − sn_k·py_j) + bx_k) / res − 0.5,
    y = ((sn_k·px_j + cs_k·py_j) + by_k) / res − 0.5 (pixel centres at whole coordinates), a neighbour
    outside the field reading 0 — ``cv2.remap``'s INTER_LINEAR with a constant border 0. Each lerp is
    rounded once (a fused multiply-add) as OpenCV 5's float remap does: with OpenCV 5.1 on an x86-64 CPU
    with FMA the values equal cv2.remap's bit for bit (416,000 reads compared when this replaced it; older
    OpenCV reads with 1/32-pixel weights). No coordinate arrays: in the 16-robot hall they were 45% of the
    refinement's time, which was 13% of the run's."""
    out = np.empty((cs.size, px.size), np.float32)
    for k in range(cs.size):
        for j in range(px.size):
            out[k, j] = _read(field, px[j], py[j], cs[k], sn[k], bx[k], by[k], res)
    return out


def square_crop(grid, center, reach: float):
    """The cells of ``grid`` within ``reach`` metres of ``center`` on each axis (unknown outside the grid)
    and the crop's origin (metres)."""
    r = grid.resolution
    c0 = int(math.floor((center[0] - reach - grid.origin[0]) / r))
    r0 = int(math.floor((center[1] - reach - grid.origin[1]) / r))
    size = int(math.ceil(2 * reach / r)) + 2
    out = np.zeros((size, size), np.uint8)
    rs0, rs1 = max(r0, 0), min(r0 + size, grid.height)
    cs0, cs1 = max(c0, 0), min(c0 + size, grid.width)
    if rs0 < rs1 and cs0 < cs1:
        out[rs0 - r0:rs1 - r0, cs0 - c0:cs1 - c0] = grid.states[rs0:rs1, cs0:cs1]
    return out, (grid.origin[0] + c0 * r, grid.origin[1] + r0 * r)


REFINE_SIGMA_CELLS = 1.0  # the smoothing of the reference's occupied cells (a likelihood field)
REFINE_MAX_DEG = 1.0  # the refinement stays within the thesis's fine window (±1°) of the grid angle ...
REFINE_MAX_CELLS = 1.0  # ... and within one cell of the grid translation (and inside the window)
REFINE_ROUNDS = 200  # the pattern search's most rounds


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
    theta_g = al.theta_grid_deg
    a0, b0 = al.cells
    if al.fine is not None and np.any(np.isclose(wrap_deg(al.fine[0]), theta_g, atol=1e-9)):
        angles, vals = al.fine
    else:
        angles = fine_angles(theta_g)
        from .searcher import searcher_for

        vals = searcher_for(problem).values_at_angles(angles, (a0, b0))
    angles = np.asarray(angles, np.float64)
    vals = np.asarray(vals, np.float64)
    i = int(np.flatnonzero(np.isclose(wrap_deg(angles), theta_g, atol=1e-9))[0])
    theta0 = _plateau_middle(angles, vals, i)
    t0 = problem.offset_m(a0, b0)
    theta, t = _smooth_refine(problem, theta0, t0)
    return replace(al, theta_deg=wrap_deg(round(theta, 9)), translation_m=t, refined=True)


def _smooth_refine(problem, theta0: float, t0, kernel: bool = True) -> tuple[float, tuple[float, float]]:
    """The pattern search of :func:`refine_alignment` from (``theta0``, ``t0``): compiled
    (:func:`_pattern_search`), or (``kernel`` False, the tests' yardstick) as a Python loop over the same
    reads; the same answer, bit for bit."""
    ref = problem.ref
    res = ref.resolution
    n = problem.n
    half = half_side(n, res)
    w_m = problem.window_m if problem.window_cells > 0 else 0.0
    # moving ROI's occupied cell centres, relative to the moving center (metres), inside its square
    p = np.stack(occupied_centres(problem), axis=1)
    p = p[(np.abs(p) < half).all(axis=1)]
    if p.shape[0] < 3:
        return theta0, (float(t0[0]), float(t0[1]))
    # the reference's occupied cells around c_ref, blurred
    cr = np.asarray(problem.center_ref, np.float64)
    crop, org = square_crop(ref, cr, half * math.sqrt(2) + w_m + 4 * res)
    field = cv2.GaussianBlur((crop == OCCUPIED_S).astype(np.float32), (0, 0), REFINE_SIGMA_CELLS)
    org = np.asarray(org, np.float64)
    x = np.array([theta0, float(t0[0]), float(t0[1])])
    lo = np.array([theta0 - REFINE_MAX_DEG, t0[0] - REFINE_MAX_CELLS * res, t0[1] - REFINE_MAX_CELLS * res])
    hi = np.array([theta0 + REFINE_MAX_DEG, t0[0] + REFINE_MAX_CELLS * res, t0[1] + REFINE_MAX_CELLS * res])
    if w_m > 0:
        lo[1:] = np.maximum(lo[1:], -w_m)
        hi[1:] = np.minimum(hi[1:], w_m)
    else:
        lo[1:] = hi[1:] = 0.0
    step = np.array([0.1, 0.25 * res, 0.25 * res])
    base = cr - org
    px, py = np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1])
    if kernel:
        x = _pattern_search(field, px, py, float(base[0]), float(base[1]), float(res), x, lo, hi, step,
                            1 if w_m == 0 else 3, SUM_BLOCK)
        return float(x[0]), (float(x[1]), float(x[2]))

    def scores(cands):
        """Mean field value at the moving points for each (θ, tx, ty)."""
        c = np.asarray(cands, np.float64)
        th = np.radians(c[:, 0])
        return _block_means(_field_reads(field, px, py, np.cos(th), np.sin(th), base[0] + c[:, 1], base[1] + c[:, 2],
                                         float(res)))

    dims = [0] if w_m == 0 else [0, 1, 2]
    best = scores([x])[0]
    for _ in range(REFINE_ROUNDS):
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



@njit(cache=True, nogil=True)
def _pairwise_sum(a, lo, n):
    """numpy's pairwise sum of a[lo:lo + n] (float64), in its order: what ``ndarray.sum`` gives, bit for bit."""
    if n < 8:
        r = 0.0
        for i in range(n):
            r += a[lo + i]
        return r
    if n <= 128:
        r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
        r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
        i = 8
        while i < n - (n % 8):
            r0 += a[lo + i]
            r1 += a[lo + i + 1]
            r2 += a[lo + i + 2]
            r3 += a[lo + i + 3]
            r4 += a[lo + i + 4]
            r5 += a[lo + i + 5]
            r6 += a[lo + i + 6]
            r7 += a[lo + i + 7]
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += a[lo + i]
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise_sum(a, lo, n2) + _pairwise_sum(a, lo + n2, n - n2)


@njit(cache=True, nogil=True)
def _mean_read(field, px, py, th_deg, tx, ty, base0, base1, res, block, buf):
    """The refinement's score at (θ°, tx, ty): the mean of :func:`_field_reads` over the points, summed as
    :func:`_block_means` sums them."""
    th = np.radians(th_deg)
    c, sn, bx, by = math.cos(th), math.sin(th), base0 + tx, base1 + ty
    for j in range(px.size):
        buf[j] = np.float64(_read(field, px[j], py[j], c, sn, bx, by, res))
    total = 0.0
    for j in range(0, px.size, block):
        total += _pairwise_sum(buf, j, min(block, px.size - j))
    return total / px.size


@njit(cache=True, nogil=True)
def _pattern_search(field, px, py, base0, base1, res, x, lo, hi, step, ndims, block):
    """:func:`_smooth_refine`'s pattern search compiled (the same candidates, order, scores and tests as its
    Python loop: the same answer, bit for bit; the GIL released). Returns (θ°, tx, ty)."""
    x = x.copy()
    step = step.copy()
    buf = np.empty(px.size, np.float64)
    cand = np.empty((2 * ndims, 3), np.float64)
    best = _mean_read(field, px, py, x[0], x[1], x[2], base0, base1, res, block, buf)
    for _ in range(REFINE_ROUNDS):
        nc = 0
        for d in range(ndims):
            for sgn in (-1.0, 1.0):
                y = min(max(x[d] + sgn * step[d], lo[d]), hi[d])
                if y != x[d]:
                    cand[nc, :] = x
                    cand[nc, d] = y
                    nc += 1
        j, vj = -1, 0.0
        for c in range(nc):  # the first maximum, as numpy's argmax
            v = _mean_read(field, px, py, cand[c, 0], cand[c, 1], cand[c, 2], base0, base1, res, block, buf)
            if j < 0 or v > vj:
                j, vj = c, v
        if j >= 0 and vj > best * (1 + 1e-9) + 1e-12:
            x[:] = cand[j]
            best = vj
            continue
        for d in range(3):
            step[d] /= 2.0
        if step[0] < 0.005 and step[1] < res / 32:
            break
    return x
