"""The pymunk world and the laser: analytic ranges, own-body exclusion, numpy == pymunk."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.config.types import LaserConfig
from circsim.world import laser
from circsim.world.laser import raycast, scan
from circsim.world.motion import trajectories
from circsim.world.world import World

BODY = 0.18


def square_room(half: float = 2.0) -> World:
    w = World()
    c = [(-half, -half), (half, -half), (half, half), (-half, half)]
    for i in range(4):
        w.add_wall(c[i], c[(i + 1) % 4])
    return w


def analytic_square(x, y, angles, half):
    """Distance from (x, y) along each angle to the walls of the square [-half, half]^2."""
    c, s = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (half - x) / c, np.where(c < 0, (-half - x) / c, np.inf))
        ty = np.where(s > 0, (half - y) / s, np.where(s < 0, (-half - y) / s, np.inf))
    return np.minimum(tx, ty)


def scene(name="scene1"):
    sc = load_scenario(bundled_scenarios()[name])
    return sc, World.from_scenario(sc)


@pytest.mark.parametrize("method", laser.METHODS)
def test_ranges_in_square_room_equal_analytic_distances(method):
    w = square_room(2.0)
    w.add_robot("r", BODY, (0.3, -0.4, 0.7))
    cfg = LaserConfig(fov_deg=360, beams=360, range_max_m=10.0, noise_std_m=0.0)
    x, y, yaw = 0.3, -0.4, 0.7
    got = laser.cast(w, "r", (x, y, yaw), cfg, method=method)
    want = analytic_square(x, y, yaw + cfg.angles(), 2.0)
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_out_of_range_is_inf_and_too_close_is_minus_inf():
    w = square_room(2.0)
    w.add_robot("r", BODY)
    far = scan(w, "r", (0.0, 0.0, 0.0), np.random.default_rng(0),
               config=LaserConfig(fov_deg=90, beams=5, range_max_m=1.5, noise_std_m=0.0))
    assert np.all(np.isposinf(far.ranges))
    w.add_circle((0.5, 0.0), 0.49)
    close = scan(w, "r", (0.0, 0.0, 0.0), np.random.default_rng(0),
                 config=LaserConfig(fov_deg=10, beams=3, range_min_m=0.05, noise_std_m=0.0))
    assert np.isneginf(close.ranges[1])


def test_scan_is_a_ros_laserscan():
    sc, w = scene()
    pose = w.robot_pose("Lyon")
    s = scan(w, "Lyon", pose, np.random.default_rng(0), config=sc.laser, stamp=1.5)
    assert len(s.ranges) == sc.laser.beams == 667
    assert math.isclose(s.angle_min, -math.radians(120)) and math.isclose(s.angle_max, math.radians(120))
    assert math.isclose(math.degrees(s.angle_increment), 0.36, abs_tol=0.001)
    assert s.stamp == 1.5 and s.frame_id == "Lyon" and s.range_max == 5.6
    assert s.points().shape == (np.isfinite(s.ranges).sum(), 2)


@pytest.mark.parametrize("method", laser.METHODS)
def test_own_body_is_never_hit_other_bodies_are(method):
    w = square_room(3.0)
    w.add_robot("a", BODY, (0.0, 0.0, 0.0))
    w.add_robot("b", BODY, (1.0, 0.0, 0.0))
    cfg = LaserConfig(fov_deg=360, beams=720, range_max_m=10.0, noise_std_m=0.0)
    for origin in [(0.0, 0.0), (0.1, 0.05), (-0.12, 0.1)]:  # rays start inside a's own circle
        r = laser.cast(w, "a", (*origin, 0.3), cfg, method=method)
        assert r.min() > 0.5
    front = laser.cast(w, "a", (0.0, 0.0, 0.0), LaserConfig(fov_deg=1, beams=3, noise_std_m=0.0), method=method)
    assert front[1] == pytest.approx(1.0 - BODY, abs=1e-9)
    # b moved: queries see the new pose at once (shapes are reindexed)
    w.set_robot_pose("b", 0.0, 1.0, 0.0)
    front = laser.cast(w, "a", (0.0, 0.0, 0.0), LaserConfig(fov_deg=1, beams=3, noise_std_m=0.0), method=method)
    assert front[1] == pytest.approx(3.0, abs=1e-9)


def random_free_poses(w: World, rng, n, margin=0.25):
    out = []
    while len(out) < n:
        x, y = rng.uniform(-3.5, 3.5), rng.uniform(-2.8, 2.8)
        if w.clearance((x, y)) > margin:
            out.append((x, y, rng.uniform(-math.pi, math.pi)))
    return out


def dist_to_geometry(geo, pts):
    """Distance from each point to the nearest obstacle surface."""
    d = np.full(len(pts), np.inf)
    for ax, ay, bx, by in geo.segments:
        v = np.array([bx - ax, by - ay])
        t = np.clip(((pts - [ax, ay]) @ v) / (v @ v), 0, 1)
        d = np.minimum(d, np.linalg.norm(pts - ([ax, ay] + t[:, None] * v), axis=1))
    for cx, cy, r in geo.circles:
        d = np.minimum(d, np.abs(np.linalg.norm(pts - [cx, cy], axis=1) - r))
    return d


@pytest.mark.parametrize("cfg", [LaserConfig(), LaserConfig(fov_deg=360, beams=400, range_max_m=8.0)])
def test_numpy_equals_pymunk_on_random_poses_in_scene1(cfg):
    sc, w = scene("scene1")
    rng = np.random.default_rng(7)
    poses = random_free_poses(w, rng, 60)
    for k, pose in enumerate(poses):
        # the other robots stand somewhere on their circle, in view of the observer
        for name, traj in trajectories(sc).items():
            w.set_robot_pose(name, *traj.pose_at_displacement(rng.uniform(-180, 180)))
        name = sc.robots.names[k % 3]
        a = laser.cast(w, name, pose, cfg, method="numpy")
        b = laser.cast(w, name, pose, cfg, method="pymunk")
        assert np.array_equal(np.isinf(a), np.isinf(b))
        fin = np.isfinite(a)
        assert np.abs(a[fin] - b[fin]).max(initial=0.0) <= 1e-9


@settings(max_examples=60, deadline=None)
@given(x=st.floats(-3.0, 3.0), y=st.floats(-2.5, 2.5), yaw=st.floats(-math.pi, math.pi),
       fov=st.floats(1.0, 360.0), beams=st.integers(2, 200))
def test_numpy_equals_pymunk_property(x, y, yaw, fov, beams):
    w = SCENE2_WORLD
    assume(w.clearance((x, y)) > 1e-6)  # a laser inside a box is no valid pose
    cfg = LaserConfig(fov_deg=fov, beams=beams, noise_std_m=0.0)
    a = laser.cast(w, "Lyon", (x, y, yaw), cfg, method="numpy")
    b = laser.cast(w, "Lyon", (x, y, yaw), cfg, method="pymunk")
    assert np.array_equal(np.isinf(a), np.isinf(b))
    fin = np.isfinite(a)
    assert np.abs(a[fin] - b[fin]).max(initial=0.0) <= 1e-9


SCENE2_WORLD = scene("scene2")[1]


def test_raycast_handles_arcs_wrapping_past_the_first_beam():
    # a circle straddling the direction of beam 0 of a full-turn scan
    start, inc = -0.001, 2 * math.pi / 100
    got = raycast((0.0, 0.0), start, inc, 100, 5.0, np.zeros((0, 4)), np.array([[2.0, 0.0, 0.3]]))
    a = start + np.arange(100) * inc
    with np.errstate(invalid="ignore"):
        want = 2.0 * np.cos(a) - np.sqrt(0.09 - (2.0 * np.sin(a)) ** 2)
    want[np.isnan(want) | (np.cos(a) < 0)] = np.inf
    assert np.isfinite(want[[0, 1, 98, 99]]).all()
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_noise_and_dropout_are_seeded():
    sc, w = scene()
    cfg = LaserConfig(noise_std_m=0.02, dropout=0.1)
    pose = w.robot_pose("Auckland")
    a = scan(w, "Auckland", pose, np.random.default_rng(3), config=cfg)
    b = scan(w, "Auckland", pose, np.random.default_rng(3), config=cfg)
    c = scan(w, "Auckland", pose, np.random.default_rng(4), config=cfg)
    np.testing.assert_array_equal(a.ranges, b.ranges)
    assert not np.array_equal(np.nan_to_num(a.ranges), np.nan_to_num(c.ranges))
    assert 0.05 < np.isnan(a.ranges).mean() < 0.15
    exact = laser.cast(w, "Auckland", pose, cfg)
    ok = np.isfinite(a.ranges)
    err = a.ranges[ok] - exact[ok]
    assert 0.015 < err.std() < 0.025 and np.all(a.ranges[ok] <= cfg.range_max_m)


@pytest.mark.parametrize("name", ["scene1", "scene2"])
def test_bundled_scenes_robots_clear_obstacles_and_see_walls(name):
    sc, w = scene(name)
    geo = w.geometry()
    for n, traj in trajectories(sc).items():
        poses = [traj.pose_at_displacement(d) for d in np.arange(0.0, 360.0, 5.0)]
        xy = np.array([p[:2] for p in poses])
        assert dist_to_geometry(geo, xy).min() > sc.robots.body_radius_m + 0.05
        for p in poses[::6]:
            r = laser.cast(w, n, p, sc.laser)
            assert np.isfinite(r).mean() > 0.8  # the 5.6 m laser sees the walls from the circle


def test_geometry_reads_the_pymunk_shapes():
    sc, w = scene("scene1")
    geo = w.geometry()
    # 4 walls + the overturned chair's seat and back; 2 pillars + 3 chairs x 4 legs
    assert geo.segments.shape == (6, 4) and geo.circles.shape == (14, 3)
    with_robots = w.geometry(include_robots=True, exclude="Lyon")
    assert with_robots.circles.shape == (16, 3)
    boxes = scene("scene2")[1].geometry()
    assert boxes.segments.shape == (4 + 16, 4)


def test_rasterize_truth_marks_surfaces():
    w = square_room(1.0)
    w.add_circle((0.0, 0.0), 0.2)
    t = w.rasterize_truth(0.1, (-1.52, -1.52), (30, 30))
    assert t[5, 6:24].all() and t[6:24, 5].all()  # walls y = -1 (row 5), x = -1 (col 5)
    assert t[6:13, 6:24].sum() == 0  # nothing between the wall and the circle
    assert t[13, 15] and not t[15, 15]  # the circle's rim, not its inside
    # in the frame of a robot at (1, 0) facing +y, the wall x = -1 lies at y' = 2
    rot = w.rasterize_truth(0.1, (-1.52, -0.55), (30, 30), frame=(1.0, 0.0, math.pi / 2))
    assert rot[25, 6:24].all()
