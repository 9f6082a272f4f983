"""Scenario loading, validation messages, overrides and the bundled scenes."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from circsim.config.scenario import (
    Scenario,
    ScenarioError,
    bundled_scenarios,
    load_scenario,
    scenario_from_dict,
    scenario_to_dict,
)
from circsim.config.types import Box, Chair, OverturnedChair
from tests.paths import REPO


def write(tmp_path: Path, text: str, name: str = "scene.yaml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def error_of(tmp_path: Path, text: str) -> str:
    with pytest.raises(ScenarioError) as e:
        load_scenario(write(tmp_path, text))
    msg = str(e.value)
    assert "\n" not in msg
    return msg


def test_bundled_scenarios_load_and_round_trip():
    found = bundled_scenarios()
    assert {"scene1", "scene2"} <= set(found)
    for name, path in found.items():
        sc = load_scenario(path)
        assert sc.name == name
        d = scenario_to_dict(sc)
        assert json.loads(json.dumps(d)) == d  # plain JSON-able
        assert scenario_from_dict(d) == sc


def test_top_level_symlink_points_at_bundled_scenarios():
    link = REPO / "scenarios"
    assert link.is_symlink() and not Path(link.readlink()).is_absolute()
    assert (link / "scene1.yaml").resolve() == bundled_scenarios()["scene1"].resolve()


def test_thesis_scenes_contents():
    s1 = load_scenario(bundled_scenarios()["scene1"])
    s2 = load_scenario(bundled_scenarios()["scene2"])
    kinds1 = sorted(type(o).__name__ for o in s1.world.objects)
    assert kinds1 == ["Chair", "Chair", "Chair", "OverturnedChair"]
    assert all(isinstance(o, Box) for o in s2.world.objects) and len(s2.world.objects) == 4
    for sc in (s1, s2):
        assert sc.robots.names == ("Lyon", "Auckland", "Nevers")
        assert sc.robots.motion == "online"
        assert 1.5 <= sc.robots.radius_m <= 2.0
        tour = 2 * math.pi * sc.robots.radius_m / sc.robots.speed_mps
        assert sc.duration_s >= tour
        # the pillars are point-symmetric about the center, the objects are not
        c = np.array(sc.world.center)
        p = [np.array(x.center) for x in sc.world.pillars]
        assert len(p) == 2 and np.allclose(p[0] - c, c - p[1])
        objs = np.array([o.center for o in sc.world.objects])
        mirrored = 2 * c - objs
        gaps = np.linalg.norm(mirrored[:, None] - objs[None], axis=2)
        assert gaps.min() > 0.5


def test_short_scenario_gets_defaults(tmp_path):
    sc = load_scenario(write(tmp_path, "seed: 3\n"))
    assert sc.name == "scene" and sc.seed == 3
    assert sc.robots.names == ("Lyon", "Auckland", "Nevers")
    assert sc.robots.start_angles_deg == (90.0, 210.0, 330.0)
    assert sc.laser.fov_deg == 240 and sc.laser.range_max_m == 5.6
    assert math.isclose(math.degrees(sc.laser.angle_increment), 0.36, abs_tol=0.005)
    assert sc.slam.resolution_m == 0.05 and sc.slam.occupied_thresh == 0.65 and sc.slam.free_thresh == 0.196
    assert sc.network.period_s == 2.0 and sc.dt_s == 0.1
    assert sc.merger.as_dict()["roi_m"] == 8.0
    # duration defaults to one full tour of the circle
    assert sc.duration_s == math.ceil(2 * math.pi * sc.robots.radius_m / sc.robots.speed_mps)
    assert len(sc.world.room.wall_segments()) == 4


def test_objects_are_typed(tmp_path):
    sc = load_scenario(write(tmp_path, """
world:
  objects:
    - {type: chair, center: [1, 2], yaw_deg: 10}
    - {type: overturned_chair, center: [0, 0]}
    - {type: box, center: [-1, 0], size_m: [0.4, 0.6]}
