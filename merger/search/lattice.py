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

from ..grid import UNKNOWN_S
from ..jit import njit


def rotation_entries(theta_deg: float) -> tuple[float, float, float, float]:
    """R(−θ) as (R00, R01, R10, R11): the moving-frame direction of a reference-frame offset."""
    t = math.radians(-theta_deg)
    c, s = math.cos(t), math.sin(t)
    return c, -s, s, c


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
    half = n * resolution / 2.0
    inside = ((col >= 0) & (col < moving.width) & (row >= 0) & (row < moving.height)
              & (np.abs(dx) < half) & (np.abs(dy) < half))
    out = np.full((n, n), UNKNOWN_S, np.uint8)
    out[inside] = moving.states[row[inside].astype(np.intp), col[inside].astype(np.intp)]
    return out


def ref_axes_numpy(ref, center_ref, n: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """``(cols, rows)``: (2k+1, n) int64 tables of the reference cell read by each lattice column (row)
    at each translation −k..k (−1 outside the grid) — the specification of the reference ROI."""
    r = ref.resolution
    off = lattice_offsets(n, r)
    out = []
    for axis, size in ((0, ref.width), (1, ref.height)):
        tab = np.empty((2 * k + 1, n), np.int64)
        for a in range(-k, k + 1):
            c = center_ref[axis] + a * r if a else center_ref[axis]
            v = np.floor(((c + off) - ref.origin[axis]) / r)
            tab[a + k] = np.where((v >= 0) & (v < size), v, -1)
        out.append(tab)
    return out[0], out[1]


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
    half = n * res / 2.0
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
