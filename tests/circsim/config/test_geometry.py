"""circsim.config.geometry: a scene that would run but never merge is refused, naming the key and what
was expected — a center outside the room, a circle that leaves it, a pillar on a start or on the path, a
wall across the path, a start outside what the walls enclose; offline robots' paths are their arcs only;
the enclosure, the distances to walls and the points along the paths are checked against plain geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from circsim.config.geometry import (
    blocks_path,
    check_geometry,
    enclosure,
    object_reach,
    path_points,
    segment_distances,
)
from circsim.config.types import (
    Box,
    Chair,
    OfflineMotion,
    OverturnedChair,
    Pillar,
    RobotsSpec,
    Room,
    WorldSpec,
)
from circsim.config.validate import Invalid

ROBOTS = RobotsSpec(radius_m=1.5)  # starts at 90°, 210°, 330°; bodies 0.18 m
ROOM = Room(size_m=(8.0, 6.0))  # x [−4, 4], y [−3, 3]
SQUARE = ((-3.0, -3.0, 3.0, -3.0), (3.0, -3.0, 3.0, 3.0), (3.0, 3.0, -3.0, 3.0), (-3.0, 3.0, -3.0, -3.0))


def test_a_sensible_room_passes():
    check_geometry(WorldSpec(room=ROOM, pillars=(Pillar((3.0, 2.0), 0.2),),
                             objects=(Box((-3.0, -2.2), (0.6, 0.4)),)), ROBOTS)
    check_geometry(WorldSpec(room=Room(size_m=None, walls=SQUARE)), ROBOTS)


@pytest.mark.parametrize("world, robots, path, words", [
    (WorldSpec(center=(5.0, 0.0), room=ROOM), ROBOTS, "world.center", "expected a point inside the room"),
    (WorldSpec(center=(2.5, 0.0), room=ROOM), ROBOTS, "robots.radius_m", "stays inside the room"),
    (WorldSpec(room=ROOM), RobotsSpec(radius_m=2.9), "robots.radius_m", "robots.body_radius_m 0.18"),
    (WorldSpec(room=ROOM, pillars=(Pillar((3.9, 0.0), 0.2),)), ROBOTS, "world.pillars[0]",
     "expected inside the room"),
    (WorldSpec(room=ROOM, pillars=(Pillar((0.0, 1.5), 0.2),)), ROBOTS, "world.pillars[0]",
     "expected clear of robot Lyon's start (0.00, 1.50)"),
    (WorldSpec(room=ROOM, objects=(Box((1.5, 0.0), (0.4, 0.4)),)), ROBOTS, "world.objects[0]",
     "stands on the robots' path (online robots drive the whole circle)"),
    (WorldSpec(room=Room(size_m=None, walls=SQUARE + ((1.5, -1.0, 1.5, 1.0),))), ROBOTS, "world.room.walls[4]",
     "expected clear of robot"),
    # walls closing a small box about the center, clear of the path: the robots would start outside it
    (WorldSpec(room=Room(size_m=None, walls=((-0.5, -0.5, 0.5, -0.5), (0.5, -0.5, 0.5, 0.5),
                                             (0.5, 0.5, -0.5, 0.5), (-0.5, 0.5, -0.5, -0.5)))),
     ROBOTS, "robots.radius_m", "(robot Lyon would start at (0.00, 1.50), outside it)"),
])
def test_a_scene_that_cannot_merge_is_refused_naming_the_key(world, robots, path, words):
    with pytest.raises(Invalid) as e:
        check_geometry(world, robots)
    assert e.value.path == path and words in e.value.text and "\n" not in e.value.text


def test_offline_robots_paths_are_their_arcs_only():
    off = RobotsSpec(radius_m=1.5, motion="offline", offline=OfflineMotion(max_deg=15.0))
    # on the circle at 0°: 90° from Lyon (90°), 30° from Nevers (330°) — beyond ±15° and the reach of a
    # disc of 0.1 m with a body of 0.18 m (0.28 m on a 1.5 m circle: 10.7°)
    box = (1.5, 0.0)
    assert blocks_path(box, 0.2, (0.0, 0.0), ROBOTS) is not None  # online: the whole circle
    assert blocks_path(box, 0.1, (0.0, 0.0), off) is None
    check_geometry(WorldSpec(room=ROOM, objects=(Box(box, (0.2, 0.2)),)), off)
    at = (1.5 * math.cos(math.radians(340)), 1.5 * math.sin(math.radians(340)))  # 10° from Nevers' start
    assert blocks_path(at, 0.1, (0.0, 0.0), off) == "robot Nevers's arc (±15° about its start)"
    assert blocks_path((0.0, 0.0), 0.3, (0.0, 0.0), off) is None  # at the center: far from every path
    # 5° past the end of Nevers' arc (330° + 15°): the disc with the body (10.7° of the circle) reaches into it
    past = (1.5 * math.cos(math.radians(350)), 1.5 * math.sin(math.radians(350)))
    assert blocks_path(past, 0.1, (0.0, 0.0), off) == "robot Nevers's arc (±15° about its start)"


def test_object_reach_holds_the_object():
    ch = Chair((0.0, 0.0), leg_spacing_m=0.4, leg_radius_m=0.02)
    assert object_reach(ch) == pytest.approx(math.hypot(0.2, 0.2) + 0.02)  # a leg's far side
    assert object_reach(Box((0.0, 0.0), (0.6, 0.8))) == pytest.approx(0.5)  # half the diagonal
    oc = OverturnedChair((0.0, 0.0))
    assert object_reach(oc) == pytest.approx(math.hypot(oc.seat_m, oc.back_m) / 2)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6))
def test_segment_distances_are_the_nearest_point_distances(seed):
    rng = np.random.default_rng(seed)
    pts, walls = rng.uniform(-3, 3, (5, 2)), rng.uniform(-3, 3, (4, 4))
    d = segment_distances(pts, walls)
    u = np.linspace(0.0, 1.0, 20001)
    for j, (ax, ay, bx, by) in enumerate(walls):
        line = np.stack([ax + u * (bx - ax), ay + u * (by - ay)], 1)
        brute = np.min(np.linalg.norm(pts[:, None] - line[None], axis=-1), axis=1)
        assert d[:, j] == pytest.approx(brute, abs=6 * 1.5e-4 + 1e-9)  # the sampling's own error
        assert np.all(d[:, j] <= brute + 1e-12)


def test_points_along_the_paths_are_on_the_circle_and_close_enough():
    for robots in (ROBOTS, RobotsSpec(radius_m=1.5, motion="offline", offline=OfflineMotion(max_deg=30.0))):
        for n, pts in path_points((0.5, -0.2), robots):
            assert np.hypot(pts[:, 0] - 0.5, pts[:, 1] + 0.2) == pytest.approx(1.5)
            gaps = np.hypot(*np.diff(pts, axis=0).T)
            assert gaps.max() <= robots.body_radius_m / 4 + 1e-9
            arc = math.degrees(gaps.sum() / 1.5)
            assert arc == pytest.approx(360.0 if robots.motion == "online" else 60.0, rel=1e-3), n


def test_the_enclosure_of_closed_and_open_walls():
    inside = enclosure(np.array(SQUARE), (0.5, 0.5))
    assert inside is not None
    assert inside(0.0, 0.0) and inside(2.9, -2.9) and not inside(3.2, 0.0) and not inside(0.0, -4.0)
    inner = np.array([(-1.0, -1.0, 1.0, -1.0), (1.0, -1.0, 1.0, 1.0), (1.0, 1.0, -1.0, 1.0), (-1.0, 1.0, -1.0, -1.0)])
    ring = enclosure(np.vstack([SQUARE, inner]), (2.0, 0.0))  # between the two squares
    assert ring(-2.0, 0.0) and not ring(0.0, 0.0)
    assert enclosure(np.array(SQUARE[:3]), (0.0, 0.0)) is None  # three sides: open
