"""The reference search recovers known rotations (property tests, hypothesis)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import merger
from merger.search import angle_diff_deg, fine_angles, runner_up, wrap_deg
from merger.synthetic import arc_viewpoints, partial_view, room_scene


def test_angle_helpers():
    assert wrap_deg(-0.1) == 359.9 and wrap_deg(360.0) == 0.0
    # a difference of two search angles lands on the 0.1° grid's float, so equal rotations compare equal
    assert wrap_deg(0.0 - 279.3) == 80.7 and wrap_deg(-1e-12) == 0.0 and wrap_deg(359.9999999999) == 0.0
    assert list(wrap_deg(np.array([-279.3, 720.1]))) == [80.7, 0.1]
    assert angle_diff_deg(1.0, 359.0) == 2.0 and angle_diff_deg(180.0, 0.0) == 180.0
    assert len(fine_angles(10.0)) == 21 and fine_angles(10.0)[0] == 9.0
    prof = np.zeros(360)
    prof[[20, 25, 200]] = [1.0, 0.9, 0.5]
    assert runner_up(prof, 20.0) == (200.0, 0.5)  # 25° is within 10° of the best peak


@pytest.mark.slow
@settings(max_examples=10, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), theta=st.floats(0.0, 359.9), arc_shift=st.floats(-20.0, 20.0))
def test_reference_recovers_rotation_of_independent_views(seed, theta, arc_shift):
    """A partial view, and a second partial view of the same scene ray-cast and rasterized anew in a
    frame rotated by θ about the center (viewpoints shifted, 0.2 % cells flipped): θ within 0.5°.

    The scene (room_scene) is not point-symmetric: the room is off-center and boxes break the
    pillars' symmetry, so the true angle is the unique answer and no symmetric alternative is allowed.
    Two independent rasterizations put the objective's own optimum off the truth: over 80 seeds the
    error was ≤ 0.46° with a 10 m ROI (whole room) but reached 0.54° with 8 m and 1.2° with 5 m, so
    this test uses the whole room; smaller ROIs are covered by the warped-map test below.
    """
    roi = 10.0
    rng = np.random.default_rng(seed)
    scene = room_scene(rng)
    a0 = rng.uniform(0, 360)
    yaw_a = rng.uniform(0, 2 * math.pi)
    frame_a = (rng.uniform(-1, 1), rng.uniform(-1, 1), yaw_a)
    frame_b = (rng.uniform(-1, 1), rng.uniform(-1, 1), yaw_a + math.radians(theta))
    ga, ca = partial_view(scene, frame_a, arc_viewpoints(a0, 30, 1.8), noise=0.002, rng=rng)
    gb, cb = partial_view(scene, frame_b, arc_viewpoints(a0 + arc_shift, 30, 1.8), noise=0.002, rng=rng)
    al = merger.search_pair(ga, gb, center_ref=ca, center_moving=cb, roi_m=roi, method="reference")
    assert abs(angle_diff_deg(al.theta_deg, theta)) <= 0.5
    assert al.score > al.runner_up_score
    assert al.profile.shape == (360,)


@pytest.mark.slow
@settings(max_examples=15, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), theta=st.floats(0.0, 359.9), roi=st.sampled_from([5.0, 6.4, 8.0]),
       shift=st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)))
def test_reference_recovers_known_rotation_of_a_map(seed, theta, roi, shift):
    """A map rotated by a known θ about its center into another frame (nearest neighbour), cut to a
    part of it and noised (0.2 % flips): θ is recovered within 0.5°."""
    from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid
    from merger.transform import warp_grid

    rng = np.random.default_rng(seed)
    scene = room_scene(rng)
    a0 = rng.uniform(0, 360)
    ga, ca = partial_view(scene, (0.3, -0.2, 0.4), arc_viewpoints(a0, 45, 1.8), noise=0.002, rng=rng)
    cb = (ca[0] + shift[0], ca[1] + shift[1])
    target = OccupancyGrid.unknown(260, 260, 0.05, (-6.5, -6.5))
    s = warp_grid(ga, -theta, ca, cb, target).states.copy()  # x_b = c_b + R(−θ)(x_a − c_a)
    keep = np.arange(s.shape[1])[None, :] < s.shape[1] * rng.uniform(0.55, 0.8)  # a part of the map
    s[~np.broadcast_to(keep, s.shape)] = 0
    known = np.flatnonzero(s.ravel() > 0)
    flip = rng.choice(known, size=known.size // 500, replace=False)
    s.ravel()[flip] = np.where(s.ravel()[flip] == FREE_S, OCCUPIED_S, FREE_S)
    gb = OccupancyGrid(s, 0.05, target.origin)
    al = merger.search_pair(ga, gb, center_ref=ca, center_moving=cb, roi_m=roi, method="reference")
    assert abs(angle_diff_deg(al.theta_deg, theta)) <= 0.5
