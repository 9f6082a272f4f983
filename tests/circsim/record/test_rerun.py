"""The rerun recording: what a .rrd holds, read back with rerun's own reader; interrupted runs; `circsim view`."""

import json
import math
import os
import signal
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from circsim.cli import main
from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.events import MergeCycle, RobotTick
from circsim.judge import judge_placement
from circsim.metrics import RobotMetrics, RunResult
from circsim.record import rerun as record
from circsim.record.entities import from_frame, known_window, overlay_fast, to_frame
from circsim.record.rerun import RerunRecorder
from circsim.record.viewer import read_recording, rerun_executable, view
from circsim.sim import truth_translation
from circsim.world.laser import scan as laser_scan
from circsim.world.motion import trajectories
from circsim.world.world import World
from merger.io.overlay import overlay_rgb
from merger.team.orders import MapInput, MergeParams, merge_team
from tests.strategies import three_views
from tests.subproc import sigint_default, wait_for

NAMES = ["Lyon", "Auckland", "Nevers"]  # scene1's robots, and the names three_views gives its maps


@pytest.fixture(autouse=True, scope="module")
def strict_rerun():
    """Bad data raises instead of being dropped with a warning (production keeps rerun's default, off)."""
    before = record.rr.strict_mode()
    record.rr.set_strict_mode(True)
    yield
    record.rr.set_strict_mode(before)


def verify(path) -> subprocess.CompletedProcess:
    """``rerun rrd verify`` (footers checked) with the executable shipped in the wheel."""
    return subprocess.run([rerun_executable(), "rrd", "verify", str(path)], capture_output=True, text=True,
                          timeout=120)


def texts(rec, entity):
    return [r["TextLog:text"][0] for r in rec.get(entity, []) if not r["static"]]


def series(rec, entity):
    """{series name: [(sim_time, value), ...]} of a plot entity (names from its static SeriesLines)."""
    rows = rec[entity]
    names = next(r["SeriesLines:names"] for r in rows if r["static"])
    out = {n: [] for n in names}
    for r in rows:
        if not r["static"]:
            for n, v in zip(names, r["Scalars:scalars"], strict=True):
                out[n].append((r["sim_time"], v))
    return out


def assert_logged_grid(row, grid):
    """A logged GridMap is ``grid`` cropped to a window holding all its known cells, placed at the
    window's corner: same cells at the same world positions, nothing known left out."""
    ros = ros_grid(row)  # row 0 = lowest y after the flip back
    assert row["GridMap:cell_size"][0] == pytest.approx(grid.resolution)
    off = (np.array(row["GridMap:translation"][0][:2]) - np.array(grid.origin)) / grid.resolution
    c0, r0 = (int(round(v)) for v in off)
    assert np.allclose(off, (c0, r0), atol=1e-4) and r0 >= 0 and c0 >= 0
    full = grid.to_ros()
    np.testing.assert_array_equal(ros, full[r0:r0 + ros.shape[0], c0:c0 + ros.shape[1]])
    assert np.count_nonzero(ros != -1) == np.count_nonzero(full != -1)


def ros_grid(row) -> np.ndarray:
    """The ROS int8 grid of a logged GridMap row (undoing the row flip)."""
    f = row["GridMap:format"][0]
    data = row["GridMap:data"][0].view(np.int8).reshape(f["height"], f["width"])
    return np.flipud(data)


