"""A 2D laser scanner (Hokuyo URG-04LX-like by default) cast in the pymunk world.

Two ray casters over the same geometry:

* ``method="numpy"`` (default): all beams at once against the world's segments and circles, as
  returned by :meth:`circsim.world.world.World.geometry` from the pymunk shapes. The intersection formulas
  are Chipmunk's own (``cpSegmentShapeSegmentQuery``, ``CircleSegmentQuery``), so both casters agree
  to rounding (the tests check 1e-9 m).
* ``method="pymunk"``: one ``Space.segment_query_first`` per beam with the robot's own
  ``ShapeFilter`` group, so its own body is never hit. Slower (a Python call per beam) and kept as
  the reference.

The scan follows ROS ``sensor_msgs/LaserScan`` and REP-117: ``+inf`` means no return within
``range_max``, ``-inf`` a return closer than ``range_min``, ``NaN`` an erroneous reading (dropout).
Angles are in the laser frame, which is the robot frame (x forward, yaw counter-clockwise).
This module never imports pymunk itself: the pymunk path goes through ``world.space``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..config.types import LaserConfig
from .raykernel import segments_alpha

if TYPE_CHECKING:  # pragma: no cover
    from .world import World

METHODS = ("numpy", "pymunk")
_TINY = np.finfo(np.float64).tiny  # Chipmunk's CPFLOAT_MIN in cpvnormalize
_MANY = 64  # more segments than this (a map world's): those out of the laser's reach left out, a compiled loop


@dataclass(frozen=True, eq=False)
class LaserScan:
    """One scan in ROS ``LaserScan`` terms (angles in radians, ranges in metres)."""

    angle_min: float
    angle_max: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray
    stamp: float = 0.0
    frame_id: str = ""

    def angles(self) -> np.ndarray:
        return self.angle_min + np.arange(len(self.ranges)) * self.angle_increment

    def points(self) -> np.ndarray:
        """(K, 2) returns in the laser frame, for beams with a finite range."""
        ok = np.isfinite(self.ranges)
        a = self.angles()[ok]
        r = self.ranges[ok]
        return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


def raycast(origin, angle_start: float, angle_increment: float, beams: int, range_max: float,
            segments: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """Exact ranges of evenly spaced beams from ``origin`` (numpy, all beams at once).

    Parameters
    ----------
    origin : (x, y) of the laser in the world.
    angle_start, angle_increment : world-frame direction of beam 0 and the step between beams, radians;
        beam k points at ``angle_start + k * angle_increment``.
    beams : number of beams.
    range_max : length of each ray.
    segments : (S, 4) zero-thickness segments ``ax, ay, bx, by``.
    circles : (C, 3) circles ``cx, cy, r``.

    Returns
    -------
    (beams,) ranges; ``+inf`` where nothing is hit within ``range_max``.

    Notes
    -----
    Only the (beam, obstacle) pairs whose directions fall in the obstacle's angular window (plus one
    beam either side) are intersected, which makes the cost grow with the beams that can hit rather
    than beams x obstacles. Each pair follows Chipmunk2D's arithmetic step by step, so the result
    equals ``Space.segment_query_first(a, b, 0, filter).alpha * range_max`` (pymunk) up to rounding.
    A ray starting inside a circle has range 0, as in Chipmunk. With more than ``_MANY`` segments (a map
    world), those farther than ``range_max`` from the origin are dropped (they cannot be hit) and the rest
    go through :func:`circsim.world.raykernel.segments_alpha`, the same pairs and arithmetic in one
    compiled loop (the same bits, without an array entry per pair).
    """
    ax, ay = float(origin[0]), float(origin[1])
    k = np.arange(beams)
    angles = angle_start + k * angle_increment
    bx = ax + range_max * np.cos(angles)
    by = ay + range_max * np.sin(angles)
    alpha = np.full(beams, np.inf)
    seg = np.asarray(segments, np.float64).reshape(-1, 4)
    circ = np.asarray(circles, np.float64).reshape(-1, 3)
    if len(seg) > _MANY:  # a map world's thousands of walls: those within reach, one compiled loop
        segments_alpha(ax, ay, float(angle_start), float(angle_increment), bx, by,
                       np.ascontiguousarray(seg[_reachable(ax, ay, seg, range_max)]), alpha)
    elif len(seg):
        pa = np.arctan2(seg[:, 1] - ay, seg[:, 0] - ax)
        sweep = _wrap_pi(np.arctan2(seg[:, 3] - ay, seg[:, 2] - ax) - pa)
        beam, obj = _window_pairs(pa + np.minimum(sweep, 0.0), np.abs(sweep), angle_start, angle_increment,
                                  beams)
        np.minimum.at(alpha, beam, _segment_alpha(ax, ay, bx[beam], by[beam], seg, obj))
    if len(circ):
        ox, oy = circ[:, 0] - ax, circ[:, 1] - ay
        dist = np.sqrt(ox * ox + oy * oy)
        if np.any(dist - circ[:, 2] <= 0.0):  # cpShapeSegmentQuery: a start inside a shape hits at 0
            return np.zeros(beams)
        half = np.arcsin(circ[:, 2] / dist)
        beam, obj = _window_pairs(np.arctan2(oy, ox) - half, 2.0 * half, angle_start, angle_increment, beams)
        np.minimum.at(alpha, beam, _circle_alpha(ax, ay, bx[beam], by[beam], circ[obj]))
    return alpha * range_max


def _reachable(ax, ay, seg, range_max):
    """Segments that come within ``range_max`` of (ax, ay) (a margin of rounding kept): the others
    cannot meet a ray of that length, so leaving them out changes no range."""
    vx, vy = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    px, py = ax - seg[:, 0], ay - seg[:, 1]
    u = np.clip((px * vx + py * vy) / np.maximum(vx * vx + vy * vy, _TINY), 0.0, 1.0)
    dx, dy = px - u * vx, py - u * vy
    return dx * dx + dy * dy <= (range_max * (1.0 + 1e-9) + 1e-9) ** 2


def _window_pairs(lo, span, angle_start, inc, beams):
    """(beam, object) index pairs for beams whose direction lies in [lo, lo + span] (± one beam)."""
    rel = np.mod(lo - angle_start, 2.0 * np.pi)
    firsts, lasts = [], []
    for shift in (0.0, -2.0 * np.pi):  # an arc may wrap past angle_start + 2π
        firsts.append(np.maximum(np.floor((rel + shift) / inc) - 1, 0))
        lasts.append(np.minimum(np.ceil((rel + shift + span) / inc) + 1, beams - 1))
    first = np.concatenate(firsts).astype(np.intp)
    count = np.maximum(np.concatenate(lasts).astype(np.intp) - first + 1, 0)
    obj = np.repeat(np.tile(np.arange(len(lo)), 2), count)
    offsets = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    return np.repeat(first, count) + offsets, obj


def _segment_alpha(ax, ay, bx, by, seg, obj):
    """cpSegmentShapeSegmentQuery with both radii 0, per (ray, segment ``obj``) pair; +inf for no hit."""
    vx, vy = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    inv = 1.0 / (np.sqrt(vx * vx + vy * vy) + _TINY)
    nx, ny = vy * inv, -(vx * inv)  # cpvrperp(cpvnormalize(b - a))
    d = (seg[:, 0] - ax) * nx + (seg[:, 1] - ay) * ny
    sax, say = seg[:, 0] + (-ax), seg[:, 1] + (-ay)
    sbx, sby = seg[:, 2] + (-ax), seg[:, 3] + (-ay)
    nx, ny, d, sax, say, sbx, sby = (v[obj] for v in (nx, ny, d, sax, say, sbx, sby))
    dx, dy = bx - ax, by - ay
    straddle = (dx * say - dy * sax) * (dx * sby - dy * sbx) <= 0.0
    ad = -d
    bd = (dx * nx + dy * ny) - d
    with np.errstate(divide="ignore", invalid="ignore"):
        alpha = ad / (ad - bd)
    return np.where(straddle & (ad * bd < 0.0), alpha, np.inf)


def _circle_alpha(ax, ay, bx, by, circ):
    """Chipmunk's CircleSegmentQuery per (ray, circle) pair (start outside the circle); +inf for no hit."""
    cx, cy, r = circ[:, 0], circ[:, 1], circ[:, 2]
    dax, day = ax - cx, ay - cy
    dbx, dby = bx - cx, by - cy
    da_da = dax * dax + day * day
    da_db = dax * dbx + day * dby
    qa = da_da - 2.0 * da_db + (dbx * dbx + dby * dby)
    qb = da_db - da_da
    det = qb * qb - qa * (da_da - r * r)
    with np.errstate(invalid="ignore"):
        alpha = (-qb - np.sqrt(det)) / qa
    return np.where((det >= 0.0) & (alpha >= 0.0) & (alpha <= 1.0), alpha, np.inf)


