"""Synthetic SLAM: a drifting pose estimate and a log-odds occupancy grid in the robot's own frame.

Each robot maps in its frame M_i = its pose at start, as gmapping does. The pose estimate is the true
pose expressed in M_i plus a drift (x, y, yaw) that is a random walk in the distance travelled. Every
scan updates a log-odds grid by ray tracing from the *estimated* pose with the usual inverse sensor
model: cells along a beam get ``miss``, the cell of its return gets ``hit``; a beam without return
(+inf) clears up to ``range_max``; -inf and NaN readings are ignored. Within one scan a cell is
updated once (a hit wins over a pass), so nearby cells crossed by many beams are not over-counted.
All beams are traced at once: OpenCV draws them as one polyline (sensor → end → sensor → …) into a
per-scan mask with sub-cell end points, which costs about as much as a few numpy passes over the
scan's window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from merger.grid import DEFAULT_FREE_THRESH, DEFAULT_OCCUPIED_THRESH, OccupancyGrid

from .motion import Pose

_FREE, _HIT = 1, 2  # codes in the per-scan mask
_SHIFT = 8  # fractional bits of the sub-cell line end points given to OpenCV


@dataclass(frozen=True)
class DriftConfig:
    """Odometry drift as a random walk in the distance travelled.

    ``xy_m_per_m`` and ``yaw_deg_per_m`` are the standard deviations of the accumulated drift after
    1 m of travel; after L metres they are ``value * sqrt(L)``, whatever the step size.
    """

    xy_m_per_m: float = 0.005
    yaw_deg_per_m: float = 0.1


@dataclass(frozen=True)
class LogOddsConfig:
    """Inverse sensor model increments and the symmetric clamp |l| ≤ clamp."""

    hit: float = 0.85
    miss: float = -0.4
    clamp: float = 3.5


@dataclass(frozen=True)
class SlamConfig:
    """Grid and noise parameters of the synthetic SLAM.

    resolution_m : cell size.
    size_m : side of the square grid, centred on the start pose (must hold the robot's circle plus
        the laser range that matters: the room).
    drift : pose-estimate drift.
    log_odds : inverse sensor model.
    occupied_thresh, free_thresh : probability thresholds to ternary (map_server's rule).
    publish_period_s : how often the robot publishes its map (used by the simulation loop; gmapping's
        ``map_update_interval``, default 5 s).
    linear_update_m, angular_update_rad : integrate a scan only after the robot has moved this far or
        turned this much since the last integrated one (gmapping's ``linearUpdate`` = 1.0 m and
        ``angularUpdate`` = 0.5 rad by default); the first scan is always integrated. 0 and 0 (the
        default here): every scan is integrated.
    """

    resolution_m: float = 0.05
    size_m: float = 16.0
    drift: DriftConfig = field(default_factory=DriftConfig)
    log_odds: LogOddsConfig = field(default_factory=LogOddsConfig)
    occupied_thresh: float = DEFAULT_OCCUPIED_THRESH
    free_thresh: float = DEFAULT_FREE_THRESH
    publish_period_s: float = 2.0
    linear_update_m: float = 0.0
    angular_update_rad: float = 0.0


class Slam:
    """One robot's mapping in its own frame M_i.

    Parameters
    ----------
    config : grid and noise parameters.
    start_pose_world : the robot's pose at start in the world; it defines M_i.
    rng : source of drift draws (three normals per update).
    """

    def __init__(self, config: SlamConfig, start_pose_world, rng: np.random.Generator) -> None:
        self.config = config
        self.start = Pose(*(float(v) for v in start_pose_world))
        self._rng = rng
        res = config.resolution_m
        self.size_cells = int(round(config.size_m / res))
        half = self.size_cells * res / 2.0
        self.origin = (-half, -half)
        self.log_odds = np.zeros((self.size_cells, self.size_cells), np.float32)
        self._lut = np.array([0.0, config.log_odds.miss, config.log_odds.hit], np.float32)
        self._drift = np.zeros(3)  # dx, dy (metres, in M_i), dyaw (radians)
        self._last_true: Pose | None = None
        self._prev_pose: Pose | None = None  # gmapping's rule: the path and turns since the last
        self._linear_acc = self._angular_acc = 0.0  # integrated scan
        self.distance_m = 0.0
        self.updates = 0
        self._est = Pose(0.0, 0.0, 0.0)
        self._grid: OccupancyGrid | None = None

    # --- frames -------------------------------------------------------------------------------
    def true_to_map(self, xy_world) -> np.ndarray:
        """World points (..., 2) expressed in M_i without drift (ground truth in the map frame)."""
        p = np.asarray(xy_world, np.float64)
        c, s = math.cos(self.start.yaw), math.sin(self.start.yaw)
        dx, dy = p[..., 0] - self.start.x, p[..., 1] - self.start.y
        return np.stack([c * dx + s * dy, -s * dx + c * dy], axis=-1)

    def true_pose_in_map(self, pose_world) -> Pose:
        x, y = self.true_to_map(np.array(pose_world[:2], np.float64))
        return Pose(float(x), float(y), _wrap_pi(float(pose_world[2]) - self.start.yaw))

    def estimated_pose(self) -> Pose:
        """The current pose estimate in M_i."""
        return self._est

    # --- mapping ------------------------------------------------------------------------------
    def update(self, true_pose_world, scan) -> Pose:
        """Integrate one scan taken at ``true_pose_world``; returns the new pose estimate in M_i."""
        true_pose_world = Pose(*(float(v) for v in true_pose_world))
        self._advance_drift(true_pose_world)
        t = self.true_pose_in_map(true_pose_world)
        self._est = Pose(t.x + self._drift[0], t.y + self._drift[1], _wrap_pi(t.yaw + self._drift[2]))
        if self._due(true_pose_world):
            self._integrate(self._est, scan)
            self.updates += 1
            self._grid = None
        return self._est

    def _due(self, pose: Pose) -> bool:
        """gmapping's rule (GridSlamProcessor::processScan): the first scan, then one once the path
        travelled since the last integrated scan reaches ``linear_update_m`` or the turns summed since
        then reach ``angular_update_rad`` (both 0: every scan)."""
        c = self.config
        prev, self._prev_pose = self._prev_pose, pose
        if prev is not None:
            self._linear_acc += math.hypot(pose.x - prev.x, pose.y - prev.y)
            self._angular_acc += abs(_wrap_pi(pose.yaw - prev.yaw))
            if c.linear_update_m > 0 or c.angular_update_rad > 0:
                if not ((c.linear_update_m > 0 and self._linear_acc >= c.linear_update_m)
                        or (c.angular_update_rad > 0 and self._angular_acc >= c.angular_update_rad)):
                    return False
        self._linear_acc = self._angular_acc = 0.0
        return True

    def _advance_drift(self, pose: Pose) -> None:
        ds = 0.0 if self._last_true is None else math.hypot(pose.x - self._last_true.x,
                                                             pose.y - self._last_true.y)
        self._last_true = pose
        self.distance_m += ds
        z = self._rng.standard_normal(3)
        d = self.config.drift
        sigma = np.array([d.xy_m_per_m, d.xy_m_per_m, math.radians(d.yaw_deg_per_m)])
        self._drift += z * sigma * math.sqrt(ds)

    def _integrate(self, pose: Pose, scan) -> None:
        res = self.config.resolution_m
        n = self.size_cells
        r = np.asarray(scan.ranges, np.float64)
        angles = pose.yaw + scan.angle_min + np.arange(len(r)) * scan.angle_increment
        cos, sin = np.cos(angles), np.sin(angles)
        hit = np.isfinite(r) & (r >= scan.range_min)
        # free space stops one cell short of a return so that grazing beams do not erode walls;
        # invalid readings (-inf, NaN) get length 0 and clear nothing
        free_len = np.where(hit, np.maximum(r - res, 0.0), np.where(np.isposinf(r), scan.range_max, 0.0))
        free_len /= res
        if not (free_len > 0).any() and not hit.any():
            return
        cx, cy = (pose.x - self.origin[0]) / res, (pose.y - self.origin[1]) / res
        reach = int(math.ceil(scan.range_max / res)) + 2  # the window of cells one scan can touch
        r0, r1 = max(0, int(cy) - reach), min(n, int(cy) + reach + 1)
        c0, c1 = max(0, int(cx) - reach), min(n, int(cx) + reach + 1)
        if r0 >= r1 or c0 >= c1:
            return
        mask = np.zeros((r1 - r0, c1 - c0), np.uint8)
        # every beam as a line sensor -> end -> sensor, drawn in one call; OpenCV puts pixel centres
        # on integers, our cell c spans [c, c + 1), hence the -0.5
        pts = np.empty((2 * len(r) + 1, 2))
        pts[0::2] = (cx - c0 - 0.5, cy - r0 - 0.5)
        pts[1::2, 0] = cx - c0 - 0.5 + free_len * cos
        pts[1::2, 1] = cy - r0 - 0.5 + free_len * sin
        fixed = np.round(pts * (1 << _SHIFT)).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(mask, [fixed], isClosed=False, color=_FREE, thickness=1, lineType=cv2.LINE_8,
                      shift=_SHIFT)
        hx = np.floor(cx + r[hit] * cos[hit] / res).astype(np.intp) - c0
        hy = np.floor(cy + r[hit] * sin[hit] / res).astype(np.intp) - r0
        ok = (hx >= 0) & (hx < c1 - c0) & (hy >= 0) & (hy < r1 - r0)
        mask[hy[ok], hx[ok]] = _HIT
        lo = self.log_odds[r0:r1, c0:c1]
        lo += self._lut[mask]
        np.clip(lo, -self.config.log_odds.clamp, self.config.log_odds.clamp, out=lo)

    # --- output -------------------------------------------------------------------------------
    def grid(self) -> OccupancyGrid:
        """The ternary map in M_i (origin = corner of cell (0, 0) in M_i coordinates)."""
        if self._grid is None:
            self._grid = OccupancyGrid.from_log_odds(
                self.log_odds, self.config.resolution_m, self.origin,
                occupied_thresh=self.config.occupied_thresh, free_thresh=self.config.free_thresh)
        return self._grid


def _wrap_pi(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi
