"""ROS 2 bags (issue 12): `merger merge --bag FILE --topics /r1/map,...` reads nav_msgs/msg/OccupancyGrid with
rosbags (no ROS install); a small bag is generated here with rosbags' own writer."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from merger.cli import main
from merger.grid import OccupancyGrid
from merger.io.bagio import grid_from_message, read_bag_maps, topic_names
from merger.io.mapread import MapFileError
from merger.search import angle_diff_deg
from tests.strategies import three_views

rosbags = pytest.importorskip("rosbags", reason="the bag extra (rosbags) is not installed")


def _msg(typestore, grid: OccupancyGrid, yaw: float = 0.0):
    T = typestore.types
    Time = T["builtin_interfaces/msg/Time"]
    header = T["std_msgs/msg/Header"](stamp=Time(sec=1, nanosec=0), frame_id="map")
    pose = T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=float(grid.origin[0]), y=float(grid.origin[1]), z=0.0),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)))
    info = T["nav_msgs/msg/MapMetaData"](map_load_time=Time(sec=1, nanosec=0), resolution=float(grid.resolution),
                                         width=grid.width, height=grid.height, origin=pose)
    return T["nav_msgs/msg/OccupancyGrid"](header=header, info=info,
                                           data=np.ascontiguousarray(grid.to_ros().ravel(), dtype=np.int8))


def write_bag(path, topics: dict[str, list[OccupancyGrid]], *, yaw: float = 0.0, extra_string_topic=False):
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(path, version=8) as w:
        t = 1_000_000_000
        for topic, grids in topics.items():
            conn = w.add_connection(topic, "nav_msgs/msg/OccupancyGrid", typestore=ts)
            for g in grids:
                t += 1_000_000
                w.write(conn, t, ts.serialize_cdr(_msg(ts, g, yaw), "nav_msgs/msg/OccupancyGrid"))
        if extra_string_topic:
            conn = w.add_connection("/chatter", "std_msgs/msg/String", typestore=ts)
            w.write(conn, t + 1, ts.serialize_cdr(ts.types["std_msgs/msg/String"](data="hi"), "std_msgs/msg/String"))


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    """Three robots' maps on /r1/map, /r2/map, /r3/map; an older, empty map first on each topic."""
    d = tmp_path_factory.mktemp("bag")
    _, names, maps, truth = three_views(5)
    topics = {}
    for i, (g, _) in enumerate(maps):
        older = OccupancyGrid.unknown(g.height, g.width, g.resolution, g.origin)
        topics[f"/r{i + 1}/map"] = [older, g]
    write_bag(d / "maps", topics, extra_string_topic=True)
    centers = [f"{c[0]:.6f},{c[1]:.6f}" for _, c in maps]
    return d / "maps", maps, centers, {f"r{i + 1}": truth[n] for i, n in enumerate(names)}


def test_read_bag_maps_gives_the_last_map_of_each_topic(bag):
    path, maps, _, _ = bag
    got = read_bag_maps(path, ["/r2/map", "/r1/map"])
    assert list(got) == ["/r2/map", "/r1/map"]
    for topic, (g, _) in zip(["/r1/map", "/r2/map"], maps[:2], strict=True):
        np.testing.assert_array_equal(got[topic].states, g.states)
        assert got[topic].origin == pytest.approx(g.origin) and got[topic].resolution == pytest.approx(g.resolution)


def test_merger_merge_from_a_bag(bag, tmp_path, capsys):
    path, _, centers, truth = bag
    args = ["merge", "--bag", str(path), "--topics", "/r1/map,/r2/map,/r3/map",
            *sum((["--center", c] for c in centers), []), "-o", str(tmp_path / "m"), "--json"]
    assert main(args) == 0
    res = json.loads(capsys.readouterr().out)
    assert set(res["chosen"]["order"]) == {"r1", "r2", "r3"}
    for n, th in truth.items():
        assert abs(angle_diff_deg(res["chosen"]["theta_deg"][n], th)) <= 0.5
    assert (tmp_path / "m.yaml").exists() and (tmp_path / "m_overlay.png").exists()


@pytest.mark.parametrize("extra, needle", [
    (["--topics", "/r1/map,/nope/map"], "topic /nope/map: not in the bag (its nav_msgs/msg/OccupancyGrid topics: "
                                        "/r1/map, /r2/map, /r3/map)"),
    (["--topics", "/r1/map,/chatter"], "topic /chatter: expected nav_msgs/msg/OccupancyGrid, got std_msgs/msg/String"),
    (["--topics", "/r1/map"], "--topics: expected at least two map topics"),
    (["--topics", "/r1/map,/r1/map"], "--topics: a topic is given twice"),
    ([], "--topics: expected at least two map topics"),
    (["--topics", "/r1/map,/r2/map", "--center", "1,1", "--center", "2,2"],
     "--center: expected once or once per topic (2), got 3"),
])
def test_bag_errors_are_one_line(bag, tmp_path, capsys, extra, needle):
    path, _, centers, _ = bag
    args = ["merge", "--bag", str(path), "--center", centers[0], "-o", str(tmp_path / "m"), *extra]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err, err
    assert not (tmp_path / "m.yaml").exists()


def test_not_a_bag_and_topics_without_bag(tmp_path, capsys):
    (tmp_path / "x.db3").write_text("not a bag")
    assert main(["merge", "--bag", str(tmp_path / "x.db3"), "--topics", "/a,/b", "--center", "0,0",
                 "-o", str(tmp_path / "m")]) == 2
    assert "not a readable ROS bag" in capsys.readouterr().err
    assert main(["merge", "a.yaml", "b.yaml", "--topics", "/a,/b", "--center", "0,0", "-o", str(tmp_path / "m")]) == 2
    assert "--topics: only with --bag" in capsys.readouterr().err


def test_rotated_origin_and_bad_sizes_are_refused(tmp_path):
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    g = OccupancyGrid(np.zeros((3, 4), np.uint8), 0.05, (1.0, -2.0))
    with pytest.raises(MapFileError, match="rotated origin"):
        grid_from_message(_msg(ts, g, yaw=0.3), "bag: topic /m")
    m = _msg(ts, g)
    m.info.width = 5
    with pytest.raises(MapFileError, match="data: expected width x height = 15 cells, got 12"):
        grid_from_message(m, "bag: topic /m")
    m.info.width, m.info.resolution = 4, float("nan")
    with pytest.raises(MapFileError, match="info.resolution"):
        grid_from_message(m, "bag: topic /m")


def test_topic_names():
    assert topic_names(["/r1/map", "/r2/map"]) == ["r1", "r2"]
    assert topic_names(["/map", "/r2/map"]) == ["map", "r2/map"]
    assert topic_names(["/a/grid", "/b/grid"]) == ["a/grid", "b/grid"]


def test_without_rosbags_the_extra_is_named(monkeypatch, tmp_path, capsys):
    import sys

    for mod in [m for m in sys.modules if m == "rosbags" or m.startswith("rosbags.")]:
        monkeypatch.setitem(sys.modules, mod, None)
    monkeypatch.setitem(sys.modules, "rosbags", None)
    (tmp_path / "bag").mkdir()  # (an output inside the bag is refused first: issue 46)
    assert main(["merge", "--bag", str(tmp_path / "bag"), "--topics", "/a,/b", "--center", "0,0",
                 "-o", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'circsim[bag]'" in err
