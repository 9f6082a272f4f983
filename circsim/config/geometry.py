"""The scene must make sense: what the loader checks of a scenario's geometry, beyond types and ranges.

The contract: :func:`check_geometry` raises :class:`~circsim.config.validate.Invalid` (key path and
expectation, one line) when a rectangular room does not hold the center, the robots' circle with their
bodies, or a pillar or object, when something stands on a robot's start, or when it blocks a robot's
arc of the circle (the robots do not avoid obstacles). Such a scene would run and only report "no
merge". A room given as ``walls`` (which need not close) has no inside to check. Pure functions of the
typed sections (:mod:`circsim.config.types`); the loader (:mod:`circsim.config.scenario`) calls it once.
"""

from __future__ import annotations

import math

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
    """The scene must make sense: a rectangular room holds the center, the robots' circle with their
    bodies, every pillar and object; nothing stands on a robot's start. (Such a scene would run and report
    "no merge".)"""
    if world.room.size_m is not None:
        (rx, ry), (w, h) = world.room.center or (0.0, 0.0), world.room.size_m
        x0, y0, x1, y1 = rx - w / 2, ry - h / 2, rx + w / 2, ry + h / 2
        span = f"the room spans x [{x0:g}, {x1:g}], y [{y0:g}, {y1:g}]"
    else:  # walls need not close a room: no inside to check
        x0 = y0 = -math.inf
        x1 = y1 = math.inf
        span = ""

    def inside(c, r):
        return x0 + r < c[0] < x1 - r and y0 + r < c[1] < y1 - r

    cx, cy = world.center
    if not inside(world.center, 0.0):
        raise bad("world.center", f"a point inside the room ({span})", list(world.center))
    reach = robots.radius_m + robots.body_radius_m
    if not inside(world.center, reach):
        raise bad("robots.radius_m", f"a circle about world.center ({cx:g}, {cy:g}) that, with "
                  f"robots.body_radius_m {robots.body_radius_m:g}, stays inside the room ({span})",
                  robots.radius_m)
    starts = {n: (cx + robots.radius_m * math.cos(math.radians(a)), cy + robots.radius_m * math.sin(math.radians(a)))
              for n, a in zip(robots.names, robots.start_angles_deg, strict=True)}
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
