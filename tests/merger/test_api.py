"""merger.merge (merger/api.py): one call from map files or grids to a verdict in the CLI's words, each
map's pose in the first map's frame and the merged map; judged against ground truth on views cut from
the real office map (tests/data/real-maps) with known robot poses, as ``merger demo --real`` makes them."""

import json
import math

import numpy as np
import pytest

import merger
from merger import MergeInputError, Pose
from merger.io.mapio import load_map, save_map
from merger.synthetic import (
    arc_viewpoints,
    partial_view_of_grid,
    robot_pose_on_circle,
    widest_free_point,
    world_to_frame,
)
from merger.transform import resample
from tests.paths import REAL_MAP

YAW_OFFSETS = (0.0, 17.0, -33.0)


@pytest.fixture(scope="module")
def views():
    """Three robots' views of the office, each in its own frame: (world poses, grids, exact centers)."""
    office = load_map(REAL_MAP)
    center, clearance = widest_free_point(office)
    radius = min(0.8 * clearance, 1.8)
    poses, grids, centers = [], [], []
    for a, off in zip((90.0, 210.0, 330.0), YAW_OFFSETS, strict=True):
        p = robot_pose_on_circle(a, radius, center, off)
        grids.append(partial_view_of_grid(office, p, arc_viewpoints(a, 15.0, radius, center)))
        poses.append(p)
        centers.append(tuple(float(v) for v in world_to_frame(center, p)))
    return poses, grids, centers


def true_pose(poses, k) -> Pose:
    """Robot k's map frame (its start pose) in robot 0's: p_0 = R(yaw_k − yaw_0) p_k + R(−yaw_0)(o_k − o_0)."""
    x0, y0, a0 = poses[0]
    xk, yk, ak = poses[k]
    d = world_to_frame([(xk, yk)], (x0, y0, a0))[0]
    return Pose(float(d[0]), float(d[1]), math.degrees(ak - a0) % 360.0)


def pose_error(p: Pose, q: Pose) -> tuple[float, float]:
    return abs((p.yaw_deg - q.yaw_deg + 180.0) % 360.0 - 180.0), math.hypot(p.x - q.x, p.y - q.y)