# --- the recorder driven directly with real inputs -----------------------------------------------------
@pytest.fixture(scope="module")
def fabricated(tmp_path_factory):
    """A recording of real scene1 scans and real merges of synthetic maps, and everything that was logged."""
    sc = load_scenario(bundled_scenarios()["scene1"])
    world, trajs = World.from_scenario(sc), trajectories(sc)
    start = {n: trajs[n].start_pose() for n in NAMES}
    _, names, views, truth_onto_lyon = three_views(3)
    assert names == NAMES
    maps = {n: v for n, v in zip(names, views, strict=True)}
    centers = {n: to_frame(sc.world.center, start[n]) for n in NAMES}
    given = {n: (c[0] + 0.03, c[1] - 0.04) for n, c in centers.items()}  # a 5 cm center error
    sim = SimpleNamespace(scenario=sc, world=world, robot_names=list(NAMES), start_poses=start,
                          centers_given=given, center_world=tuple(sc.world.center),
                          circle_radius=sc.robots.radius_m, seed=sc.seed)
    path = tmp_path_factory.mktemp("rec") / "fabricated.rrd"
    rec = RerunRecorder(path, scan_log_hz=2.0, rays_every=2, merged_log_period_s=2.0)
    log = {"ticks": [], "published": {n: [] for n in NAMES}, "cycles": []}
    rng = np.random.default_rng(0)
    rec.on_start(sim)

    def tick(k):
        t = round(k * 0.1, 6)
        poses = {n: trajs[n].pose_at(t) for n in NAMES}
        for n, p in poses.items():
            world.set_robot_pose(n, *p)
        ticks = []
        for n, p in poses.items():
            s = laser_scan(world, n, p, rng, config=sc.laser, stamp=t)
            x, y = to_frame(p[:2], start[n])
            est = (x + 0.01 * k, y, p[2] - start[n][2] + 0.001 * k)  # a drifting SLAM estimate in M_i
            ticks.append(RobotTick(n, tuple(p), est, (0.0, 0.0, 0.0), 0.0, s))
        rec.on_tick(t, k, ticks)
        log["ticks"].append((t, k, ticks))
        return t

    # the maps' centers are given with errors (metres, in each map's frame): the translation window finds
    # t*_ij = R(θ*_ij)·e_j − e_i
    center_errors = {"Lyon": (0.15, 0.0), "Auckland": (0.0, -0.1), "Nevers": (-0.1, 0.1)}

    def merge(t, robot, params=None):
        order = [robot] + [n for n in NAMES if n != robot]
        e = center_errors
        inputs = [MapInput(n, maps[n][0], (maps[n][1][0] + e[n][0], maps[n][1][1] + e[n][1])) for n in order]
        res = merge_team(inputs, params or MergeParams(window_m=0.5))
        truth = {j: (truth_onto_lyon[j] - truth_onto_lyon[robot]) % 360 for j in order}
        t_truth = {j: truth_translation(truth[j], e[robot], e[j]) for j in order}
        top = res.top
        errors, t_errors, correct = judge_placement(top.theta_deg, {k: top.translation(k) for k in order},
                                                    truth, t_truth, 2.0, 0.1)
        first = res.accepted and correct and not any(c.robot == robot and c.first_correct for c in log["cycles"])
        c = MergeCycle(t, robot, "test", res, truth, correct, errors, first, res.accepted and not correct,
                       truth_translation_m=t_truth, translation_error_m=t_errors)
        rec.on_merge_cycle(c)
        log["cycles"].append(c)

    for k in range(30):
        t = tick(k)
        if k in (5, 20):
            for n in NAMES:
                rec.on_map_published(t, n, maps[n][0], given[n], centers[n])
                log["published"][n].append((t, maps[n][0]))
        if k == 6:
            for n in NAMES:
                for m in NAMES:
                    if m != n:
                        rec.on_map_received(t, n, m, 0.5)
        if k == 7:
            merge(t, "Lyon", MergeParams(nu_min=0.99, window_m=0.5, verification="whole_map"))  # rejected: ν_min impossible
            for n in NAMES:
                merge(t, n)  # accepted, first correct: logged at once
        if k in (8, 10):
            merge(t, "Lyon")  # within the period: kept pending, the newest (t = 1.0) wins
    rec.on_event(2.9, "warn", "something to note")
    merge(2.9, "Lyon")  # pending again, flushed by on_end
    res = RunResult(sc.name, sc.seed, {}, {n: RobotMetrics() for n in NAMES})
    res.sim_s = 2.9
    rec.on_end(res)
    return SimpleNamespace(path=path, rec=read_recording(path), log=log, sim=sim, maps=maps)


def test_recording_has_the_entity_tree(fabricated):
    paths = set(fabricated.rec)
    expected = {"/world", "/world/walls", "/world/pillars", "/world/objects", "/world/center",
                "/events/sim", "/run/scenario", "/run/metrics"}
    for n in NAMES:
        w = f"/world/robots/{n}"
        expected |= {f"{w}/circle", f"{w}/pose", f"{w}/scan", f"{w}/rays", f"{w}/map", f"{w}/map/local",
                     f"{w}/map/slam_pose", f"{w}/map/center_given", f"{w}/map/merged", f"/merge/{n}/overlay",
                     f"/events/{n}", f"{w}/centers/given", f"{w}/centers/placed", f"{w}/centers/placed_error"}
        expected |= {f"/plots/{n}/{p}" for p in ("omega", "nu", "support", "angle_error_deg",
                                                 "translation_error_m", "cycle_ms")}
    assert expected <= paths, expected - paths
    assert verify(fabricated.path).returncode == 0


