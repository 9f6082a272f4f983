"""Rotation of a grid about its center point onto another grid's frame (nearest neighbour on states).

An alignment of map j onto map i is ``x_i = c_i + R(θ)(x_j − c_j)`` (DESIGN.md). To resample map j in
frame i we go backwards: every target point ``x_i`` looks up the cell of map j that contains
``c_j + R(−θ)(x_i − c_i)``. Looking up the *containing* cell of a point is nearest-neighbour
resampling on cell centres, so no state is ever invented; points outside map j are unknown.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid
from .jit import njit


def rotation(theta_deg: float) -> np.ndarray:
    t = math.radians(theta_deg)
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s], [s, c]])


def apply_alignment(xy_j, theta_deg: float, center_j, center_i) -> np.ndarray:
    """Map points of frame j into frame i: ``c_i + R(θ)(x_j − c_j)``."""
    xy_j = np.asarray(xy_j, np.float64)
    return np.asarray(center_i, np.float64) + (xy_j - np.asarray(center_j, np.float64)) @ rotation(theta_deg).T


def sample_nearest(grid: OccupancyGrid, xy: np.ndarray) -> np.ndarray:
    """States of the cells of ``grid`` that contain the world points ``xy`` (..., 2); unknown outside."""
    cr = np.floor(grid.world_to_cell(xy)).astype(np.int64)
    col, row = cr[..., 0], cr[..., 1]
    inside = (col >= 0) & (col < grid.width) & (row >= 0) & (row < grid.height)
    out = np.full(col.shape, UNKNOWN_S, np.uint8)
    out[inside] = grid.states[row[inside], col[inside]]
    return out


def warp_grid(moving: OccupancyGrid, theta_deg: float, center_moving, center_target,
              target: OccupancyGrid) -> OccupancyGrid:
    """Resample the whole ``moving`` grid into the geometry (shape, resolution, origin) of ``target``.

    Same result as :func:`warp_grid_numpy` (nearest neighbour: the moving cell containing each target
    cell centre), computed with OpenCV's nearest-neighbour affine warp; the few cells whose source
    point lies within 1/512 cell of a cell border, where OpenCV's float32 arithmetic could pick the
    neighbour, are found analytically and recomputed exactly (:func:`_near_integer`).
    """
    states = _warp_states_fast(moving, theta_deg, center_moving, center_target, target)
    if states is None:
        return warp_grid_numpy(moving, theta_deg, center_moving, center_target, target)
    return OccupancyGrid(states, target.resolution, target.origin)


WARP_BLOCK_CELLS = 1 << 20  # the numpy warp's working arrays (~70 bytes a cell) cover this many cells at once


def warp_grid_numpy(moving: OccupancyGrid, theta_deg: float, center_moving, center_target,
                    target: OccupancyGrid) -> OccupancyGrid:
    """:func:`warp_grid` in plain numpy, every cell by :func:`sample_nearest` (the yardstick). Computed in
    blocks of rows of about :data:`WARP_BLOCK_CELLS` cells: each cell is its own computation, so the states
    are the same, and the working arrays stay ~70 MB (a 4224² target took 1.2 GB at once, per thread)."""
    h, w = target.shape
    out = np.empty((h, w), np.uint8)
    step = max(1, WARP_BLOCK_CELLS // max(w, 1))
    for r0 in range(0, h, step):
        rows, cols = np.indices((min(step, h - r0), w))
        pts_target = target.cell_center(rows + r0, cols)
        out[r0:r0 + step] = sample_nearest(moving, apply_alignment(pts_target, -theta_deg, center_target,
                                                                   center_moving))
    return OccupancyGrid(out, target.resolution, target.origin)


_WARP_EPS = 1.0 / 512  # OpenCV computes the source point to ~3e-4 cell or better (float32)
_EXACT_EPS = 1e-9  # float64 margin: closer to a border, the reference's own code path decides
_WARP_MAX_COORD = 4096.0  # beyond this, float32 coordinates are too coarse for the margin


def _near_integer(a: np.ndarray, b: np.ndarray, eps: float):
    """All (i, j) with a[j] + b[i] within ``eps`` of an integer, without forming the (len b, len a) grid.

    With f = a mod 1 sorted (and repeated at f ± 1 for the wrap-around), row i needs f within ``eps``
    of g = −b[i] mod 1: one binary search per row.
    """
    f = np.mod(a, 1.0)
    order = np.argsort(f, kind="stable")
    fs = f[order]
    fs = np.concatenate([fs - 1.0, fs, fs + 1.0])
    g = np.mod(-b, 1.0)
    lo = np.searchsorted(fs, g - eps)
    cnt = np.searchsorted(fs, g + eps, side="right") - lo
    rows = np.repeat(np.arange(b.size), cnt)
    k = np.repeat(lo - np.cumsum(cnt) + cnt, cnt) + np.arange(rows.size)
    return rows, order[k % a.size]


def _warp_nearest(moving: OccupancyGrid, r: np.ndarray, step: float, u0: float, v0: float, size) -> np.ndarray:
    """``cv2.warpAffine`` (nearest, unknown outside) of the moving states onto a target of ``size`` (w, h)
    whose first cell looks up the continuous moving-cell coordinates (u0, v0), ``step`` moving cells per
    target cell along the rotation ``r`` (OpenCV's pixel-centre convention: −0.5)."""
    m = np.array([[r[0, 0] * step, r[0, 1] * step, u0 - 0.5],
                  [r[1, 0] * step, r[1, 1] * step, v0 - 0.5]])
    return cv2.warpAffine(np.ascontiguousarray(moving.states), m, size, flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
                          borderMode=cv2.BORDER_CONSTANT, borderValue=int(UNKNOWN_S))


def _warp_states_fast(moving: OccupancyGrid, theta_deg: float, center_moving, center_target,
                      target: OccupancyGrid):
    """States of :func:`warp_grid` via ``cv2.warpAffine``; None when the sizes are out of its range."""
    h, w = target.shape
    if not (0 < h < 32767 and 0 < w < 32767 and 0 < moving.height < 32767 and 0 < moving.width < 32767):
        return None
    r = rotation(-theta_deg)  # target offsets → moving offsets, as apply_alignment(·, −θ, …)
    rt, rm = target.resolution, moving.resolution
    gx = target.origin[0] + (np.arange(w) + 0.5) * rt - center_target[0]
    gy = target.origin[1] + (np.arange(h) + 0.5) * rt - center_target[1]
    # continuous moving-cell coordinates u = (A[j] + B[i], C[j] + D[i]); the cell is their floor
    a = (center_moving[0] - moving.origin[0] + r[0, 0] * gx) / rm
    b = r[0, 1] * gy / rm
    c = (center_moving[1] - moving.origin[1] + r[1, 0] * gx) / rm
    d = r[1, 1] * gy / rm
    corners = np.array([a[0] + b[0], a[-1] + b[0], a[0] + b[-1], a[-1] + b[-1],
                        c[0] + d[0], c[-1] + d[0], c[0] + d[-1], c[-1] + d[-1]])
    if not np.abs(corners).max() < _WARP_MAX_COORD:
        return None
    out = _warp_nearest(moving, r, rt / rm, a[0] + b[0], c[0] + d[0], (w, h))
    # the cells whose lookup lies within 1/512 cell of a border, where OpenCV's fixed-point arithmetic could
    # pick the neighbour, looked up again in float64; those within 1e-9 of it are returned (the kernel
    # :func:`_fix_borders`; :func:`_fix_borders_reference` in numpy, the tests compare them)
    it, jt = _fix_borders(out, np.ascontiguousarray(moving.states), a, b, c, d, _WARP_EPS, _EXACT_EPS)
    _tight(out, it, jt, moving, theta_deg, center_moving, center_target, target)
    return out


def _tight(out, it, jt, moving, theta_deg, center_moving, center_target, target) -> None:
    """Cells (it, jt) too close to a border to call in float64: the reference's own arithmetic decides."""
    if it.size:
        rows_, cols_ = np.concatenate([it, it[:1]]), np.concatenate([jt, jt[:1]])  # ≥ 2 rows
        pts = apply_alignment(target.cell_center(rows_, cols_), -theta_deg, center_target, center_moving)
        out[it, jt] = sample_nearest(moving, pts)[:it.size]


def _fix_borders_reference(out, states, a, b, c, d, eps: float, exact_eps: float):
    """:func:`_fix_borders` in numpy (the tests compare them)."""
    ix, jx = _near_integer(a, b, eps)
    iy, jy = _near_integer(c, d, eps)
    i, j = np.concatenate([ix, iy]), np.concatenate([jx, jy])
    ux, uy = a.take(j) + b.take(i), c.take(j) + d.take(i)
    if not i.size:
        return i, j
    h_m, w_m = states.shape
    col, row = np.floor(ux), np.floor(uy)
    inside = (col >= 0) & (col < w_m) & (row >= 0) & (row < h_m)
    cell = np.where(inside, row * w_m + col, 0).astype(np.intp)
    out.reshape(-1)[i * out.shape[1] + j] = np.where(inside, states.reshape(-1).take(cell), UNKNOWN_S)
    tight = (np.abs(ux - np.round(ux)) < exact_eps) | (np.abs(uy - np.round(uy)) < exact_eps)
    return i[tight], j[tight]


@njit(cache=True, nogil=True)
def _fix_borders(out, states, a, b, c, d, eps, exact_eps):
    """Target cells (i, j) whose continuous moving-cell coordinates (a[j] + b[i], c[j] + d[i]) lie within
    ``eps`` of a cell border on either axis: looked up again in float64 (nearest: the containing cell,
    unknown outside ``states``); returns those within ``exact_eps`` of a border (rows, cols). Per axis, the
    fractional parts of ``a`` (``c``) sorted, one binary search per row, as :func:`_near_integer`."""
    h_m, w_m = states.shape
    ti, tj = [], []
    for axis in range(2):
        p, q = (a, b) if axis == 0 else (c, d)
        f = np.mod(p, 1.0)
        order = np.argsort(f)
        fs = f[order]
        for i in range(q.size):
            g = np.mod(-q[i], 1.0)
            for s in (-1.0, 0.0, 1.0):  # f − 1, f, f + 1: the wrap-around
                lo, hi = 0, fs.size  # the first k with fs[k] + s >= g − eps (np.searchsorted's left side)
                while lo < hi:
                    mid = (lo + hi) // 2
                    if fs[mid] + s < g - eps:
                        lo = mid + 1
                    else:
                        hi = mid
                for k in range(lo, fs.size):  # every fs[k] + s from there up to g + eps
                    if fs[k] + s > g + eps:
                        break
                    j = order[k]
                    ux, uy = a[j] + b[i], c[j] + d[i]
                    col, row = math.floor(ux), math.floor(uy)
                    out[i, j] = states[row, col] if 0 <= col < w_m and 0 <= row < h_m else UNKNOWN_S
                    if abs(ux - round(ux)) < exact_eps or abs(uy - round(uy)) < exact_eps:
                        ti.append(i)
                        tj.append(j)
    return np.array(ti, np.int64), np.array(tj, np.int64)


def _lattice_box(ref: OccupancyGrid, x0: float, x1: float, y0: float, y1: float) -> OccupancyGrid:
    """An all-unknown grid on ``ref``'s cell lattice covering [x0, x1] × [y0, y1]."""
    r = ref.resolution
    ox, oy = ref.origin
    c0 = math.floor((x0 - ox) / r + 1e-9)
    r0 = math.floor((y0 - oy) / r + 1e-9)
    c1 = math.ceil((x1 - ox) / r - 1e-9)
    r1 = math.ceil((y1 - oy) / r - 1e-9)
    return OccupancyGrid.unknown(max(r1 - r0, 0), max(c1 - c0, 0), r, (ox + c0 * r, oy + r0 * r))


def _placed_bounds(g: OccupancyGrid, theta: float, c, center_ref):
    gx0, gx1, gy0, gy1 = g.extent
    corners = np.array([[gx0, gy0], [gx1, gy0], [gx0, gy1], [gx1, gy1]])
    p = apply_alignment(corners, theta, c, center_ref)
    return p[:, 0].min(), p[:, 0].max(), p[:, 1].min(), p[:, 1].max()


def canvas(ref: OccupancyGrid, placed: list[tuple[OccupancyGrid, float, tuple[float, float]]],
           center_ref) -> OccupancyGrid:
    """An all-unknown grid on ``ref``'s cell lattice covering ``ref`` and every placed map.

    ``placed`` holds (grid, θ onto ref, grid's center). The canvas extends ``ref`` by whole cells so
    that ``ref`` copies onto it without resampling.
    """
    x0, x1, y0, y1 = ref.extent
    for g, theta, c in placed:
        px0, px1, py0, py1 = _placed_bounds(g, theta, c, center_ref)
        x0, x1, y0, y1 = min(x0, px0), max(x1, px1), min(y0, py0), max(y1, py1)
    return _lattice_box(ref, x0, x1, y0, y1)


def footprint(ref: OccupancyGrid, g: OccupancyGrid, theta: float, center_g, center_ref) -> OccupancyGrid:
    """The part of :func:`canvas` that ``g`` rotated by θ covers: an all-unknown grid on ``ref``'s lattice.

    Every cell of a canvas outside it is unknown after :func:`warp_grid` (its centre lies outside the
    rotated grid), so ``paste(warp_grid(g, …, footprint), canvas)`` equals ``warp_grid(g, …, canvas)``,
    except on a cell whose source point lies exactly on a cell border: there the nearest cell is a tie,
    decided by the rounding of that grid's own cell-centre floats (a test bounds this).
    """
    return _lattice_box(ref, *_placed_bounds(g, theta, center_g, center_ref))


def overlap(a: OccupancyGrid, b: OccupancyGrid) -> tuple[np.ndarray, np.ndarray]:
    """The states of two grids on one cell lattice where their extents overlap (possibly empty)."""
    r = a.resolution
    dc = int(round((b.origin[0] - a.origin[0]) / r))
    dr = int(round((b.origin[1] - a.origin[1]) / r))
    c0, c1 = max(0, dc), min(a.width, dc + b.width)
    r0, r1 = max(0, dr), min(a.height, dr + b.height)
    if c0 >= c1 or r0 >= r1:
        return np.zeros((0, 0), np.uint8), np.zeros((0, 0), np.uint8)
    return a.states[r0:r1, c0:c1], b.states[r0 - dr:r1 - dr, c0 - dc:c1 - dc]


def paste(ref: OccupancyGrid, target: OccupancyGrid) -> OccupancyGrid:
    """Copy ``ref`` into ``target``'s geometry (same lattice, as built by :func:`canvas`)."""
    dc = int(round((ref.origin[0] - target.origin[0]) / target.resolution))
    dr = int(round((ref.origin[1] - target.origin[1]) / target.resolution))
    out = np.zeros(target.shape, np.uint8)
    out[dr:dr + ref.height, dc:dc + ref.width] = ref.states
    return OccupancyGrid(out, target.resolution, target.origin)


RESAMPLE_FREE_FRACTION = 0.5  # a coarser cell is free when free cells cover at least this share of it


def resample(grid: OccupancyGrid, resolution: float) -> OccupancyGrid:
    """``grid`` on cells of ``resolution`` metres, same origin (OpenCV's ``resize``), with this rule for the
    three states:

    * **coarser cells** (``INTER_AREA``: each new cell averages the old cells it covers): *occupied* when
      any occupied cell covers part of it (a one-cell wall stays a wall, as ω̃ counts walls), else *free*
      when free cells cover at least ``RESAMPLE_FREE_FRACTION`` of it, else *unknown*;
    * **finer cells** (``INTER_NEAREST``): each new cell takes the state of the old cell under its centre
      (no state is invented).

    The new grid has round(old side × old / new resolution) cells a side, so every cell lands within half
    a new cell of its place at the far edge (exactly in place when the ratio is a whole number)."""
    r0 = grid.resolution
    if math.isclose(resolution, r0, rel_tol=1e-9):
        return grid
    h, w = grid.shape
    size = (max(1, round(w * r0 / resolution)), max(1, round(h * r0 / resolution)))  # OpenCV: (width, height)
    if resolution < r0:
        states = cv2.resize(grid.states, size, interpolation=cv2.INTER_NEAREST)
    else:
        occ = cv2.resize((grid.states == OCCUPIED_S).astype(np.float32), size, interpolation=cv2.INTER_AREA)
        free = cv2.resize((grid.states == FREE_S).astype(np.float32), size, interpolation=cv2.INTER_AREA)
        states = np.where(occ > 1e-6, OCCUPIED_S, np.where(free >= RESAMPLE_FREE_FRACTION - 1e-6, FREE_S,
                                                            UNKNOWN_S)).astype(np.uint8)
    return OccupancyGrid(states, resolution, grid.origin)
