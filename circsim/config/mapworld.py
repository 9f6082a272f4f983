"""A map world: its file read (``world.map``) and the scene checked against its free space.

The contract: :func:`load_world_map` reads ``world.map`` with merger's own map loader — a ROS map_server
YAML (``mode``, thresholds, ``negate`` and ``origin`` as :func:`merger.io.mapio.load_map` reads them), or an
image of ``world.map_resolution_m`` cells read with map_server's defaults, its lower-left corner at (0, 0)
(:func:`merger.io.mapio.load_image_map`) — into a :class:`~circsim.config.types.MapGrid`. Its occupied
and unknown cells are solid (unknown is outside the building). A missing or malformed file raises
:class:`~circsim.config.validate.Invalid` at ``world.map`` with the map loader's one line (file and key).

:func:`check_map_world` holds a map world to the checks a room gets (:mod:`circsim.config.geometry`):
``world.center`` in a free cell; every robot's start and every point of its path (the whole circle
online, its arc offline) at least a body radius from every solid cell; pillars and objects wholly in free
space. Distances are exact to the cells' squares (:func:`clearance`). A refusal names the first blocking
point in map coordinates, what is there, and the largest circle about ``world.center`` that is clear
(:func:`largest_clear_radius`, found on OpenCV's distance transform of the map, a lower bound by √2
cells: the radius it names passes the exact check).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from .types import MapGrid, RobotsSpec, WorldSpec
from .validate import Invalid, bad

YAML_SUFFIXES = (".yaml", ".yml")


def load_world_map(world: WorldSpec) -> WorldSpec:
    """``world`` with its map's cells read from ``world.map`` (a relative path is the current folder's:
    the scenario loader makes a file's paths absolute first)."""
    from merger.io.mapio import load_image_map, load_map
    from merger.io.mapread import MapFileError

    path = Path(world.map)
    is_yaml = path.suffix.lower() in YAML_SUFFIXES
    if is_yaml and world.map_resolution_m is not None:
        raise Invalid("world.map_resolution_m", "expected only with an image world.map (a map_server YAML "
                      f"states its own resolution: {path.name})")
    if not is_yaml and world.map_resolution_m is None:
        raise Invalid("world.map_resolution_m", f"expected the cell size in metres of the image world.map "
                      f"({path.name}), or a map_server YAML (.yaml) as world.map")
    try:
        grid = load_map(path) if is_yaml else load_image_map(path, world.map_resolution_m)
    except MapFileError as e:
        raise Invalid("world.map", str(e)) from None
    return replace(world, map_grid=MapGrid(grid.states, grid.resolution, tuple(grid.origin)))


def clearance(g: MapGrid, points, cap: float) -> np.ndarray:
    """Distance (m) from each point (n, 2) to the nearest solid cell (its square; beyond the map's edge is
    solid), capped at ``cap``; 0 inside a solid cell. Exact: every cell within ``cap`` is looked at."""
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    res, (ox, oy) = g.resolution, g.origin
    k = int(math.ceil(cap / res)) + 1
    col = np.floor((pts[:, 0] - ox) / res).astype(np.int64)
    row = np.floor((pts[:, 1] - oy) / res).astype(np.int64)
    off = np.arange(-k, k + 1)
    cc = col[:, None] + np.tile(off, len(off))[None, :]
    rr = row[:, None] + np.repeat(off, len(off))[None, :]
    h, w = g.states.shape
    inside = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
    solid = np.ones(cc.shape, bool)
    solid[inside] = g.states[rr[inside], cc[inside]] != g.FREE
    x0, y0 = ox + cc * res, oy + rr * res
    dx = np.maximum(np.maximum(x0 - pts[:, :1], pts[:, :1] - (x0 + res)), 0.0)
    dy = np.maximum(np.maximum(y0 - pts[:, 1:], pts[:, 1:] - (y0 + res)), 0.0)
    d = np.where(solid, np.hypot(dx, dy), np.inf)
    return np.minimum(d.min(axis=1), cap)