"""))
    chair, over, box = sc.world.objects
    assert isinstance(chair, Chair) and chair.center == (1.0, 2.0) and chair.leg_spacing_m == 0.4
    assert isinstance(over, OverturnedChair) and isinstance(box, Box) and box.size_m == (0.4, 0.6)
    assert scenario_to_dict(sc)["world"]["objects"][0]["type"] == "chair"


def test_room_from_wall_segments(tmp_path):
    sc = load_scenario(write(tmp_path, "world: {room: {walls: [[-3, -3, 4, -3], [4, -3, 4, 3]]}}\n"))
    assert sc.world.room.wall_segments() == ((-3.0, -3.0, 4.0, -3.0), (4.0, -3.0, 4.0, 3.0))
    assert scenario_from_dict(scenario_to_dict(sc)) == sc


# an L-shaped room: the square [-4, 4]² without its upper right quarter [1, 4] x [1, 4]
L_WALLS = "[[-4, -4, 4, -4], [4, -4, 4, 1], [4, 1, 1, 1], [1, 1, 1, 4], [1, 4, -4, 4], [-4, 4, -4, -4]]"


def wall_room(world_extra: str = "", robots: str = "{radius_m: 1.5}", center: str = "[-1.5, -1.5]") -> str:
    return f"world: {{center: {center}, room: {{walls: {L_WALLS}}}{world_extra}}}\nrobots: {robots}\n"


def test_wall_rooms_are_checked_like_rectangles(tmp_path):
    """Issue 36 item 6 / 37 item 4: a room of walls had no checks — a circle crossing the L's inner walls,
    a pillar outside the L, a wall through a robot's start and robots starting outside the room ran."""
    sc = load_scenario(write(tmp_path, wall_room()))  # the circle in the L's lower-left square: fine
    assert len(sc.world.room.walls) == 6
    cases = [
        (wall_room(robots="{radius_m: 2.3}", center="[-0.5, -0.5]"),  # clear of the outer walls by 1.2 m
         "world.room.walls[2]: expected clear of robot"),
        (wall_room(", pillars: [{center: [3, 3], radius: 0.2}]"),
         "world.pillars[0]: expected inside the room (the region the walls enclose"),
        (wall_room(", objects: [{type: box, center: [2.5, 2.5], size_m: [0.4, 0.4]}]"),
         "world.objects[0]: expected inside the room"),
        # a wall through Lyon's start (-1.5, 0.0), inside the room
        (f"world: {{center: [-1.5, -1.5], room: {{walls: {L_WALLS[:-1]}, [-2, 0, -1, 0]]}}}}\n"
         "robots: {radius_m: 1.5}\n", "world.room.walls[6]: expected clear of robot Lyon's path"),
        # the walls close a small box about the center; the circle runs outside it, crossing no wall
        ("world: {center: [0, 0], room: {walls: [[-1, -1, 1, -1], [1, -1, 1, 1], [1, 1, -1, 1], [-1, 1, -1, -1]]}}\n"
         "robots: {radius_m: 2.0}\n",
         "robots.radius_m: expected a circle about world.center that stays inside the room the walls enclose"),
    ]
    for text, needle in cases:
        with pytest.raises(ScenarioError) as e:
            load_scenario(write(tmp_path, text))
        assert needle in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_walls_that_do_not_close_check_only_the_path(tmp_path):
    """An open scene (two walls) has no inside: a pillar anywhere off the path is accepted, a wall across
    the circle is not."""
    ok = write(tmp_path, "world: {center: [0, 0], room: {walls: [[-3, -3, 3, -3], [3, -3, 3, 3]]}, "
                         "pillars: [{center: [9, 9], radius: 0.2}]}\nrobots: {radius_m: 1.5}\n")
    assert load_scenario(ok).world.pillars[0].center == (9.0, 9.0)
    cross = write(tmp_path, "world: {center: [0, 0], room: {walls: [[-3, 0, 3, 0]]}}\nrobots: {radius_m: 1.5}\n")
    with pytest.raises(ScenarioError, match=r"world.room.walls\[0\]: expected clear of robot"):
        load_scenario(cross)


