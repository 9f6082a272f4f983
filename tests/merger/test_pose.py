"""merger.pose: a Pose is the rigid motion p_ref = R(yaw)·p + (x, y); its inverse undoes it; the pose of a
placement (θ, t about the centers) maps every point exactly as the placement does."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from merger.pose import IDENTITY, Pose, pose_of_placement

coord = st.floats(-50, 50, allow_nan=False)
angle = st.floats(0, 360, allow_nan=False, exclude_max=True)


def matrix(p: Pose) -> np.ndarray:
    """The homogeneous 3 × 3 matrix of ``p`` written from its definition."""
    a = math.radians(p.yaw_deg)
    return np.array([[math.cos(a), -math.sin(a), p.x], [math.sin(a), math.cos(a), p.y], [0, 0, 1]])


def test_apply_rotates_counter_clockwise_then_translates():
    p = Pose(1.0, 2.0, 90.0)
    np.testing.assert_allclose(p.apply([1.0, 0.0]), [1.0, 3.0], atol=1e-12)  # x axis -> y axis, then shifted
    np.testing.assert_allclose(p.apply([[0.0, 1.0], [0.0, 0.0]]), [[0.0, 2.0], [1.0, 2.0]], atol=1e-12)
    np.testing.assert_array_equal(IDENTITY.apply([[3.5, -1.25]]), [[3.5, -1.25]])


@settings(max_examples=200, deadline=None)
@given(coord, coord, angle, st.lists(st.tuples(coord, coord), min_size=1, max_size=5))
def test_apply_equals_the_homogeneous_matrix_and_inverse_undoes_it(x, y, yaw, pts):
    p = Pose(x, y, yaw)
    pts = np.array(pts)
    want = (matrix(p) @ np.c_[pts, np.ones(len(pts))].T).T[:, :2]
    np.testing.assert_allclose(p.apply(pts), want, atol=1e-9)
    inv = p.inverse()
    assert 0 <= inv.yaw_deg <= 360
    np.testing.assert_allclose(matrix(inv), np.linalg.inv(matrix(p)), atol=1e-9)
    np.testing.assert_allclose(inv.apply(p.apply(pts)), pts, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(angle, coord, coord, coord, coord, coord, coord, st.tuples(coord, coord))
def test_pose_of_placement_places_points_as_the_placement(theta, tx, ty, c0x, c0y, ckx, cky, q):
    """x_0 = c_0 + t + R(θ)(x_k − c_k) for every point x_k of map k."""
    pose = pose_of_placement(theta, (tx, ty), (c0x, c0y), (ckx, cky))
    a = math.radians(theta)
    r = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    want = np.array([c0x + tx, c0y + ty]) + r @ (np.array(q) - np.array([ckx, cky]))
    np.testing.assert_allclose(pose.apply(q), want, atol=1e-9)
    assert pose.yaw_deg == theta % 360.0
    # map k's center lands on the first map's center moved by t
    np.testing.assert_allclose(pose.apply((ckx, cky)), (c0x + tx, c0y + ty), atol=1e-9)


def test_the_first_maps_pose_is_the_identity_and_yaw_wraps():
    assert pose_of_placement(0.0, (0.0, 0.0), (1.2, 0.4), (1.2, 0.4)) == Pose(0.0, 0.0, 0.0)
    assert pose_of_placement(-90.0, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)).yaw_deg == 270.0
    assert Pose(1.0, 2.0, 30.0).to_dict() == {"x": 1.0, "y": 2.0, "yaw_deg": 30.0}


def test_yaw_stays_below_360_for_a_tiny_angle():
    """(−yaw) % 360.0 rounds to 360.0 for a yaw below about 1e-14°, outside the documented [0, 360)."""
    assert Pose(0.0, 0.0, 1e-20).inverse().yaw_deg == 0.0
    assert pose_of_placement(-1e-20, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)).yaw_deg == 0.0
    assert Pose(0.0, 0.0, 30.0).inverse().yaw_deg == 330.0
