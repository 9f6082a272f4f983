"""The ROI lattice: the one place that says which cell each lattice point reads (docs/design/search.md §1).

A problem compares two square regions of interest of ``n × n`` lattice points, spaced one reference
cell apart and centred on the common center. Lattice point (i, j) has the offset
``k = ((j − (n−1)/2)·r, (i − (n−1)/2)·r)`` (r: the reference's resolution).

* **Reference at translation (a, b)** (cells): it reads the reference cell containing
  ``(c_ref + (a·r, b·r)) + k`` — row ``rows[b + K, i]``, column ``cols[a + K, j]`` (−1: outside the
  grid, unknown). Rows depend on (b, i) only and columns on (a, j) only (Lemma 1).
* **Moving map under θ**: lattice point k reads the moving cell containing ``c_m + R(−θ)k`` with
  ``d = R(−θ)k`` computed as ``d_x = R00·k_x + R01·k_y``, ``d_y = R10·k_x + R11·k_y`` (two products and a
  sum, no fused multiply-add), and is unknown when ``|d_x|`` or ``|d_y|`` ≥ n·r/2 (outside the moving
  ROI's square).

:func:`moving_states_numpy` and :func:`ref_axes_numpy` are the specification in plain numpy; the
compiled :func:`moving_states` computes the same floats in the same order (numba without fastmath
does not contract products into FMAs), so every method reads exactly the same cells.
"""

from __future__ import annotations

import math

import numpy as np

from .grid import UNKNOWN_S
from .jit import njit


def rotation_entries(theta_deg: float) -> tuple[float, float, float, float]:
    """R(−θ) as (R00, R01, R10, R11): the moving-frame direction of a reference-frame offset."""
    t = math.radians(-theta_deg)
    c, s = math.cos(t), math.sin(t)
    return c, -s, s, c


@njit(cache=True, nogil=True, inline=True)
def half_side(n, resolution):
    """Half the ROI's side, n·r/2 (metres): a lookup beyond it on either axis is outside the ROI's square."""
    return n * resolution / 2.0


def lattice_offsets(n: int, resolution: float) -> np.ndarray:
    """The 1-D lattice coordinates ``(j − (n−1)/2)·r`` (metres)."""
    return (np.arange(n) - (n - 1) / 2.0) * resolution


def moving_states_numpy(moving, theta_deg: float, center_moving, n: int, resolution: float) -> np.ndarray:
    """(n, n) states of the moving map on the ROI lattice under θ — the specification."""
    r00, r01, r10, r11 = rotation_entries(theta_deg)
    k = lattice_offsets(n, resolution)
    kx, ky = np.meshgrid(k, k)
    dx = r00 * kx + r01 * ky
    dy = r10 * kx + r11 * ky
    col = np.floor(((center_moving[0] + dx) - moving.origin[0]) / moving.resolution)
    row = np.floor(((center_moving[1] + dy) - moving.origin[1]) / moving.resolution)
    half = half_side(n, resolution)
    inside = ((col >= 0) & (col < moving.width) & (row >= 0) & (row < moving.height)
              & (np.abs(dx) < half) & (np.abs(dy) < half))
    out = np.full((n, n), UNKNOWN_S, np.uint8)
    out[inside] = moving.states[row[inside].astype(np.intp), col[inside].astype(np.intp)]
    return out


def axis_floor(center: float, origin: float, resolution: float, n: int, k: int) -> np.ndarray:
    """(2k+1, n) float table: the (unclipped) reference cell index lattice line j reads along one axis at
    each translation −k..k cells, ``floor(((c + a·r) + off_j − origin) / r)`` — the one computation of
    the reference's lookups."""
    off = lattice_offsets(n, resolution)
    tab = np.empty((2 * k + 1, n), np.float64)
    for a in range(-k, k + 1):
        c = center + a * resolution if a else center
        tab[a + k] = np.floor(((c + off) - origin) / resolution)
    return tab


def ref_axes_numpy(ref, center_ref, n: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """``(cols, rows)``: (2k+1, n) int64 tables of the reference cell read by each lattice column (row)
    at each translation −k..k (−1 outside the grid) — the specification of the reference ROI."""
    out = []
    for axis, size in ((0, ref.width), (1, ref.height)):
        v = axis_floor(center_ref[axis], ref.origin[axis], ref.resolution, n, k)
        out.append(np.where((v >= 0) & (v < size), v, -1).astype(np.int64))
    return out[0], out[1]


def roi_cells(roi_m: float, resolution: float) -> int:
    """Side of the square region of interest in cells (at least 1)."""
    return max(1, int(round(roi_m / resolution)))


def extract_roi(grid, center, n: int) -> np.ndarray:
    """The (n, n) states of ``grid`` on the ROI lattice of its own cell size centred on ``center`` (the
    reference ROI; unknown outside the grid)."""
    cols, rows = ref_axes_numpy(grid, (float(center[0]), float(center[1])), n, 0)
    r, c = rows[0][:, None], cols[0][None, :]
    return np.where((r >= 0) & (c >= 0), grid.states[np.maximum(r, 0), np.maximum(c, 0)], UNKNOWN_S).astype(np.uint8)


def rotated_roi(moving, theta_deg: float, center_moving, center_ref, n: int, resolution: float) -> np.ndarray:
    """The moving map's region of interest rotated by θ, on the reference ROI lattice: the square of side
    ``n · resolution`` about ``center_moving`` in the moving map's own frame (the thesis's roi_2); after
    rotation its corners leave the reference square and the reference square's corners are unknown
    (:func:`moving_states_numpy`; ``center_ref`` does not enter: the lattice is relative)."""
    return moving_states_numpy(moving, theta_deg, center_moving, n, resolution)


@njit(cache=True, nogil=True)
def state_at(states, res_m, ox, oy, cx, cy, m, half, res, r00, r01, r10, r11, i, j):
    """The state lattice point (i, j) reads under the rotation R(−θ) = (r00, r01, r10, r11): the
    compiled form of :func:`moving_states_numpy` at one point (m = (n−1)/2, half = n·r/2)."""
    ky = (i - m) * res
    kx = (j - m) * res
    dx = r00 * kx + r01 * ky
    dy = r10 * kx + r11 * ky
    if abs(dx) < half and abs(dy) < half:
        h, w = states.shape
        u = ((cx + dx) - ox) / res_m  # floor(u) in [0, w) ⇔ 0 ≤ u < w
        v = ((cy + dy) - oy) / res_m
        if 0.0 <= u < w and 0.0 <= v < h:
            return states[int(v), int(u)]
    return 0


@njit(cache=True, nogil=True)
def moving_states(states, res_m, ox, oy, cx, cy, n, res, r00, r01, r10, r11, out):
    """Compiled :func:`moving_states_numpy` into ``out`` (n·n uint8, row-major); returns the number of
    occupied and of free lattice points."""
    half = half_side(n, res)
    m = (n - 1) / 2.0
    n_occ = 0
    n_free = 0
    for i in range(n):
        for j in range(n):
            s = state_at(states, res_m, ox, oy, cx, cy, m, half, res, r00, r01, r10, r11, i, j)
            out[i * n + j] = s
            if s == 2:
                n_occ += 1
            elif s == 1:
                n_free += 1
    return n_occ, n_free
