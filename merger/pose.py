"""Where a map's frame sits in another's: :class:`Pose` (x, y, yaw), the form a ROS tf or
``circsim score --transforms`` takes.

A merge places map k onto the first map's frame about the common centers (DESIGN.md, Frames):
x_0 = c_0 + t + R(θ)(x_k − c_k). Written as a rigid motion of map k's frame,
x_0 = R(θ) x_k + (c_0 + t − R(θ) c_k): the pose of map k's frame in map 0's frame is
(x, y) = c_0 + t − R(θ) c_k and yaw = θ (:func:`pose_of_placement`). The first map's own pose is the
identity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Pose:
    """The pose of a map's frame in a reference frame: a point p of the map lies at
    ``R(yaw_deg) · p + (x, y)`` in the reference frame (metres, degrees counter-clockwise, REP-103).
    ``yaw_deg`` is in [0, 360)."""

    x: float
    y: float
    yaw_deg: float

    def apply(self, points) -> np.ndarray:
        """Points (…, 2) of the map's frame in the reference frame."""
        p = np.asarray(points, np.float64)
        a = math.radians(self.yaw_deg)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        return p @ rot.T + np.array([self.x, self.y])

    def inverse(self) -> Pose:
        """The reference frame's pose in the map's frame."""
        back = Pose(0.0, 0.0, -self.yaw_deg).apply([-self.x, -self.y])
        return Pose(float(back[0]), float(back[1]), wrap_yaw(-self.yaw_deg))

    def to_dict(self) -> dict:
        return {"x": self.x, "y": self.y, "yaw_deg": self.yaw_deg}


IDENTITY = Pose(0.0, 0.0, 0.0)


def wrap_yaw(deg: float) -> float:
    """``deg`` in [0, 360): ``x % 360.0`` alone rounds to 360.0 for a tiny negative x (−1e-20 % 360 == 360.0)."""
    w = float(deg) % 360.0
    return 0.0 if w >= 360.0 else w


def pose_of_placement(theta_deg: float, t, c_first, c_map) -> Pose:
    """The pose of a map's frame in the first map's frame from its placement (θ, t) about the centers
    ``c_first`` (the first map's) and ``c_map`` (its own): x_0 = c_0 + t + R(θ)(x − c)."""
    rc = Pose(0.0, 0.0, theta_deg).apply(c_map)
    return Pose(float(c_first[0] + t[0] - rc[0]), float(c_first[1] + t[1] - rc[1]), wrap_yaw(theta_deg))
