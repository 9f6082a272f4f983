"""The ring the team drives, left out of the pairs' evidence (merger.team.teammates)."""

import math

import numpy as np
import pytest

from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid
from merger.team.params import MapInput, MergeParams
from merger.team.teammates import ring, without_teammates

RES = 0.05


def _map(states, center=(3.0, 3.0), trajectory=None):
    return MapInput("A", OccupancyGrid(states, RES, (0.0, 0.0)), center, trajectory=trajectory)


def _circle_path(radius, center=(3.0, 3.0), arc_deg=40.0, n=20, start_deg=0.0):
    a = np.radians(np.linspace(start_deg, start_deg + arc_deg, n))
    return np.c_[np.arange(n) * 0.1, center[0] + radius * np.cos(a), center[1] + radius * np.sin(a)]


def _distance_of_cells(shape, center):
    h, w = shape
    xs = (np.arange(w) + 0.5) * RES - center[0]
    ys = (np.arange(h) + 0.5) * RES - center[1]
    return np.hypot(xs[None, :], ys[:, None])


def test_the_ring_is_the_paths_radii_widened_by_the_body_and_half_the_window():
    m = _map(np.zeros((120, 120), np.uint8), trajectory=_circle_path(2.0))
    lo, hi = ring(m, 0.2, 0.5)
    assert lo == pytest.approx(2.0 - 0.45) and hi == pytest.approx(2.0 + 0.45)
    assert ring(m, 0.2, 0.0) == pytest.approx((1.8, 2.2))


def test_no_ring_without_a_path_with_the_setting_off_or_for_a_path_that_is_no_circle():
    states = np.full((120, 120), OCCUPIED_S, np.uint8)
    assert ring(_map(states), 0.2, 0.5) is None
    assert ring(_map(states, trajectory=_circle_path(2.0)), 0.0, 0.5) is None
    wander = np.c_[np.arange(5.0), [3.0, 3.5, 4.0, 4.5, 5.5], [3.0] * 5]  # from the center out to 2.5 m
    assert ring(_map(states, trajectory=wander), 0.2, 0.5) is None
    m = _map(states, trajectory=wander)
    assert without_teammates(m, 0.2, 0.5) is m


def test_occupied_cells_on_the_ring_become_unknown_and_nothing_else_changes():
    rng = np.random.default_rng(3)
    states = rng.choice([UNKNOWN_S, FREE_S, OCCUPIED_S], size=(120, 120)).astype(np.uint8)
    m = _map(states, trajectory=_circle_path(2.0))
    out = without_teammates(m, 0.2, 0.5)
    d = _distance_of_cells(states.shape, m.center)
    on = (d >= 1.55) & (d <= 2.45)
    assert (out.grid.states[on & (states == OCCUPIED_S)] == UNKNOWN_S).all()
    assert (out.grid.states[on & (states != OCCUPIED_S)] == states[on & (states != OCCUPIED_S)]).all()
    assert (out.grid.states[~on] == states[~on]).all()
    assert (m.grid.states == states).all()  # the caller's map is not written
    assert (out.name, out.center, out.grid.origin, out.grid.resolution) == ("A", m.center, (0.0, 0.0), RES)


def test_the_ring_is_the_same_whatever_the_maps_rotation_about_the_center():
    """A rotation about the center maps the ring onto itself: one mask serves every hypothesis."""
    m = _map(np.zeros((120, 120), np.uint8), trajectory=_circle_path(2.0))
    turned = _map(np.zeros((120, 120), np.uint8), trajectory=_circle_path(2.0, start_deg=137.0))
    assert ring(m, 0.2, 0.5) == pytest.approx(ring(turned, 0.2, 0.5))


def test_the_setting_is_checked():
    assert MergeParams().teammate_radius_m == 0.0  # off by default (the module's notes)
    for bad in (-0.1, math.nan, True):
        with pytest.raises(ValueError, match="teammate_radius_m"):
            MergeParams(teammate_radius_m=bad)


