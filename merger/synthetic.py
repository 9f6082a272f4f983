"""Synthetic scenes and partial views for tests, benchmarks and demos (no simulator needed).

A :class:`Scene` is plain 2-D geometry in a world frame (segments and circles). :func:`partial_view`
rasterizes it into the frame of a map whose origin is a robot's start pose and casts rays through that
raster from a few viewpoints, so the view has free space up to the first obstacle, occupied cells where
rays hit, and unknown behind — the shape of a real local map. circsim produces maps the full way
(pymunk world, laser, SLAM); this module stays inside merger so that merger is testable on its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from .grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid


@dataclass(frozen=True, eq=False)
class Scene:
    """Segments (K, 2, 2) and circles (M, 3: x, y, r) in the world frame, and the common center."""

    segments: np.ndarray
    circles: np.ndarray
    center: tuple[float, float] = (0.0, 0.0)
    meta: dict = field(default_factory=dict)


def rectangle_segments(cx, cy, w, h, yaw_deg=0.0) -> np.ndarray:
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    pts = np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])
    pts = pts @ np.array([[c, -s], [s, c]]).T + [cx, cy]
    return np.stack([pts, np.roll(pts, -1, axis=0)], axis=1)


def room_scene(rng: np.random.Generator | None = None, *, room=(8.0, 6.0), room_center=(0.7, 0.4),
               n_boxes: int = 4, pillar_offset=(1.4, 0.9), pillar_radius=0.15) -> Scene:
    """A room with two pillars point-symmetric about the center (0, 0) and ``n_boxes`` random boxes.

    The boxes break the pillars' symmetry (as the chairs and boxes of the thesis's scenes do). The
    room is off-center by ``room_center``, so its walls disagree under a 180° rotation; with
    ``n_boxes=0`` and ``room_center=(0, 0)`` the scene is point-symmetric.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    w, h = room
    segs = [rectangle_segments(room_center[0], room_center[1], w, h)]
    px, py = pillar_offset
    circles = [[px, py, pillar_radius], [-px, -py, pillar_radius]]
    placed = 0
    while placed < n_boxes:
        r = rng.uniform(0.6, 2.6)
        a = rng.uniform(0, 2 * math.pi)
        cx, cy = r * math.cos(a), r * math.sin(a)
        if min(math.hypot(cx - x, cy - y) for x, y, _ in circles) < 0.7:
            continue
        segs.append(rectangle_segments(cx, cy, rng.uniform(0.3, 0.7), rng.uniform(0.3, 0.7),
                                       rng.uniform(0, 90)))
        circles.append([cx, cy, 0.0])  # keep boxes apart; radius 0 circles are not drawn
        placed += 1
    circles = np.array([c for c in circles if c[2] > 0], np.float64)
    return Scene(np.concatenate(segs), circles, (0.0, 0.0), {"room": room})


def world_to_frame(xy, pose) -> np.ndarray:
    """World points into the frame of ``pose`` = (x, y, yaw_rad)."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    d = np.asarray(xy, np.float64) - [x, y]
    return d @ np.array([[c, s], [-s, c]]).T


def rasterize(scene: Scene, frame_pose, shape, resolution, origin) -> np.ndarray:
    """Boolean (H, W) image of the scene's surfaces drawn in the frame of ``frame_pose`` (for display)."""
    img = np.zeros(shape, np.uint8)
    scale = (1 << 4) / resolution  # cv2 draws with 4 fractional bits (shift=4); pixel centre = cell centre
    org = np.asarray(origin)

    def px(p):
        q = ((world_to_frame(p, frame_pose) - org) / resolution - 0.5) * (1 << 4)
        return tuple(int(round(v)) for v in q)

    for a, b in scene.segments:
        cv2.line(img, px(a), px(b), 1, 1, cv2.LINE_8, 4)
    for x, y, r in scene.circles:
        cv2.circle(img, px([x, y]), int(round(r * scale)), 1, 1, cv2.LINE_8, 4)
    return img.astype(bool)


def ray_cast(scene: Scene, origin_xy, angles: np.ndarray, range_max: float) -> np.ndarray:
    """Exact ranges of rays from ``origin_xy`` to the first segment or circle (inf for no hit)."""
    o = np.asarray(origin_xy, np.float64)
    d = np.stack([np.cos(angles), np.sin(angles)], axis=1)  # (B, 2)
    best = np.full(angles.size, np.inf)
    if len(scene.segments):
        a, b = scene.segments[:, 0], scene.segments[:, 1]  # (K, 2)
        e = b - a
        denom = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (B, K)
        ao = a[None] - o
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (ao[..., 0] * e[None, :, 1] - ao[..., 1] * e[None, :, 0]) / denom
            u = (ao[..., 0] * d[:, None, 1] - ao[..., 1] * d[:, None, 0]) / denom
        ok = (np.abs(denom) > 1e-12) & (t >= 0) & (u >= 0) & (u <= 1)
        best = np.minimum(best, np.where(ok, t, np.inf).min(axis=1))
    if len(scene.circles):
        c, r = scene.circles[:, :2], scene.circles[:, 2]
        oc = o - c  # (M, 2)
        bq = d @ oc.T  # (B, M)
        cq = (oc ** 2).sum(axis=1) - r ** 2
        disc = bq ** 2 - cq[None]
        with np.errstate(invalid="ignore"):
            t = -bq - np.sqrt(disc)
        ok = (disc >= 0) & (t >= 0)
        best = np.minimum(best, np.where(ok, t, np.inf).min(axis=1))
    best[best > range_max] = np.inf
    return best


def trace(states: np.ndarray, origin_cells: np.ndarray, angles: np.ndarray, ranges: np.ndarray,
          range_max_cells: float, hits: np.ndarray | None = None) -> None:
    """Mark free cells along each ray and the occupied cell at each hit (in place).

    ``ranges`` (cells) ends each ray (+inf: at ``range_max_cells``); a finite range is a hit unless
    ``hits`` (bool per ray) says otherwise — then the ray only clears up to it (e.g. it ran into the
    unknown part of a real map)."""
    h, w = states.shape
    finite = np.isfinite(ranges)
    length = np.where(finite, ranges, range_max_cells)
    steps = np.arange(0.0, range_max_cells, 0.5)
    dirs = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    pts = origin_cells + dirs[:, None, :] * steps[None, :, None]
    col, row = np.floor(pts[..., 0]).astype(np.int64), np.floor(pts[..., 1]).astype(np.int64)
    seen = (steps[None, :] < length[:, None] - 0.5) & (col >= 0) & (col < w) & (row >= 0) & (row < h)
    cells = row[seen] * w + col[seen]
    flat = states.ravel()
    flat[cells[flat[cells] != OCCUPIED_S]] = FREE_S
    if hits is not None:
        finite = finite & hits
    hit = origin_cells + dirs[finite] * ranges[finite, None]
    hc, hr = np.floor(hit[:, 0]).astype(np.int64), np.floor(hit[:, 1]).astype(np.int64)
    ok = (hc >= 0) & (hc < w) & (hr >= 0) & (hr < h)
    flat[hr[ok] * w + hc[ok]] = OCCUPIED_S


def _traced_views(cast, frame_pose, viewpoints_world, resolution: float, size_m: float, range_m: float,
                  beams: int) -> OccupancyGrid:
    """360° scans of ``beams`` rays from every viewpoint, ``cast(vp, angles) -> (ranges m, hits or
    None)`` in the world, traced into a square grid of side ``size_m`` centred on the frame's origin."""
    n = int(round(size_m / resolution))
    origin = np.array([-n * resolution / 2.0, -n * resolution / 2.0])
    states = np.zeros((n, n), np.uint8)
    angles = np.linspace(0, 2 * np.pi, beams, endpoint=False)
    for vp in np.atleast_2d(viewpoints_world):
        ranges, hits = cast(vp, angles)
        vp_cells = (world_to_frame(vp, frame_pose) - origin) / resolution
        trace(states, vp_cells, angles - frame_pose[2], ranges / resolution, range_m / resolution, hits)
    return OccupancyGrid(states, resolution, tuple(origin.tolist()))


def partial_view(scene: Scene, frame_pose, viewpoints_world, *, resolution: float = 0.05,
                 size_m: float = 12.0, range_m: float = 5.6, beams: int = 720,
                 noise: float = 0.0, rng: np.random.Generator | None = None) -> tuple[OccupancyGrid, tuple]:
    """A local map of ``scene`` in the frame of ``frame_pose`` seen from ``viewpoints_world``.

    Rays are cast exactly against the geometry (360° scans of ``beams`` rays from every viewpoint) and
    traced into a grid in the map frame: free along the ray, occupied at the hit. Returns the grid
    (square ``size_m`` centred on the frame's origin) and the scene's center in that frame.
    ``noise`` flips that fraction of the known cells to the other known state.
    """
    grid = _traced_views(lambda vp, angles: (ray_cast(scene, vp, angles, range_m), None), frame_pose,
                         viewpoints_world, resolution, size_m, range_m, beams)
    states = grid.states
    if noise > 0:
        rng = np.random.default_rng(0) if rng is None else rng
        known = np.flatnonzero(states.ravel() != UNKNOWN_S)
        flip = rng.choice(known, size=int(noise * known.size), replace=False)
        flat = states.ravel()
        flat[flip] = np.where(flat[flip] == FREE_S, OCCUPIED_S, FREE_S)
    center = tuple(world_to_frame(scene.center, frame_pose).tolist())
    return grid, center


def grid_ray_cast(grid: OccupancyGrid, origin_xy, angles: np.ndarray, range_m: float,
                  step_cells: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """Rays marched through an occupancy grid (e.g. a real saved map), in the grid's frame.

    Returns ``(ranges, hits)``: the distance (m) to the first occupied cell (``hits`` True), or to the
    first unknown cell or the map's edge (``hits`` False: the map does not say what is there), or +inf
    when the ray stays in free space for ``range_m``. Sampled every ``step_cells`` of a cell."""
    res = grid.resolution
    steps = np.arange(0.0, range_m, step_cells * res)
    dirs = np.stack([np.cos(angles), np.sin(angles)], axis=1)
    pts = np.asarray(origin_xy, float)[None, None, :] + dirs[:, None, :] * steps[None, :, None]
    col = np.floor((pts[..., 0] - grid.origin[0]) / res).astype(np.int64)
    row = np.floor((pts[..., 1] - grid.origin[1]) / res).astype(np.int64)
    h, w = grid.shape
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    state = np.full(col.shape, UNKNOWN_S, np.uint8)
    state[inside] = grid.states[row[inside], col[inside]]
    stop = state != FREE_S
    any_stop = stop.any(axis=1)
    first = np.argmax(stop, axis=1)
    ranges = np.where(any_stop, steps[first], np.inf)
    hits = any_stop & (state[np.arange(len(angles)), first] == OCCUPIED_S)
    return ranges, hits


def partial_view_of_grid(world: OccupancyGrid, frame_pose, viewpoints_world, *, size_m: float = 12.0,
                         range_m: float = 5.6, beams: int = 720) -> OccupancyGrid:
    """A local map of a saved map ``world`` (its own frame = the world) in the frame of ``frame_pose``,
    seen from ``viewpoints_world``: rays are marched through ``world`` (:func:`grid_ray_cast`) and traced
    into a new grid of the same resolution, square ``size_m`` centred on the frame's origin. Real
    surfaces (thick, noisy walls, clutter) re-rasterized in another frame: an independent resampling."""
    return _traced_views(lambda vp, angles: grid_ray_cast(world, vp, angles, range_m), frame_pose,
                         viewpoints_world, world.resolution, size_m, range_m, beams)


def widest_free_point(grid: OccupancyGrid) -> tuple[tuple[float, float], float]:
    """The free cell farthest from every non-free cell of ``grid``: its center (x, y) and that clearance
    (m). A circle of smaller radius about it lies in free space: a place for robots around a center."""
    free = (grid.states == FREE_S).astype(np.uint8)
    if not free.any():
        raise ValueError("the map has no free cell")
    dist = cv2.distanceTransform(np.pad(free, 1), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
    r, c = np.unravel_index(int(dist.argmax()), dist.shape)
    x = grid.origin[0] + (c + 0.5) * grid.resolution
    y = grid.origin[1] + (r + 0.5) * grid.resolution
    return (float(x), float(y)), float(dist[r, c]) * grid.resolution


def robot_pose_on_circle(angle_deg: float, radius: float, center=(0.0, 0.0), yaw_offset_deg: float = 0.0):
    """Pose (x, y, yaw_rad) on a circle, facing the center (plus an offset)."""
    a = math.radians(angle_deg)
    x, y = center[0] + radius * math.cos(a), center[1] + radius * math.sin(a)
    return (x, y, a + math.pi + math.radians(yaw_offset_deg))


def arc_viewpoints(angle_deg: float, half_arc_deg: float, radius: float, center=(0.0, 0.0), k: int = 5):
    """Viewpoints on the circle spread over angle ± half_arc (the offline displacement experiment)."""
    a = np.radians(np.linspace(angle_deg - half_arc_deg, angle_deg + half_arc_deg, k))
    return np.stack([center[0] + radius * np.cos(a), center[1] + radius * np.sin(a)], axis=1)


def random_view_pair(seed: int, scale: float = 1.0):
    """Two partial views of one generated room, seen from frames rotated by a random θ about nearly the
    same center, with varying overlap (viewpoint arcs 5–60°, up to 60° apart): the problems on which the
    fast search is compared with the reference (tests, ``benchmarks/agree_fast.py``).

    ``scale`` grows the room (8 × 6 m at 1), the robots' circle, the laser's range and the ROI (3.2–8 m
    at 1) together, for ROIs the fast search pools (≥ 192 cells).
    Returns ``(ref_grid, ref_center, moving_grid, moving_center, roi_m)``.
    """
    s = float(scale)
    rng = np.random.default_rng(seed)
    scene = room_scene(rng, room=(8.0 * s, 6.0 * s), room_center=(0.7 * s, 0.4 * s), n_boxes=int(rng.integers(0, 6)),
                       pillar_offset=(1.4 * s, 0.9 * s), pillar_radius=0.15 * max(s, 1.0))
    theta, a0, yaw = rng.uniform(0, 360), rng.uniform(0, 360), rng.uniform(0, 2 * math.pi)
    fa = (rng.uniform(-1, 1) * s, rng.uniform(-1, 1) * s, yaw)
    fb = (rng.uniform(-1, 1) * s, rng.uniform(-1, 1) * s, yaw + math.radians(theta))
    view = {"size_m": 12.0 * s, "range_m": 5.6 * s, "beams": int(720 * max(1.0, s)), "noise": 0.002, "rng": rng}
    ga, ca = partial_view(scene, fa, arc_viewpoints(a0, rng.uniform(5, 60), 1.8 * s, k=3), **view)
    gb, cb = partial_view(scene, fb, arc_viewpoints(a0 + rng.uniform(-60, 60), rng.uniform(5, 60), 1.8 * s, k=3),
                          **view)
    return ga, ca, gb, cb, float(rng.uniform(3.2, 8.0)) * s


WINDOW_KINDS = ("views", "noise", "identical", "symmetric", "sparse")


@dataclass(frozen=True, eq=False)
class WindowCase:
    """A generated alignment problem with a rough center and its ground truth.

    ``ref``/``moving`` with the centers as given (``center_moving`` is off by ``error_m`` in the moving
    frame, the reference's is exact); the truth: x_ref = c_ref + t* + R(θ*)(x_moving − c_moving) with
    θ* = ``theta_deg`` and t* = ``translation_m`` = R(θ*)·error_m (None for the noise grids, which have
    no truth). ``roi_m``/``window_m``: the search's parameters."""

    kind: str
    seed: int
    ref: OccupancyGrid
    center_ref: tuple[float, float]
    moving: OccupancyGrid
    center_moving: tuple[float, float]
    roi_m: float
    window_m: float
    theta_deg: float | None
    translation_m: tuple[float, float] | None
    error_m: tuple[float, float]


def near_empty_grid(rng: np.random.Generator) -> OccupancyGrid:
    """A small, nearly empty ternary grid (10–89 cells a side, 5 cm, centred on the origin): mostly unknown,
    some free cells with probability 0.8, and 0–6 occupied cells — the adversarial "near_empty" problems'
    maps (``benchmarks/agree_fast.py``, ``benchmarks/agree_window.py``)."""
    side = int(rng.integers(10, 90))
    st = np.zeros((side, side), np.uint8)
    if rng.random() < 0.8:
        st[rng.random(st.shape) < rng.uniform(0, 0.6)] = FREE_S
    for _ in range(int(rng.integers(0, 7))):
        st[rng.integers(0, side), rng.integers(0, side)] = OCCUPIED_S
    return OccupancyGrid(st, 0.05, (-side * 0.025, -side * 0.025))


def window_case(seed: int, kind: str = "views", *, roi_m: tuple[float, float] = (3.2, 4.8),
                window_m: tuple[float, float] = (0.15, 0.4), error_frac: float = 0.8,
                size_m: float = 12.0) -> WindowCase:
    """A generated problem for the rotation × translation search (tests, ``benchmarks/agree_window.py``).

    kinds: ``views`` — two partial views of a generated room (random θ, overlap); ``symmetric`` — a
    point-symmetric room (two pillars, no boxes) seen over a short arc (the thesis's 180° ambiguity);
    ``sparse`` — pillars and a few boxes, no walls in range (the chair-legs case); ``identical`` — a
    view aligned with itself (plateaus; θ* = 0); ``noise`` — random ternary grids (no truth). The
    moving center is off by a random error of at most ``error_frac`` × window on each axis.
    """
    if kind not in WINDOW_KINDS:
        raise ValueError(f"kind must be one of {WINDOW_KINDS}, got {kind!r}")
    rng = np.random.default_rng([seed, WINDOW_KINDS.index(kind)])
    roi = float(rng.uniform(*roi_m))
    win = float(rng.uniform(*window_m))
    err = tuple(float(v) for v in rng.uniform(-error_frac * win, error_frac * win, 2))
    if kind == "noise":
        n = int(round(roi / 0.05)) + 24
        p = rng.dirichlet([1, 1, 1]) if rng.random() < 0.5 else np.array([0.5, 0.4, 0.1])
        a = rng.choice(3, size=(n, n), p=p).astype(np.uint8)
        b = rng.choice(3, size=(n, n), p=p).astype(np.uint8)
        org = (-n * 0.025, -n * 0.025)
        c = (float(rng.uniform(-0.1, 0.1)), float(rng.uniform(-0.1, 0.1)))
        return WindowCase(kind, seed, OccupancyGrid(a, 0.05, org), c, OccupancyGrid(b, 0.05, org),
                          (c[0] + err[0], c[1] + err[1]), roi, win, None, None, err)
    if kind == "symmetric":
        scene = room_scene(rng, room_center=(0.0, 0.0), n_boxes=0)
        arcs = (float(rng.uniform(3, 12)), float(rng.uniform(3, 12)))
    elif kind == "sparse":
        scene = room_scene(rng, room=(30.0, 30.0), room_center=(0.0, 0.0), n_boxes=int(rng.integers(2, 5)))
        arcs = (float(rng.uniform(20, 60)), float(rng.uniform(20, 60)))
    else:
        scene = room_scene(rng, n_boxes=int(rng.integers(0, 6)))
        arcs = (float(rng.uniform(5, 60)), float(rng.uniform(5, 60)))
    theta = 0.0 if kind == "identical" else float(rng.uniform(0, 360))
    yaw = float(rng.uniform(0, 2 * math.pi))
    fa = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), yaw)
    fb = (float(rng.uniform(-1, 1)), float(rng.uniform(-1, 1)), yaw + math.radians(theta))
    a0 = float(rng.uniform(0, 360))
    view = {"size_m": size_m, "range_m": 5.6, "beams": 720, "noise": 0.002, "rng": rng}
    ga, ca = partial_view(scene, fa, arc_viewpoints(a0, arcs[0], 1.8, k=3), **view)
    if kind == "identical":
        gb, cb = ga, ca
    else:
        gb, cb = partial_view(scene, fb, arc_viewpoints(a0 + float(rng.uniform(-40, 40)), arcs[1], 1.8, k=3),
                              **view)
    r = math.radians(theta)
    t = (math.cos(r) * err[0] - math.sin(r) * err[1], math.sin(r) * err[0] + math.cos(r) * err[1])
    return WindowCase(kind, seed, ga, tuple(ca), gb, (cb[0] + err[0], cb[1] + err[1]), roi, win, theta, t, err)
