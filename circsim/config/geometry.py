"""The scene must make sense: what the loader checks of a scenario's geometry, beyond types and ranges.

The contract: :func:`check_geometry` raises :class:`~circsim.config.validate.Invalid` (key path and
expectation, one line) when a rectangular room does not hold the center, the robots' circle with their
bodies, or a pillar or object, when something stands on a robot's start, or when it blocks a robot's
arc of the circle (the robots do not avoid obstacles). Such a scene would run and only report "no
merge". A room given as ``walls`` gets the same checks: no wall may cross a robot's path (its arc, as
wide as its body) and, when the walls close around ``world.center`` (:func:`enclosure`), the robots'
starts and every pillar and object must lie in what they enclose; walls that do not close around the
center (an open scene) have no inside, and only the path is checked. A map world (``world.map``) gets
them against its free space (:mod:`circsim.config.mapworld`). Pure functions of the typed
sections (:mod:`circsim.config.types`); the loader (:mod:`circsim.config.scenario`) calls it once.
"""

from __future__ import annotations

import math

import numpy as np

from .types import Box, Chair, RobotsSpec, WorldSpec
from .validate import Invalid, bad


def object_reach(o) -> float:
    """Radius of a circle about the object's center that holds it."""
    if isinstance(o, Chair):
        return o.leg_spacing_m / math.sqrt(2) + o.leg_radius_m
    if isinstance(o, Box):
        return math.hypot(*o.size_m) / 2
    return math.hypot(o.seat_m, o.back_m) / 2  # an overturned chair: an L centred on its bounding box


def check_geometry(world: WorldSpec, robots: RobotsSpec) -> None:
    """The scene must make sense: the room (a rectangle, or the region ``walls`` enclose) holds the center,
    the robots' circle with their bodies, every pillar and object; nothing stands on a robot's start or
    path. (Such a scene would run and report "no merge".)"""
    cx, cy = world.center
    starts = {n: (cx + robots.radius_m * math.cos(math.radians(a)), cy + robots.radius_m * math.sin(math.radians(a)))
              for n, a in zip(robots.names, robots.start_angles_deg, strict=True)}
    if world.map_grid is not None:
        from .mapworld import check_map_world

        inside, span = check_map_world(world, robots, starts, path_points(world.center, robots))
    elif world.room.size_m is not None:
        (rx, ry), (w, h) = world.room.center or (0.0, 0.0), world.room.size_m
        x0, y0, x1, y1 = rx - w / 2, ry - h / 2, rx + w / 2, ry + h / 2
        span = f"the room spans x [{x0:g}, {x1:g}], y [{y0:g}, {y1:g}]"

        def inside(c, r):
            return x0 + r < c[0] < x1 - r and y0 + r < c[1] < y1 - r

        if not inside(world.center, 0.0):
            raise bad("world.center", f"a point inside the room ({span})", list(world.center))
        reach = robots.radius_m + robots.body_radius_m
        if not inside(world.center, reach):
            raise bad("robots.radius_m", f"a circle about world.center ({cx:g}, {cy:g}) that, with "
                      f"robots.body_radius_m {robots.body_radius_m:g}, stays inside the room ({span})",
                      robots.radius_m)
    else:
        inside, span = check_wall_room(world, robots, starts)
    things = [(f"world.pillars[{i}]", p.center, p.radius) for i, p in enumerate(world.pillars)]
    things += [(f"world.objects[{i}]", o.center, object_reach(o)) for i, o in enumerate(world.objects)]
    for path, c, r in things:
        if not inside(c, r):
            raise Invalid(path, f"expected inside the room ({span}), got center {list(c)} reaching {r:.2f} m")
        for n, s in starts.items():
            if math.dist(c, s) < r + robots.body_radius_m:
                raise Invalid(path, f"expected clear of robot {n}'s start ({s[0]:.2f}, {s[1]:.2f}) "
                                    f"(body radius {robots.body_radius_m:g} m), got center {list(c)}, "
                                    f"reaching {r:.2f} m")
        blocked = blocks_path(c, r, world.center, robots)
        if blocked:
            raise Invalid(path, f"expected clear of the robots' circle (radius {robots.radius_m:g} m about "
                                f"world.center, bodies {robots.body_radius_m:g} m): center {list(c)} reaching "
                                f"{r:.2f} m stands on {blocked}, and they do not avoid "
                                "obstacles; move it, or change robots.radius_m")


def blocks_path(c, r: float, center, robots: RobotsSpec) -> str | None:
    """The first robot whose path (its arc of the circle, as wide as its body) the disc (``c``, ``r``)
    reaches, or None. Online robots drive the whole circle; offline ones ±``offline.max_deg`` about their
    starts."""
    d = math.dist(c, center)
    if abs(d - robots.radius_m) >= r + robots.body_radius_m:
        return None
    if robots.motion == "online":
        return "the robots' path (online robots drive the whole circle)"
    a = math.degrees(math.atan2(c[1] - center[1], c[0] - center[0]))
    half = math.degrees((r + robots.body_radius_m) / robots.radius_m)  # the disc's angular reach (upper bound)
    for n, s in zip(robots.names, robots.start_angles_deg, strict=True):
        if abs((a - s + 180.0) % 360.0 - 180.0) <= robots.offline.max_deg + half:
            return f"robot {n}'s arc (±{robots.offline.max_deg:g}° about its start)"
    return None