def test_overrides_are_applied_before_the_file_is_validated(tmp_path):
    """Issue 36 item 5: a file whose circle needs a larger slam.size_m could not be fixed by --set
    slam.size_m=20 (the file was validated before the override: still 'got 16.0')."""
    from circsim.commands import load_with_overrides

    path = write(tmp_path, "world: {room: {size_m: [12, 12]}}\nrobots: {radius_m: 4.5}\nslam: {size_m: 16}\n")
    with pytest.raises(ScenarioError, match="slam.size_m: expected a number > 4 \\* robots.radius_m .18.*got 16.0"):
        load_scenario(path)
    sc = load_with_overrides(str(path), None, ["slam.size_m=20"])
    assert sc.slam.size_m == 20.0 and sc.robots.radius_m == 4.5
    assert load_scenario(path, ["slam.size_m=20", "seed=3"]).seed == 3
    with pytest.raises(ScenarioError) as e:  # an override that does not fix it is named
        load_with_overrides(str(path), None, ["slam.size_m=17"])
    assert "(--set slam.size_m=17): slam.size_m: expected a number > 4 * robots.radius_m (18)" in str(e.value)


@pytest.mark.parametrize("text, expected", [
    ("robots: {speed_mps: fast}", "scene.yaml: robots.speed_mps: expected a number > 0, got 'fast'"),
    ("robots: {speed_mps: -1}", "scene.yaml: robots.speed_mps: expected a number > 0, got -1"),
    ("robots: {sped_mps: 1}", "scene.yaml: robots.sped_mps: unknown key; expected one of names, radius_m"),
    ("robot: {}", "scene.yaml: robot: unknown key; expected one of name, description"),
    ("seed: true", "scene.yaml: seed: expected an integer >= 0, got True"),
    ("laser: {dropout: 1.5}", "scene.yaml: laser.dropout: expected a number in [0, 0.5], got 1.5"),
    ("laser: {fov_deg: 400}", "scene.yaml: laser.fov_deg: expected a number in (0, 360], got 400"),
    ("laser: {beams: 66.5}", "scene.yaml: laser.beams: expected an integer in [2, 100000], got 66.5"),
    ("laser: {range_min_m: 1, range_max_m: 1}", "scene.yaml: laser.range_min_m: expected a number < laser.range_max_m (1)"),
    ("slam: {free_thresh: 0.7}", "scene.yaml: slam.free_thresh: expected a number < slam.occupied_thresh"),
    ("slam: {size_m: 6}", "scene.yaml: slam.size_m: expected a number > 4 * robots.radius_m (7) so that"),
    ("slam: {drift: {xy: 1}}", "scene.yaml: slam.drift.xy: unknown key; expected one of xy_m_per_m"),
    ("slam: {log_odds: {miss: 0.4}}", "scene.yaml: slam.log_odds.miss: expected a number < 0, got 0.4"),
    ("world: {center: [1]}", "scene.yaml: world.center: expected a list [x, y] of two numbers, got [1]"),
    ("world: {pillars: [{radius: 0.2}]}", "scene.yaml: world.pillars[0].center: missing required key"),
    ("world: {objects: [{type: chair, center: [0, 0]}, {type: sofa, center: [1, 1]}]}",
     "scene.yaml: world.objects[1].type: expected an object type, one of 'chair'"),
    ("world: {objects: [{type: box, center: [0, 0], size_m: [0, 1]}]}",
     "scene.yaml: world.objects[0].size_m[0]: expected a number > 0, got 0"),
    ("world: {room: {walls: [[0, 0, 1]]}}", "scene.yaml: world.room.walls[0]: expected a wall [ax, ay, bx, by]"),
    ("world: {room: {size_m: [4, 3], walls: [[0, 0, 1, 1]]}}",
     "scene.yaml: world.room: expected either size_m (and center) or walls"),
    ("robots: {start_angles_deg: [0, 120]}",
     "scene.yaml: robots.start_angles_deg: expected a list of 3 numbers (one per robot), got [0.0, 120.0]"),
    ("robots: {names: [A, A]}", "scene.yaml: robots.names: expected unique robot names"),
    ("robots: {names: [A]}", "scene.yaml: robots.names: expected at least two robots"),
    ("robots: {motion: wander}", "scene.yaml: robots.motion: expected one of 'online', 'offline', got 'wander'"),
    ("center_error: {per_robot: {Bob: [0.1, 0]}}",
     "scene.yaml: center_error.per_robot.Bob: expected a robot name (one of Lyon, Auckland, Nevers)"),
    ("merger: {measure: sad}", "scene.yaml: merger.measure must be one of 'similarity', 'birk_carpin', 'ncc', got "
                               "'sad'"),
    ("network: {loss: 1}", "scene.yaml: network.loss: expected a number in [0, 1), got 1"),
    ("merger: {share_hypotheses: maybe}", "scene.yaml: merger.share_hypotheses: expected true or false, got 'maybe'"),
    ("merger: {share_hypotheses: 1}", "scene.yaml: merger.share_hypotheses: expected true or false, got 1"),
    ("output: {rrd: 3}", "scene.yaml: output.rrd: expected null or a path, got 3"),
    ("- 1\n- 2\n", "scene.yaml: (top level): expected a mapping of scenario sections"),
    ("robots: [1, 2]", "scene.yaml: robots: expected a mapping with keys names"),
])
def test_errors_name_file_key_and_expectation(tmp_path, text, expected):
    assert error_of(tmp_path, text).startswith(expected)


def test_invalid_yaml_and_missing_file(tmp_path):
    assert error_of(tmp_path, "robots: {speed_mps: [1,\n").startswith("scene.yaml: invalid YAML at line")
    with pytest.raises(ScenarioError, match=r"^nope.yaml: cannot read file"):
        load_scenario(tmp_path / "nope.yaml")


def test_overrides_revalidate_and_keep_defaults_derived(tmp_path):
    sc = load_scenario(write(tmp_path, "robots: {radius_m: 1.5, speed_mps: 0.2}\n"))
    fast = sc.with_overrides(["robots.speed_mps=0.5", "laser.fov_deg=360", "output.rrd=out/run.rrd",
                              "center_error.per_robot.Lyon=[0.1, -0.05]"])
    assert fast.robots.speed_mps == 0.5 and fast.laser.fov_deg == 360.0
    assert fast.output.rrd == "out/run.rrd"
    assert fast.center_error.per_robot == {"Lyon": (0.1, -0.05)}
    assert fast.duration_s == math.ceil(2 * math.pi * 1.5 / 0.5)  # not given: follows the new speed
    assert sc.robots.speed_mps == 0.2  # the original is unchanged
    assert isinstance(fast, Scenario) and fast.source == "scene.yaml"


@pytest.mark.parametrize("assignment, expected", [
    ("robots.speed_mps=fast",
     "scene.yaml (--set robots.speed_mps=fast): robots.speed_mps: expected a number > 0, got 'fast'"),
    ("robots.sped=1", "scene.yaml (--set robots.sped=1): robots.sped: unknown key"),
    ("robots.speed_mps", "scene.yaml: --set 'robots.speed_mps': expected key.path=value"),
    ("seed.x=1", "scene.yaml: --set seed.x=1: seed: expected a mapping to set keys in, got 0"),
])
def test_override_errors_name_the_assignment(tmp_path, assignment, expected):
    sc = load_scenario(write(tmp_path, "seed: 0\n"))
    with pytest.raises(ScenarioError) as e:
        sc.with_overrides(["laser.beams=100", assignment])
    assert str(e.value).startswith(expected)


def test_center_error_vectors_are_seeded():
    sc = scenario_from_dict({"center_error": {"magnitude_m": 0.2, "per_robot": {"Nevers": [0.0, 0.1]}}})
    a = sc.center_error.vectors(sc.robots.names, np.random.default_rng(5))
    b = sc.center_error.vectors(sc.robots.names, np.random.default_rng(5))
    assert a == b
    assert math.isclose(math.hypot(*a["Lyon"]), 0.2) and math.isclose(math.hypot(*a["Auckland"]), 0.2)
    assert a["Nevers"] == (0.0, 0.1)


# --- issue 12: scenes that would run but mean nothing, sizes that do not fit, YAML 1.2 numbers ---------
@pytest.mark.parametrize("text", ["", "\n", "# only a comment\n", "---\n"])
def test_empty_scenario_file_is_refused(tmp_path, text):
    with pytest.raises(ScenarioError, match=r"^scene.yaml: empty scenario \(expected a mapping"):
        load_scenario(write(tmp_path, text))