def test_a_teammate_seen_from_both_sides_of_the_circle_is_gone_from_both_maps():
    """Two maps of one body on the circle, one face each (as robots across the circle see it): both
    faces are left out, the walls are kept."""
    center = (3.0, 3.0)
    d = _distance_of_cells((120, 120), center)
    states = np.full((120, 120), FREE_S, np.uint8)
    states[5, :] = OCCUPIED_S  # a wall 2.75 m below the center, off the ring
    body = (2.0 * math.cos(1.0) + center[0], 2.0 * math.sin(1.0) + center[1])
    xs, ys = np.meshgrid((np.arange(120) + 0.5) * RES, (np.arange(120) + 0.5) * RES)
    rim = np.abs(np.hypot(xs - body[0], ys - body[1]) - 0.18) < RES
    near, far = rim & (d < 2.0), rim & (d >= 2.0)
    for face in (near, far):
        s = states.copy()
        s[face] = OCCUPIED_S
        out = without_teammates(_map(s, center, _circle_path(2.0, center, start_deg=200.0)), 0.2, 0.5)
        assert not (out.grid.states[face] == OCCUPIED_S).any()
        assert (out.grid.states[5, :] == OCCUPIED_S).all()


def _walls(box: bool) -> OccupancyGrid:
    """A 10 x 10 m map, free inside two long walls 1 m either side of the center (5, 5); with ``box``, a
    0.6 m box between them fixes the position along the walls."""
    s = np.full((200, 200), FREE_S, np.uint8)
    s[[79, 80, 119, 120], :] = OCCUPIED_S
    if box:
        s[95:107, 60:72] = OCCUPIED_S
    return OccupancyGrid(s, RES, (0.0, 0.0))


@pytest.mark.parametrize("box", [False, True])
def test_a_slide_along_two_walls_is_a_translation_ridge_and_a_box_ends_it(box):
    from merger.search import RotationProblem, search
    from merger.team.ambiguity import ridge

    g = _walls(box)
    prob = RotationProblem(g, g, (5.0, 5.0), (5.0, 5.0), 8.0, "similarity", 0.5, False, 50)
    al = search(prob, "fast")
    assert abs(al.translation_m[1]) < 1e-9 and (box is False or abs(al.translation_m[0]) < 1e-9)
    why = ridge(prob, al, 0.05)
    assert (why != "") is (not box), why
    assert ridge(prob, al, 0.0) == ""  # no margin: off


def _face(states_shape, body, seen_from, radius=0.18):
    """The cells of a round body's rim that a robot at ``seen_from`` sees (normals within 60° of it)."""
    h, w = states_shape
    xs, ys = np.meshgrid((np.arange(w) + 0.5) * RES, (np.arange(h) + 0.5) * RES)
    rim = np.abs(np.hypot(xs - body[0], ys - body[1]) - radius) < RES / 2
    to = np.array(seen_from, float) - body
    to /= np.linalg.norm(to)
    return rim & (((xs - body[0]) * to[0] + (ys - body[1]) * to[1]) / radius > math.cos(math.radians(60)))


def _centroid(mask):
    r, c = np.nonzero(mask)
    return np.array([(c.mean() + 0.5) * RES, (r.mean() + 0.5) * RES])


@pytest.mark.parametrize("seen_from_deg", [200.0, 330.0, 20.0])
def test_centring_moves_a_teammates_face_towards_its_body_along_the_line_of_sight(seen_from_deg):
    """A teammate on the circle, seen from across it (200°) and from the side (330°, 20°): its face's cells
    move ``shift`` along the line of sight from the robot's path, towards the body's centre."""
    from merger.team.teammates import teammates_centred

    center = np.array([3.0, 3.0])
    body = center + 2.0 * np.array([math.cos(1.0), math.sin(1.0)])
    path = _circle_path(2.0, tuple(center), arc_deg=10.0, start_deg=seen_from_deg - 5.0)
    seen = path[-1, 1:3]
    states = np.full((120, 120), FREE_S, np.uint8)
    states[5, :] = OCCUPIED_S  # a wall off the ring
    face = _face(states.shape, body, seen)
    states[face] = OCCUPIED_S
    out = teammates_centred(_map(states, tuple(center), path), 0.09, 0.5)
    moved = out.grid.states == OCCUPIED_S
    moved[5, :] = False
    before, after = _centroid(face), _centroid(moved)
    sight = (before - seen) / np.linalg.norm(before - seen)
    assert np.dot(after - before, sight) == pytest.approx(0.09, abs=RES / 2)
    assert np.linalg.norm(after - body) < np.linalg.norm(before - body)
    assert (out.grid.states[5, :] == OCCUPIED_S).all()  # off the ring: as it was
    left = face & ~moved
    assert (out.grid.states[left] == UNKNOWN_S).all()  # where the face was is unknown, not free
    assert (states[face] == OCCUPIED_S).all()  # the caller's map is not written


