"""Scan-to-map matching of the bench SLAM: a correlative search on a small window, then Gauss–Newton.

The contract: :func:`match` takes a robot's log-odds grid (its map so far), one scan's points in the
robot frame and a predicted pose (odometry), and returns the pose in the map frame at which the scan
fits the map best, with the search's score. Nothing here draws random numbers or keeps state: the same
inputs give the same pose.

Two stages, as Cartographer's 2D local SLAM does them (``RealTimeCorrelativeScanMatcher2D`` then
``CeresScanMatcher2D``):

1. **Correlative search** — every pose of a window around the prediction: translations on the grid's
   cells (±``n_lin`` cells on each axis), rotations in steps of ``acos(1 − r²/(2 d²))`` (r the cell
   size, d the farthest point: the step moves that point by one cell, Cartographer's rule), ±``n_ang``
   steps. A pose scores the mean map value of the cells its points fall in, times
   ``exp(−(w_t·|Δt| + w_r·|Δθ|)²)`` (Cartographer's ``translation_delta_cost_weight`` and
   ``rotation_delta_cost_weight``, 0.1 each: equal fits go to the pose nearest the prediction, so a
   featureless direction keeps the odometry).
2. **Local refinement** — Gauss–Newton from the correlative pose and from the prediction (the lower
   cost wins), minimizing the mean squared distance of the points to the map's walls over σ = one cell,
   (1/N)·Σ (r_i/σ)², plus the odometry's prior w_t²·|t − t_pred|² + w_r²·(θ − θ_pred)² (the caller
   weighs it by the prediction's uncertainty; it also holds a direction the scan leaves free, a
   corridor's axis). A point's distance r_i is to the mean hit μ of the nearest occupied cell among the
   3×3 about it (gmapping keeps such means: a wall's place within its cell), along the surface normal
   estimated from the neighbouring returns (point-to-line, as PL-ICP: a wall does not pull along itself),
   or |S(p) − μ| for a point without one; beyond two cells a point is an outlier.

The correlative score of a cell is its log-odds clipped to [0, clamp] over clamp. Cells below
``min_log_odds`` are not matched. A cell (row r,
column c) spans [origin + c·res, origin + (c + 1)·res) in x (rows in y), as in
:class:`merger.grid.OccupancyGrid`.

The kernels are compiled with ``@njit(cache=True, nogil=True)``, no fastmath (as merger's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from merger.jit import njit

CSM_DELTA_WEIGHT = 0.1  # Cartographer's translation_/rotation_delta_cost_weight defaults (per m, per rad)
GN_ITERATIONS = 10
STOP_M, STOP_RAD = 1e-4, 1e-5  # Gauss–Newton stops below a step of 0.1 mm and 0.0006°
GN_HALVINGS = 2
STOP_GAIN = 1e-4
OUTLIER_SIGMAS = 2.0  # a point farther than this from every mean hit near it pulls nothing


@dataclass(frozen=True)
class Match:
    """A matched pose (x, y, yaw in the map frame), the correlative score (mean map value at the points,
    in [0, 1]) and the refinement's fit (mean squared distance of the points to their mean hits, in σ²,
    outliers counted as ``OUTLIER_SIGMAS``²)."""

    x: float
    y: float
    yaw: float
    score: float
    fit: float


class HitMeans:
    """Per cell, the sum of the scan returns (map-frame x, y) that fell in it and their count: the cell's
    mean hit, where its wall really is within the cell (gmapping's ``PointAccumulator``). A wall is unknown
    until its first hit. Which cells are matched is the log-odds' business (``min_log_odds``): a
    teammate's body crosses a cell in less time than a wall takes to get there, and its trace is then
    cleared by the beams that pass through it."""

    def __init__(self, shape) -> None:
        self.sum_x = np.zeros(shape, np.float64)
        self.sum_y = np.zeros(shape, np.float64)
        self.count = np.zeros(shape, np.float64)

    def add(self, rows: np.ndarray, cols: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
        """Add returns at map-frame (x, y) in cells (rows, cols) (repeated cells add up)."""
        _accumulate(self.sum_x, self.sum_y, self.count, np.ascontiguousarray(rows, np.int64),
                    np.ascontiguousarray(cols, np.int64), np.ascontiguousarray(x, np.float64),
                    np.ascontiguousarray(y, np.float64))


@njit(cache=True, nogil=True)
def _accumulate(sx, sy, cnt, rows, cols, x, y):
    for i in range(rows.size):
        sx[rows[i], cols[i]] += x[i]
        sy[rows[i], cols[i]] += y[i]
        cnt[rows[i], cols[i]] += 1.0


def scan_points(ranges: np.ndarray, angle_min: float, angle_increment: float, range_min: float,
                max_points: int, neighbour: int = 2, max_gap_m: float = 0.15):
    """A scan's points for matching, in the robot frame: at most ``max_points`` valid returns (every
    k-th), each with the unit normal of the surface it lies on, from the returns ``neighbour`` beams
    either side (when both are valid and within ``max_gap_m`` of it; else (0, 0): no normal).
    Returns px, py, nx, ny."""
    r = np.ascontiguousarray(ranges, np.float64)
    valid = int(np.count_nonzero(np.isfinite(r) & (r >= range_min)))
    stride = max(1, -(-valid // max_points))
    return _scan_points(r, float(angle_min), float(angle_increment), float(range_min), stride, neighbour,
                        max_gap_m)


@njit(cache=True, nogil=True)
def _scan_points(r, angle_min, inc, range_min, stride, k, gap):
    n = r.size
    ok = np.empty(n, np.bool_)
    x = np.zeros(n)
    y = np.zeros(n)
    for i in range(n):
        ok[i] = math.isfinite(r[i]) and r[i] >= range_min
        if ok[i]:
            a = angle_min + i * inc
            x[i] = r[i] * math.cos(a)
            y[i] = r[i] * math.sin(a)
    m = 0
    for i in range(n):
        m += ok[i]
    m = (m + stride - 1) // stride
    px, py, nx, ny = np.empty(m), np.empty(m), np.zeros(m), np.zeros(m)
    j = seen = 0
    for i in range(n):
        if not ok[i]:
            continue
        seen += 1
        if (seen - 1) % stride:
            continue
        px[j], py[j] = x[i], y[i]
        lo, hi = i - k, i + k
        if lo >= 0 and hi < n and ok[lo] and ok[hi] \
                and math.hypot(x[lo] - x[i], y[lo] - y[i]) < gap and math.hypot(x[hi] - x[i], y[hi] - y[i]) < gap:
            tx, ty = x[hi] - x[lo], y[hi] - y[lo]
            norm = math.hypot(tx, ty)
            if norm > 0.0:
                nx[j], ny[j] = -ty / norm, tx / norm
        j += 1
    return px, py, nx, ny


def angular_step(resolution_m: float, max_range_m: float) -> float:
    """Cartographer's angular step: the rotation that moves the farthest point by one cell (radians)."""
    d = max(max_range_m, resolution_m)
    return math.acos(max(-1.0, 1.0 - resolution_m * resolution_m / (2.0 * d * d)))


