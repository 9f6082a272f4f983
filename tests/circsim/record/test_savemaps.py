"""circsim.record.savemaps (``circsim run --save-maps``): after a short run, each robot's last published map
as map_server files that load back cell for cell, and ``centers.yaml`` whose centers and ground truth are
the run's (the true centers: the scenario's center seen from each start pose; θ* from the start yaws);
robot names made file names."""

from __future__ import annotations

import math
import shlex
from pathlib import Path

import numpy as np
import pytest
import yaml

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.record.savemaps import MapSaver, file_stem
from circsim.sim import Simulation
from merger.io.mapio import load_map, write_files
from merger.search import angle_diff_deg


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(
        ["duration_s=2.5", "center_error.magnitude_m=0.1", "merger.window_m=0.3"])
    saver = MapSaver()
    sim = Simulation(sc, [saver])
    sim.run()
    out = tmp_path_factory.mktemp("maps")
    files = saver.files(out)
    write_files(files)
    return sc, sim, saver, out, files


def test_every_robots_last_map_is_written_and_loads_back(saved):
    sc, _, saver, out, files = saved
    assert set(p.name for p in files) == {f"{n}{e}" for n in sc.robots.names for e in (".yaml", ".pgm")} | \
        {"centers.yaml"}
    for n in sc.robots.names:
        back = load_map(out / f"{n}.yaml")
        g = saver.grids[n]
        assert np.array_equal(back.states, g.states) and back.origin == pytest.approx(g.origin)
        assert back.resolution == g.resolution


def test_centers_yaml_states_the_runs_centers_and_truth(saved):
    sc, sim, _, out, _ = saved
    doc = yaml.safe_load((out / "centers.yaml").read_text())
    names = list(sc.robots.names)
    assert list(doc["maps"]) == names and doc["truth_onto"] == names[0]
    cx, cy = sc.world.center
    for n in names:
        m = doc["maps"][n]
        x, y, yaw_deg = m["pose_world"]
        yaw = math.radians(yaw_deg)
        # the true center: the world's center in the robot's map frame (its start pose)
        c, s = math.cos(yaw), math.sin(yaw)
        want = (c * (cx - x) + s * (cy - y), -s * (cx - x) + c * (cy - y))
        assert m["center_true"] == pytest.approx(want, abs=1e-6)
        assert math.hypot(m["center"][0] - want[0], m["center"][1] - want[1]) == pytest.approx(0.1, abs=1e-6)
        th = doc["truth"][n]["theta_deg"]
        assert abs(angle_diff_deg(th, yaw_deg - doc["maps"][names[0]]["pose_world"][2])) < 1e-4
        assert doc["truth"][n]["translation_m"] == pytest.approx(list(sim.truth_translation_m[names[0]][n]),
                                                                 abs=1e-6)
    argv = shlex.split(doc["merge_command"])
    assert argv[:2] == ["merger", "merge"] and [a for a in argv if a.endswith(".yaml")] == \
        [str(out / f"{n}.yaml") for n in names]
    assert "--window" in argv and argv[argv.index("--window") + 1] == "0.3"
    assert "scene1 seed" in doc["note"]


def test_nothing_to_write_before_any_map():
    saver = MapSaver()
    saver.on_start(type("Sim", (), {"robot_names": ["a", "b"]})())
    assert saver.files(Path("/nonexistent")) == {}


@pytest.mark.parametrize("name, index, stem", [("Lyon", 0, "Lyon"), ("r/1 x", 1, "r_1_x"), ("..", 2, "robot2"),
                                               ("a.b", 3, "a.b"), ("été", 4, "été"), ("../up", 5, "_up")])
def test_a_robot_name_is_a_file_name(name, index, stem):
    assert file_stem(name, index) == stem