def _distance_transform(g: MapGrid) -> np.ndarray:
    """A lower bound (m) of each cell's clearance, wherever in the cell a point lies: OpenCV's distance
    (centre to centre) to the nearest solid cell, less √2 cells (half a diagonal at either end)."""
    import cv2

    free = np.pad((g.states == g.FREE).astype(np.uint8), 1)  # beyond the edge: solid
    dt = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
    return np.maximum(dt - math.sqrt(2.0), 0.0) * g.resolution


def largest_clear_radius(g: MapGrid, center, body_radius_m: float) -> float | None:
    """The largest radius of a circle about ``center`` whose every point is at least ``body_radius_m`` from
    every solid cell (on the distance transform's lower bound, in steps of half a cell), or None."""
    dt = _distance_transform(g)
    res, (ox, oy) = g.resolution, g.origin
    h, w = dt.shape
    far = max(math.dist(center, (x, y)) for x in (ox, ox + w * res) for y in (oy, oy + h * res))
    best = None
    for r in np.arange(body_radius_m * 1.01, far, res / 2):
        n = max(8, int(math.ceil(2 * math.pi * r / (body_radius_m / 4))))
        a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
        col = np.floor((center[0] + r * np.cos(a) - ox) / res).astype(np.int64)
        row = np.floor((center[1] + r * np.sin(a) - oy) / res).astype(np.int64)
        if ((col >= 0) & (col < w) & (row >= 0) & (row < h)).all() and dt[row, col].min() >= body_radius_m:
            best = float(r)
    return best


def _what(g: MapGrid, xy) -> str:
    """What the map has at ``xy``: 'unknown space', 'an occupied cell', 'free space' or 'beyond the map'."""
    col = int(math.floor((xy[0] - g.origin[0]) / g.resolution))
    row = int(math.floor((xy[1] - g.origin[1]) / g.resolution))
    if not (0 <= row < g.states.shape[0] and 0 <= col < g.states.shape[1]):
        return "beyond the map"
    return {0: "unknown space", 1: "free space", 2: "an occupied cell"}.get(int(g.states[row, col]), "?")


def map_label(world: WorldSpec) -> str:
    """How refusals name a map world's map: its file's name, or the generated plan (world.generate)."""
    if world.generate is not None:
        return f"generated by world.generate (seed {world.generate.seed})"
    return Path(world.map).name


def check_map_world(world: WorldSpec, robots: RobotsSpec, starts: dict, path_points):
    """The scene in the map's free space (module docstring); returns ``(inside(c, r), span)`` for the
    pillars and objects, as :func:`circsim.config.geometry.check_wall_room` does."""
    g, body = world.map_grid, robots.body_radius_m
    name = map_label(world)
    if clearance(g, [world.center], g.resolution)[0] <= 0.0:
        raise bad("world.center", f"a point in the free space of the map {name} "
                  f"(({world.center[0]:g}, {world.center[1]:g}) is in {_what(g, world.center)})", list(world.center))

    def refuse(robot: str, where: str, xy, d: float):
        r = largest_clear_radius(g, world.center, body)
        fits = (f"the largest clear circle about world.center has radius {r:.2f} m" if r is not None else
                "no circle about world.center is clear")
        raise Invalid("robots.radius_m", f"expected a circle about world.center ({world.center[0]:g}, "
                      f"{world.center[1]:g}) in the free space of the map {name}, with the robots' clearance "
                      f"(body radius {body:g} m): robot {robot}'s {where} is blocked at ({xy[0]:.2f}, {xy[1]:.2f}) "
                      f"in map coordinates ({_what(g, xy)}, {d:.2f} m from the nearest occupied or unknown "
                      f"cell); {fits}, got {robots.radius_m:g}")

    for n, s in starts.items():
        d = clearance(g, [s], body)[0]
        if d < body:
            refuse(n, "start", s, d)
    for n, pts in path_points:
        d = clearance(g, pts, body)
        bad_at = np.flatnonzero(d < body)
        if bad_at.size:
            k = int(bad_at[0])
            refuse(n, "path", pts[k], d[k])

    def inside(c, r):
        return bool(clearance(g, [c], r)[0] >= r)
    return inside, f"the free space of the map {name}"
