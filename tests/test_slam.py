"""Synthetic SLAM: frames, drift, and the grid against rasterized ground truth."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from circsim.laser import LaserConfig, LaserScan, scan
from circsim.motion import trajectories
from circsim.scenario import bundled_scenarios, load_scenario
from circsim.slam import DriftConfig, Slam, SlamConfig
from circsim.world import World
from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid

EXACT = SlamConfig(drift=DriftConfig(0.0, 0.0))


def empty_scan(n=3):
    return LaserScan(-0.1, 0.1, 0.1, 0.02, 5.6, np.full(n, np.nan))


def tour_map(name="scene1", robot="Lyon", *, config=EXACT, laser_cfg=None, seed=0, others=False, step_deg=3.0):
    """The robot's grid after one tour of its circle (other robots removed unless ``others``)."""
    sc = load_scenario(bundled_scenarios()[name])
    world = World.from_scenario(sc)
    if not others:  # park the teammates 1 km away, far out of the laser's range
        for k, other in enumerate(n for n in sc.robots.names if n != robot):
            world.set_robot_pose(other, 1000.0 + 10.0 * k, 1000.0, 0.0)
    traj = trajectories(sc)[robot]
    laser_cfg = laser_cfg or LaserConfig(noise_std_m=0.0)
    rng = np.random.default_rng(seed)
    slam = Slam(config, traj.start_pose(), np.random.default_rng(seed + 1))
    for d in np.arange(0.0, 360.0, step_deg):
        pose = traj.pose_at_displacement(d)
        slam.update(pose, scan(world, robot, pose, rng, config=laser_cfg))
    return world, traj, slam


def test_map_frame_is_the_start_pose():
    slam = Slam(EXACT, (1.0, 2.0, math.pi / 2), np.random.default_rng(0))
    np.testing.assert_allclose(slam.true_to_map([1.0, 3.0]), [1.0, 0.0], atol=1e-12)  # 1 m ahead
    np.testing.assert_allclose(slam.true_to_map([[0.0, 2.0]]), [[0.0, 1.0]], atol=1e-12)  # 1 m to the left
    est = slam.update((1.0, 2.0, math.pi / 2), empty_scan())
    assert est == pytest.approx((0.0, 0.0, 0.0))
    est = slam.update((2.0, 2.0, 0.0), empty_scan())
    assert est == pytest.approx((0.0, -1.0, -math.pi / 2))
    assert slam.distance_m == pytest.approx(1.0)
    g = slam.grid()
    assert isinstance(g, OccupancyGrid) and g.shape == (320, 320) and g.origin == (-8.0, -8.0)
    assert g.count()["occupied"] == 0


def test_single_scan_free_along_beams_occupied_at_hits():
    w = World()
    w.add_wall((2.0, -3.0), (2.0, 3.0))  # a wall 2 m ahead
    w.add_robot("r", 0.18)
    cfg = LaserConfig(fov_deg=60, beams=61, noise_std_m=0.0, range_max_m=5.6)
    slam = Slam(EXACT, (0.0, 0.0, 0.0), np.random.default_rng(0))
    slam.update((0.0, 0.0, 0.0), scan(w, "r", (0.0, 0.0, 0.0), np.random.default_rng(0), config=cfg))
    lo = slam.log_odds
    g = slam.grid().states
    col = lambda x: int((x + 8.0) / 0.05)  # noqa: E731
    row0 = col(0.0)
    assert lo[row0, col(2.0)] == pytest.approx(0.85) and g[row0, col(2.0)] == OCCUPIED_S
    assert lo[row0, col(1.0)] == pytest.approx(-0.4)  # one pass: not yet free (threshold 0.196)
    assert lo[row0, col(2.2)] == 0.0 and g[row0, col(2.2)] == UNKNOWN_S  # behind the wall
    for _ in range(4):
        slam.update((0.0, 0.0, 0.0), scan(w, "r", (0.0, 0.0, 0.0), np.random.default_rng(0), config=cfg))
    g = slam.grid().states
    assert g[row0, col(1.0)] == FREE_S and g[row0, col(2.0)] == OCCUPIED_S
    assert lo.max() <= 3.5 and lo.min() >= -3.5


