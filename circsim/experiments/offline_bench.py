"""The offline experiment's robots: displaced around their start points, each mapping in its own frame.

:class:`OfflineBench` builds a scenario's world, trajectories and one SLAM per robot, and
:meth:`OfflineBench.maps` displaces every robot to 0, +step, −step, +2·step, … up to ±max_deg
(:func:`circsim.world.motion.offline_schedule`), scanning ``scans_per_pose`` times at every pose, and
yields each robot's map at φ once it has been at both +φ and −φ. The others are seen at their current
poses (``"lockstep"``), at their starts (``"start"``) or not at all (``"absent"``); the SLAM drifts along
the arc (:class:`ArcDriftSlam`, ``"arc"``: a function of the displacement, the same estimate back at a
place) or along the path (the plain :class:`circsim.slam.models.Slam`, ``"path"``). Random streams are
split as :class:`circsim.sim.Simulation` splits them, so a seed's center errors, SLAM drift and laser noise
are an online run's. The bench also holds the truth: ``truth_deg`` (θ*_1j = yaw_j(0) − yaw_1(0)) and
``truth_translation_m`` (t*_1j about the given centers). What these choices mean for the experiment, and
how its merges are judged: :mod:`circsim.experiments.offline`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace

import numpy as np

from merger.grid import OccupancyGrid
from merger.team.orders import MapInput

from ..config.scenario import Scenario
from ..sim import truth_translation
from ..slam.models import Slam
from ..world.laser import scan as laser_scan
from ..world.motion import offline_schedule, trajectories
from ..world.world import World


class ArcDriftSlam(Slam):
    """A :class:`Slam` whose drift depends on where the robot is on its arc, not on the path to it.

    Each side of the start point has its own random walk in the arc length (same per-metre sigmas as
    the scenario's drift); the first visit of a displacement draws its increment from the SLAM's
    stream, every later visit reuses it. Set :attr:`displacement_deg` before :meth:`update`.
    """

    def __init__(self, config, start_pose_world, rng, radius_m: float) -> None:
        super().__init__(config, start_pose_world, rng)
        self.radius_m = float(radius_m)
        self.displacement_deg = 0.0
        self._arc_drift: dict[float, np.ndarray] = {0.0: np.zeros(3)}

    def _advance_drift(self, pose) -> None:
        d = self.displacement_deg
        if d not in self._arc_drift:
            side = [k for k in self._arc_drift if k * d >= 0 and abs(k) < abs(d)]
            prev = max(side, key=abs)  # the last place mapped on this side (0 at first)
            ds = 2.0 * self.radius_m * math.sin(math.radians(abs(d - prev)) / 2.0)
            c = self.config.drift
            sigma = np.array([c.xy_m_per_m, c.xy_m_per_m, math.radians(c.yaw_deg_per_m)])
            self._arc_drift[d] = self._arc_drift[prev] + self._rng.standard_normal(3) * sigma * math.sqrt(ds)
        if self._last_true is not None:
            self.distance_m += math.hypot(pose.x - self._last_true.x, pose.y - self._last_true.y)
        self._last_true = pose
        self._drift = self._arc_drift[d].copy()


class OfflineBench:
    """The robots of a scenario displaced around their start points, each mapping in its own frame."""

    def __init__(self, sc: Scenario, *, others: str = "lockstep", scans_per_pose: int = 5,
                 drift: str = "arc") -> None:
        self.scenario = sc
        self.others = others
        self.drift = drift
        self.scans_per_pose = scans_per_pose
        self.names = list(sc.robots.names)
        ss = np.random.SeedSequence(int(sc.seed))  # same stream layout as circsim.sim.Simulation
        streams = iter(ss.spawn(3 + 2 * len(self.names)))
        next(streams)  # network (unused offline)
        err_rng = np.random.default_rng(next(streams))
        next(streams)  # publish phases (unused offline)
        self.world = World.from_scenario(sc)
        self.trajs = trajectories(sc)
        self.start_poses = {n: self.trajs[n].start_pose() for n in self.names}
        errors = sc.center_error.vectors(self.names, err_rng)
        self.slams: dict[str, Slam] = {}
        self.laser_rngs: dict[str, np.random.Generator] = {}
        self.centers: dict[str, tuple[float, float]] = {}
        self.center_errors: dict[str, tuple[float, float]] = {}
        for n in self.names:
            rng = np.random.default_rng(next(streams))
            # the displacement experiment keeps its drift models (random walks in the arc or the path),
            # whatever the scenario's online SLAM model
            cfg = replace(sc.slam, model="odometry_only")
            self.slams[n] = (ArcDriftSlam(cfg, self.start_poses[n], rng, sc.robots.radius_m)
                             if drift == "arc" else Slam(cfg, self.start_poses[n], rng))
            self.laser_rngs[n] = np.random.default_rng(next(streams))
            c = self.slams[n].true_to_map(np.array(sc.world.center, np.float64))
            self.centers[n] = (float(c[0]) + errors[n][0], float(c[1]) + errors[n][1])
            self.center_errors[n] = (self.centers[n][0] - float(c[0]), self.centers[n][1] - float(c[1]))
        ref = self.names[0]
        # θ*_1j = yaw_j(0) − yaw_1(0): rotation of map j onto map 1 (robot 1's frame)
        self.truth_deg = {n: math.degrees(self.start_poses[n].yaw - self.start_poses[ref].yaw) % 360.0
                          for n in self.names}
        # t*_1j = R(θ*_1j)·e_j − e_1: translation of map j onto map 1 about the given centers
        self.truth_translation_m = {n: truth_translation(self.truth_deg[n], self.center_errors[ref],
                                                         self.center_errors[n]) for n in self.names}

    def _scan_all(self, displacement_deg: float) -> None:
        sc = self.scenario
        poses = {n: self.trajs[n].pose_at_displacement(displacement_deg) for n in self.names}
        for n in self.names:
            if self.others == "lockstep":
                for m in self.names:
                    self.world.set_robot_pose(m, *poses[m])
            elif self.others == "start":
                for m in self.names:
                    self.world.set_robot_pose(m, *(poses[m] if m == n else self.start_poses[m]))
            else:  # absent: park the others far outside the room (the laser never reaches them)
                for k, m in enumerate(self.names):
                    self.world.set_robot_pose(m, *(poses[m] if m == n else (1e4 + 10.0 * k, 1e4, 0.0)))
            if isinstance(self.slams[n], ArcDriftSlam):
                self.slams[n].displacement_deg = float(displacement_deg)
            for _ in range(self.scans_per_pose):
                s = laser_scan(self.world, n, poses[n], self.laser_rngs[n], config=sc.laser)
                self.slams[n].update(poses[n], s)

    def maps(self, max_deg: float, step_deg: float) -> Iterator[tuple[float, dict[str, OccupancyGrid]]]:
        """(φ, {robot: map covering [−φ, +φ]}) for φ = 0, step, 2·step, … ≤ max_deg, in order."""
        for d in offline_schedule(max_deg, step_deg):
            self._scan_all(d)
            if d <= 0.0:  # the robot has now been at +|d| and −|d|
                yield abs(d), {n: self.slams[n].grid() for n in self.names}

    def inputs(self, grids: dict[str, OccupancyGrid]) -> list[MapInput]:
        return [MapInput(n, grids[n], self.centers[n]) for n in self.names]
