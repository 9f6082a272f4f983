"""The scenario sections' checks (circsim.config.schema): the physical ranges, their sources and their extremes."""

import math

import numpy as np
import pytest

from circsim.config.scenario import ScenarioError, bundled_scenarios, load_scenario
from circsim.config.schema import (
    MAX_SPEED_MPS,
    MIN_BODY_RADIUS_M,
    center_error_section,
    robots_section,
    world_section,
)
from circsim.config.types import Box, Chair, Room
from circsim.config.validate import Invalid


# issue 37, items 2 and 3: values inside the old ranges that hung or meant nothing physical
@pytest.mark.parametrize("sets, needle", [
    (["laser.noise_std_m=1e6"], "laser.noise_std_m: expected a number in [0, 0.2], got 1000000.0"),  # 19 false merges
    ([f"slam.odometry.alpha{k}=1e6" for k in range(1, 6)], "slam.odometry.alpha1: expected a number in [0, 0.2]"),
    (["laser.range_max_m=1e-9"], "laser.range_max_m: expected a number in [1, 100]"),  # the robots mapped nothing
    (["laser.dropout=0.99"], "laser.dropout: expected a number in [0, 0.5]"),
    (["laser.noise_rel=0.9"], "laser.noise_rel: expected a number in [0, 0.1]"),
    (["slam.resolution_m=1e-6"], "slam.resolution_m: expected a number in [0.01, 0.5]"),
    (["slam.drift.yaw_deg_per_m=90"], "slam.drift.yaw_deg_per_m: expected a number in [0, 5.7]"),
    # the hang: 5 s of scan matching with these windows had not finished after 180 s
    (["slam.matcher.linear_window_m=100"], "slam.matcher.linear_window_m: expected a number in [0, 0.5]"),
    (["slam.matcher.angular_window_deg=180"], "slam.matcher.angular_window_deg: expected a number in [0, 45]"),
    # 10⁶ ticks of 1 µs (the old cap) had not finished after 540 s
    (["duration_s=1", "dt_s=1e-6"], "dt_s: expected a number in [0.01, 1], got 1e-06"),
])
def test_settings_no_real_robot_has_are_refused(sets, needle):
    sc = load_scenario(bundled_scenarios()["scene1"])
    with pytest.raises(ScenarioError) as e:
        sc.with_overrides(["slam.model=scan_matching", *sets])
    assert needle in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_the_physical_ranges_cite_their_source_in_the_reference():
    from circsim.config.reference_doc import scenario_reference

    rows = {ln.split("|")[1].strip(" `"): ln for ln in scenario_reference().splitlines() if ln.startswith("| `")}
    for key in ("dt_s", "laser.range_max_m", "laser.range_min_m", "laser.noise_std_m", "laser.noise_rel",
                "laser.dropout", "slam.resolution_m", "slam.odometry.alpha1", "slam.odometry.alpha5",
                "slam.matcher.linear_window_m", "slam.matcher.angular_window_deg", "slam.drift.xy_m_per_m"):
        assert " — " in rows[key], rows[key]


def test_the_extremes_of_the_ranges_run():
    """The worst allowed SLAM work (every alpha, both matcher windows and the tick at their caps, the fastest
    robots) runs and stays a SLAM: 2 simulated seconds, the pose errors bounded by the caps' meaning."""
    from circsim.sim import Simulation

    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(
        ["slam.model=scan_matching", "duration_s=2", "dt_s=1", "robots.speed_mps=2",
         *[f"slam.odometry.alpha{k}=0.2" for k in range(1, 6)],
         "slam.matcher.linear_window_m=0.5", "slam.matcher.angular_window_deg=45", "laser.noise_std_m=0.2"])
    res = Simulation(sc).run()
    assert res.sim_s == 2.0 and set(res.robots) == {"Lyon", "Auckland", "Nevers"}


# --- the three sections checked beyond their keys (issue 45: world_section, robots_section,
# center_error_section called directly) ---

def test_a_rectangular_room_is_centred_on_the_center_unless_given():
    w = world_section({"center": [1.0, -2.0], "room": {"size_m": [6, 4]}})
    assert w.center == (1.0, -2.0) and w.room == Room((6.0, 4.0), (1.0, -2.0))
    w = world_section({"center": [1.0, -2.0], "room": {"center": [0, 0]}})
    assert w.room == Room(Room.size_m, (0.0, 0.0))
    w = world_section({"room": {"walls": [[0, 0, 1, 0], [1, 0, 1, 1]]}})
    assert w.room.size_m is None and w.room.walls == ((0.0, 0.0, 1.0, 0.0), (1.0, 0.0, 1.0, 1.0))
    w = world_section({"objects": [{"type": "box", "center": [1, 1]}, {"type": "chair", "center": [2, 0]}]})
    assert w.objects == (Box((1.0, 1.0)), Chair((2.0, 0.0)))