def test_beams_without_return_clear_up_to_range_max_only():
    w = World()
    w.add_robot("r", 0.18)
    cfg = LaserConfig(fov_deg=10, beams=11, noise_std_m=0.0, range_max_m=3.0)
    slam = Slam(EXACT, (0.0, 0.0, 0.0), np.random.default_rng(0))
    s = scan(w, "r", (0.0, 0.0, 0.0), np.random.default_rng(0), config=cfg)
    assert np.isposinf(s.ranges).all()
    slam.update((0.0, 0.0, 0.0), s)
    row0 = int(8.0 / 0.05)
    assert slam.log_odds[row0, int((2.9 + 8) / 0.05)] < 0
    assert slam.log_odds[row0, int((3.1 + 8) / 0.05)] == 0
    assert slam.log_odds.max() == 0  # no hits


@pytest.mark.parametrize("name", ["scene1", "scene2"])
def test_zero_noise_grid_matches_ground_truth(name):
    world, traj, slam = tour_map(name)
    g = slam.grid()
    truth = world.rasterize_truth(g.resolution, g.origin, g.shape, frame=traj.start_pose())
    near_truth = cv2.dilate(truth.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    occ = g.states == OCCUPIED_S
    assert occ.sum() > 500
    assert not (occ & ~near_truth).any()  # every occupied cell within one cell of a true surface
    seen = truth & (g.states != UNKNOWN_S)
    assert (occ & truth).sum() / seen.sum() > 0.85  # most surface cells seen are occupied...
    near_occ = cv2.dilate(occ.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    assert (near_occ & seen).sum() / seen.sum() > 0.99  # ...and nearly all are within one cell of one


def test_robots_seen_by_the_laser_leave_no_trace_when_they_move_on():
    world, traj, slam = tour_map("scene1", others=True, laser_cfg=LaserConfig(noise_std_m=0.0))
    g = slam.grid()
    truth = world.rasterize_truth(g.resolution, g.origin, g.shape, frame=traj.start_pose())
    near_truth = cv2.dilate(truth.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    stray = (g.states == OCCUPIED_S) & ~near_truth
    assert stray.sum() < 0.05 * (g.states == OCCUPIED_S).sum()


def test_drift_is_zero_when_configured_so_and_grows_like_a_random_walk():
    _, traj, exact = tour_map("scene2", step_deg=30.0)
    est, true = exact.estimated_pose(), exact.true_pose_in_map(traj.pose_at_displacement(330.0))
    assert est == pytest.approx(tuple(true), abs=1e-12)
    cfg = SlamConfig(drift=DriftConfig(xy_m_per_m=0.02, yaw_deg_per_m=1.0))
    finals = []
    for seed in range(200):
        slam = Slam(cfg, (0.0, 0.0, 0.0), np.random.default_rng(seed))
        for x in np.linspace(0.0, 4.0, 21):  # 4 m in 0.2 m steps
            slam.update((x, 0.0, 0.0), empty_scan())
        finals.append(np.array(slam.estimated_pose()) - [4.0, 0.0, 0.0])
    std = np.std(finals, axis=0)
    assert std[0] == pytest.approx(0.02 * 2.0, rel=0.25) and std[1] == pytest.approx(0.04, rel=0.25)
    assert math.degrees(std[2]) == pytest.approx(1.0 * 2.0, rel=0.25)


def test_same_seed_same_grid():
    cfg = SlamConfig()  # default drift
    laser_cfg = LaserConfig(noise_std_m=0.02, dropout=0.05)
    _, _, a = tour_map("scene1", config=cfg, laser_cfg=laser_cfg, seed=4, step_deg=20.0)
    _, _, b = tour_map("scene1", config=cfg, laser_cfg=laser_cfg, seed=4, step_deg=20.0)
    _, _, c = tour_map("scene1", config=cfg, laser_cfg=laser_cfg, seed=5, step_deg=20.0)
    np.testing.assert_array_equal(a.log_odds, b.log_odds)
    assert a.estimated_pose() == b.estimated_pose() != c.estimated_pose()
    assert not np.array_equal(a.log_odds, c.log_odds)
