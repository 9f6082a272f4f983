"""``circsim score RUN --merged-bag BAG``: estimates read off a merged map (m-explore's ``/map``, say).

A merger that publishes only its merged grid (nav_msgs/OccupancyGrid, one frame for all) does not say where
it placed each robot's map; but the merged grid *contains* every map it placed, warped rigidly. So each
robot's map (its newest message on the run's bag at or before the merged map's stamp) is located in the
merged grid: its occupied cells, rotated by every whole degree, are correlated with the merged grid's
occupied cells (dilated by one cell, at half resolution first: OpenCV ``matchTemplate``, TM_CCORR), and
the best three rotations are refined at full resolution over ±1° in 0.1° steps (on the occupied cells
blurred by about a cell, whose correlation peaks at the exact placement), then polished off the lattices
(bilinear reads, 0.05° and quarter-cell steps). A map is *placed* when at
least ``match_min`` (default 0.7) of its occupied cells fall on (dilated) occupied cells of the merged
grid; a map the merger left out matches far less. From the placements T_k of the maps in the merged
frame, every placed robot i gets an estimate: T_i⁻¹ ∘ T_j for every other placed map j
(:class:`circsim.score.Estimate`). The locating is exact to about a cell and a few tenths of a degree (a
merged grid resampled to its own lattice moves a map by up to half a cell), inside the default tolerances
(10 cm, 2°). Time of a merged map: its header stamp (simulated seconds when the
merger ran with ``use_sim_time`` on ``ros2 bag play --clock``); ``every_s`` judges at most one merged map
per that many seconds (locating costs about 2 s per map and merged map on 60 s scene 1 maps).
"""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np

from merger.grid import OCCUPIED_S, OccupancyGrid
from merger.pose import wrap_yaw

from .score import Estimate, ScoreError, Truth

MATCH_MIN = 0.7


def _points(grid: OccupancyGrid) -> np.ndarray:
    """Centres (x, y) of the occupied cells, metres in the grid's frame."""
    r, c = np.nonzero(grid.states == OCCUPIED_S)
    res = grid.resolution
    return np.stack([grid.origin[0] + (c + 0.5) * res, grid.origin[1] + (r + 0.5) * res], axis=1)


def _raster(q: np.ndarray, res: float):
    """Points as a binary float32 image at ``res`` (row = y), and the world position of pixel (0, 0)'s corner."""
    o = np.floor(q.min(axis=0) / res) * res
    ij = np.floor((q - o) / res).astype(np.int64)
    img = np.zeros((ij[:, 1].max() + 1, ij[:, 0].max() + 1), np.float32)
    img[ij[:, 1], ij[:, 0]] = 1.0
    return img, o


def _match(target: np.ndarray, t_origin, q: np.ndarray, res: float):
    """Best translation of the points ``q`` onto the binary image ``target`` (origin ``t_origin``, cell ``res``):
    (hits / template pixels, translation p such that q + p lands on the target)."""
    tpl, o = _raster(q, res)
    th, tw = tpl.shape
    padded = cv2.copyMakeBorder(target, th, th, tw, tw, cv2.BORDER_CONSTANT, value=0.0)
    corr = cv2.matchTemplate(padded, tpl, cv2.TM_CCORR)
    _, best, _, (u, v) = cv2.minMaxLoc(corr)
    p = (t_origin[0] + (u - tw) * res - o[0], t_origin[1] + (v - th) * res - o[1])
    return best / float(tpl.sum()), p


def _rot(pts: np.ndarray, deg: float) -> np.ndarray:
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return pts @ np.array([[c, s], [-s, c]])