def segment_distances(points: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """(n, m) distances from n points (x, y) to m segments (ax, ay, bx, by)."""
    a, b = walls[None, :, :2], walls[None, :, 2:]
    ab = b - a
    ap = points[:, None, :] - a
    den = np.maximum((ab * ab).sum(-1), 1e-300)
    u = np.clip((ap * ab).sum(-1) / den, 0.0, 1.0)
    return np.hypot(*np.moveaxis(ap - u[..., None] * ab, -1, 0))


def path_points(center, robots: RobotsSpec) -> list[tuple[str, np.ndarray]]:
    """Points along each robot's path (its whole circle online, ±``offline.max_deg`` about its start
    offline), at most a quarter of a body radius apart: a wall closer to the path than 7/8 of a body
    radius is closer than a body radius to one of them."""
    step = math.degrees(robots.body_radius_m / 4 / robots.radius_m)
    out = []
    for n, s in zip(robots.names, robots.start_angles_deg, strict=True):
        half = 180.0 if robots.motion == "online" else robots.offline.max_deg
        k = max(2, math.ceil(2 * half / step) + 1)
        a = np.radians(np.linspace(s - half, s + half, k))
        out.append((n, np.stack([center[0] + robots.radius_m * np.cos(a), center[1] + robots.radius_m * np.sin(a)], 1)))
    return out


def enclosure(walls: np.ndarray, center):
    """What the walls enclose about ``center``: a function ``(x, y) -> bool`` (is the point in the same
    enclosed region as the center), or None when the walls do not close around it (the region reaches
    past every wall). The walls are drawn on a raster of cells of at most 2 cm (at most 2,000 a side) and
    the region is the center's 4-connected component of the cells no wall crosses (OpenCV)."""
    import cv2

    xs = np.r_[walls[:, 0], walls[:, 2], center[0]]
    ys = np.r_[walls[:, 1], walls[:, 3], center[1]]
    h = max(0.02, float(max(np.ptp(xs), np.ptp(ys))) / 2000)
    x0, y0 = xs.min() - 3 * h, ys.min() - 3 * h
    shape = (int(math.ceil((ys.max() - y0) / h)) + 4, int(math.ceil((xs.max() - x0) / h)) + 4)
    img = np.full(shape, 255, np.uint8)

    def px(x, y):
        return int(math.floor((x - x0) / h)), int(math.floor((y - y0) / h))

    for ax, ay, bx, by in walls:
        cv2.line(img, px(ax, ay), px(bx, by), 0, 1, cv2.LINE_8)
    _, labels = cv2.connectedComponents(img, connectivity=4)
    c = px(*center)
    own = labels[c[1], c[0]]
    if own == 0 or own in labels[0] or own in labels[-1] or own in labels[:, 0] or own in labels[:, -1]:
        return None

    def inside(x, y) -> bool:
        col, row = px(x, y)
        return 0 <= row < shape[0] and 0 <= col < shape[1] and labels[row, col] == own
    return inside


def check_wall_room(world: WorldSpec, robots: RobotsSpec, starts: dict):
    """A room of ``walls``: no wall within a body radius of a robot's path; when the walls close around the
    center, every start in what they enclose. Returns ``(inside(c, r), span)`` for the pillars and
    objects: in the enclosure and clear of every wall (always true for an open scene)."""
    walls = np.asarray(world.room.walls, np.float64).reshape(-1, 4)
    for n, pts in path_points(world.center, robots):
        d = segment_distances(pts, walls)
        near = np.argwhere(d < robots.body_radius_m)
        if near.size:
            k, i = near[0]
            raise Invalid(f"world.room.walls[{i}]", f"expected clear of robot {n}'s path (radius "
                          f"{robots.radius_m:g} m about world.center, body {robots.body_radius_m:g} m): wall "
                          f"{list(map(float, walls[i]))} passes {d[k, i]:.2f} m from "
                          f"({pts[k, 0]:.2f}, {pts[k, 1]:.2f}), and the robots do not avoid obstacles; move "
                          "it, or change robots.radius_m or world.center")
    region = enclosure(walls, world.center)
    if region is None:
        return (lambda c, r: True), ""
    span = "the region the walls enclose about world.center"
    for n, s in starts.items():
        if not region(*s):
            raise bad("robots.radius_m", f"a circle about world.center that stays inside the room the walls "
                      f"enclose (robot {n} would start at ({s[0]:.2f}, {s[1]:.2f}), outside it)", robots.radius_m)

    def inside(c, r):
        return region(*c) and float(segment_distances(np.asarray([c], np.float64), walls).min()) > r
    return inside, span