def test_static_world_is_split_into_walls_pillars_objects(fabricated):
    rec, sc = fabricated.rec, fabricated.sim.scenario
    assert len(rec["/world/walls"][0]["LineStrips3D:strips"]) == 4
    assert len(rec["/world/pillars"][0]["LineStrips3D:strips"]) == len(sc.world.pillars) == 2
    # three chairs of four legs, and the overturned chair's seat and back
    assert len(rec["/world/objects"][0]["LineStrips3D:strips"]) == 3 * 4 + 2
    assert rec["/world"][0]["ViewCoordinates:xyz"] is not None


def test_poses_every_tick_and_scans_at_their_rate(fabricated):
    rec, ticks = fabricated.rec, fabricated.log["ticks"]
    for n in NAMES:
        pose_rows = rec[f"/world/robots/{n}/pose"]
        temporal = [r for r in pose_rows if not r["static"]]
        assert [r["step"] for r in temporal] == list(range(len(ticks)))
        for r, (t, _, tk) in zip(temporal, ticks, strict=True):
            p = next(k for k in tk if k.name == n).true_pose
            assert r["sim_time"] == pytest.approx(t)
            np.testing.assert_allclose(r["Transform3D:translation"][0][:2], p[:2], atol=1e-5)
            qz, qw = r["Transform3D:quaternion"][0][2:]
            assert math.remainder(2 * math.atan2(qz, qw) - p[2], 2 * math.pi) == pytest.approx(0, abs=1e-5)
        assert len([r for r in rec[f"/world/robots/{n}/map/slam_pose"] if not r["static"]]) == len(ticks)
        # 3 s at 2 Hz: t = 0, 0.5, ..., 2.5; rays with every second scan
        scans = rec[f"/world/robots/{n}/scan"]
        assert [r["sim_time"] for r in scans] == pytest.approx([0.0, 0.5, 1.0, 1.5, 2.0, 2.5])
        assert len(rec[f"/world/robots/{n}/rays"]) == 3
    # scan points are the laser returns in the world frame
    t, _, tk = ticks[5]
    k = next(k for k in tk if k.name == "Lyon")
    x, y, yaw = k.true_pose
    pts = k.scan.points()
    world = np.stack([x + np.cos(yaw) * pts[:, 0] - np.sin(yaw) * pts[:, 1],
                      y + np.sin(yaw) * pts[:, 0] + np.cos(yaw) * pts[:, 1]], axis=1)
    row = next(r for r in rec["/world/robots/Lyon/scan"] if r["sim_time"] == pytest.approx(t))
    np.testing.assert_allclose(np.array(row["Points3D:positions"])[:, :2], world, atol=1e-4)


def test_local_maps_at_each_publication_in_ros_order(fabricated):
    rec = fabricated.rec
    for n in NAMES:
        rows = rec[f"/world/robots/{n}/map/local"]
        published = fabricated.log["published"][n]
        assert len(rows) == len(published) == 2
        for r, (t, grid) in zip(rows, published, strict=True):
            assert r["sim_time"] == pytest.approx(t)
            assert_logged_grid(r, grid)
        s = fabricated.sim.start_poses[n]
        frame = rec[f"/world/robots/{n}/map"][0]
        assert frame["static"] and frame["Transform3D:translation"][0][:2] == pytest.approx(s[:2])
        label = rec[f"/world/robots/{n}/map/center_given"][0]["Points3D:labels"][0]
        assert "error 5.0 cm" in label, label
        given_w = rec[f"/world/robots/{n}/centers/given"][0]  # the same point, in W
        assert given_w["static"] and given_w["Points3D:labels"][0] == label
        np.testing.assert_allclose(given_w["Points3D:positions"][0][:2],
                                   from_frame(fabricated.sim.centers_given[n], s), atol=1e-5)
    assert sum("published map" in x for n in NAMES for x in texts(rec, f"/events/{n}")) == 6
    assert sum("received" in x and "delay" in x for n in NAMES for x in texts(rec, f"/events/{n}")) == 6


def test_merge_events_plots_and_throttled_merged_maps(fabricated):
    rec, cycles = fabricated.rec, fabricated.log["cycles"]
    accepted = [c for c in cycles if c.result.accepted]
    assert accepted and all(not c.false_merge for c in accepted)
    for n in NAMES:
        ev = texts(rec, f"/events/{n}")
        mine = [c for c in accepted if c.robot == n]
        assert sum(x.startswith("accepted merge") for x in ev) == len(mine)
        assert sum(x.startswith("FIRST CORRECT MERGE") for x in ev) == 1
        # plotted angle errors are the cycles' errors, one row per accepted merge
        plotted = series(rec, f"/plots/{n}/angle_error_deg")
        for m in NAMES:
            if m != n:
                assert [v for _, v in plotted[f"{m} angle error (°)"]] == pytest.approx(
                    [c.angle_error_deg[m] for c in mine])
        t_plotted = series(rec, f"/plots/{n}/translation_error_m")
        for m in NAMES:
            if m != n:
                assert [v for _, v in t_plotted[f"{m} translation error (m)"]] == pytest.approx(
                    [c.translation_error_m[m] for c in mine])
        # where the accepted alignments put the teammates' given centers: c_i + t_ij, drawn in W
        placed = [r for r in rec[f"/world/robots/{n}/centers/placed"] if not r["static"]]
        assert [r["sim_time"] for r in placed] == pytest.approx([c.t for c in mine])
        s_i, g_i, top = fabricated.sim.start_poses[n], fabricated.sim.centers_given[n], mine[-1].result.top
        mates = [m for m in top.theta_deg if m != n]
        want = [from_frame((g_i[0] + top.translation(m)[0], g_i[1] + top.translation(m)[1]), s_i)
                for m in mates]
        np.testing.assert_allclose(np.array(placed[-1]["Points3D:positions"])[:, :2], want, atol=1e-5)
        strips = rec[f"/world/robots/{n}/centers/placed_error"][-1]["LineStrips3D:strips"]
        sim = fabricated.sim
        ends = [from_frame(sim.centers_given[m], sim.start_poses[m]) for m in mates]
        np.testing.assert_allclose([np.array(st)[1, :2] for st in strips], ends, atol=1e-5)
        ms = series(rec, f"/plots/{n}/cycle_ms")[f"{n} merge cycle (ms)"]
        assert [v for _, v in ms] == pytest.approx([c.result.cost_ms for c in cycles if c.robot == n])
    rejected = [x for x in texts(rec, "/events/Lyon") if x.startswith("rejected merge")]
    assert len(rejected) == 1 and "ν_min 0.99" in rejected[0]
    nu = series(rec, "/plots/Lyon/nu")
    assert {"ν Lyon|Auckland", "ν Lyon|Nevers", "ν Auckland|Nevers", "ν_min"} == set(nu)
    assert len(series(rec, "/plots/Lyon/omega")) == 6  # 3 orders x 2 alignment steps
    # Lyon accepted at 0.7 (logged), 0.8 and 1.0 (pending: 1.0 wins at 2.7), 2.9 (flushed at the end)
    merged = rec["/world/robots/Lyon/map/merged"]
    assert [r["sim_time"] for r in merged] == pytest.approx([0.7, 1.0, 2.9])
    assert len(rec["/world/robots/Auckland/map/merged"]) == 1
    last = next(c for c in reversed(accepted) if c.robot == "Lyon")
    assert_logged_grid(merged[-1], last.result.merged)
    # the overlay is the thesis colour image of the aligned maps [self, teammates], in image row order
    ov = rec["/merge/Lyon/overlay"][-1]
    f = ov["Image:format"][0]
    img = np.flipud(ov["Image:buffer"][0].reshape(f["height"], f["width"], 3))
    names = ["Lyon", "Auckland", "Nevers"]
    full = overlay_rgb([last.result.layers[k].states for k in names], names)
    rs, cs = known_window([last.result.layers[k].states for k in names])
    np.testing.assert_array_equal(img, full[rs, cs])
    # the crop keeps every cell some map knows (every non-grey pixel of the full overlay)
    grey = np.all(full == (128, 128, 128), axis=2)
    assert np.count_nonzero(~grey[rs, cs]) == np.count_nonzero(~grey) > 0
    assert img.shape[0] < full.shape[0] and img.shape[1] < full.shape[1]
    assert "something to note" in texts(rec, "/events/sim")
    assert "finished" in texts(rec, "/events/sim")[-1]
    assert '"interrupted": false' in rec["/run/metrics"][0]["TextDocument:text"][0]


def test_overlay_fast_equals_overlay_rgb():
    rng = np.random.default_rng(1)
    for n in (2, 3, 4):
        layers = [rng.integers(0, 3, (37, 53)).astype(np.uint8) for _ in range(n)]
        names = ["Lyon", "Nevers", "Auckland", "Paris"][:n]
        np.testing.assert_array_equal(overlay_fast(layers, names), overlay_rgb(layers, names))


# --- whole runs ---------------------------------------------------------------------------------------
def test_every_accepted_merge_logged_with_merged_log_period_0(tmp_path):
    """``output.merged_log_period_s: 0`` logs the merged map and overlay of every accepted merge."""
    rrd, js = tmp_path / "all.rrd", tmp_path / "all.json"
    assert main(["run", "scene1", "--set", "duration_s=6", "--set", "output.merged_log_period_s=0",
                 "--rrd", str(rrd), "--json", str(js), "--quiet"]) == 0
    rec, d = read_recording(rrd), json.loads(js.read_text())
    assert sum(m["accepted"] for m in d["robots"].values()) > 3
    for n, m in d["robots"].items():
        assert len(rec.get(f"/world/robots/{n}/map/merged", [])) == m["accepted"]
        assert len(rec.get(f"/merge/{n}/overlay", [])) == m["accepted"]



@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("run")
    rrd, js = d / "run.rrd", d / "run.json"
    rc = main(["run", "scene1", "--set", "duration_s=12", "--set", "merger.method=fast", "--set",
               "center_error.magnitude_m=0.1", "--set", "merger.window_m=0.3", "--rrd", str(rrd), "--json",
               str(js), "--quiet"])
    assert rc == 0
    return SimpleNamespace(path=rrd, rec=read_recording(rrd), metrics=json.loads(js.read_text()))


@pytest.mark.slow
def test_run_recording_matches_the_metrics(short_run):
    rec, d = short_run.rec, short_run.metrics
    assert verify(short_run.path).returncode == 0
    for n, m in d["robots"].items():
        ev = texts(rec, f"/events/{n}")
        assert len(rec[f"/world/robots/{n}/map/local"]) == m["maps_published"] > 0
        assert sum(x.startswith("published map") for x in ev) == m["maps_published"]
        assert sum(x.startswith("received") for x in ev) == m["maps_received"] + m["maps_stale"]
        assert sum(x.startswith("received") and "stale" in x for x in ev) == m["maps_stale"]
        assert sum(x.startswith("accepted merge") for x in ev) == m["accepted"] > 0
        assert sum(x.startswith("rejected merge") for x in ev) == m["cycles"] - m["accepted"]
        assert sum("FALSE MERGE" in x for x in ev) == m["false_merges"]
        first = [r for r in rec[f"/events/{n}"] if r["TextLog:text"][0].startswith("FIRST CORRECT MERGE")]
        assert [r["sim_time"] for r in first] == pytest.approx([m["first_merge_s"]])
        # every accepted merge is plotted; the last plotted errors are the run's final angle errors
        plotted = series(rec, f"/plots/{n}/angle_error_deg")
        for mate, err in m["final_angle_error_deg"].items():
            if mate != n:
                values = plotted[f"{mate} angle error (°)"]
                assert len(values) == m["accepted"]
                assert values[-1][1] == pytest.approx(err)
        t_plotted = series(rec, f"/plots/{n}/translation_error_m")
        for mate, err in m["final_translation_error_m"].items():
            if mate != n:
                assert len(t_plotted[f"{mate} translation error (m)"]) == m["accepted"]
                assert t_plotted[f"{mate} translation error (m)"][-1][1] == pytest.approx(err)
        # the segment from where n's held alignment puts a teammate's given center to where it truly is
        # is as long as that alignment's translation error |t − t*|
        last = rec[f"/world/robots/{n}/centers/placed_error"][-1]
        labels = rec[f"/world/robots/{n}/centers/placed"][-1]["Points3D:labels"]
        for st, label in zip(last["LineStrips3D:strips"], labels, strict=True):
            mate = label.split("'s center")[0]
            a, b = np.array(st)[:, :2]
            assert np.hypot(*(a - b)) == pytest.approx(m["final_translation_error_m"][mate], abs=1e-5)
        assert len(series(rec, f"/plots/{n}/cycle_ms")[f"{n} merge cycle (ms)"]) == m["cycles"]
        assert 0 < len(rec[f"/world/robots/{n}/map/merged"]) <= m["accepted"]
        assert len(rec[f"/merge/{n}/overlay"]) == len(rec[f"/world/robots/{n}/map/merged"])
        ticks = int(round(d["sim_s"] / d["params"]["dt_s"])) + 1
        assert len([r for r in rec[f"/world/robots/{n}/pose"] if not r["static"]]) == ticks
        # the SLAM pose error every tick; at whole seconds it is the JSON's sample (cm there, m in the JSON)
        err = series(rec, f"/plots/{n}/slam_pose_error")
        assert len(err["position error (cm)"]) == len(err["yaw error (°)"]) == ticks
        at = {round(t, 6): v for t, v in err["position error (cm)"]}
        at_deg = {round(t, 6): v for t, v in err["yaw error (°)"]}
        for t, m_err, deg in m["slam_pose_error"]:
            assert at[round(t, 6)] == pytest.approx(100 * m_err, abs=1e-6)
            assert at_deg[round(t, 6)] == pytest.approx(deg, abs=1e-6)
        assert max(v for _, v in err["position error (cm)"]) == pytest.approx(100 * m["slam_pose_error_max"]["m"])
    metrics_doc = rec["/run/metrics"][0]["TextDocument:text"][0]
    assert json.loads(metrics_doc.split("```json\n")[1].split("\n```")[0])["robots"] == d["robots"]


@pytest.mark.slow
def test_ctrl_c_leaves_a_complete_readable_recording(tmp_path):
    rrd, js = tmp_path / "cut.rrd", tmp_path / "cut.json"
    cmd = [sys.executable, "-m", "circsim.cli", "run", "scene1", "--set", "duration_s=60", "--set",
           "merger.method=fast", "--rrd", str(rrd), "--json", str(js), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "RERUN_STRICT": "1"}, preexec_fn=sigint_default)
    try:
        # wait until merges are being logged (the file grows past the static part), then press Ctrl-C; the
        # recording is written to a temporary file beside cut.rrd and renamed when complete (issue 26)
        def grown():
            parts = list(tmp_path.glob(".cut.rrd.*.part.rrd"))
            return parts and parts[0].stat().st_size > 300_000

        wait_for(lambda: grown() or proc.poll() is not None, 120, "the recording to grow")
        assert proc.poll() is None, proc.communicate()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    d = json.loads(js.read_text())
    assert d["interrupted"] and d["sim_s"] < 60
    assert verify(rrd).returncode == 0, verify(rrd).stderr
    assert not list(tmp_path.glob(".*.part*")), "the temporary recording was renamed into place"
    rec = read_recording(rrd)
    assert "INTERRUPTED" in texts(rec, "/events/sim")[-1]
    for n, m in d["robots"].items():
        assert len(rec[f"/world/robots/{n}/map/local"]) == m["maps_published"] > 0
        assert sum(x.startswith("accepted merge") for x in texts(rec, f"/events/{n}")) == m["accepted"]
    # buffered poses were flushed up to the interruption (the interrupted tick may have logged its poses)
    poses = [r["sim_time"] for r in rec["/world/robots/Lyon/pose"] if not r["static"]]
    assert d["sim_s"] - 1e-6 <= poses[-1] <= d["sim_s"] + d["params"]["dt_s"] + 1e-6


