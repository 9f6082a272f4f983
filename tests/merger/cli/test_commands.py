"""merger.cli.commands, each command called on its parsed arguments: ``align`` finds a generated scene's
known rotation, ``merge`` writes the superposition of the maps placed at the truth (exit 0) or nothing
for unrelated maps (exit 1), and ``demo``'s stated ground truth is the geometry of its own views."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from merger.cli import params_from
from merger.cli.commands import cmd_align, cmd_demo, cmd_merge
from merger.cli.parser import UsageError, build_parser
from merger.grid import OCCUPIED_S, OccupancyGrid
from merger.io.mapio import load_map, save_map
from merger.search import angle_diff_deg
from merger.synthetic import world_to_frame
from merger.transform import rotation
from tests.strategies import saved_views


def _args(argv):
    args = build_parser().parse_args(argv)
    args.params = params_from(args)
    return args


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    paths, centers, truth = saved_views(tmp_path_factory.mktemp("maps"))
    return [str(p) for p in paths], [f"{c[0]!r},{c[1]!r}" for c in centers], truth


def test_align_finds_the_known_rotation(saved, capsys):
    paths, centers, truth = saved
    rc = cmd_align(_args(["align", paths[0], paths[2], "--center", centers[0], "--center-moving", centers[2],
                          "--window", "0", "--json"]))
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["verification"]["accepted"]
    assert abs(angle_diff_deg(out["theta_deg"], truth["Nevers"])) <= 1.0
    assert out["center_ref"] == [float(v) for v in centers[0].split(",")]


def test_merge_writes_the_superposition_in_the_first_maps_frame(saved, tmp_path, capsys):
    """Every occupied cell of the first map (the merged map's frame) is occupied in the merged map: the
    superposition keeps a cell occupied when either map has it."""
    paths, centers, truth = saved
    out = tmp_path / "merged"
    rc = cmd_merge(_args(["merge", *paths, *(x for c in centers for x in ("--center", c)), "-o", str(out),
                          "--window", "0", "--json"]))
    res = json.loads(capsys.readouterr().out)
    assert rc == 0 and res["accepted"]
    for n in truth:
        assert abs(angle_diff_deg(res["chosen"]["theta_deg"][n], truth[n])) <= 1.0
    merged, first = load_map(out.with_suffix(".yaml")), load_map(paths[0])
    r, c = np.nonzero(first.states == OCCUPIED_S)
    xy = np.stack([first.origin[0] + (c + 0.5) * first.resolution, first.origin[1] + (r + 0.5) * first.resolution], 1)
    cells = np.floor(merged.world_to_cell(xy)).astype(int)
    assert (merged.states[cells[:, 1], cells[:, 0]] == OCCUPIED_S).all()
    assert (merged.states == OCCUPIED_S).sum() > (first.states == OCCUPIED_S).sum()
    assert (tmp_path / "merged_overlay.png").exists()


def test_merge_of_unrelated_maps_exits_1_and_writes_nothing(tmp_path, capsys):
    rng = np.random.default_rng(1)
    paths = []
    for k in range(2):
        g = OccupancyGrid(rng.choice(3, size=(120, 120), p=[0.4, 0.5, 0.1]).astype(np.uint8), 0.05, (-3.0, -3.0))
        paths.append(str(save_map(g, tmp_path / f"n{k}.yaml")[0]))
    rc = cmd_merge(_args(["merge", *paths, "--center", "0,0", "-o", str(tmp_path / "out"), "--roi", "4",
                          "--window", "0"]))
    text = capsys.readouterr().out
    assert rc == 1 and "nothing written (rejected by" in text and "--force writes the best hypothesis" in text
    assert not list(tmp_path.glob("out*"))


def test_topics_without_a_bag_is_refused_before_any_work(tmp_path):
    with pytest.raises(UsageError, match=r"^--topics: only with --bag BAG$"):
        cmd_merge(_args(["merge", "a.yaml", "b.yaml", "--center", "0,0", "-o", str(tmp_path / "o"),
                         "--topics", "/r1/map,/r2/map"]))
    assert not list(tmp_path.iterdir())


def test_the_demos_ground_truth_is_the_geometry_of_its_views(tmp_path, capsys):
    """From centers.yaml alone: each map's true center is the scene's center (the world origin) seen from
    its robot's start pose; θ*_k = yaw_k − yaw_0; and t*_k carries map k's true center onto map 0's
    through the given (erroneous) centers: t*_k = (c_0 − ĉ_0) − R(θ*_k)(c_k − ĉ_k). (The file states
    its figures to 6 decimals.)"""
    out = tmp_path / "demo"
    rc = cmd_demo(_args(["demo", "-o", str(out), "--seed", "3", "--center-error", "0.1", "--window", "0.3",
                         "--json"]))
    res = json.loads(capsys.readouterr().out)
    doc = yaml.safe_load((out / "centers.yaml").read_text())
    maps, truth = doc["maps"], doc["truth"]
    yaw0 = math.radians(maps["Lyon"]["pose_world"][2])
    for n, m in maps.items():
        x, y, yaw_deg = m["pose_world"]
        assert m["center_true"] == pytest.approx(world_to_frame((0.0, 0.0), (x, y, math.radians(yaw_deg))).tolist(), abs=1e-5)
        th = math.degrees(math.radians(yaw_deg) - yaw0) % 360
        assert abs(angle_diff_deg(truth[n]["theta_deg"], th)) < 1e-4
        e0 = np.subtract(maps["Lyon"]["center_true"], maps["Lyon"]["center"])
        ek = np.subtract(m["center_true"], m["center"])
        assert truth[n]["translation_m"] == pytest.approx((e0 - rotation(th) @ ek).tolist(), abs=1e-5)
        assert 0 < max(abs(ek[0]), abs(ek[1])) <= 0.1  # the centers given are off, by at most the error
        assert load_map(out / m["map"]).resolution == 0.05
    assert rc == (0 if res["accepted"] else 1) == 0
    for n, t in truth.items():  # and the merge found it
        assert abs(angle_diff_deg(res["chosen"]["theta_deg"][n], t["theta_deg"])) <= 0.5
        assert math.dist(res["chosen"]["translation_m"][n], t["translation_m"]) <= 0.05
    assert (out / "merged.yaml").exists() and (out / "merged_overlay.png").exists()
