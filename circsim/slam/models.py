"""The bench SLAM: a pose estimate and a log-odds occupancy grid in the robot's own frame.

Each robot maps in its frame M_i = its pose at start, as gmapping does. Two models of the pose estimate
(``SlamConfig.model``):

* ``scan_matching`` (default, online): the pose is predicted from **wheel odometry with noise** — the
  true motion since the last scan as a translation δt along its bearing and a rotation δr, perturbed by
  zero-mean normal draws of standard deviation √(α3·δt² + α4·δr²) along the bearing, √(α4·δr² + α5·δt²)
  across it and √(α1·δr² + α2·δt²) in yaw: Probabilistic Robotics' odometry model (table 5.6) in the
  holonomic form of ROS amcl's ``omni-corrected`` model (Nav2 amcl's ``OmniMotionModel``), because the
  bench's robots drive sideways round the circle while facing the center (the differential form would
  read that as two ±90° turns per scan and add α1·(π/2)² of yaw variance to each) — then **corrected by matching the scan to the robot's own map so far**
  (:mod:`circsim.slam.scanmatch`: a correlative search on a window of three standard deviations of the
  odometry's accumulated uncertainty, capped by ``matcher`` and at least one cell and one angular step,
  then Gauss–Newton), and the scan is integrated at the corrected pose. With gmapping's update rule
  (``linear_update_m`` / ``angular_update_rad``) every scan is still matched but only the
  scans the rule picks are integrated: gmapping matches only those, but it carries 30 particles through
  the odometry between them; one matched pose per scan is the single-hypothesis stand-in that keeps the
  integrated scans as well placed. The map's errors come from the
  matcher in the room's geometry (slips along featureless walls), not from an invented random walk.
  Every draw comes from the robot's SLAM stream (three normals per scan).
* ``odometry_only`` (a stress option): the true pose expressed in M_i plus a drift (x, y, yaw) that is
  a random walk in the distance travelled (σ = ``drift`` · √L), never corrected: after many laps of
  one room two robots' maps disagree by degrees. Use it to test the merger against drifted maps.

Every integrated scan updates the log-odds grid by ray tracing from the *estimated* pose with the usual
inverse sensor model: cells along a beam get ``miss``, the cell of its return gets ``hit``; a beam without return
(+inf) clears up to ``range_max``; -inf and NaN readings are ignored. Within one scan a cell is
updated once (a hit wins over a pass), so nearby cells crossed by many beams are not over-counted.
All beams are traced at once: OpenCV draws them as one polyline (sensor → end → sensor → …) into a
per-scan mask with sub-cell end points, which costs about as much as a few numpy passes over the
scan's window.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from merger.grid import OccupancyGrid
from merger.jit import njit

from ..config.types import SLAM_MODELS, SlamConfig
from ..world.motion import Pose
from . import scanmatch

WINDOW_SIGMAS = 3.0  # the correlative window covers this many standard deviations of the prediction
MIN_SIGMA_M, MIN_SIGMA_RAD = 1e-4, 1e-5  # the prior's weight stays finite with exact odometry
_FREE, _HIT = 1, 2  # codes in the per-scan mask
_SHIFT = 8  # fractional bits of the sub-cell line end points given to OpenCV


class Slam:
    """One robot's mapping in its own frame M_i.

    Parameters
    ----------
    config : grid and noise parameters.
    start_pose_world : the robot's pose at start in the world; it defines M_i.
    rng : source of the odometry noise or the drift (three normals per update).
    """

    def __init__(self, config: SlamConfig, start_pose_world, rng: np.random.Generator) -> None:
        if config.model not in SLAM_MODELS:
            raise ValueError(f"slam model must be one of {', '.join(SLAM_MODELS)}, got {config.model!r}")
        self.config = config
        self.start = Pose(*(float(v) for v in start_pose_world))
        self._rng = rng
        res = config.resolution_m
        self.size_cells = int(round(config.size_m / res))
        half = self.size_cells * res / 2.0
        self.origin = (-half, -half)
        self.log_odds = np.zeros((self.size_cells, self.size_cells), np.float32)
        # where, within each cell, the returns fell (the matcher's sub-cell walls); scan_matching only
        self.hits = scanmatch.HitMeans(self.log_odds.shape) if config.model == "scan_matching" else None
        # the matcher's map (scan_matching only): the same log-odds clamped at matcher.evidence_clamp instead
        # of log_odds.clamp, so that a wall seen for laps is not rewritten by a few scans at a drifted pose
        self.evidence = np.zeros_like(self.log_odds) if self.hits is not None else None
        self._lut = np.array([0.0, config.log_odds.miss, config.log_odds.hit], np.float32)
        self._drift = np.zeros(3)  # dx, dy (metres, in M_i), dyaw (radians)
        self._last_true: Pose | None = None
        self._prev_pose: Pose | None = None  # gmapping's rule: the path and turns since the last
        self._linear_acc = self._angular_acc = 0.0  # integrated scan
        self.distance_m = 0.0
        self.updates = 0
        self.matches = 0  # scans matched to the map (scan_matching)
        self.last_match: scanmatch.Match | None = None
        self._var_yaw = self._var_xy = 0.0  # the odometry's variance since the last matched scan
        self._integrated_at: tuple[Pose, Pose] | None = None  # (true pose in W, estimate in M_i)
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
        """Take one scan taken at ``true_pose_world`` (the odometry sees the true motion since the last
        scan, with noise); returns the new pose estimate in M_i."""
        true_pose_world = Pose(*(float(v) for v in true_pose_world))
        if self.config.model == "odometry_only":
            self._advance_drift(true_pose_world)
            t = self.true_pose_in_map(true_pose_world)
            self._est = Pose(t.x + self._drift[0], t.y + self._drift[1], _wrap_pi(t.yaw + self._drift[2]))
            due = self._due(true_pose_world)
        else:
            first = self._last_true is None
            self._predict(true_pose_world)
            if not first:
                self._match(scan)
            due = self._due(true_pose_world)
        if due:
            self._integrate(self._est, scan)
            self.updates += 1
            self._grid = None
            self._integrated_at = (true_pose_world, self._est)
        return self._est

    def map_frame_estimate(self) -> Pose | None:
        """Where the map's frame lies in the world as the SLAM built it: the frame in which the last
        integrated scan's true pose has the estimated coordinates, F = P_true ∘ P_est⁻¹ (the start pose when
        the estimate is exact); None before the first scan. The transform between two robots' F is the
        alignment their maps as built call for (the estimated-frame truth of :mod:`circsim.metrics`)."""
        if self._integrated_at is None:
            return None
        p, e = self._integrated_at
        yaw = p.yaw - e.yaw
        c, s = math.cos(yaw), math.sin(yaw)
        return Pose(p.x - (c * e.x - s * e.y), p.y - (s * e.x + c * e.y), _wrap_pi(yaw))

    def _predict(self, pose: Pose) -> None:
        """The odometry motion model (Nav2 amcl's OmniMotionModel): the true motion since the last scan
        as a translation δt along its bearing and a rotation δr, with noise on the translation, a
        sideways slip and the rotation, applied to the estimate."""
        prev, self._last_true = self._last_true, pose
        z = self._rng.standard_normal(3)  # drawn at every scan, the first too: a stable stream
        if prev is None:
            return
        a = self.config.odometry
        dx, dy = pose.x - prev.x, pose.y - prev.y
        trans = math.hypot(dx, dy)
        rot = _wrap_pi(pose.yaw - prev.yaw)
        self.distance_m += trans
        var_t = a.alpha3 * trans * trans + a.alpha4 * rot * rot
        var_r = a.alpha1 * rot * rot + a.alpha2 * trans * trans
        var_s = a.alpha4 * rot * rot + a.alpha5 * trans * trans
        trans_hat = trans + z[0] * math.sqrt(var_t)
        rot_hat = rot + z[1] * math.sqrt(var_r)
        strafe_hat = z[2] * math.sqrt(var_s)
        e = self._est
        bearing = math.atan2(dy, dx) - prev.yaw + e.yaw  # the direction of travel, in the estimate's frame
        c, s = math.cos(bearing), math.sin(bearing)
        self._est = Pose(e.x + trans_hat * c + strafe_hat * s, e.y + trans_hat * s - strafe_hat * c,
                         _wrap_pi(e.yaw + rot_hat))
        # first order: the heading's variance displaces the path sideways
        self._var_xy += var_t + var_s + trans * trans * self._var_yaw
        self._var_yaw += var_r

    def _match(self, scan) -> None:
        """Correct the predicted pose by matching the scan to the map so far (:func:`scanmatch.match`)."""
        m = self.config.matcher
        px, py, nx, ny = scanmatch.scan_points(scan.ranges, scan.angle_min, scan.angle_increment, scan.range_min,
                                               m.max_points)
        if px.size == 0:
            return
        res = self.config.resolution_m
        lin = min(m.linear_window_m, WINDOW_SIGMAS * math.sqrt(self._var_xy))
        ang = min(math.radians(m.angular_window_deg), WINDOW_SIGMAS * math.sqrt(self._var_yaw))
        e = self._est
        # the prior's weights in the matcher's units (mean squared distance over a cell): the odometry's
        # information relative to N points of σ point_sigma_m, −log p = Σ r²/2σ² + Δ²/2σ_odo²
        k = m.point_sigma_m / (res * math.sqrt(px.size))
        w_t = k / max(math.sqrt(self._var_xy), MIN_SIGMA_M)
        w_r = k / max(math.sqrt(self._var_yaw), MIN_SIGMA_RAD)
        self.last_match = scanmatch.match(self.evidence, self.hits, self.origin, res, self.config.log_odds.clamp, px, py,
                                          nx, ny, (e.x, e.y, e.yaw), lin, ang, w_t, w_r,
                                          min(m.min_log_odds, 0.99 * self.updates * self.config.log_odds.hit))
        self._est = Pose(self.last_match.x, self.last_match.y, _wrap_pi(self.last_match.yaw))
        self._var_xy = self._var_yaw = 0.0
        self.matches += 1

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
        if self.hits is not None:
            rows, cols = hy[ok] + r0, hx[ok] + c0
            self.hits.add(rows, cols, pose.x + r[hit][ok] * cos[hit][ok], pose.y + r[hit][ok] * sin[hit][ok])
        # the cells the scan touched, in one compiled pass (the others' increment is 0 and they lie within
        # the clamps already: the same floats as adding the whole window's increments and clipping it, the
        # numpy of before; tests/circsim/slam/test_models.py compares them)
        ev = self.evidence[r0:r1, c0:c1] if self.evidence is not None else self.log_odds[:0, :0]
        _add_clipped(self.log_odds[r0:r1, c0:c1], ev, mask, self._lut, np.float32(self.config.log_odds.clamp),
                     np.float32(self.config.matcher.evidence_clamp if self.evidence is not None else 0.0))

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


@njit(cache=True, nogil=True)
def _add_clipped(lo, ev, mask, lut, clamp, ev_clamp):
    """lo (and ev, unless empty) += lut[mask] where mask is set, each clipped to ±its clamp (float32)."""
    evidence = ev.shape[0] > 0
    for i in range(mask.shape[0]):
        for j in range(mask.shape[1]):
            m = mask[i, j]
            if m == 0:
                continue
            inc = lut[m]
            v = lo[i, j] + inc
            lo[i, j] = min(max(v, -clamp), clamp)
            if evidence:
                w = ev[i, j] + inc
                ev[i, j] = min(max(w, -ev_clamp), ev_clamp)