def test_spawn_and_file_together(tmp_path, monkeypatch):
    """``--spawn --rrd``: the file is complete and the live stream goes to the viewer's gRPC port."""
    port = _free_port()
    server = subprocess.Popen([rerun_executable(), "--serve-grpc", "--port", str(port), "--bind", "127.0.0.1"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    spawned = []
    try:
        wait_for(lambda: _listening(port), 30, "the gRPC server")
        monkeypatch.setattr(record, "VIEWER_PORT", port)
        monkeypatch.setattr(record, "has_display", lambda: True)
        monkeypatch.setattr(record.rr, "spawn", lambda **kw: spawned.append(kw))  # the server stands in
        rrd = tmp_path / "both.rrd"
        from circsim.sim import Simulation

        sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=3", "merger.method=fast"])
        Simulation(sc, [RerunRecorder(rrd, spawn=True)]).run()
    finally:
        server.terminate()
        server.wait(timeout=30)
    assert spawned and spawned[0]["executable_path"] == rerun_executable() and spawned[0]["port"] == port
    assert verify(rrd).returncode == 0
    assert len(read_recording(rrd)["/world/robots/Lyon/map/local"]) >= 1


def test_recorder_rejects_bad_outputs(tmp_path, monkeypatch):
    with pytest.raises(ValueError, match="no_dir"):
        RerunRecorder(tmp_path / "no_dir" / "x.rrd")
    with pytest.raises(ValueError, match=r"\.rrd"):
        RerunRecorder(tmp_path / "x.txt")
    with pytest.raises(ValueError):
        RerunRecorder()
    monkeypatch.setattr(record, "has_display", lambda: False)
    with pytest.raises(ValueError, match="--web"):
        RerunRecorder(spawn=True)


# --- circsim view ---------------------------------------------------------------------------------------
def test_view_rejects_missing_or_foreign_files(tmp_path, fabricated):
    with pytest.raises(ValueError, match="nope.rrd: no such file"):
        view(tmp_path / "nope.rrd")
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(ValueError, match=r"notes.txt: not a rerun recording \(expected a .rrd file\)"):
        view(tmp_path / "notes.txt")
    (tmp_path / "fake.rrd").write_bytes(b"PK\x03\x04 zip")
    with pytest.raises(ValueError, match="fake.rrd: not a rerun recording"):
        view(tmp_path / "fake.rrd")
    (tmp_path / "empty.rrd").write_bytes(b"")
    with pytest.raises(ValueError, match="empty file"):
        view(tmp_path / "empty.rrd")


def test_view_without_display_prints_one_line(fabricated, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    assert main(["view", str(fabricated.path)]) == 1
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "no display" in out
    assert "--serve-web" in out and "--bind 127.0.0.1" in out and "--web" in out


def test_cli_view_of_a_missing_file_is_a_user_error(tmp_path, capsys):
    assert main(["view", str(tmp_path / "gone.rrd")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "gone.rrd: no such file" in err


def test_view_web_serves_on_localhost_until_ctrl_c(fabricated):
    web, grpc = _free_port(), _free_port()
    code = (f"import sys; from circsim.record.viewer import view; "
            f"sys.exit(view({str(fabricated.path)!r}, web=True, web_port={web}, grpc_port={grpc}))")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True, preexec_fn=sigint_default)
    try:
        wait_for(lambda: _http_ok(f"http://127.0.0.1:{web}/") or proc.poll() is not None, 60, "the web viewer")
        assert proc.poll() is None
        assert _listening(grpc)
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    assert f"http://127.0.0.1:{web}" in out
    wait_for(lambda: not _listening(web), 30, "the web viewer to stop")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _listening(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex(("127.0.0.1", port)) == 0


def _http_ok(url: str) -> bool:
    try:
        with urllib.request.urlopen(url, timeout=2) as r:
            return r.status == 200
    except OSError:
        return False


def test_rerun_executable_is_the_bundled_viewer():
    exe = Path(rerun_executable())
    assert exe.is_file() and os.access(exe, os.X_OK)
    assert "rerun_cli" in exe.parts


@pytest.mark.parametrize("rule, whole", [("auto", True), ("whole_map", True), ("contrast", True),
                                         ("roi_score", False)])
def test_the_verdict_plot_names_nu_whenever_the_checks_hold_nu(rule, whole):
    """The checks of ``auto`` (the default) and ``contrast`` hold ω̃ of the whole maps: plotted as ν against
    ν_min (they were labelled "score" against score_min, a threshold those values are never compared with)."""
    from types import SimpleNamespace

    from circsim.record.rerun import verdict_series
    from merger.team.verify import Verification

    cfg = SimpleNamespace(verification=rule, nu_min=0.5, score_min=0.3)
    rows = verdict_series(cfg, {"A|B": Verification(0.61, None, True)})
    assert rows[0][:2] == (("ν A|B" if whole else "score A|B"), 0.61)
    assert rows[-1][:2] == (("ν_min", 0.5) if whole else ("score_min", 0.3))
