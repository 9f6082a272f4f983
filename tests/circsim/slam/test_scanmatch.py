"""circsim.slam.scanmatch: a scan cast from a known pose in a known room, matched to the room's map from a
wrong prediction, comes back to the true pose; a scan's points and their wall normals; Cartographer's
angular step; a featureless map keeps the prediction; the same inputs give the same pose."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from circsim.slam.scanmatch import HitMeans, Match, angular_step, match, scan_points
from merger.synthetic import Scene, ray_cast, rectangle_segments

RES, CLAMP = 0.05, 3.5
ORIGIN = (-5.0, -5.0)
N = 200  # 10 m square
BEAMS = 360
ANGLE_MIN, INC = -math.pi, 2 * math.pi / BEAMS
# an off-centre room with a turned box: no symmetry to slide along
SCENE = Scene(np.concatenate([rectangle_segments(0.3, 0.2, 7.0, 5.0), rectangle_segments(1.2, -0.8, 0.6, 0.4, 25.0),
                              rectangle_segments(-1.5, 1.0, 0.5, 0.5, 10.0)]), np.zeros((0, 3)))


def _scan(pose):
    """Ranges of a 360-beam scan from ``pose`` (robot frame: beam i at angle_min + i·inc)."""
    a = pose[2] + ANGLE_MIN + INC * np.arange(BEAMS)
    return ray_cast(SCENE, pose[:2], a, 8.0)


@pytest.fixture(scope="module")
def room_map():
    """The room's map as SLAM would have it: the hit cells at the clamp, with their mean hits, from scans
    of 720 beams at a few places."""
    lo = np.zeros((N, N))
    hits = HitMeans((N, N))
    for vp in [(0.0, 0.0), (1.5, 1.0), (-1.5, -1.0), (2.0, -1.5)]:
        a = np.linspace(-math.pi, math.pi, 720, endpoint=False)
        r = ray_cast(SCENE, vp, a, 8.0)
        ok = np.isfinite(r)
        x, y = vp[0] + r[ok] * np.cos(a[ok]), vp[1] + r[ok] * np.sin(a[ok])
        cols = np.floor((x - ORIGIN[0]) / RES).astype(np.int64)
        rows = np.floor((y - ORIGIN[1]) / RES).astype(np.int64)
        lo[rows, cols] = CLAMP
        hits.add(rows, cols, x, y)
    return lo, hits


def _match(room_map, truth, pred, **kw):
    lo, hits = room_map
    px, py, nx, ny = scan_points(_scan(truth), ANGLE_MIN, INC, 0.1, 300)
    return match(lo, hits, ORIGIN, RES, CLAMP, px, py, nx, ny, pred, kw.get("lin", 0.2), kw.get("ang", 0.06),
                 kw.get("wt", 1.0), kw.get("wr", 1.0))


@settings(max_examples=8, deadline=None, derandomize=True)
@given(x=st.floats(-1.0, 1.0), y=st.floats(-0.8, 0.8), yaw=st.floats(-math.pi, math.pi),
       dx=st.floats(-0.12, 0.12), dy=st.floats(-0.12, 0.12), dth=st.floats(-0.04, 0.04))
def test_a_scan_matched_from_a_wrong_prediction_returns_to_the_true_pose(room_map, x, y, yaw, dx, dy, dth):
    """The prediction off by up to 12 cm and 2.3° (inside the ±20 cm, ±3.4° window): the matched pose
    within 1 cm and 0.3° of the pose the scan was cast from."""
    m = _match(room_map, (x, y, yaw), (x + dx, y + dy, yaw + dth))
    assert isinstance(m, Match)
    assert math.hypot(m.x - x, m.y - y) <= 0.01, (m, (x, y, yaw))
    assert abs((m.yaw - yaw + math.pi) % (2 * math.pi) - math.pi) <= math.radians(0.3)
    assert 0.5 < m.score <= 1.0 and m.fit < 0.1  # most points on walls, within a tenth of a cell²


def test_the_same_inputs_give_the_same_pose(room_map):
    a = _match(room_map, (0.3, -0.2, 1.0), (0.38, -0.25, 1.03))
    b = _match(room_map, (0.3, -0.2, 1.0), (0.38, -0.25, 1.03))
    assert a == b


def test_without_points_or_walls_the_prediction_stands(room_map):
    lo, hits = room_map
    e = np.zeros(0)
    m = match(lo, hits, ORIGIN, RES, CLAMP, e, e, e, e, (0.4, 0.5, 0.6), 0.2, 0.06, 1.0, 1.0)
    assert (m.x, m.y, m.yaw, m.score) == (0.4, 0.5, 0.6, 0.0)
    # an empty map: nothing to match, the prior holds the prediction
    px, py, nx, ny = scan_points(_scan((0.0, 0.0, 0.0)), ANGLE_MIN, INC, 0.1, 300)
    m = match(np.zeros((N, N)), HitMeans((N, N)), ORIGIN, RES, CLAMP, px, py, nx, ny, (0.1, 0.2, 0.3), 0.2, 0.06,
              1.0, 1.0)
    assert (m.x, m.y, m.yaw) == pytest.approx((0.1, 0.2, 0.3), abs=1e-12) and m.score == 0.0


def test_scan_points_lie_on_the_returns_with_the_walls_normals():
    """A robot 1 m from a long wall x = 1 facing it: points at r·(cos a, sin a), the normals of the wall
    (±1, 0); invalid and too-short returns dropped; at most max_points, every k-th."""
    a = np.radians(np.linspace(-40, 40, 81))
    r = 1.0 / np.cos(a)
    r[5] = np.inf
    r[6] = 0.05  # below range_min
    px, py, nx, ny = scan_points(r, float(a[0]), float(a[1] - a[0]), 0.1, 1000)
    valid = np.isfinite(r) & (r >= 0.1)
    assert px.size == valid.sum() == 79
    assert np.allclose(px, 1.0) and np.allclose(py, np.tan(a[valid]))
    has = (nx != 0) | (ny != 0)
    assert has.sum() >= 60  # all but the ends and the neighbours of the gaps
    assert np.allclose(np.abs(nx[has]), 1.0) and np.allclose(ny[has], 0.0, atol=1e-9)
    px2, *_ = scan_points(r, float(a[0]), float(a[1] - a[0]), 0.1, 20)
    assert px2.size <= 20 and np.array_equal(py[::4][:px2.size], scan_points(r, float(a[0]), float(a[1] - a[0]), 0.1, 20)[1])


def test_no_normal_across_a_gap_between_surfaces():
    """Returns 0.5 m apart (two surfaces at different depths): no normal where a neighbour is beyond the gap."""
    a = np.radians(np.linspace(-10, 10, 21))
    r = np.where(np.arange(21) < 10, 1.0, 1.5) / np.cos(a)
    _, _, nx, ny = scan_points(r, float(a[0]), float(a[1] - a[0]), 0.1, 100)
    for i in (8, 9, 10, 11):  # within two beams of the depth step
        assert nx[i] == 0.0 and ny[i] == 0.0


@pytest.mark.parametrize("res, d", [(0.05, 6.0), (0.05, 1.0), (0.1, 3.0)])
def test_the_angular_step_moves_the_farthest_point_by_one_cell(res, d):
    step = angular_step(res, d)
    assert 2 * d * math.sin(step / 2) == pytest.approx(res, rel=1e-9)  # the chord of the farthest point
    assert angular_step(res, res / 10) == angular_step(res, res)  # a point nearer than a cell: one cell's
