"""Robot trajectories on the circle around the scene's center.

Positions: a robot at polar angle α (degrees, counter-clockwise from the world x axis, measured at
the center) stands at ``center + radius * (cos α, sin α)``.

Heading (``robots.heading`` in a scenario):

* ``"center"`` (default): the robot faces the scene's center, ``yaw = α + 180°``, at every instant.
  With the 240° field of view the laser sees the whole center region in the middle of its field,
  both neighbouring robots' sectors to the sides, and walls up to ±120° off the center direction;
  the blind 120° sector points outward, at the nearest wall, which the other robots see. It matches
  the thesis's offline experiment (robots displaced by hand, lasers kept on the scene). The body is
  kinematic, so driving sideways along the circle is allowed.
* ``"tangent"``: the robot faces its direction of travel (counter-clockwise), ``yaw = α + 90°``;
  the center is then at +90° in the laser frame and the outer wall at −90°, both inside the field.

Per-robot ``yaw_offset_deg`` is added to either rule, so map frames can differ by more than the
start positions alone.

Motion patterns:

* ``online``: counter-clockwise at ``speed_mps``, ``α(t) = α0 + speed * t / radius``.
* ``offline``: the thesis's displacement experiment. The robot is displaced to 0, +s, −s, +2s, −2s,
  … up to ±max_deg; once it has been at ±φ its map covers the arc [−φ, +φ]
  (see :func:`offline_steps`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:  # pragma: no cover
    from ..config.scenario import Scenario

HEADINGS = ("center", "tangent")


class Pose(NamedTuple):
    """A planar pose: metres and radians (REP-103, yaw counter-clockwise)."""

    x: float
    y: float
    yaw: float


@dataclass(frozen=True)
class CircleTrajectory:
    """One robot's place and motion on the circle.

    Parameters
    ----------
    center : (x, y) of the scene's center in the world frame.
    radius_m : circle radius.
    start_angle_deg : polar angle of the start position about the center.
    speed_mps : speed along the circle for online motion.
    heading : "center" or "tangent" (see the module notes).
    yaw_offset_deg : added to the heading rule.
    """

    center: tuple[float, float]
    radius_m: float
    start_angle_deg: float
    speed_mps: float = 0.2
    heading: str = "center"
    yaw_offset_deg: float = 0.0

    def __post_init__(self) -> None:
        if self.heading not in HEADINGS:
            raise ValueError(f"heading must be one of {HEADINGS}, got {self.heading!r}")

    def pose_at_displacement(self, displacement_deg: float) -> Pose:
        """Pose after a counter-clockwise displacement (negative: clockwise) from the start point."""
        alpha = math.radians(self.start_angle_deg + displacement_deg)
        x = self.center[0] + self.radius_m * math.cos(alpha)
        y = self.center[1] + self.radius_m * math.sin(alpha)
        rule = math.pi if self.heading == "center" else math.pi / 2.0
        return Pose(x, y, _wrap_pi(alpha + rule + math.radians(self.yaw_offset_deg)))

    def start_pose(self) -> Pose:
        """The pose at t = 0; it defines the robot's map frame M_i."""
        return self.pose_at_displacement(0.0)

    def arc_travelled_deg(self, t: float) -> float:
        """Degrees travelled on the circle after ``t`` seconds of online motion."""
        return math.degrees(self.speed_mps * max(t, 0.0) / self.radius_m)

    def pose_at(self, t: float) -> Pose:
        """Online motion: the pose ``t`` seconds after start, driving counter-clockwise."""
        return self.pose_at_displacement(self.arc_travelled_deg(t))

    def tour_s(self) -> float:
        """Seconds for one full tour of the circle."""
        return 2.0 * math.pi * self.radius_m / self.speed_mps


@dataclass(frozen=True)
class OfflineStep:
    """One displacement of the offline experiment.

    phi_deg : the half-arc the map covers once this step is scanned, if ``completes`` is True.
    displacement_deg : signed displacement of this pose from the start point.
    pose : world pose to scan from.
    completes : True when, after this pose, the robot has been at both +phi and −phi.
    """

    phi_deg: float
    displacement_deg: float
    pose: Pose
    completes: bool


def offline_schedule(max_deg: float, step_deg: float) -> list[float]:
    """Displacements 0, +s, −s, +2s, −2s, … up to ±max_deg (degrees)."""
    if step_deg <= 0:
        raise ValueError("step_deg must be > 0")
    n = int(math.floor(max_deg / step_deg + 1e-9))
    out = [0.0]
    for k in range(1, n + 1):
        out += [k * step_deg, -k * step_deg]
    return out


def offline_steps(traj: CircleTrajectory, max_deg: float, step_deg: float) -> Iterator[OfflineStep]:
    """The poses of the offline experiment in order, marking where each arc [−φ, +φ] is complete.

    A caller scans at every pose into one SLAM instance and saves the map whenever ``completes`` is
    True: that map is the robot's map for ``phi_deg`` (φ = 0 is the start pose alone).
    """
    for d in offline_schedule(max_deg, step_deg):
        yield OfflineStep(phi_deg=abs(d), displacement_deg=d, pose=traj.pose_at_displacement(d),
                          completes=d <= 0.0)


def trajectories(sc: Scenario) -> dict[str, CircleTrajectory]:
    """Every robot's trajectory, keyed by name, from a scenario."""
    r = sc.robots
    return {name: CircleTrajectory(center=sc.world.center, radius_m=r.radius_m, start_angle_deg=a,
                                   speed_mps=r.speed_mps, heading=r.heading, yaw_offset_deg=off)
            for name, a, off in zip(r.names, r.start_angles_deg, r.yaw_offsets_deg, strict=True)}


def _wrap_pi(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi
