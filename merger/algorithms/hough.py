"""``algorithm: hough`` — Carpin's Hough-spectrum map merging. It uses no center.

S. Carpin, "Fast and accurate map merging for multi-robot systems", Autonomous Robots 25(3):305–316, 2008
(and its implementation, ``mapmerge``, UC Merced 2007: ``get_hypothesis``), as read, not copied:

1. the Hough transform HT(ρ, θ) of each map's occupied cells, θ over the whole turn in 1° cells
   (``theta_cells`` 360), ρ in cells of the grid's resolution;
2. its Hough spectrum HS(θ) = Σ_ρ HT(ρ, θ)² (invariant to translations; a rotation of the map by α shifts it
   circularly by α), normalized to a maximum of 1;
3. the circular cross-correlation of the two spectra; its ``HYPOTHESES`` (4) highest local maxima are the
   rotation hypotheses, each also tried 1° either side (as the implementation does);
4. per hypothesis: the moving map's occupied cells rotated by it, and the translation from the
   cross-correlation of the two maps' x and y projections (occupied cells per column, per row);
5. the hypotheses ranked by Carpin's acceptance index, Birk and Carpin's ω = agr / (agr + dis) on the
   whole maps placed (agr counting free/free too, :func:`merger.measures.birk_carpin`); the best is
   accepted when ω ≥ ``AI_MIN`` and ω rests on at least ``params.min_support`` occupied cells (agr̃ + dis).
   The paper ranks by ω and leaves the decision to the user: ``AI_MIN`` = 0.9 is this implementation's
   choice, not Carpin's.
"""

from __future__ import annotations

import math

import numpy as np

from ..grid import OCCUPIED_S
from ..measures import count_cells, index_from_counts
from ..transform import overlap
from .base import PairAnswer, refused

THETA_CELLS = 360
HYPOTHESES = 4
AI_MIN = 0.9


def _points(g) -> np.ndarray:
    r, c = np.nonzero(g.states == OCCUPIED_S)
    return np.stack([g.origin[0] + (c + 0.5) * g.resolution, g.origin[1] + (r + 0.5) * g.resolution], axis=1)


def spectrum(pts: np.ndarray, res: float) -> np.ndarray:
    """The normalized Hough spectrum of points (metres), θ_k = k · 360° / THETA_CELLS."""
    th = np.arange(THETA_CELLS) * (2 * np.pi / THETA_CELLS)
    rho = np.rint((pts[:, 0:1] * np.cos(th) + pts[:, 1:2] * np.sin(th)) / res).astype(np.int64)  # (N, 360)
    rho -= rho.min()
    width = int(rho.max()) + 1
    flat = (np.arange(THETA_CELLS) * width + rho).ravel()
    ht = np.bincount(flat, minlength=THETA_CELLS * width).reshape(THETA_CELLS, width).astype(np.float64)
    hs = (ht * ht).sum(axis=1)
    return hs / hs.max()


def rotation_hypotheses(hs_ref: np.ndarray, hs_mov: np.ndarray) -> list[float]:
    """Degrees α (moving onto reference): the highest circular local maxima of
    CC(α) = Σ_θ HS_ref(θ) HS_mov(θ − α), each with α ± 1°."""
    cc = np.array([float(np.dot(hs_ref, np.roll(hs_mov, k))) for k in range(THETA_CELLS)])
    peaks = [k for k in range(THETA_CELLS) if cc[k] >= cc[k - 1] and cc[k] >= cc[(k + 1) % THETA_CELLS]]
    peaks = sorted(peaks, key=lambda k: -cc[k])[:HYPOTHESES]
    step = 360.0 / THETA_CELLS
    return [((k + d) * step) % 360.0 for k in peaks for d in (0, 1, -1)]


def _projections(pts: np.ndarray, res: float, lo: np.ndarray, shape) -> tuple[np.ndarray, np.ndarray]:
    ij = np.floor((pts - lo) / res).astype(np.int64)
    return np.bincount(ij[:, 0], minlength=shape[0]).astype(float), np.bincount(ij[:, 1], minlength=shape[1]).astype(float)


def translation(p_ref: np.ndarray, p_rot: np.ndarray, res: float) -> tuple[float, float]:
    """The shift s (metres, whole cells) that best lays the rotated moving points on the reference's:
    the peaks of the cross-correlations of the x and y projections."""
    lo = np.floor(np.minimum(p_ref.min(0), p_rot.min(0)) / res) * res
    hi = np.maximum(p_ref.max(0), p_rot.max(0))
    shape = (int((hi[0] - lo[0]) / res) + 1, int((hi[1] - lo[1]) / res) + 1)
    xr, yr = _projections(p_ref, res, lo, shape)
    xm, ym = _projections(p_rot, res, lo, shape)
    # np.correlate(a, v, "full")[k] = Σ_n a[n + k − (len(v) − 1)] v[n]: the peak k gives the shift of v onto a
    dx = int(np.argmax(np.correlate(xr, xm, "full"))) - (len(xm) - 1)
    dy = int(np.argmax(np.correlate(yr, ym, "full"))) - (len(ym) - 1)
    return dx * res, dy * res


def _rot(pts: np.ndarray, deg: float) -> np.ndarray:
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return pts @ np.array([[c, s], [-s, c]])


def align(ref, mov, params) -> PairAnswer:
    """Map ``mov`` onto map ``ref`` (:class:`merger.team.orders.MapInput`) by Carpin's method;
    ``params.min_support`` is the acceptance index's support floor."""
    from ..team.frames import Warps

    p_ref, p_mov = _points(ref.grid), _points(mov.grid)
    if len(p_ref) < 2 or len(p_mov) < 2:
        return refused(f"hough: too few occupied cells ({len(p_mov)} and {len(p_ref)})")
    res = ref.grid.resolution
    hyps = rotation_hypotheses(spectrum(p_ref, res), spectrum(p_mov, res))
    warps = Warps([ref, mov])
    best = None
    tried = []
    for alpha in hyps:
        s = translation(p_ref, _rot(p_mov, alpha), res)
        # x_ref = R(α) x_mov + s  ⇔  about the centers, t = s + R(α) c_mov − c_ref
        cm = _rot(np.asarray([mov.center], float), alpha)[0]
        t = (float(s[0] + cm[0] - ref.center[0]), float(s[1] + cm[1] - ref.center[1]))
        a, b = overlap(ref.grid, warps.get(0, 1, alpha, t))
        counts = count_cells(a, b)
        ai = index_from_counts(counts, "birk_carpin")
        tried.append([float(alpha), ai])
        if best is None or ai > best[0]:
            best = (ai, alpha, t, counts.support)
    ai, alpha, t, support = best
    ev = {"acceptance_index": ai, "support": support, "hypotheses": tried}
    min_support = getattr(params, "min_support", 0)
    if ai < AI_MIN:
        return PairAnswer(False, alpha, t, ai, ev, f"hough: acceptance index ω {ai:.3f} < {AI_MIN:g}")
    if support < min_support:
        return PairAnswer(False, alpha, t, ai, ev, f"hough: ω rests on {support} occupied cells < {min_support}")
    return PairAnswer(True, alpha, t, ai, ev, "")