def match(log_odds: np.ndarray, hits: HitMeans, origin, resolution_m: float, clamp: float, px: np.ndarray,
          py: np.ndarray, nx: np.ndarray, ny: np.ndarray, pred, linear_window_m: float, angular_window_rad: float,
          translation_weight: float, rotation_weight: float, min_log_odds: float = 0.0) -> Match:
    """The pose near ``pred`` (x, y, yaw) at which the points (``px``, ``py``, robot frame, metres, with
    their surface normals ``nx``, ``ny``; (0, 0) for none) fit the map best; the search covers
    ±``linear_window_m`` on each axis (at least one cell) and ±``angular_window_rad`` (at least one step);
    ``translation_weight`` and ``rotation_weight`` weigh the prior about ``pred`` (per metre, per radian,
    in the units of the mean squared distance over a cell)."""
    px = np.ascontiguousarray(px, np.float64)
    py = np.ascontiguousarray(py, np.float64)
    nx = np.ascontiguousarray(nx, np.float64)
    ny = np.ascontiguousarray(ny, np.float64)
    if px.size == 0:
        return Match(float(pred[0]), float(pred[1]), float(pred[2]), 0.0, False)
    step = angular_step(resolution_m, float(np.sqrt(px * px + py * py).max()))
    n_lin = max(1, int(math.ceil(linear_window_m / resolution_m - 1e-9)))
    n_ang = max(1, int(math.ceil(angular_window_rad / step - 1e-9)))
    ox, oy = float(origin[0]), float(origin[1])
    floor = max(float(min_log_odds), 1e-6)  # cells below it are not matched (the clamp only scales scores)
    x, y, th, score = correlative_search(log_odds, hits.count, ox, oy, resolution_m, clamp, floor, px, py, float(pred[0]),
                                         float(pred[1]), float(pred[2]), n_lin, n_ang, step, CSM_DELTA_WEIGHT,
                                         CSM_DELTA_WEIGHT)
    best = None
    for start in ((x, y, th), (float(pred[0]), float(pred[1]), float(pred[2]))):
        r = refine(log_odds, hits.sum_x, hits.sum_y, hits.count, ox, oy, resolution_m, floor, resolution_m, px, py,
                   nx, ny, start[0], start[1], start[2], float(pred[0]), float(pred[1]), float(pred[2]),
                   translation_weight, rotation_weight, GN_ITERATIONS)
        if best is None or r[4] < best[4]:
            best = r
        if (x, y, th) == tuple(map(float, pred)):
            break
    return Match(best[0], best[1], best[2], score, best[3])


