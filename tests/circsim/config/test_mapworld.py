"""Map worlds in scenarios (circsim.config.mapworld): world.map read as merger reads map files, relative to
the scenario file, and the scene checked against the map's free space; one-line refusals, exit 2."""

from __future__ import annotations

import numpy as np
import pytest

from circsim.cli import main
from circsim.config.mapworld import clearance, largest_clear_radius
from circsim.config.scenario import ScenarioError, load_scenario, scenario_from_dict, scenario_to_dict
from circsim.config.types import MapGrid
from circsim.world.world import World
from merger.grid import Cell, OccupancyGrid
from merger.io.mapio import load_map, save_map

RES = 0.05


def building() -> OccupancyGrid:
    """A 10 x 8 m map, origin (-5, -4): a free room x [-4, 4), y [-3, 3) walled in (occupied ring), unknown
    outside; inside, a wall at x [2, 2.05) from y -3 to 0 and an unknown patch x [-3.5, -2.5), y [1.5, 2.5)."""
    s = np.full((160, 200), Cell.UNKNOWN, np.uint8)
    s[18:142, 18:182] = Cell.OCCUPIED
    s[20:140, 20:180] = Cell.FREE
    s[20:80, 140:141] = Cell.OCCUPIED
    s[110:130, 30:50] = Cell.UNKNOWN
    return OccupancyGrid(s, RES, (-5.0, -4.0))


def scene(tmp_path, world: str, robots: str = "{radius_m: 1.5}", name="scene.yaml"):
    maps = tmp_path / "maps"
    if not maps.exists():
        maps.mkdir()
        save_map(building(), maps / "b.yaml")
        save_map(building(), maps / "b_png", image_suffix=".png")
    p = tmp_path / name
    p.write_text(f"world: {world}\nrobots: {robots}\n")
    return p


def refusal(path) -> str:
    with pytest.raises(ScenarioError) as e:
        load_scenario(path)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith(path.name + ": ")
    return msg


def test_a_map_world_loads_relative_to_its_file_and_round_trips(tmp_path, monkeypatch):
    p = scene(tmp_path, "{map: maps/b.yaml, center: [0, 0], pillars: [{center: [0.3, 0.4], radius: 0.2}]}")
    monkeypatch.chdir(tmp_path / "maps")  # the map is the scenario file's, wherever the command runs
    sc = load_scenario(p)
    g = sc.world.map_grid
    assert g.origin == (-5.0, -4.0) and g.resolution == RES
    assert np.array_equal(g.states, load_map(tmp_path / "maps" / "b.yaml").states)
    d = scenario_to_dict(sc)
    assert "room" not in d["world"] and d["world"]["map"] == str((tmp_path / "maps" / "b.yaml").resolve())
    assert scenario_from_dict(d) == sc
    w = World.from_scenario(sc)
    assert w.clearance((0.3, 0.4)) < 0 and w.clearance((3.0, -2.0)) == pytest.approx(0.95)  # pillar; wall x=2.05


def test_an_image_map_takes_its_resolution_and_lies_at_the_origin(tmp_path):
    sc = load_scenario(scene(tmp_path, "{map: maps/b_png.png, map_resolution_m: 0.05, center: [5, 4]}"))
    assert sc.world.map_grid.origin == (0.0, 0.0)
    assert np.array_equal(sc.world.map_grid.states, building().states)


def test_room_worlds_are_unchanged_by_the_map_keys():
    d = scenario_to_dict(scenario_from_dict({}))
    assert set(d["world"]) == {"center", "room", "pillars", "objects"}


def test_a_circle_through_a_wall_is_refused_naming_the_blocking_point_and_the_largest_clear_radius(tmp_path):
    msg = refusal(scene(tmp_path, "{map: maps/b.yaml, center: [0, 0]}", "{radius_m: 2.0}"))
    assert "robots.radius_m: expected a circle about world.center (0, 0) in the free space of the map b.yaml" \
        in msg
    assert "path is blocked at (1.8" in msg and "in map coordinates" in msg
    r = float(msg.split("the largest clear circle about world.center has radius ")[1].split(" m")[0])
    assert 1.7 <= r < 2.0 - 0.18 + 0.05  # the wall at x = 2 less a body radius, to within a cell and a half
    load_scenario(scene(tmp_path, "{map: maps/b.yaml, center: [0, 0]}", f"{{radius_m: {r}}}", "ok.yaml"))


def test_a_start_in_unknown_space_is_refused(tmp_path):
    msg = refusal(scene(tmp_path, "{map: maps/b.yaml, center: [-1.5, 1.0]}",
                        "{radius_m: 1.8, start_angles_deg: [146, 266, 26]}"))
    assert "robot Lyon's start is blocked at (-2.99, 2.01) in map coordinates (unknown space, 0.00 m" in msg


def test_a_center_in_a_wall_and_an_object_on_a_wall_are_refused(tmp_path):
    msg = refusal(scene(tmp_path, "{map: maps/b.yaml, center: [2.02, -1.0]}", "{radius_m: 0.5}"))
    assert "world.center: expected a point in the free space of the map b.yaml ((2.02, -1) is in an occupied " \
           "cell)" in msg
    msg = refusal(scene(tmp_path, "{map: maps/b.yaml, center: [0, 0], objects: [{type: box, center: [2.0, -2.5]}]}",
                        name="box.yaml"))
    assert "world.objects[0]: expected inside the room (the free space of the map b.yaml)" in msg


@pytest.mark.parametrize("world, needle", [
    ("{map: maps/nothere.yaml}", "world.map: {maps}/nothere.yaml: cannot read: No such file or directory"),
    ("{map: maps/bad.yaml}", "world.map: {maps}/bad.yaml: key 'resolution': expected a number in (0.0, 1000.0]"),
    ("{map: maps/junk.pgm, map_resolution_m: 0.05}", "world.map: {maps}/junk.pgm: not a readable image"),
    ("{map: maps/b_png.png}", "world.map_resolution_m: expected the cell size in metres of the image world.map "
                              "(b_png.png)"),
    ("{map: maps/b.yaml, map_resolution_m: 0.05}", "world.map_resolution_m: expected only with an image"),
    ("{map: maps/b.yaml, room: {size_m: [4, 4]}}", "world.room: expected either world.room or world.map"),
    ("{map_resolution_m: 0.05}", "world.map_resolution_m: expected only with world.map"),
    ("{map: 3}", "world.map: expected a string, the path of a map file, got 3"),
])
def test_bad_map_files_and_keys_are_one_line_errors_with_exit_2(tmp_path, capsys, world, needle):
    p = scene(tmp_path, world)
    (tmp_path / "maps" / "bad.yaml").write_text("image: b.pgm\nresolution: -1\norigin: [0, 0, 0]\n")
    (tmp_path / "maps" / "junk.pgm").write_bytes(b"not an image at all")
    assert needle.format(maps=(tmp_path / "maps").resolve()) in refusal(p)
    assert main(["run", str(p), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and "world." in err


def test_clearance_is_the_distance_to_the_nearest_solid_square():
    g = MapGrid(building().states, RES, (-5.0, -4.0))
    got = clearance(g, [(0.0, 0.0), (1.9, -1.0), (2.02, -1.0), (1.9, 0.1), (3.9, 2.9)], 1.0)
    assert got == pytest.approx([1.0, 0.1, 0.0, np.hypot(0.1, 0.1), 0.1])
    assert largest_clear_radius(g, (0.0, 0.0), 0.18) == pytest.approx(1.75, abs=0.08)
