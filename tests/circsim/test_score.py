"""`circsim score RUN` (issue 35): any merger's answers judged against a bag's truth with the run's metrics.
The bench's own merges, exported beside the bag, score exactly as the run did; a merged map is read back
into placements."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from circsim.cli import main
from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.locate import locate
from circsim.score import MERGES_FILE, ScoreError, load_truth, read_transforms, score
from circsim.sim import Simulation
from merger.grid import OccupancyGrid
from merger.team.superpose import fuse
from merger.transform import sample_nearest

pytest.importorskip("rosbags", reason="the ros extra (rosbags) is not installed")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """Scene 1 with centers 5 cm off, rotation only and a low ν_min: correct merges and false ones (some
    within a millimetre of the 10 cm tolerance) in 8 simulated seconds."""
    from circsim.record.bag import BagRecorder

    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(
        ["duration_s=8", "center_error=0.05", "merger.nu_min=0.3", "merger.min_support=30"])
    out = tmp_path_factory.mktemp("score") / "scene1"
    maps = {}

    class Maps(BagRecorder):
        def on_map_published(self, t, robot, grid, center_given, center_true):
            super().on_map_published(t, robot, grid, center_given, center_true)
            maps[robot] = (t, grid)

    sim = Simulation(sc, [Maps(out)])
    res = sim.run()
    return sim, res, out, maps


def test_the_bench_merges_score_as_the_run(run):
    sim, res, out, _ = run
    assert res.false_merges > 0 and any(r.first_merge_s is not None for r in res.robots.values())
    d = score(load_truth(out), read_transforms(out / MERGES_FILE, load_truth(out)))
    assert d["false_merges"] == res.false_merges and d["gross_merges"] == res.gross_merges
    for n, r in res.robots.items():
        s = d["robots"][n]
        assert (s["first_merge_s"], s["first_pair_merge_s"], s["estimates"], s["false_merges"]) == \
            (r.first_merge_s, r.first_pair_merge_s, r.accepted, r.false_merges)
        assert s["first_merge_translation_error_m"] == pytest.approx(r.first_merge_translation_error_m, abs=1e-12)
        for k, v in r.final_angle_error_deg.items():
            assert s["final_angle_error_deg"][k] == pytest.approx(v, abs=1e-9)
            assert s["final_translation_error_m"][k] == pytest.approx(r.final_translation_error_m[k], abs=1e-12)
    assert [(e["t"], e["robot"]) for e in d["false_merge_log"]] == [(e["t"], e["robot"]) for e in res.false_merge_log]


def _rows(truth, t, robot, placements, estimate=None):
    return [{"t_s": t, "robot": robot, "map": j, "yaw_deg": p[0], "x_m": p[1], "y_m": p[2],
             **({"estimate": estimate} if estimate is not None else {})} for j, p in placements.items()]


def test_an_external_merger_in_yaml(run, tmp_path):
    """The truth itself is a correct merge at once; a half-turn of one map is a gross false merge; an estimate
    of one teammate is a pair merge only."""
    sim, _, out, _ = run
    truth = load_truth(out)
    a, b, c = sim.robot_names
    exact = {j: truth.rigid[a][j] for j in (b, c)}
    flipped = dict(exact, **{c: ((exact[c][0] + 180.0) % 360.0, exact[c][1], exact[c][2])})
    rows = _rows(truth, 1.0, a, {b: exact[b]}) + _rows(truth, 2.0, a, flipped) + _rows(truth, 3.0, a, exact) \
        + _rows(truth, 3.0, b, {a: truth.rigid[b][a], c: (truth.rigid[b][c][0] + 2.5, *truth.rigid[b][c][1:])})
    f = tmp_path / "t.yaml"
    f.write_text(yaml.safe_dump({"transforms": rows}))
    d = score(truth, read_transforms(f, truth))
    ra, rb = d["robots"][a], d["robots"][b]
    assert (ra["first_pair_merge_s"], ra["first_merge_s"], ra["false_merges"], ra["gross_merges"]) == (1.0, 3.0, 1, 1)
    assert ra["final_angle_error_deg"][b] == pytest.approx(0.0, abs=1e-9)
    assert (rb["first_merge_s"], rb["false_merges"], rb["gross_merges"]) == (None, 1, 0)  # 2.5° off: not gross
    assert d["robots"][c]["estimates"] == 0


def test_bad_transforms_files_are_one_line(run, tmp_path, capsys):
    _, _, out, _ = run
    truth = load_truth(out)
    f = tmp_path / "t.csv"
    f.write_text("t_s,robot,map,yaw_deg,x_m\n1,a,b,0,0\n")
    with pytest.raises(ScoreError, match="missing y_m"):
        read_transforms(f, truth)
    f.write_text("t_s,robot,map,yaw_deg,x_m,y_m\n1,Lyon,Paris,0,0,0\n")
    with pytest.raises(ScoreError, match=r"line 2: map: 'Paris' is no robot"):
        read_transforms(f, truth)
    f.write_text("t_s,robot,map,yaw_deg,x_m,y_m\n1,Lyon,Nevers,nan,0,0\n")
    assert main(["score", str(out), "--transforms", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "finite" in err[0] and "line 2" in err[0]
    assert main(["score", str(tmp_path), "--transforms", str(f)]) == 2
    assert "no circsim_truth.yaml" in capsys.readouterr().err


def _merged(maps, placed, res=0.05):
    """The maps superposed in one frame: map k at pose placed[k] (nearest-cell sampling, as a merger warps)."""
    box = []
    for k, (yaw, x, y) in placed.items():
        g = maps[k]
        a = math.radians(yaw)
        for cx in (g.origin[0], g.origin[0] + g.width * res):
            for cy in (g.origin[1], g.origin[1] + g.height * res):
                box.append((x + math.cos(a) * cx - math.sin(a) * cy, y + math.sin(a) * cx + math.cos(a) * cy))
    lo, hi = np.min(box, axis=0), np.max(box, axis=0)
    w, h = int(math.ceil((hi[0] - lo[0]) / res)), int(math.ceil((hi[1] - lo[1]) / res))
    yy, xx = np.mgrid[0:h, 0:w]
    pts = np.stack([lo[0] + (xx + 0.5) * res, lo[1] + (yy + 0.5) * res], axis=-1)
    layers = []
    for k, (yaw, x, y) in placed.items():
        a = math.radians(yaw)
        d = pts - (x, y)
        local = np.stack([math.cos(a) * d[..., 0] + math.sin(a) * d[..., 1],
                          -math.sin(a) * d[..., 0] + math.cos(a) * d[..., 1]], axis=-1)
        layers.append(sample_nearest(maps[k], local.reshape(-1, 2)).reshape(h, w))
    return OccupancyGrid(fuse(layers), res, (float(lo[0]), float(lo[1])))


@pytest.mark.slow
def test_locate_finds_a_map_in_a_merged_grid(run):
    sim, _, out, maps = run
    truth = load_truth(out)
    a, b, c = sim.robot_names
    grids = {k: g for k, (_, g) in maps.items()}
    placed = {a: (0.0, 0.0, 0.0), b: truth.rigid[a][b], c: truth.rigid[a][c]}
    merged = _merged(grids, placed)
    for k, p in placed.items():
        f, (yaw, x, y) = locate(grids[k], merged)
        assert f > 0.9
        assert abs(math.remainder(yaw - p[0], 360.0)) <= 0.5 and math.dist((x, y), p[1:]) <= 0.05


def _write_merged_bag(path, grids_at):
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    from tests.merger.io.test_bagio import _msg

    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(path, version=9) as w:
        conn = w.add_connection("/map", "nav_msgs/msg/OccupancyGrid", typestore=ts)
        for t, g in grids_at:
            m = _msg(ts, g)
            m.header.stamp.sec, m.header.stamp.nanosec = int(t), int(round((t % 1) * 1e9))
            w.write(conn, int(t * 1e9) + 1, ts.serialize_cdr(m, "nav_msgs/msg/OccupancyGrid"))


@pytest.mark.slow
def test_merged_bag_scores_right_and_wrong_placements(run, tmp_path, capsys):
    """A merged /map with every map at its true place: every robot merged at its stamp; with one map turned
    30° about its center: a false merge for each robot that sees it."""
    sim, _, out, maps = run
    truth = load_truth(out)
    a, b, c = sim.robot_names
    t_last = max(t for t, _ in maps.values()) + 0.5
    grids = {k: g for k, (_, g) in maps.items()}
    good = {a: (0.0, 0.0, 0.0), b: truth.rigid[a][b], c: truth.rigid[a][c]}
    yaw, x, y = good[c]
    cc = truth.centers[c]  # turn c's map 30° about its given center: a placement 30° off
    a30 = math.radians(30.0)
    x2, y2 = math.cos(a30) * cc[0] - math.sin(a30) * cc[1], math.sin(a30) * cc[0] + math.cos(a30) * cc[1]
    r = math.radians(yaw)
    bad = dict(good, **{c: (yaw + 30.0, x + math.cos(r) * (cc[0] - x2) - math.sin(r) * (cc[1] - y2),
                            y + math.sin(r) * (cc[0] - x2) + math.cos(r) * (cc[1] - y2))})
    bag = tmp_path / "merged"
    _write_merged_bag(bag, [(t_last, _merged(grids, good)), (t_last + 6.0, _merged(grids, bad))])
    js = tmp_path / "s.json"
    assert main(["score", str(out), "--merged-bag", str(bag), "--json", str(js)]) == 0
    d = yaml.safe_load(js.read_text())
    for k in (a, b, c):
        assert d["robots"][k]["first_merge_s"] == pytest.approx(t_last)
        assert d["robots"][k]["false_merges"] == 1 and d["robots"][k]["gross_merges"] == 1
    assert "false merges 3 (3 gross)" in capsys.readouterr().out


def test_scores_never_overwrite_an_input(run, capsys):
    _, _, out, _ = run
    before = (out / "circsim_truth.yaml").read_bytes()
    assert main(["score", str(out), "--transforms", str(out / MERGES_FILE), "--json", str(out / "circsim_truth.yaml")]) == 2
    assert "is also an input" in capsys.readouterr().err
    assert (out / "circsim_truth.yaml").read_bytes() == before