@njit(cache=True, nogil=True)
def _cell_value(lo, r, c, clamp):
    if r < 0 or c < 0 or r >= lo.shape[0] or c >= lo.shape[1]:
        return 0.0
    v = lo[r, c]
    if v <= 0.0:
        return 0.0
    return min(v, clamp) / clamp


@njit(cache=True, nogil=True)
def correlative_search(lo, cnt, ox, oy, res, clamp, floor, px, py, x0, y0, th0, n_lin, n_ang, step, w_t, w_r):
    """The best (x, y, θ, raw score) over the window; translations are whole cells, so each rotated scan
    is discretized once and shifted by integer offsets (Cartographer's DiscreteScan2D)."""
    n = px.size
    side = 2 * n_lin + 1
    ci = np.empty(n, np.int64)
    ri = np.empty(n, np.int64)
    sums = np.empty(side * side, np.float64)
    best = -1.0
    bx, by, bth, braw = x0, y0, th0, 0.0
    for a in range(-n_ang, n_ang + 1):
        th = th0 + a * step
        c, s = math.cos(th), math.sin(th)
        for i in range(n):
            ci[i] = int(math.floor((c * px[i] - s * py[i] + x0 - ox) / res))
            ri[i] = int(math.floor((s * px[i] + c * py[i] + y0 - oy) / res))
        sums[:] = 0.0
        for i in range(n):
            for dy in range(-n_lin, n_lin + 1):
                r = ri[i] + dy
                if r < 0 or r >= lo.shape[0]:
                    continue
                base = (dy + n_lin) * side + n_lin
                for dx in range(-n_lin, n_lin + 1):
                    col = ci[i] + dx
                    if col < 0 or col >= lo.shape[1]:
                        continue
                    v = lo[r, col]
                    if v >= floor and cnt[r, col] > 0.0:
                        sums[base + dx] += min(v, clamp)
        for dy in range(-n_lin, n_lin + 1):
            for dx in range(-n_lin, n_lin + 1):
                raw = sums[(dy + n_lin) * side + dx + n_lin] / (clamp * n)
                d = math.sqrt(float(dx * dx + dy * dy)) * res * w_t + abs(a * step) * w_r
                sc = raw * math.exp(-d * d)
                if sc > best:
                    best = sc
                    bx, by, bth, braw = x0 + dx * res, y0 + dy * res, th, raw
    return bx, by, bth, braw