def locate(grid: OccupancyGrid, merged: OccupancyGrid) -> tuple[float, tuple[float, float, float]] | None:
    """Where ``grid`` lies in ``merged``: (fraction of its occupied cells matched, (yaw_deg, x, y)) with
    x_merged = R(yaw)·x_grid + (x, y); None when either has no occupied cell."""
    pts = _points(grid)
    occ = (merged.states == OCCUPIED_S).astype(np.uint8)
    if len(pts) == 0 or not occ.any():
        return None
    res = merged.resolution
    fine = cv2.dilate(occ, np.ones((3, 3), np.uint8)).astype(np.float32)
    coarse_res = 2 * res
    h, w = occ.shape
    pooled = np.pad(occ, ((0, h % 2), (0, w % 2))).reshape((h + 1) // 2, 2, (w + 1) // 2, 2).max(axis=(1, 3))
    coarse = cv2.dilate(pooled, np.ones((3, 3), np.uint8)).astype(np.float32)
    scores = [(_match(coarse, merged.origin, _rot(pts, d), coarse_res)[0], d) for d in range(360)]
    # the fine stage picks on the occupied cells blurred by a cell (a peak at the exact placement; the dilated
    # image is flat within a cell) and reports the fraction on the dilated ones
    sharp = cv2.GaussianBlur(occ.astype(np.float32), (5, 5), 1.0)
    best = None
    for _, d0 in sorted(scores, reverse=True)[:3]:
        for k in range(-10, 11):
            d = (d0 + 0.1 * k) % 360.0
            v, p = _match(sharp, merged.origin, _rot(pts, d), res)
            if best is None or v > best[0]:
                best = (v, d, p)
    _, d, p = best
    d, p = _polish(sharp, merged, pts, d, p)
    f, _ = _match(fine, merged.origin, _rot(pts, d), res)
    return f, (d, p[0], p[1])


def _polish(sharp: np.ndarray, merged: OccupancyGrid, pts: np.ndarray, d: float, p) -> tuple[float, tuple]:
    """The pose off the lattices: the blurred grid read at the moved points (bilinear), over ±0.5° in 0.05°
    steps and ±1 cell in quarter cells about (d, p); the best mean."""
    from scipy.ndimage import map_coordinates

    res = merged.resolution
    steps = np.arange(-4, 5) * 0.25 * res
    shifts = np.stack(np.meshgrid(steps, steps, indexing="ij"), axis=-1).reshape(-1, 1, 2)
    best = (-1.0, d, p)
    for dd in np.arange(-10, 11) * 0.05:
        q = _rot(pts, d + dd) + np.asarray(p) + shifts  # (81, N, 2)
        col = (q[..., 0] - merged.origin[0]) / res - 0.5
        row = (q[..., 1] - merged.origin[1]) / res - 0.5
        v = map_coordinates(sharp, [row.ravel(), col.ravel()], order=1, mode="constant").reshape(col.shape).mean(axis=1)
        k = int(np.argmax(v))
        if v[k] > best[0]:
            best = (float(v[k]), wrap_yaw(d + dd), (p[0] + shifts[k, 0, 0], p[1] + shifts[k, 0, 1]))
    return best[1], best[2]


def _compose_inv(a, b):
    """T_a⁻¹ ∘ T_b for poses (yaw_deg, x, y): the pose of b's frame in a's."""
    ya, yb = math.radians(a[0]), math.radians(b[0])
    c, s = math.cos(ya), math.sin(ya)
    dx, dy = b[1] - a[1], b[2] - a[2]
    return (wrap_yaw(math.degrees(yb - ya)), c * dx + s * dy, -s * dx + c * dy)


def estimates_from_placements(t: float, placed: dict, where: str = "") -> list[Estimate]:
    """One estimate per placed robot from the maps' poses in a common frame."""
    return [Estimate(t, i, {j: _compose_inv(placed[i], placed[j]) for j in placed if j != i}, where)
            for i in placed if len(placed) >= 2]


def merged_estimates(truth: Truth, run: Path, merged_bag: Path, topic: str = "/map", every_s: float = 5.0,
                     match_min: float = MATCH_MIN, progress=None) -> list[Estimate]:
    """Estimates from the merged map topic of ``merged_bag``, judged on the robots' maps of the run's bag."""
    from merger.io.bagio import read_bag_map_series
    from merger.io.mapread import MapFileError

    try:
        robot_maps = read_bag_map_series(run, [truth.map_topics[n] for n in truth.robots])
        merged = read_bag_map_series(merged_bag, [topic])[topic]
    except MapFileError as e:
        raise ScoreError(str(e)) from None
    if not merged:
        raise ScoreError(f"{merged_bag}: topic {topic}: no message")
    out, last = [], -math.inf
    for t, m in merged:
        if t < last + every_s - 1e-9:
            continue
        last = t
        placed = {}
        for n in truth.robots:
            held = [g for s, g in robot_maps[truth.map_topics[n]] if s <= t + 1e-9]
            if held:
                found = locate(held[-1], m)
                if found is not None and found[0] >= match_min:
                    placed[n] = found[1]
        out += estimates_from_placements(t, placed, f"{merged_bag}: {topic} at {t:.3f} s")
        if progress:
            progress(t)
    return out
