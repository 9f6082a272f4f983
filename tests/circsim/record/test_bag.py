"""`circsim run --bag OUT` (issue 35): the run as a ROS 2 bag, read back with rosbags and checked message by
message against what the simulation told its observers; the side files hold the run's truth and merges."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest
import yaml

from circsim.cli import main
from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.events import Observer
from circsim.record.bag import MERGES_FILE, TRUTH_FILE, BagRecorder, rigid_from_center, ros_name
from circsim.sim import Simulation

pytest.importorskip("rosbags", reason="the ros extra (rosbags) is not installed")


class Tape(Observer):
    """What the run told its observers."""

    def __init__(self):
        self.ticks, self.maps, self.cycles = [], [], []

    def on_tick(self, t, step, ticks):
        self.ticks.append((t, ticks))

    def on_map_published(self, t, robot, grid, center_given, center_true):
        self.maps.append((t, robot, grid))

    def on_merge_cycle(self, cycle):
        self.cycles.append(cycle)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=4.5", "center_error=0.1",
                                                                      "merger.window_m=0.3"])
    out = tmp_path_factory.mktemp("bag") / "scene1"
    tape = Tape()
    sim = Simulation(sc, [BagRecorder(out), tape])
    res = sim.run()
    return sim, res, tape, out


def _read(out):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    msgs = {}
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as r:
        for conn, stamp, raw in r.messages():
            msgs.setdefault(conn.topic, []).append((stamp, r.deserialize(raw, conn.msgtype)))
        types = {c.topic: c.msgtype for c in r.connections}
    return msgs, types


def test_bag_holds_every_message_of_the_run(run):
    sim, res, tape, out = run
    msgs, types = _read(out)
    names = sim.robot_names
    assert types["/tf"] == "tf2_msgs/msg/TFMessage" and types["/tf_static"] == "tf2_msgs/msg/TFMessage"
    for n in names:
        assert types[f"/{n}/map"] == "nav_msgs/msg/OccupancyGrid"
        assert types[f"/{n}/scan"] == "sensor_msgs/msg/LaserScan"
        assert types[f"/{n}/odom"] == "nav_msgs/msg/Odometry"
    # scans and odometry: one per robot and tick, equal to what the run measured and estimated
    for n in names:
        scans, odoms = msgs[f"/{n}/scan"], msgs[f"/{n}/odom"]
        assert len(scans) == len(odoms) == len(tape.ticks)
        for (t, ticks), (stamp, scan), (_, odo) in zip(tape.ticks, scans, odoms, strict=True):
            k = next(k for k in ticks if k.name == n)
            assert stamp == round(t * 1e9) and scan.header.stamp.sec * 10**9 + scan.header.stamp.nanosec == stamp
            assert scan.header.frame_id == f"{n}/laser"
            np.testing.assert_array_equal(scan.ranges, k.scan.ranges.astype(np.float32))
            assert scan.angle_increment == pytest.approx(k.scan.angle_increment)
            p = odo.pose.pose
            assert (p.position.x, p.position.y) == (k.est_pose[0], k.est_pose[1])
            assert math.atan2(2 * p.orientation.w * p.orientation.z, 1 - 2 * p.orientation.z ** 2) \
                == pytest.approx(k.est_pose[2], abs=1e-12)
            assert odo.header.frame_id == f"{n}/odom" and odo.child_frame_id == f"{n}/base_link"
    # maps: every publication, cell for cell
    for n in names:
        published = [(t, g) for t, r, g in tape.maps if r == n]
        got = msgs[f"/{n}/map"]
        assert len(got) == len(published) > 0
        for (t, g), (stamp, m) in zip(published, got, strict=True):
            assert stamp == round(t * 1e9) and m.header.frame_id == f"{n}/map"
            assert (m.info.width, m.info.height) == (g.width, g.height)
            assert (m.info.origin.position.x, m.info.origin.position.y) == g.origin
            np.testing.assert_array_equal(np.asarray(m.data).reshape(g.height, g.width), g.to_ros())
    # tf: per tick, every robot's map -> odom -> base_link; static base_link -> laser
    assert len(msgs["/tf"]) == len(tape.ticks)
    edges = {(tf.header.frame_id, tf.child_frame_id) for tf in msgs["/tf"][-1][1].transforms}
    assert edges == {(f"{n}/{a}", f"{n}/{b}") for n in names for a, b in [("map", "odom"), ("odom", "base_link")]}
    static = {(tf.header.frame_id, tf.child_frame_id) for tf in msgs["/tf_static"][0][1].transforms}
    assert static == {(f"{n}/base_link", f"{n}/laser") for n in names}


def test_side_files_hold_the_truth_and_the_merges(run):
    sim, res, tape, out = run
    truth = yaml.safe_load((out / TRUTH_FILE).read_text())
    for i in sim.robot_names:
        assert truth["robots"][i]["center_given"] == list(sim.centers_given[i])
        for j in sim.robot_names:
            if j == i:
                continue
            p = truth["truth"][i][j]
            assert p["theta_deg"] == sim.truth_deg[i][j] and p["t_m"] == list(sim.truth_translation_m[i][j])
            # the rigid pose of j/map in i/map maps j's true center onto i's
            a = math.radians(p["yaw_deg"])
            cj = sim.robots[j].center_true
            x = (p["x_m"] + math.cos(a) * cj[0] - math.sin(a) * cj[1], p["y_m"] + math.sin(a) * cj[0] + math.cos(a) * cj[1])
            assert x == pytest.approx(sim.robots[i].center_true, abs=1e-9)
    with open(out / MERGES_FILE, newline="") as f:
        rows = list(csv.DictReader(f))
    accepted = [c for c in tape.cycles if c.result.accepted]
    assert accepted and len({r["estimate"] for r in rows}) == len(accepted)
    for c, est in zip(accepted, sorted({int(r["estimate"]) for r in rows}), strict=True):
        mine = [r for r in rows if int(r["estimate"]) == est]
        assert {r["robot"] for r in mine} == {c.robot} and float(mine[0]["t_s"]) == c.t
        for r in mine:
            k = r["map"]
            ch = c.result.chosen
            assert (float(r["yaw_deg"]), float(r["x_m"]), float(r["y_m"])) == rigid_from_center(
                ch.theta_deg[k], ch.translation(k), sim.centers_given[c.robot], sim.centers_given[k])


def test_ros_names():
    assert ros_name("Lyon") == "Lyon" and ros_name("robot-2 b") == "robot_2_b" and ros_name("2a") == "r_2a"


def test_cli_refuses_an_existing_bag_in_one_line(tmp_path, capsys):
    (tmp_path / "b").mkdir()
    assert main(["run", "scene1", "--set", "duration_s=0.2", "--quiet", "--bag", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "already exists" in err[0]


def test_cli_without_rosbags_says_how_to_install(tmp_path, capsys, monkeypatch):
    import builtins

    real = builtins.__import__

    def no_rosbags(name, *a, **k):
        if name == "rosbags" or name.startswith("rosbags."):
            raise ImportError(name)
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_rosbags)
    assert main(["run", "scene1", "--set", "duration_s=0.2", "--quiet", "--bag", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'pip install -e ".[ros]"' in err[0]
    assert not (tmp_path / "b").exists()


def test_a_failed_run_leaves_no_bag_and_no_temporary_folder(tmp_path):
    from circsim.events import Observer

    class Boom(Observer):
        def on_tick(self, t, step, ticks):
            if step == 3:
                raise ValueError("boom")

    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=1"])
    bag = BagRecorder(tmp_path / "b")
    with pytest.raises(ValueError, match="boom"):
        Simulation(sc, [bag, Boom()]).run()
    bag.abort()
    assert list(tmp_path.iterdir()) == []