def test_pose_is_a_rigid_motion_and_its_inverse():
    p = Pose(1.0, -2.0, 90.0)
    np.testing.assert_allclose(p.apply([1.0, 0.0]), [1.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(p.inverse().apply(p.apply([[0.3, 0.7], [-2.0, 5.0]])), [[0.3, 0.7], [-2.0, 5.0]],
                               atol=1e-12)
    assert p.inverse().yaw_deg == 270.0


def test_three_map_files_merge_to_their_true_poses(views, tmp_path):
    poses, grids, centers = views
    paths = [save_map(g, tmp_path / f"{n}.yaml")[0] for n, g in zip(("Lyon", "Auckland", "Nevers"), grids,
                                                                    strict=True)]
    res = merger.merge(paths, centers=centers)
    assert res.accepted and res.names == ("Lyon", "Auckland", "Nevers") and res.frame == "Lyon"
    assert res.poses["Lyon"] == Pose(0.0, 0.0, 0.0)
    for k, n in enumerate(res.names):
        d_deg, d_m = pose_error(res.poses[n], true_pose(poses, k))
        assert d_deg <= 0.3 and d_m <= 0.05, (n, res.poses[n], true_pose(poses, k))
    assert res.merged is not None and res.merged.count()["occupied"] > max(g.count()["occupied"] for g in grids)
    assert set(res.evidence) == {"Lyon|Auckland", "Lyon|Nevers", "Auckland|Nevers"}


def test_rough_centers_in_a_window_give_the_same_true_pose(views):
    """The pose is of the frames, not of the centers: centers 0.25 m off, searched in a ±0.5 m window."""
    poses, grids, centers = views
    rough = [centers[0], (centers[1][0] + 0.2, centers[1][1] - 0.15)]
    res = merger.merge(grids[:2], centers=rough, window_m=0.5, names=["A", "B"])
    assert res.accepted
    d_deg, d_m = pose_error(res.poses["B"], true_pose(poses, 1))
    assert d_deg <= 0.3 and d_m <= 0.05, res.poses["B"]
    # the placement about the given centers is the same motion as the pose
    o = res.team.chosen
    x0 = np.asarray(rough[0]) + o.translation("B") + Pose(0, 0, o.theta_deg["B"]).apply(
        np.asarray([0.7, -0.4]) - rough[1])
    np.testing.assert_allclose(res.poses["B"].apply([0.7, -0.4]), x0, atol=1e-9)


def test_the_verdict_is_in_the_command_line_words(views, tmp_path, capsys):
    """rule and reason say what ``merger merge`` prints ("accepted by whole-map ν: …"), and the command
    prints the same poses (issue 45, items 2 and 3: ``TeamMergeResult.rule`` said "verification")."""
    from merger.cli import main

    _, grids, centers = views
    paths = [str(save_map(g, tmp_path / f"{n}.yaml")[0]) for n, g in zip(("a", "b"), grids[:2], strict=True)]
    res = merger.merge(paths, centers=centers[:2])
    assert res.team.rule == "verification" and res.rule in ("whole-map ν", "contrast")
    args = ["merge", *paths, "--center", "{},{}".format(*centers[0]), "--center", "{},{}".format(*centers[1]),
            "-o", str(tmp_path / "m")]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert f"(accepted by {res.rule}: {res.reason})" in out
    p = res.poses["b"]
    assert f"b in a's frame: x {p.x:+.3f} m, y {p.y:+.3f} m, yaw {p.yaw_deg:.2f}°" in out
    assert main([*args[:-2], "-o", str(tmp_path / "m2"), "--json"]) == 0
    js = json.loads(capsys.readouterr().out)
    assert js["poses"]["b"] == pytest.approx(p.to_dict()) and js["decided_by"] == res.rule


def test_a_refusal_has_its_rule_and_no_merged_map(views):
    _, grids, centers = views
    res = merger.merge(grids[:2], centers=centers[:2], nu_min=1.0, verification="whole_map")
    assert not res.accepted and res.merged is None
    assert res.rule == "verification" and "ν" in res.reason
    assert set(res.poses) == {"map1", "map2"}  # the best refused hypothesis, for the record


def test_a_coarser_map_is_resampled_with_a_note(views):
    poses, grids, centers = views
    res = merger.merge([grids[0], resample(grids[1], 0.1)], centers=centers[:2])
    assert res.notes == ("maps[1]: resampled from 0.1 to 0.05 m per cell, the first map's (occupied where any "
                         "occupied cell falls, free where free cells cover half a cell; docs/real-maps.md)",)
    assert res.accepted
    d_deg, d_m = pose_error(res.poses["map2"], true_pose(poses, 1))
    assert d_deg <= 0.5 and d_m <= 0.1


@pytest.mark.parametrize(("kw", "message"), [
    ({"centers": [(0.0, 0.0)]}, "centers: expected one (x, y) per map (2), got [(0.0, 0.0)]"),
    ({"centers": [(0.0, 0.0), (1e7, 0.0)]}, "centers[1]: (1e+07, 0) is outside maps[1], which spans"),
    ({"centers": [(0.0, 0.0), (math.nan, 0.0)]}, "centers[1]: expected finite numbers"),
    ({"roi_m": 1000.0}, "roi_m: expected a number in (0, 100], got 1000"),
    ({"roi_m": 0.2, "window_m": 0.0}, "roi_m: expected a side of 10 to"),
    ({"window_m": 3.0}, "window_m"),
    ({"nu_min": 2.0}, "nu_min must be a number in [0, 1], got 2.0"),
    ({"roi": 16}, "roi: not a setting of a merge: expected one of roi_m, measure,"),
    ({"algorithm": "sift"}, "algorithm: expected one of thesis, features, hough, got 'sift'"),
    ({"names": ["a", "a"]}, "names: expected 2 distinct names"),
])
def test_every_input_check_is_one_error_type_naming_the_input(views, kw, message):
    _, grids, centers = views
    kw = {"centers": [(0.0, 0.0), (0.0, 0.0)], **kw}
    with pytest.raises(MergeInputError) as e:
        merger.merge(grids[:2], **kw)
    assert message in str(e.value) and "\n" not in str(e.value)


def test_files_are_named_and_checked(views, tmp_path):
    _, grids, _ = views
    a = save_map(grids[0], tmp_path / "r1" / "map.yaml")[0]
    (tmp_path / "bad.yaml").write_text("image: nowhere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(MergeInputError, match=r"given twice"):
        merger.merge([a, a], centers=[(0, 0), (0, 0)])
    with pytest.raises(MergeInputError, match=r"nowhere\.pgm"):
        merger.merge([a, tmp_path / "bad.yaml"], centers=[(0, 0), (0, 0)])
    with pytest.raises(MergeInputError, match=r"maps: expected at least two maps, got 1"):
        merger.merge([a], centers=[(0, 0)])
    with pytest.raises(MergeInputError, match=r"maps\[1\]: expected a map file path or an OccupancyGrid"):
        merger.merge([a, 3], centers=[(0, 0), (0, 0)])


def test_search_pair_is_the_unverified_search_and_align_its_old_name(views):
    """merger.align answered the search unverified while ``merger align`` runs every check (issue 45,
    item 4): the search is merger.search_pair; the old name warns and answers the same."""
    _, grids, centers = views
    al = merger.search_pair(grids[0], grids[1], center_ref=centers[0], center_moving=centers[1])
    with pytest.warns(DeprecationWarning, match="search_pair"):
        old = merger.align(grids[0], grids[1], center_ref=centers[0], center_moving=centers[1])
    assert (old.theta_deg, old.translation_m, old.score) == (al.theta_deg, al.translation_m, al.score)
    assert not hasattr(al, "accepted")  # an answer of the search, not a verdict