@pytest.mark.parametrize("sets, needle", [
    (["robots.radius_m=3.5"], "robots.radius_m=3.5): robots.radius_m: expected a circle about world.center"),
    (["world.center=[5, 0]"], "world.center: expected a point inside the room (the room spans x [-3.75, 3.75]"),
    (["world.center=[3, 0]"], "robots.radius_m: expected a circle"),  # inside, but the circle is not
    (["world.pillars=[{center: [9, 0]}]"], "world.pillars[0]: expected inside the room"),
    (["world.pillars=[{center: [0.15, 1.5], radius: 0.2}]"], "world.pillars[0]: expected clear of robot Lyon's start"),
    (["world.objects=[{type: box, center: [-1.24, -0.9], size_m: [0.3, 0.3]}]"],
     "world.objects[0]: expected clear of robot Auckland's start"),
    (["world.objects=[{type: chair, center: [3.7, 0]}]"], "world.objects[0]: expected inside the room"),
    (["merger.roi_m=1000"], "merger.roi_m: expected a number in (0, 100], got 1000"),
    (["slam.size_m=1000"], "slam.size_m: expected a grid of at most 4000 cells a side"),
    (["duration_s=3601"], "duration_s: expected at most 36000 ticks of dt_s (0.1 s): a number <= 3600"),
    (["laser.beams=100000000"], "laser.beams: expected an integer in [2, 100000]"),
])
def test_geometry_and_sizes_are_checked(sets, needle):
    sc = load_scenario(bundled_scenarios()["scene1"])
    with pytest.raises(ScenarioError) as e:
        sc.with_overrides(sets)
    assert needle in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_bundled_scenes_pass_the_geometry_checks_and_a_clear_start_is_accepted():
    sc = load_scenario(bundled_scenarios()["scene1"])
    assert sc.with_overrides(["world.pillars=[{center: [0.15, 1.15], radius: 0.1}]"]).world.pillars[0].radius == 0.1
    # 2.5 + 0.18 < 3 - 0.1: the circle fits the room; the chair at (2.55, 0.8) would then stand on the robots'
    # path (issue 26: they drive through it), so it goes
    assert sc.with_overrides(["robots.radius_m=2.5", "world.objects=[]"]).robots.radius_m == 2.5
    with pytest.raises(ScenarioError, match=r"world.objects\[1\]: expected clear of the robots' circle"):
        sc.with_overrides(["robots.radius_m=2.5"])
    load_scenario(bundled_scenarios()["scene2"])


@pytest.mark.parametrize("text, value", [("1e1", 10.0), ("2E1", 20.0), ("1.5e1", 15.0), (".5e2", 50.0)])
def test_exponent_numbers_are_numbers(tmp_path, text, value):
    """YAML 1.2: ``1e1`` is ten (PyYAML's YAML 1.1 reads a string and the check refused it)."""
    sc = load_scenario(bundled_scenarios()["scene1"])
    assert sc.with_overrides([f"duration_s={text}"]).duration_s == value
    assert load_scenario(write(tmp_path, f"duration_s: {text}\n")).duration_s == value


@pytest.mark.parametrize("text", ["when: 2001-13-01\n", "\x00\n", "a: [" * 2000 + "\n"])
def test_yaml_the_parser_cannot_construct_is_one_line(tmp_path, text):
    with pytest.raises(ScenarioError, match=r"^scene.yaml: invalid YAML") as e:
        load_scenario(write(tmp_path, text))
    assert "\n" not in str(e.value)


def test_the_slam_thresholds_are_the_merger_s():
    """circsim.config.types imports nothing of ours: its map thresholds are written out; they must stay
    the merger's (map_server's) defaults."""
    from circsim.config.types import SlamConfig
    from merger.grid import DEFAULT_FREE_THRESH, DEFAULT_OCCUPIED_THRESH

    assert (SlamConfig().occupied_thresh, SlamConfig().free_thresh) == (DEFAULT_OCCUPIED_THRESH, DEFAULT_FREE_THRESH)