def _wrap_pi(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def cast(world: World, robot_name: str, pose, config: LaserConfig, *, method: str = "numpy") -> np.ndarray:
    """Exact ranges (no noise, no range_min) of ``robot_name``'s laser at ``pose`` = (x, y, yaw).

    Static obstacles and the bodies of the other robots are seen; the robot's own body never is.
    """
    x, y, yaw = (float(v) for v in pose)
    if method == "numpy":
        geo = world.geometry(include_robots=True, exclude=robot_name)
        return raycast((x, y), yaw + config.angle_min, config.angle_increment, config.beams,
                       config.range_max_m, geo.segments, geo.circles)
    if method == "pymunk":
        angles = yaw + config.angle_min + np.arange(config.beams) * config.angle_increment
        return _cast_pymunk(world, robot_name, x, y, angles, config.range_max_m)
    raise ValueError(f"unknown laser method {method!r}; expected one of {METHODS}")


def _cast_pymunk(world: World, robot_name: str, x: float, y: float, angles: np.ndarray,
                 range_max: float) -> np.ndarray:
    query = world.space.segment_query_first
    flt = world.shape_filter(robot_name)
    ex = (x + range_max * np.cos(angles)).tolist()
    ey = (y + range_max * np.sin(angles)).tolist()
    start = (x, y)
    out = np.full(len(angles), np.inf)
    for k in range(len(ex)):
        info = query(start, (ex[k], ey[k]), 0.0, flt)
        if info is not None:
            out[k] = info.alpha * range_max
    return out


def apply_sensor_model(ideal: np.ndarray, config: LaserConfig, rng: np.random.Generator) -> np.ndarray:
    """Turn exact ranges into readings: range_min, Gaussian noise, clipping and dropout.

    Returns closer than ``range_min`` become ``-inf``; returns get ``N(0, σ)`` added (σ = noise_std_m, or
    max(noise_std_m, noise_rel · r) with a relative part) and are
    clipped to ``[range_min, range_max]``; with probability ``dropout`` a beam reads ``NaN``.
    The generator is always advanced by the same amount, so a seed gives the same stream whatever
    the noise settings.
    """
    r = np.array(ideal, np.float64)
    noise = rng.standard_normal(r.shape)
    drop = rng.random(r.shape) < config.dropout
    too_close = r < config.range_min_m
    ret = np.isfinite(r) & ~too_close
    sigma = config.noise_std_m if config.noise_rel <= 0 else np.maximum(config.noise_std_m,
                                                                         config.noise_rel * r[ret])
    r[ret] = np.clip(r[ret] + sigma * noise[ret], config.range_min_m, config.range_max_m)
    r[too_close] = -np.inf
    r[drop] = np.nan
    return r


def scan(world: World, robot_name: str, pose, rng: np.random.Generator, *,
         config: LaserConfig | None = None, stamp: float = 0.0, method: str = "numpy") -> LaserScan:
    """One scan of ``robot_name``'s laser mounted at ``pose`` = (x, y, yaw) in the world frame.

    Parameters
    ----------
    world : the pymunk world (other robots at their current poses are obstacles).
    robot_name : whose laser; its own body is excluded.
    pose : laser pose in the world frame, metres and radians.
    rng : source of noise and dropout draws.
    config : scanner parameters (default :class:`LaserConfig`).
    stamp : simulated time of the scan, seconds.
    method : "numpy" (default, vectorized) or "pymunk" (one query per beam).
    """
    config = config or LaserConfig()
    ranges = apply_sensor_model(cast(world, robot_name, pose, config, method=method), config, rng)
    return LaserScan(angle_min=config.angle_min, angle_max=config.angle_max,
                     angle_increment=config.angle_increment, range_min=config.range_min_m,
                     range_max=config.range_max_m, ranges=ranges, stamp=float(stamp), frame_id=robot_name)