@pytest.mark.parametrize("v, path, words", [
    ({"room": {"walls": [[0, 0, 1, 0]], "size_m": [2, 2]}}, "world.room",
     "expected either size_m (and center) or walls, not both"),
    ({"room": {"size_m": [2, 2]}, "map": "m.yaml"}, "world.room", "expected either world.room or world.map"),
    ({"map": "m.yaml", "generate": {"kind": "floorplan"}}, "world.map",
     "expected either world.generate or world.map, not both"),
    ({"map_resolution_m": 0.05}, "world.map_resolution_m", "expected only with world.map"),
    ({"room": [1, 2]}, "world.room", "expected a mapping with size_m and center, or walls, got [1, 2]"),
    ({"room": {"walls": [[0, 0, 1]]}}, "world.room.walls[0]", "a wall [ax, ay, bx, by] of four numbers"),
    ({"objects": [{"type": "sofa", "center": [0, 0]}]}, "world.objects[0].type",
     "expected an object type, one of 'chair', 'overturned_chair', 'box', got 'sofa'"),
    ({"objects": [[0, 0]]}, "world.objects[0]", "expected an object type"),
    ({"objects": [{"type": "box"}]}, "world.objects[0].center", "missing required key"),
    ({"pillars": [{"center": [0, 0], "radius": 0}]}, "world.pillars[0].radius", "expected a number > 0, got 0"),
    ({"map": ""}, "world.map", "expected a string, the path of a map file"),
    ({"roof": 1}, "world.roof", "unknown key"),
])
def test_a_bad_world_names_its_key(v, path, words):
    with pytest.raises(Invalid) as e:
        world_section(v)
    assert e.value.path == path and words in e.value.text


def test_robots_other_than_three_spread_evenly_from_90_degrees():
    r = robots_section({"names": ["a", "b", "c", "d"]})
    assert r.start_angles_deg == (90.0, 180.0, 270.0, 0.0) and r.yaw_offsets_deg == (0.0,) * 4
    r = robots_section({"names": ["a", "b"], "start_angles_deg": [0, 45]})
    assert r.start_angles_deg == (0.0, 45.0)
    assert robots_section(None) == robots_section({})  # the defaults: three robots


@pytest.mark.parametrize("v, path, words", [
    ({"names": ["a", "a"]}, "robots.names", "expected unique robot names"),
    ({"names": ["solo"]}, "robots.names", "at least two robots"),
    ({"names": ["a", "b\tc"]}, "robots.names[1]", "a name of printable characters"),
    ({"names": ["a", " "]}, "robots.names[1]", "(not empty;"),
    ({"names": ["a", "b"], "start_angles_deg": [0, 90, 180]}, "robots.start_angles_deg",
     "a list of 2 numbers (one per robot)"),
    ({"yaw_offsets_deg": [0, 0]}, "robots.yaw_offsets_deg", "a list of 3 numbers"),
    ({"radius_m": 0.5, "body_radius_m": 0.5}, "robots.body_radius_m", "a number < robots.radius_m (0.5)"),
    ({"body_radius_m": 0.01}, "robots.body_radius_m", f"a number >= {MIN_BODY_RADIUS_M:g}"),
    ({"speed_mps": 2.5}, "robots.speed_mps", f"a number in (0, {MAX_SPEED_MPS:g}]"),
    ({"names": ["a", "b"], "start_angles_deg": [0, 5], "radius_m": 1.0}, "robots.start_angles_deg",
     "a and b are 0.087 m apart, bodies of radius 0.18 m"),
    ({"heading": "north"}, "robots.heading", "expected one of 'center', 'tangent'"),
])
def test_bad_robots_name_their_key(v, path, words):
    with pytest.raises(Invalid) as e:
        robots_section(v)
    assert e.value.path == path and words in e.value.text


def test_center_errors_are_of_known_robots_within_half_the_roi():
    names = ("A", "B")
    ce = center_error_section({"magnitude_m": 0.2, "per_robot": {"B": [0.3, -0.4]}}, names, 8.0)
    assert ce.magnitude_m == 0.2 and ce.per_robot == {"B": (0.3, -0.4)}
    v = ce.vectors(names, np.random.default_rng(0))
    assert v["B"] == (0.3, -0.4) and math.hypot(*v["A"]) == pytest.approx(0.2)
    with pytest.raises(Invalid, match=r"center_error.per_robot.C: expected a robot name \(one of A, B\)"):
        center_error_section({"per_robot": {"C": [0, 0]}}, names, 8.0)
    with pytest.raises(Invalid, match=r"center_error.per_robot.A: expected an error \[dx, dy\] of at most 1 m"):
        center_error_section({"per_robot": {"A": [1.0, 0.5]}}, names, 2.0)
    with pytest.raises(Invalid, match=r"center_error.magnitude_m: expected a number in \[0, 1\], got 1.5"):
        center_error_section({"magnitude_m": 1.5}, names, 2.0)
    with pytest.raises(Invalid, match=r"center_error.per_robot: expected a mapping robot name -> \[dx, dy\]"):
        center_error_section({"per_robot": [1, 2]}, names, 8.0)
