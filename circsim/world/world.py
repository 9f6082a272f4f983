"""The pymunk world: walls, pillars, scene objects and the robots' bodies.

Static obstacles are zero-thickness segments (walls, a map world's cell edges (:mod:`circsim.world.mapgeometry`),
the overturned chair's seat and back), circles
(pillars, chair legs) and polygons (boxes) on the space's static body. Each robot is a KINEMATIC body
with one circle shape in its own ``ShapeFilter`` group, so its laser can exclude it. The space is the
source of truth for the geometry: :meth:`World.geometry` reads the shapes back as numpy arrays for the
vectorized ray caster and for rasterizing ground truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pymunk

from .mapgeometry import boundary_segments
from .motion import Pose, trajectories

if TYPE_CHECKING:  # pragma: no cover
    from ..config.scenario import Scenario
    from ..config.types import Box, Chair, OverturnedChair


@dataclass(frozen=True, eq=False)
class Geometry:
    """Obstacles as plain arrays, world frame, metres.

    segments : (S, 4) ``ax, ay, bx, by`` (polygon edges included).
    circles : (C, 3) ``cx, cy, r``.
    """

    segments: np.ndarray
    circles: np.ndarray


class World:
    """A pymunk space holding the static scene and one kinematic body per robot.

    Build it with :meth:`from_scenario`, or by hand with the ``add_*`` methods (tests do).
    """

    def __init__(self) -> None:
        self.space = pymunk.Space()
        self._robots: dict[str, tuple[pymunk.Body, pymunk.Circle, int]] = {}
        self._static_cache: Geometry | None = None

    # --- construction ---------------------------------------------------------------------------
    def add_wall(self, a, b) -> None:
        """A zero-thickness segment from ``a`` to ``b``."""
        self._add_static(pymunk.Segment(self.space.static_body, _xy(a), _xy(b), 0.0))

    def add_walls(self, segments) -> None:
        """Many zero-thickness segments at once, (S, 4) ``ax, ay, bx, by`` (a map world's walls)."""
        body = self.space.static_body
        shapes = [pymunk.Segment(body, (ax, ay), (bx, by), 0.0)
                  for ax, ay, bx, by in np.asarray(segments, np.float64).reshape(-1, 4).tolist()]
        if shapes:
            self.space.add(*shapes)
            self._static_cache = None

    def add_circle(self, center, radius: float) -> None:
        self._add_static(pymunk.Circle(self.space.static_body, float(radius), _xy(center)))

    def add_polygon(self, vertices) -> None:
        """A convex polygon (pymunk takes the convex hull of the vertices)."""
        self._add_static(pymunk.Poly(self.space.static_body, [_xy(v) for v in vertices], None, 0.0))

    def add_robot(self, name: str, body_radius_m: float, pose=(0.0, 0.0, 0.0)) -> None:
        """A kinematic body with a circle of ``body_radius_m``, in its own shape-filter group."""
        if name in self._robots:
            raise ValueError(f"robot {name!r} already exists")
        body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        shape = pymunk.Circle(body, float(body_radius_m))
        group = len(self._robots) + 1
        shape.filter = pymunk.ShapeFilter(group=group)
        self.space.add(body, shape)
        self._robots[name] = (body, shape, group)
        self.set_robot_pose(name, *pose)

    def _add_static(self, shape: pymunk.Shape) -> None:
        self.space.add(shape)
        self._static_cache = None

    @classmethod
    def from_scenario(cls, sc: Scenario) -> World:
        """The scenario's room, pillars, objects and robots at their start poses."""
        w = cls()
        for a, b in _pairs(sc.world.room.wall_segments()):
            w.add_wall(a, b)
        if sc.world.map_grid is not None:  # a map world: the edges between its free and solid cells
            g = sc.world.map_grid
            w.add_walls(boundary_segments(g.solid, g.resolution, g.origin))
        for p in sc.world.pillars:
            w.add_circle(p.center, p.radius)
        for obj in sc.world.objects:
            _ADDERS[obj.type](w, obj)
        for name, traj in trajectories(sc).items():
            w.add_robot(name, sc.robots.body_radius_m, traj.start_pose())
        return w

    # --- robots ----------------------------------------------------------------------------------
    @property
    def robot_names(self) -> list[str]:
        return list(self._robots)

    def set_robot_pose(self, name: str, x: float, y: float, yaw: float) -> None:
        """Move a robot's body; its shapes are reindexed so queries see the new pose at once."""
        body = self._robots[name][0]
        body.position = (float(x), float(y))
        body.angle = float(yaw)
        self.space.reindex_shapes_for_body(body)

    def robot_pose(self, name: str) -> Pose:
        body = self._robots[name][0]
        return Pose(float(body.position.x), float(body.position.y), float(body.angle))

    def shape_filter(self, name: str) -> pymunk.ShapeFilter:
        """The query filter of ``name``'s laser: excludes its own body, sees everything else."""
        return pymunk.ShapeFilter(group=self._robots[name][2])

    # --- geometry --------------------------------------------------------------------------------
    def clearance(self, xy, max_distance: float = 10.0) -> float:
        """Signed distance from a point to the nearest static obstacle (negative inside one).

        Capped at ``max_distance``; robots are ignored. Useful to check placements.
        """
        hits = self.space.point_query(_xy(xy), float(max_distance), pymunk.ShapeFilter())
        return min((h.distance for h in hits if h.shape.body is self.space.static_body), default=max_distance)

    def geometry(self, *, include_robots: bool = False, exclude: str | None = None) -> Geometry:
        """All obstacles as arrays, read from the pymunk shapes.

        Parameters
        ----------
        include_robots : add the robots' body circles (at their current poses).
        exclude : a robot whose body is left out (the observer).
        """
        if self._static_cache is None:
            self._static_cache = self._read_static()
        if not include_robots:
            return self._static_cache
        rob = [(*body.local_to_world(shape.offset), shape.radius)
               for name, (body, shape, _) in self._robots.items() if name != exclude]
        if not rob:
            return self._static_cache
        circles = np.vstack([self._static_cache.circles, np.array(rob, np.float64)])
        return Geometry(self._static_cache.segments, circles)

    def _read_static(self) -> Geometry:
        segs: list[tuple[float, float, float, float]] = []
        circ: list[tuple[float, float, float]] = []
        for s in self.space.static_body.shapes:
            body = s.body
            if isinstance(s, pymunk.Segment):
                segs.append((*body.local_to_world(s.a), *body.local_to_world(s.b)))
            elif isinstance(s, pymunk.Circle):
                circ.append((*body.local_to_world(s.offset), s.radius))
            elif isinstance(s, pymunk.Poly):
                v = [body.local_to_world(p) for p in s.get_vertices()]
                segs.extend((*v[i], *v[(i + 1) % len(v)]) for i in range(len(v)))
        # shapes is a set: sort so the arrays (and everything downstream) are deterministic
        seg_arr = np.array(sorted(segs), np.float64).reshape(-1, 4)
        circ_arr = np.array(sorted(circ), np.float64).reshape(-1, 3)
        return Geometry(seg_arr, circ_arr)

    def rasterize_truth(self, resolution: float, origin, shape, *, frame=None) -> np.ndarray:
        """Cells containing an obstacle surface (robots excluded), as a bool (H, W) array.

        Parameters
        ----------
        resolution : cell size, metres.
        origin : (x, y) of the corner of cell (0, 0) in the grid's frame (ROS convention, row 0 = lowest y).
        shape : (H, W).
        frame : optional pose (x, y, yaw) of the grid's frame in the world (e.g. a robot's map frame
            M_i); surfaces are transformed into it first. ``None`` means the world frame.
        """
        geo = self.geometry()
        step = resolution / 4.0
        pts = [_sample_segments(geo.segments, step), _sample_circles(geo.circles, step)]
        p = np.vstack(pts)
        if frame is not None:
            fx, fy, fyaw = (float(v) for v in frame)
            c, s = math.cos(fyaw), math.sin(fyaw)
            dx, dy = p[:, 0] - fx, p[:, 1] - fy
            p = np.stack([c * dx + s * dy, -s * dx + c * dy], axis=1)
        h, w = int(shape[0]), int(shape[1])
        col = np.floor((p[:, 0] - origin[0]) / resolution).astype(np.int64)
        row = np.floor((p[:, 1] - origin[1]) / resolution).astype(np.int64)
        ok = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        out = np.zeros((h, w), bool)
        out[row[ok], col[ok]] = True
        return out


def _sample_segments(seg: np.ndarray, step: float) -> np.ndarray:
    out = [np.zeros((0, 2))]
    for ax, ay, bx, by in seg:
        n = max(2, int(math.ceil(math.hypot(bx - ax, by - ay) / step)) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        out.append(np.array([ax, ay]) + t * np.array([bx - ax, by - ay]))
    return np.vstack(out)


def _sample_circles(circ: np.ndarray, step: float) -> np.ndarray:
    out = [np.zeros((0, 2))]
    for cx, cy, r in circ:
        n = max(8, int(math.ceil(2 * math.pi * r / step)))
        a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
        out.append(np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=1))
    return np.vstack(out)


def _xy(p) -> tuple[float, float]:
    return (float(p[0]), float(p[1]))


def _pairs(segments):
    for ax, ay, bx, by in segments:
        yield (ax, ay), (bx, by)


def _local_to_world(center, yaw_deg: float, pts) -> list[tuple[float, float]]:
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return [(center[0] + c * x - s * y, center[1] + s * x + c * y) for x, y in pts]


def _add_chair(w: World, o: Chair) -> None:
    h = o.leg_spacing_m / 2.0
    for p in _local_to_world(o.center, o.yaw_deg, [(h, h), (-h, h), (-h, -h), (h, -h)]):
        w.add_circle(p, o.leg_radius_m)


def _add_overturned_chair(w: World, o: OverturnedChair) -> None:
    # lying on its side: seat and back form an L in the laser plane, centred on its bounding box
    sx, bx = o.seat_m / 2.0, o.back_m / 2.0
    corner, seat_end, back_end = _local_to_world(o.center, o.yaw_deg, [(-sx, -bx), (sx, -bx), (-sx, bx)])
    w.add_wall(corner, seat_end)
    w.add_wall(corner, back_end)


def _add_box(w: World, o: Box) -> None:
    hx, hy = o.size_m[0] / 2.0, o.size_m[1] / 2.0
    w.add_polygon(_local_to_world(o.center, o.yaw_deg, [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)]))


_ADDERS = {"chair": _add_chair, "overturned_chair": _add_overturned_chair, "box": _add_box}