def test_centring_needs_a_path_that_circles_the_center():
    from merger.team.teammates import teammates_centred

    states = np.full((120, 120), OCCUPIED_S, np.uint8)
    m = _map(states)
    assert teammates_centred(m, 0.09, 0.5) is m
    wander = np.c_[np.arange(5.0), [3.0, 3.5, 4.0, 4.5, 5.5], [3.0] * 5]
    m = _map(states, trajectory=wander)
    assert teammates_centred(m, 0.09, 0.5) is m
    m = _map(np.full((120, 120), FREE_S, np.uint8), trajectory=_circle_path(2.0))
    assert teammates_centred(m, 0.09, 0.5) is m  # nothing on the ring


def test_the_shift_is_checked():
    for bad in (-0.1, math.nan, True, 2.0):
        with pytest.raises(ValueError, match="teammate_shift_m"):
            MergeParams(teammate_shift_m=bad)


@pytest.mark.parametrize("arc_deg", [40.0, -40.0])
def test_moved_on_in_time_a_teammates_face_turns_about_the_center_as_the_robot_does(arc_deg):
    """``until`` later than the map's instant: the centred face turns about the center as far as the map's
    robot turns in that time (the team drives its circle together), either way round; at the map's own
    instant (or earlier) nothing more moves."""
    from merger.team.teammates import angular_speed, teammates_centred

    center = np.array([3.0, 3.0])
    body = center + 2.0 * np.array([math.cos(1.0), math.sin(1.0)])
    path = _circle_path(2.0, tuple(center), arc_deg=arc_deg, start_deg=200.0)  # 20 rows, 0.1 s apart
    states = np.full((120, 120), FREE_S, np.uint8)
    face = _face(states.shape, body, path[-1, 1:3])
    states[face] = OCCUPIED_S
    m = _map(states, tuple(center), path)
    omega = angular_speed(m)
    assert omega == pytest.approx(math.radians(arc_deg) / 1.9, rel=1e-9)
    now = teammates_centred(m, 0.09, 0.5)
    assert (teammates_centred(m, 0.09, 0.5, float(path[-1, 0])).grid.states == now.grid.states).all()
    assert (teammates_centred(m, 0.09, 0.5, 0.5).grid.states == now.grid.states).all()
    later = teammates_centred(m, 0.09, 0.5, float(path[-1, 0]) + 0.8)

    def bearing(g):
        c = _centroid(g.states == OCCUPIED_S) - center
        return math.atan2(c[1], c[0])
    turned = (bearing(later.grid) - bearing(now.grid) + math.pi) % (2 * math.pi) - math.pi
    assert math.degrees(turned) == pytest.approx(math.degrees(omega * 0.8), abs=math.degrees(RES / 2.0))
    assert (states[face] == OCCUPIED_S).all()  # the caller's map is not written


def test_the_angular_speed_is_the_paths_last_second_about_the_center():
    from merger.team.teammates import angular_speed, map_time

    center = (3.0, 3.0)
    slow = _circle_path(2.0, center, arc_deg=5.0, n=11)  # 1 s, 5°
    fast = _circle_path(2.0, center, arc_deg=30.0, n=21, start_deg=5.0)[1:]  # 2 s more, 30°
    fast[:, 0] += 1.0
    path = np.r_[slow, fast]
    assert angular_speed(_map(np.zeros((120, 120), np.uint8), center, path)) == pytest.approx(math.radians(15.0))
    assert angular_speed(_map(np.zeros((120, 120), np.uint8), center, path[:1])) == 0.0  # not yet moved
    assert angular_speed(_map(np.zeros((120, 120), np.uint8), center)) == 0.0  # no path
    assert map_time(_map(np.zeros((120, 120), np.uint8), center, path)) == pytest.approx(3.0)
    assert map_time(_map(np.zeros((120, 120), np.uint8), center)) is None