@njit(cache=True, nogil=True)
def _nearest_mean(lo, sx, sy, cnt, ox, oy, res, floor, wx, wy):
    """The mean hit nearest to (wx, wy) among the occupied cells (log-odds > 0) of the 3×3 cells about
    it: (found, mean x, mean y)."""
    c0 = int(math.floor((wx - ox) / res))
    r0 = int(math.floor((wy - oy) / res))
    best, mx, my = math.inf, 0.0, 0.0
    for r in range(r0 - 1, r0 + 2):
        if r < 0 or r >= lo.shape[0]:
            continue
        for c in range(c0 - 1, c0 + 2):
            if c < 0 or c >= lo.shape[1]:
                continue
            n = cnt[r, c]
            if lo[r, c] < floor or n <= 0.0:
                continue
            ux = sx[r, c] / n
            uy = sy[r, c] / n
            d = (wx - ux) ** 2 + (wy - uy) ** 2
            if d < best:
                best, mx, my = d, ux, uy
    return best < math.inf, mx, my


@njit(cache=True, nogil=True)
def _cost_grad(lo, sx, sy, cnt, ox, oy, res, floor, sigma, px, py, nx, ny, x, y, th, x0, y0, th0, w_t, w_r, want_grad,
               h, g):
    """Cost at (x, y, θ) with and without the prior; with ``want_grad`` also the Gauss–Newton normal
    equations (h 3×3, g 3).

    A point p with a surface normal n (robot frame, unit; (0, 0) for none) contributes
    (R(θ)n · (S(p) − μ) / σ)², its distance to the mean hit μ nearest to it along the surface's normal
    (point-to-line, as PL-ICP: a wall does not pull along itself); without a normal, |S(p) − μ|² / σ².
    A point farther than ``OUTLIER_SIGMAS``·σ from every mean hit near it adds that constant squared
    and pulls nothing."""
    n = px.size
    inv_n = 1.0 / n
    cap = OUTLIER_SIGMAS * OUTLIER_SIGMAS
    c, s = math.cos(th), math.sin(th)
    cost = 0.0
    if want_grad:
        h[:, :] = 0.0
        g[:] = 0.0
    j = np.zeros(3)
    for i in range(n):
        wx = c * px[i] - s * py[i] + x
        wy = s * px[i] + c * py[i] + y
        found, mx, my = _nearest_mean(lo, sx, sy, cnt, ox, oy, res, floor, wx, wy)
        if not found:
            cost += cap * inv_n
            continue
        ex = (wx - mx) / sigma
        ey = (wy - my) / sigma
        e2 = ex * ex + ey * ey
        if e2 >= cap:
            cost += cap * inv_n
            continue
        a = (-s * px[i] - c * py[i]) / sigma  # dS/dθ over σ
        b = (c * px[i] - s * py[i]) / sigma
        q = 1.0 / sigma
        if nx[i] != 0.0 or ny[i] != 0.0:
            mxn = c * nx[i] - s * ny[i]
            myn = s * nx[i] + c * ny[i]
            r = mxn * ex + myn * ey
            cost += r * r * inv_n
            if want_grad:
                j[0] = mxn * q
                j[1] = myn * q
                j[2] = mxn * a + myn * b + (-myn) * ex + mxn * ey  # n·dS/dθ + dn/dθ·(S − μ)
                for u in range(3):
                    g[u] += j[u] * r * inv_n
                    for v in range(u, 3):
                        h[u, v] += j[u] * j[v] * inv_n
            continue
        cost += e2 * inv_n
        if want_grad:
            h[0, 0] += q * q * inv_n
            h[1, 1] += q * q * inv_n
            h[0, 2] += q * a * inv_n
            h[1, 2] += q * b * inv_n
            h[2, 2] += (a * a + b * b) * inv_n
            g[0] += q * ex * inv_n
            g[1] += q * ey * inv_n
            g[2] += (a * ex + b * ey) * inv_n
    dth = (th - th0 + math.pi) % (2.0 * math.pi) - math.pi
    data = cost
    cost += w_t * w_t * ((x - x0) ** 2 + (y - y0) ** 2) + w_r * w_r * dth * dth
    if want_grad:
        h[1, 0] = h[0, 1]
        h[2, 0] = h[0, 2]
        h[2, 1] = h[1, 2]
        h[0, 0] += w_t * w_t
        h[1, 1] += w_t * w_t
        h[2, 2] += w_r * w_r
        g[0] += w_t * w_t * (x - x0)
        g[1] += w_t * w_t * (y - y0)
        g[2] += w_r * w_r * dth
    return cost, data


