"""Contrast verification: evidence for an alignment that tolerates the noise of real maps.

Maps of one place from independent runs disagree cell by cell: thick or doubled walls, walls a cell or
two apart, maps bent by their SLAM. The thesis's whole-map ω̃ counts only exact cell agreement, and on
such maps it stays low at the true placement (Halmstad, ROI 8 m cases: 0.16–0.42, median 0.30),
so no fixed ν_min separates them (docs/merging-real-maps.md). This verification asks instead how far
the placement stands above the same maps' other placements:

* **fit** f(θ, δ) of map b onto map a, both already placed on one lattice: the mean over b's occupied
  cells of w(d) = max(0, 1 − (d / D)²), d the distance (cells) from the cell, rotated by θ about the
  pivot and shifted by δ, to a's nearest occupied cell, D = ``tolerance_m`` / resolution; cells landing
  on a's unknown cells count 0. A wall a cell or two off still counts most of its weight.
* **best**: the largest fit near the placement (a pattern search over |θ| ≤ ``LOCAL_DEG``, |δ| ≤
  ``LOCAL_M`` on each axis: bent maps fit best a little away from the ROI's optimum).
* **rival**: the largest fit of the other hypotheses: every rotation at least ``RIVAL_SEP_DEG`` away
  (``RIVAL_STEP_DEG`` steps); the scan's ``RIVAL_REFINED`` highest local maxima are refined like the
  best, and one that climbs to its limit towards the placement is the placement's own shoulder, not a
  rival (a broad peak, e.g. large rooms near the center).
* **contrast** = best / rival. Accepted when contrast ≥ ``contrast_min``, b has at least
  ``min_support`` occupied cells on a's known cells, and the best fit lies within ``FIT_AGREE_DEG`` of the
  placement's angle: the contrast says the placement is in the right basin, the agreement that the
  search's answer is where the whole maps fit (on bent real maps an ROI's optimum was 3–9° off with a
  contrast of 1.9–5.5; measured in docs/merging-real-maps.md). A point-symmetric scene has a rival as good as the
  best (contrast ≈ 1) and is refused, as the thesis's rule would; a correct alignment of noisy maps
  stands well above its rivals even when ω̃ is low.

Everything is deterministic (fixed step sizes and orders) and pure (arrays in, numbers out). The defaults of
``tolerance_m`` and ``contrast_min`` (``TOLERANCE_M``, ``CONTRAST_MIN``) are the settings' (:mod:`merger.team.defaults`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..grid import OCCUPIED_S, UNKNOWN_S, OccupancyGrid
from ..jit import njit
from .defaults import CONTRAST_MIN, TOLERANCE_M  # noqa: F401 (the settings' defaults, read here; CONTRAST_MIN's old path)

LOCAL_DEG = 5.0
LOCAL_M = 0.5
RIVAL_SEP_DEG = 15.0  # rivals start this far from the placement and stay ≥ 10° away
RIVAL_STEP_DEG = 2.0
RIVAL_REFINED = 3
STEPS = ((1.0, 2.0), (0.5, 1.0), (0.25, 0.5), (0.1, 0.25))  # (degrees, cells) of the pattern search
REFINE_DEG = 5.0  # the refinement of an accepted placement (refine): within this angle ...
REFINE_M = 1.0  # ... and this translation on each axis
SCAN_DEG = (-2.0, -1.0, 0.0, 1.0, 2.0)  # its coarse scan: these angles × translations every SCAN_STEP_M
SCAN_STEP_M = 0.1
SCAN_POINTS = 4096
FIT_AGREE_DEG = 4.0  # the whole maps' best fit must lie this close to the placement's angle (see verify_contrast; chosen
# leaving one Halmstad building out, with the accepted placement refined: docs/merging-real-maps.md)


@dataclass(frozen=True)
class Contrast:
    """The evidence of one pair: the best fit near the placement (θ, δ in cells, relative to it), the
    best rival fit and where it lies, their ratio and the support (b's occupied cells on a's known cells
    at the placement)."""

    best: float
    best_at: tuple[float, float, float]
    rival: float
    rival_at: tuple[float, float, float]
    support: int

    @property
    def contrast(self) -> float:
        return self.best / self.rival if self.rival > 0 else (math.inf if self.best > 0 else 0.0)


@njit(cache=True, nogil=True)
def _fit_sum(px, py, cx, cy, co, si, dx, dy, weight):
    """Σ weight[row, col] over the points (px, py) rotated by (co, si) about (cx, cy) and shifted by (dx, dy)
    (cell units; the points are relative to the pivot); points off the grid count 0."""
    h, w = weight.shape
    s = 0.0
    for k in range(px.shape[0]):
        x = px[k] * co - py[k] * si + cx + dx
        y = px[k] * si + py[k] * co + cy + dy
        c = int(math.floor(x))
        r = int(math.floor(y))
        if 0 <= r < h and 0 <= c < w:
            s += weight[r, c]
    return s


class Fit:
    """f(θ, δ) of b's occupied cells onto grid a (see the module documentation); ``pivot``: world (x, y)."""

    def __init__(self, a: OccupancyGrid, b: OccupancyGrid, pivot, tol_cells: float) -> None:
        self.dist = cv2.distanceTransform(np.where(a.states == OCCUPIED_S, 0, 255).astype(np.uint8),
                                          cv2.DIST_L2, 5)
        self.known = a.states != UNKNOWN_S
        res = a.resolution
        r, c = np.nonzero(b.states == OCCUPIED_S)
        # b's occupied cell centres and the pivot in a's cell units (x = column, y = row)
        self.pivot = np.array([(pivot[0] - a.origin[0]) / res, (pivot[1] - a.origin[1]) / res])
        bx = (b.origin[0] - a.origin[0]) / res + c + 0.5
        by = (b.origin[1] - a.origin[1]) / res + r + 0.5
        self.pts = np.stack([bx, by], 1) - self.pivot
        self.d = float(tol_cells)
        self.shape = a.states.shape
        # w(d) on a's known cells, 0 on its unknown ones: one look-up per point and placement
        near = np.minimum(self.dist * np.float32(1.0 / self.d), np.float32(1.0))  # cv2's distance to no cell is ~1e38
        self.weight = np.where(self.known, np.float32(1.0) - near ** 2, np.float32(0.0)).astype(np.float32)
        self._px = np.ascontiguousarray(self.pts[:, 0])
        self._py = np.ascontiguousarray(self.pts[:, 1])
        step = max(1, len(self.pts) // SCAN_POINTS)  # every step-th point: the refinement's coarse scan
        self._sx, self._sy = self._px[::step].copy(), self._py[::step].copy()

    def _cells(self, theta_deg: float, dx: float, dy: float):
        t = math.radians(theta_deg)
        co, si = math.cos(t), math.sin(t)
        x = self.pts[:, 0] * co - self.pts[:, 1] * si + self.pivot[0] + dx
        y = self.pts[:, 0] * si + self.pts[:, 1] * co + self.pivot[1] + dy
        c, r = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
        ok = (r >= 0) & (r < self.shape[0]) & (c >= 0) & (c < self.shape[1])
        r, c = r[ok], c[ok]
        on = self.known[r, c]
        return r[on], c[on]

    def __call__(self, theta_deg: float, dx: float, dy: float) -> float:
        if not len(self.pts):
            return 0.0
        t = math.radians(theta_deg)
        return _fit_sum(self._px, self._py, float(self.pivot[0]), float(self.pivot[1]), math.cos(t), math.sin(t),
                        float(dx), float(dy), self.weight) / len(self.pts)

    def sampled(self, theta_deg: float, dx: float, dy: float) -> float:
        """f on at most ~``SCAN_POINTS`` of b's occupied cells (evenly taken in their raster order)."""
        if not len(self._sx):
            return 0.0
        t = math.radians(theta_deg)
        return _fit_sum(self._sx, self._sy, float(self.pivot[0]), float(self.pivot[1]), math.cos(t), math.sin(t),
                        float(dx), float(dy), self.weight) / len(self._sx)

    def support(self) -> int:
        """b's occupied cells on a's known cells at the placement itself."""
        return int(self._cells(0.0, 0.0, 0.0)[0].size) if len(self.pts) else 0


def climb(f: Fit, start: tuple[float, float, float], lim_deg: float, lim_cells: float, around=None):
    """Pattern search from ``start`` (θ°, dx, dy cells) within ±lim of ``around`` (default: ``start``);
    returns (value, (θ, dx, dy))."""
    th0, x0, y0 = start if around is None else around
    best, at = f(*start), start
    for sa, sc in STEPS:
        moved = True
        while moved:
            moved = False
            for d in ((sa, 0.0, 0.0), (-sa, 0.0, 0.0), (0.0, sc, 0.0), (0.0, -sc, 0.0), (0.0, 0.0, sc), (0.0, 0.0, -sc)):
                q = (at[0] + d[0], at[1] + d[1], at[2] + d[2])
                if abs(q[0] - th0) > lim_deg + 1e-9 or abs(q[1] - x0) > lim_cells + 1e-9 or abs(q[2] - y0) > lim_cells + 1e-9:
                    continue
                v = f(*q)
                if v > best:
                    best, at, moved = v, q, True
    return best, at


def refine(a: OccupancyGrid, b: OccupancyGrid, pivot, tolerance_m: float = TOLERANCE_M, lim_m: float = REFINE_M):
    """The best fit of b placed onto a near its placement: (fit, (θ°, dx, dy cells)), the offset relative
    to the placement, θ about ``pivot``, within ±``REFINE_DEG`` and ±``lim_m`` on each axis. Two climbs
    (:func:`climb`): from the placement, and from the best of a coarse scan of that box (``SCAN_DEG`` ×
    ``SCAN_STEP_M`` steps, on ~``SCAN_POINTS`` of b's occupied cells); the higher fit wins. The scan finds
    the whole maps' peak when the search's answer sits on a lesser one nearby (a corridor's: Halmstad F5,
    0.6 m along it, docs/merging-real-maps.md)."""
    res = a.resolution
    f = Fit(a, b, pivot, max(tolerance_m / res, 1.0))
    lim = lim_m / res
    here = climb(f, (0.0, 0.0, 0.0), REFINE_DEG, lim)
    n = int(round(lim_m / SCAN_STEP_M))
    offs = [k * SCAN_STEP_M / res for k in range(-n, n + 1)]
    scan = max(((f.sampled(th, dx, dy), (th, dx, dy)) for th in SCAN_DEG for dx in offs for dy in offs),
               key=lambda v: v[0])
    there = climb(f, scan[1], REFINE_DEG, lim, (0.0, 0.0, 0.0))
    return there if there[0] > here[0] else here


def contrast(a: OccupancyGrid, b: OccupancyGrid, pivot, tolerance_m: float = TOLERANCE_M, *,
             min_support: int = 0, agree_deg: float | None = None) -> Contrast:
    """The contrast evidence of b placed onto a (two grids on one cell lattice), rotations about ``pivot``
    (world x, y: where the maps' common center lies). ``min_support`` and ``agree_deg`` (the rule's own
    tests, :func:`merger.team.verify.verify_contrast`): when the support is below the first, or the best
    fit lies farther than the second from the placement, the rule refuses whatever the rivals, and they are
    not computed (``rival`` NaN; below the support neither is the best fit)."""
    res = a.resolution
    f = Fit(a, b, pivot, max(tolerance_m / res, 1.0))
    support = f.support()
    nan = float("nan")
    if support < min_support:
        return Contrast(nan, (nan, 0.0, 0.0), nan, (nan, 0.0, 0.0), support)
    lim = LOCAL_M / res
    best, best_at = climb(f, (0.0, 0.0, 0.0), LOCAL_DEG, lim)
    if agree_deg is not None and abs(best_at[0]) > agree_deg:
        return Contrast(best, best_at, nan, (nan, 0.0, 0.0), support)
    far = np.arange(RIVAL_SEP_DEG, 360.0 - RIVAL_SEP_DEG + 1e-9, RIVAL_STEP_DEG)
    vals = np.array([f(float(th), 0.0, 0.0) for th in far])
    # the rivals: the scan's local maxima (a slope towards the placement is its peak's shoulder, not a rival)
    peak = (vals >= np.r_[-1.0, vals[:-1]]) & (vals >= np.r_[vals[1:], -1.0]) & (vals > 0)
    order = sorted(np.flatnonzero(peak), key=lambda i: (-vals[i], far[i]))
    rival, rival_at = 0.0, (float("nan"), 0.0, 0.0)
    for i in order[:RIVAL_REFINED]:
        v, at = climb(f, (float(far[i]), 0.0, 0.0), LOCAL_DEG, lim)
        if abs((at[0] - best_at[0] + 180.0) % 360.0 - 180.0) <= RIVAL_SEP_DEG - LOCAL_DEG + 1e-6:
            continue  # climbed to its limit towards the placement: the placement's shoulder
        if v > rival:
            rival, rival_at = v, at
    return Contrast(best, best_at, rival, rival_at, support)
