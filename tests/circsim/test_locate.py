"""circsim.locate: a robot's map is found in a merged map at the rigid placement it was put at (the
same room seen in another frame), an unrelated map matches far less, and each robot's estimates are the
relative poses of the placements."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from circsim.locate import MATCH_MIN, estimates_from_placements, locate
from merger.grid import FREE_S, OccupancyGrid
from merger.synthetic import arc_viewpoints, partial_view, room_scene


@pytest.fixture(scope="module")
def scene():
    return room_scene(np.random.default_rng(6)), arc_viewpoints(120.0, 50.0, 1.8, k=4)


@pytest.mark.parametrize("pose", [(0.6, -0.4, 35.0), (-1.0, 0.3, 200.0)])
def test_a_map_is_located_at_its_placement_in_the_merged_map(scene, pose):
    """The merged map is the room in the world frame; the robot's map the same room from the same
    viewpoints in the frame of ``pose`` (x, y, yaw°): x_world = R(yaw) x_map + (x, y). The locating is
    exact to about a cell and a few tenths of a degree (the module's claim)."""
    sc, vps = scene
    merged, _ = partial_view(sc, (0.0, 0.0, 0.0), vps, size_m=10.0)
    grid, _ = partial_view(sc, (pose[0], pose[1], math.radians(pose[2])), vps, size_m=10.0)
    f, (yaw, x, y) = locate(grid, merged)
    assert f >= 0.9
    assert abs((yaw - pose[2] + 180) % 360 - 180) <= 0.5
    assert math.hypot(x - pose[0], y - pose[1]) <= 0.05


def test_an_unrelated_map_matches_below_the_floor(scene):
    sc, vps = scene
    merged, _ = partial_view(sc, (0.0, 0.0, 0.0), vps, size_m=10.0)
    other, _ = partial_view(room_scene(np.random.default_rng(99), room=(5.0, 9.0)), (0.0, 0.0, 0.0),
                            arc_viewpoints(0.0, 50.0, 1.8, k=4), size_m=10.0)
    f, _ = locate(other, merged)
    assert f < MATCH_MIN


def test_nothing_to_locate_without_occupied_cells(scene):
    sc, vps = scene
    merged, _ = partial_view(sc, (0.0, 0.0, 0.0), vps, size_m=10.0)
    blank = OccupancyGrid(np.full((20, 20), FREE_S, np.uint8), 0.05, (0.0, 0.0))
    assert locate(blank, merged) is None and locate(merged, blank) is None


def _apply(p, q):
    """The pose (yaw°, x, y) applied to a point: R(yaw) q + (x, y)."""
    a = math.radians(p[0])
    return np.array([math.cos(a) * q[0] - math.sin(a) * q[1] + p[1], math.sin(a) * q[0] + math.cos(a) * q[1] + p[2]])


@settings(max_examples=30, deadline=None)
@given(poses=st.lists(st.tuples(st.floats(0, 359.9), st.floats(-5, 5), st.floats(-5, 5)), min_size=1, max_size=4),
       q=st.tuples(st.floats(-3, 3), st.floats(-3, 3)))
def test_each_robots_estimates_are_the_relative_poses_of_the_placements(poses, q):
    """Robot i's estimate of map j, T_i⁻¹ ∘ T_j, carries a point of map j to where map i has it: both land
    on the same point of the merged frame."""
    placed = {f"r{k}": p for k, p in enumerate(poses)}
    ests = estimates_from_placements(3.5, placed, "here")
    if len(placed) < 2:
        assert ests == []
        return
    assert [e.robot for e in ests] == list(placed) and all(e.t == 3.5 and e.where == "here" for e in ests)
    for e in ests:
        assert set(e.placements) == set(placed) - {e.robot}
        for j, rel in e.placements.items():
            assert 0.0 <= rel[0] < 360.0
            assert _apply(placed[e.robot], _apply(rel, q)) == pytest.approx(_apply(placed[j], q), abs=1e-9)


def test_an_estimate_of_a_tiny_turn_stays_in_0_360():
    ests = estimates_from_placements(0.0, {"a": (1e-300, 0.0, 0.0), "b": (0.0, 0.0, 0.0)})
    assert ests[0].placements["b"][0] < 360.0