@njit(cache=True, nogil=True)
def _solve3(h, g):
    """−h⁻¹·g by Cramer's rule (h symmetric positive definite with the prior); zeros if singular."""
    a, b, c = h[0, 0], h[0, 1], h[0, 2]
    d, e, f = h[1, 1], h[1, 2], h[2, 2]
    det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
    out = np.zeros(3)
    if abs(det) < 1e-300:
        return out
    i00 = d * f - e * e
    i01 = c * e - b * f
    i02 = b * e - c * d
    i11 = a * f - c * c
    i12 = b * c - a * e
    i22 = a * d - b * b
    out[0] = -(i00 * g[0] + i01 * g[1] + i02 * g[2]) / det
    out[1] = -(i01 * g[0] + i11 * g[1] + i12 * g[2]) / det
    out[2] = -(i02 * g[0] + i12 * g[1] + i22 * g[2]) / det
    return out


@njit(cache=True, nogil=True)
def refine(lo, sx, sy, cnt, ox, oy, res, floor, sigma, px, py, nx, ny, xs, ys, ths, x0, y0, th0, w_t, w_r,
           iterations):
    """Gauss–Newton from (xs, ys, θs) with the prior about (x0, y0, θ0); returns the refined (x, y, θ), its
    fit (the cost without the prior) and its cost. A step that does not lower the cost is halved (``GN_HALVINGS`` times at
    most); the iterations stop when a step is below ``STOP_M`` / ``STOP_RAD`` or gains less than
    ``STOP_GAIN`` of the cost."""
    h, g = np.zeros((3, 3)), np.zeros(3)
    h2, g2 = np.zeros((3, 3)), np.zeros(3)
    x, y, th = xs, ys, ths
    cost, fit = _cost_grad(lo, sx, sy, cnt, ox, oy, res, floor, sigma, px, py, nx, ny, x, y, th, x0, y0, th0, w_t,
                           w_r, True, h, g)
    for _ in range(iterations):
        d = _solve3(h, g)
        if abs(d[0]) < STOP_M and abs(d[1]) < STOP_M and abs(d[2]) < STOP_RAD:
            break
        gain = -1.0
        for _k in range(GN_HALVINGS + 1):
            qx, qy, qth = x + d[0], y + d[1], th + d[2]
            c2, f2 = _cost_grad(lo, sx, sy, cnt, ox, oy, res, floor, sigma, px, py, nx, ny, qx, qy, qth, x0, y0, th0,
                                w_t, w_r, True, h2, g2)
            if c2 < cost:
                gain = cost - c2
                x, y, th, cost, fit = qx, qy, qth, c2, f2
                h, h2 = h2, h
                g, g2 = g2, g
                break
            d *= 0.5
        if gain < STOP_GAIN * cost:
            break
    return x, y, th, fit, cost
