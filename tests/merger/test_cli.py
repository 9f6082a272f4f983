"""The `merger` command: align and merge real files, JSON output, one-line errors with exit code 2."""

import dataclasses
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from merger import load_map
from merger.cli import OPTIONS, UsageError, build_parser, join_negative_xy, main, params_from
from merger.io.mapio import save_map
from merger.search import angle_diff_deg
from merger.synthetic import arc_viewpoints, partial_view_of_grid, robot_pose_on_circle, world_to_frame
from merger.team.frames import fused_layers
from merger.team.orders import MapInput, MergeParams
from merger.team.params import RULES
from merger.team.superpose import fuse
from merger.transform import rotation
from tests.paths import REAL_MAP
from tests.strategies import saved_views

REAL = REAL_MAP


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    d = tmp_path_factory.mktemp("maps")
    paths, centers, truth = saved_views(d)
    return d, paths, [f"{c[0]:.6f},{c[1]:.6f}" for c in centers], truth


def test_align_json(saved, capsys):
    d, paths, centers, truth = saved
    rc = main(["align", str(paths[0]), str(paths[1]), "--center", centers[0], "--center-moving", centers[1],
               "--json", "--method", "reference", "--window", "0"])  # the thesis's search: rotation only
    out = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert abs((out["theta_deg"] - truth["Auckland"] + 180) % 360 - 180) <= 1.0
    for k in ("score", "runner_up_deg", "verification", "center_ref", "center_moving", "theta_grid_deg",
              "translation_grid_m", "refined"):
        assert k in out
    assert out["translation_m"] == [0.0, 0.0] and out["window_m"] == 0.0
    assert out["verification"]["accepted"] and out["verification"]["support"] >= 150


@pytest.mark.parametrize("name", ["merged", "merged.yaml"])
def test_merge_writes_map_and_overlay(saved, capsys, name, tmp_path):
    d, paths, centers, truth = saved
    rc = main(["merge", *map(str, paths), *sum((["--center", c] for c in centers), []), "-o", str(tmp_path / name)])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["merged.pgm", "merged.yaml", "merged_overlay.png"]
    assert "chosen" in text


def test_merge_json_orders_carry_translations(saved, capsys):
    d, paths, centers, truth = saved
    for window in ("0", "0.3"):
        rc = main(["merge", *map(str, paths), *sum((["--center", c] for c in centers), []), "-o", str(d / "m"),
                   "--json", "--roi", "6", "--window", window])
        res = json.loads(capsys.readouterr().out)
        assert rc in (0, 1)
        for o in res["orders"]:
            assert set(o["translation_m"]) == set(o["theta_deg"]) == {"Lyon", "Auckland", "Nevers"}
            assert o["translation_m"]["Lyon"] == [0.0, 0.0]
            assert all(s["window_m"] == float(window) for s in o["steps"])
            if window == "0":
                assert all(t == [0.0, 0.0] for t in o["translation_m"].values())


# --- a real translation: views of the real office map, the moving map's center given off by E ---

E = (0.2, -0.15)  # the error of the moving center, in the moving map's frame (the reference center is exact)


@pytest.fixture(scope="module")
def off_center(tmp_path_factory):
    """Two views of the real office (upper room) saved as map_saver files; the truth (θ*, t* = R(θ*)·E)."""
    from merger.synthetic import widest_free_point

    office = load_map(REAL)
    c, clearance = widest_free_point(office)
    radius = min(0.8 * clearance, 1.8)
    d = tmp_path_factory.mktemp("real")
    out = []
    for name, a, yaw in (("ref", 90.0, -60.0), ("mov", 210.0, 45.0)):
        pose = robot_pose_on_circle(a, radius, c, yaw)
        g = partial_view_of_grid(office, pose, arc_viewpoints(a, 15.0, radius, c))
        out.append((pose, save_map(g, d / f"{name}.yaml")[0], tuple(float(v) for v in world_to_frame(c, pose))))
    (p1, y1, c1), (p2, y2, c2) = out
    theta = math.degrees(p2[2] - p1[2]) % 360
    t = rotation(theta) @ np.array(E)
    c2_given = (c2[0] + E[0], c2[1] + E[1])
    args = ["align", str(y1), str(y2), "--center", f"{c1[0]!r},{c1[1]!r}",
            "--center-moving", f"{c2_given[0]!r},{c2_given[1]!r}", "--roi", "4"]
    return args, theta, t, c1, office.resolution


def test_align_recovers_the_translation_of_a_rough_center(off_center, capsys):
    args, theta, t, c_ref, _ = off_center
    assert main([*args, "--window", "0.3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert abs(angle_diff_deg(out["theta_deg"], theta)) <= 0.5, (out["theta_deg"], theta)
    assert np.hypot(*(np.array(out["translation_m"]) - t)) <= 0.05, (out["translation_m"], t)
    assert out["refined"] and out["window_m"] == 0.3 and out["verification"]["accepted"]
    # the text names the translation and where MOVING's center lands in REF's frame (c_ref + t)
    assert main([*args, "--window", "0.3"]) == 0
    text = capsys.readouterr().out
    tx, ty = out["translation_m"]
    assert f"translation  {tx:+.3f}, {ty:+.3f} m" in text
    assert f"lands at ({c_ref[0] + tx:.3f}, {c_ref[1] + ty:.3f}) in REF's frame" in text
    assert "ACCEPTED" in text


def test_no_refine_gives_the_grid_answer_and_window_0_no_translation(off_center, capsys):
    args, theta, t, _, res = off_center
    assert main([*args, "--window", "0.3", "--no-refine", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert not out["refined"]
    assert out["theta_deg"] == out["theta_grid_deg"] and out["translation_m"] == out["translation_grid_m"]
    assert round(out["theta_deg"] * 10) == pytest.approx(out["theta_deg"] * 10, abs=1e-6)  # the 0.1° grid
    cells = np.array(out["translation_m"]) / res
    assert np.allclose(cells, np.round(cells), atol=1e-9)  # whole cells
    assert np.abs(np.array(out["translation_m"]) - t).max() <= res  # within a cell of the truth
    main([*args, "--window", "0", "--json"])
    out = json.loads(capsys.readouterr().out)
    assert out["translation_m"] == [0.0, 0.0] and out["window_m"] == 0.0


def test_merge_force_places_the_maps_with_their_translations(off_center, tmp_path, capsys):
    """A rejected merge written with --force uses the top hypothesis's rotations *and* translations."""
    args, *_ = off_center
    y1, y2, c1, c2 = args[1], args[2], args[4], args[6]
    out = tmp_path / "forced"
    rc = main(["merge", y1, y2, "--center", c1, "--center", c2, "-o", str(out), "--roi", "4", "--window", "0.3",
               "--nu-min", "1", "--verification", "whole_map", "--force", "--json"])  # ν = 1 is never reached: rejected
    res = json.loads(capsys.readouterr().out)
    assert rc == 1 and not res["accepted"]
    top = max(res["orders"], key=lambda o: o["nu_sum"])
    assert np.hypot(*top["translation_m"]["mov"]) > 0.1
    maps = [MapInput(Path(p).stem, load_map(p), tuple(map(float, c.split(",")))) for p, c in ((y1, c1), (y2, c2))]
    layers = fused_layers(maps, top["theta_deg"], {k: tuple(v) for k, v in top["translation_m"].items()})
    assert np.array_equal(load_map(out.with_suffix(".yaml")).states, fuse([g.states for g in layers]))


# --- negative centers: the natural spelling --center -1.2,0.5 ---

@pytest.mark.parametrize("argv, expected", [
    (["align", "a", "b", "--center", "-1.2,0.5"], ["align", "a", "b", "--center=-1.2,0.5"]),
    (["--center-moving", "-.5,-2", "--center", "1,-2"], ["--center-moving=-.5,-2", "--center", "1,-2"]),
    (["--real-center", "-1e-3,4"], ["--real-center=-1e-3,4"]),
    (["--center", "-o", "x"], ["--center", "-o", "x"]),  # not a pair: argparse reports the missing value
    (["--", "--center", "-1,2"], ["--", "--center", "-1,2"]),
])
def test_join_negative_xy(argv, expected):
    assert join_negative_xy(argv) == expected


def test_negative_centers_parse(saved):
    p = build_parser()
    a = p.parse_args(join_negative_xy(["align", "r.yaml", "m.yaml", "--center", "-1.2,0.5",
                                       "--center-moving", "-0.3,-0.4", "--window", "0.2"]))
    assert (a.center, a.center_moving, a.window, a.refine) == ("-1.2,0.5", "-0.3,-0.4", 0.2, True)
    m = p.parse_args(join_negative_xy(["merge", "a.yaml", "b.yaml", "--center", "-1,-2", "--center", "3,-4",
                                       "-o", "x", "--no-refine"]))
    assert m.center == ["-1,-2", "3,-4"] and not m.refine
    d = p.parse_args(join_negative_xy(["demo", "--real", "r.yaml", "--real-center", "-1.825,-2.825"]))
    assert d.real_center == "-1.825,-2.825"
    # end to end, in a separate process as a user types it
    _, paths, _, _ = saved
    r = subprocess.run([sys.executable, "-m", "merger.cli", "align", str(paths[0]), str(paths[1]),
                        "--center", "-1.2,0.5", "--center-moving", "-0.3,-0.4", "--roi", "4", "--window", "0.2"],
                       capture_output=True, text=True)
    assert r.returncode in (0, 1), r.stderr  # parsed and aligned (the centers are wrong: likely rejected)
    assert "MOVING's center lands at" in r.stdout and "given REF center (-1.200, 0.500)" in r.stdout


BAD_PARAMS = [
    (["--window", "-0.1"], "--window"), (["--window", "nan"], "--window"), (["--window", "inf"], "--window"),
    (["--window", "2.5"], "--window"), (["--roi", "4", "--window", "1.5"], "--window"),
    (["--window", "abc"], "--window"), (["--nu-min", "nan"], "--nu-min"), (["--nu-min", "5"], "--nu-min"),
    (["--nu-min", "-0.5"], "--nu-min"),  # ν is ω̃ ≥ 0: a negative threshold accepted every placement
    (["--min-support", "-1"], "--min-support"), (["--roi", "nan"], "--roi"), (["--roi", "-2"], "--roi"),
    (["--roi", "1e6"], "--roi"), (["--roi", "inf"], "--roi"), (["--tolerance", "0"], "--tolerance"),
    (["--contrast-min", "-1"], "--contrast-min"), (["--roi-min-support", "-1"], "--roi-min-support"),
    (["--min-support", "1099511627776"], None),  # the whole-map support has no cap (only the ROI's floor has)
]


@pytest.mark.parametrize("cmd", ["align", "merge", "demo"])
@pytest.mark.parametrize("bad, needle", BAD_PARAMS)
def test_bad_parameters_one_line_exit_2_nothing_written(saved, tmp_path, capsys, cmd, bad, needle):
    d, paths, centers, _ = saved
    out = tmp_path / "out"
    out.mkdir()
    args = {"align": ["align", str(paths[0]), str(paths[1]), "--center", centers[0]],
            "merge": ["merge", str(paths[0]), str(paths[1]), "--center", centers[0], "-o", str(out / "m")],
            "demo": ["demo", "-o", str(out / "demo")]}[cmd]
    if needle is None:
        assert params_from(build_parser().parse_args([*args, *bad])).min_support == 2 ** 40
        return
    assert main([*args, *bad]) == 2
    err = capsys.readouterr()
    assert err.out == "" and err.err.count("\n") == 1 and err.err.startswith("merger: error: ")
    assert needle in err.err and any(w in err.err for w in ("expected", "must be", "invalid")), err.err
    assert list(out.iterdir()) == []


@pytest.mark.parametrize("cmd", ["align", "merge", "demo"])
def test_the_options_default_to_merge_params_and_refuse_by_its_rules(cmd):
    """Each merge option's default is MergeParams's and its refusal is the setting's one rule named by the
    option (merger.team.params.RULES)."""
    required = {"align": ["align", "a.yaml", "b.yaml", "--center", "0,0"],
                "merge": ["merge", "a.yaml", "--center", "0,0", "-o", "m"], "demo": ["demo"]}[cmd]
    args, d = build_parser().parse_args(required), MergeParams()
    p = params_from(args)
    assert all(getattr(p, f.name) == getattr(d, f.name) for f in dataclasses.fields(MergeParams))
    for name, (_, dest) in OPTIONS.items():
        if hasattr(args, dest):
            assert getattr(args, dest) == getattr(d, name), name
    bad = build_parser().parse_args([*required, "--nu-min", "1.5"])
    with pytest.raises(UsageError) as e:
        params_from(bad)
    assert str(e.value) == "--nu-min must be a number in [0, 1], got 1.5" == str(_refusal("nu_min", 1.5, "--nu-min"))


def _refusal(name, value, key):
    with pytest.raises(ValueError) as e:
        RULES[name](value, key)
    return e.value


def test_merge_params_value_error_is_the_last_line_of_defence(saved, monkeypatch, capsys):
    """A value the CLI's own checks let through but MergeParams refuses is still a one-line error."""
    import merger.cli

    monkeypatch.setattr(merger.cli, "check_window", lambda *a: None)
    d, paths, centers, _ = saved
    assert main(["align", str(paths[0]), str(paths[1]), "--center", centers[0], "--window", "3"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "window" in err and "quarter" in err


@pytest.mark.parametrize("args, needle", [
    (["align", "nope.yaml", "nope2.yaml", "--center", "0,0"], "nope.yaml"),
    (["align", "{p0}", "{p1}", "--center", "abc"], "--center"),
    (["merge", "{p0}", "{p1}", "--center", "0,0", "--center", "1,1", "--center", "2,2", "-o", "x"], "--center"),
    (["align", "{p0}"], "required"),
    (["align", "{p0}", "{p1}", "--center", "0,0", "--roi", "-3"], "--roi"),
    (["align", "{p0}", "{p1}", "--center", "0,0", "--window", "-1"], "--window"),
    (["merge", "{p0}", "{p1}", "--center", "0,0", "-o", "x", "--roi", "2", "--window", "nan"], "--window"),
    (["merge", "{p0}", "{p1}", "--center", "0,0", "-o", "{p0}/out"], "cannot write"),  # a file, not a folder
    (["demo", "-o", "{p0}/x"], "cannot write"),
])
def test_user_errors_one_line_exit_2(saved, args, needle):
    d, paths, _, _ = saved
    args = [a.format(p0=paths[0], p1=paths[1]) for a in args]
    r = subprocess.run([sys.executable, "-m", "merger.cli", *args], capture_output=True, text=True, cwd=d)
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and needle in r.stderr and "Traceback" not in r.stderr


def test_corrupt_image_is_one_line(tmp_path):
    """OpenCV's own log line about an unreadable image is silenced: the user sees our one line."""
    (tmp_path / "g.pgm").write_bytes(b"P5\n10 10\n255\nxx")
    (tmp_path / "g.yaml").write_text("image: g.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    r = subprocess.run([sys.executable, "-m", "merger.cli", "align", "g.yaml", "g.yaml", "--center", "0,0"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "g.pgm: not a readable image" in r.stderr, r.stderr


def errors(text: str, what: str) -> dict[str, float]:
    line = text.split(f"{what} errors: ")[1].splitlines()[0]
    return {n: float(re.match(r"[-\d.]+", v).group()) for n, v in (e.split(maxsplit=1) for e in line.split(", "))}


def test_demo_recovers_rough_centers(tmp_path, capsys):
    """The demo with centers given off by up to ±0.2 m: angle and translation errors against the truth."""
    rc = main(["demo", "-o", str(tmp_path), "--center-error", "0.2"])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert "centers given off by up to ±0.2 m" in text
    assert max(errors(text, "angle").values()) <= 0.5
    assert max(errors(text, "translation").values()) <= 0.05
    assert (tmp_path / "merged_overlay.png").exists()


def test_demo_window_0_is_the_thesis_search(tmp_path, capsys):
    rc = main(["demo", "-o", str(tmp_path), "--window", "0"])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert max(errors(text, "angle").values()) <= 0.5 and max(errors(text, "translation").values()) == 0.0


def test_demo_defaults_are_accepted(tmp_path, capsys):
    assert main(["demo", "-o", str(tmp_path)]) == 0, capsys.readouterr().out


def test_demo_real_map_negative_center(tmp_path, capsys):
    rc = main(["demo", "--real", str(REAL), "--real-center", "-1.825,-2.825", "--radius", "1.0",
               "-o", str(tmp_path), "--window", "0"])
    text = capsys.readouterr().out
    assert rc == 0, text
    m = re.search(r"\(center ([-\d.]+),([-\d.]+),", text)
    assert abs(float(m.group(1)) + 1.825) < 0.01 and abs(float(m.group(2)) + 2.825) < 0.01


# --- issue 12: names, resolutions, all-or-none outputs, demo's centers ---------------------------------
def test_maps_saved_under_one_name_are_named_by_folder(saved, tmp_path, capsys):
    """Three maps saved as map_saver's default ``map.yaml`` in r1/, r2/, r3/ keep three names."""
    d, paths, centers, _ = saved
    copies = []
    for i, p in enumerate(paths):
        g = load_map(p)
        copies.append(save_map(g, tmp_path / f"r{i + 1}" / "map.yaml")[0])
    args = ["merge", *map(str, copies), *sum((["--center", c] for c in centers), []), "-o", str(tmp_path / "m"),
            "--json"]
    assert main(args) == 0
    res = json.loads(capsys.readouterr().out)
    assert set(res["chosen"]["order"]) == {"r1/map", "r2/map", "r3/map"}


def test_the_same_map_twice_is_refused(saved, tmp_path, capsys):
    d, paths, centers, _ = saved
    assert main(["merge", str(paths[0]), str(paths[0]), "--center", centers[0], "-o", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "given twice" in err and str(paths[0]) in err
    assert list(tmp_path.iterdir()) == []


def test_maps_of_different_resolutions_are_resampled_alike_by_align_and_merge(saved, tmp_path, capsys):
    """Issue 36 item 7: merge refused ("resample one first", with no tool to do it) and align ran silently on
    0.1 m against 0.05 m cells. Both now resample the other maps onto the first one's cells and say so."""
    from merger.transform import resample

    d, paths, centers, truth = saved
    g = load_map(paths[1])
    coarse = save_map(resample(g, 2 * g.resolution), tmp_path / "coarse.yaml")[0]
    # upsampled walls are two cells thick: ω̃ drops (0.59 -> 0.41 here), the contrast rule still separates them
    align = ["align", str(paths[0]), str(coarse), "--center", centers[0], "--center-moving", centers[1],
             "--verification", "contrast"]
    assert main([*align, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["resampled"]) == 1 and "coarse.yaml: resampled from 0.1 to 0.05 m per cell" in out["resampled"][0]
    assert abs(angle_diff_deg(out["theta_deg"], truth["Auckland"])) <= 1.0
    assert main(align) == 0
    assert "note         " + out["resampled"][0] in capsys.readouterr().out
    merge = ["merge", str(paths[0]), str(coarse), "--center", centers[0], "--center", centers[1],
             "-o", str(tmp_path / "m"), "--verification", "contrast"]
    assert main([*merge, "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["resampled"] == out["resampled"]
    assert res["chosen"]["theta_deg"]["coarse"] == pytest.approx(out["theta_deg"])  # the same answer
    assert main(merge) == 0
    assert "note: " + out["resampled"][0] in capsys.readouterr().out
    assert load_map(tmp_path / "m.yaml").resolution == g.resolution


def test_merge_outputs_all_or_none(saved, tmp_path, capsys):
    """The overlay cannot be written (a folder holds its name): neither are OUT.yaml and OUT.pgm."""
    d, paths, centers, _ = saved
    (tmp_path / "m_overlay.png").mkdir()
    args = ["merge", *map(str, paths), *sum((["--center", c] for c in centers), []), "-o", str(tmp_path / "m")]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "m_overlay.png" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m_overlay.png"]


def test_demo_writes_centers_and_the_command_that_re_merges(tmp_path, capsys):
    import shlex

    import yaml

    assert main(["demo", "-o", str(tmp_path / "d"), "--center-error", "0.1", "--window", "0.3"]) == 0
    out = capsys.readouterr().out
    doc = yaml.safe_load((tmp_path / "d" / "centers.yaml").read_text())
    assert list(doc["maps"]) == ["Lyon", "Auckland", "Nevers"] and doc["truth_onto"] == "Lyon"
    for m in doc["maps"].values():
        assert (tmp_path / "d" / m["map"]).exists()
        assert 0 < math.dist(m["center"], m["center_true"]) <= 0.1 * math.sqrt(2) + 1e-9
    command = doc["merge_command"]
    assert f"re-merge them: {command}" in out and "--window 0.3" in command
    argv = shlex.split(command)
    assert argv[:2] == ["merger", "merge"]
    assert main([*argv[1:], "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    for n, t in doc["truth"].items():  # the re-merge finds the ground truth the file states
        assert abs(angle_diff_deg(res["chosen"]["theta_deg"][n], t["theta_deg"])) <= 0.5
        assert math.dist(res["chosen"]["translation_m"][n], t["translation_m"]) <= 0.05
    assert (tmp_path / "d" / "remerged.yaml").exists() and (tmp_path / "d" / "remerged_overlay.png").exists()


def test_overlay_picture_title_names_the_order_angles_nu_and_verdict(saved, tmp_path):
    import cv2

    from merger.cli import overlay_title
    from merger.team.orders import MergeParams, merge_team

    d, paths, centers, truth = saved
    maps = [MapInput(p.stem, load_map(p), tuple(map(float, c.split(",")))) for p, c in zip(paths, centers,
                                                                                         strict=True)]
    res = merge_team(maps, MergeParams(verification="whole_map"))
    title = overlay_title(res)
    head, evidence = title.split("\n")
    assert title.isascii() and head.endswith("ACCEPTED by whole-map nu") and ">".join(res.chosen.order) in head
    assert f"{res.chosen.theta_deg[maps[1].name]:.1f}" in head
    assert evidence == "; ".join(f"{k} nu {v.nu:.3f} ({v.support} cells)" for k, v in res.chosen.checks.items())
    rejected = merge_team(maps, MergeParams(verification="whole_map", nu_min=0.99))
    rejected_title = overlay_title(rejected)
    assert "REJECTED, written with --force: verification: nu(" in rejected_title and rejected_title.isascii()
    assert "?" not in rejected_title  # the reason's ν spelt out, not lost
    args = ["merge", *map(str, paths), *sum((["--center", c] for c in centers), []), "-o", str(tmp_path / "m")]
    assert main(args) == 0
    img = cv2.imread(str(tmp_path / "m_overlay.png"))
    g = load_map(tmp_path / "m.yaml")
    assert img.shape[1] >= 420 and img.shape[0] > 24  # upscaled and cropped, with its title and legend
    assert max(img.shape[:2]) <= 4 * max(g.shape) + 24 + 200


def test_align_says_no_evidence_when_the_rois_hold_no_occupied_cell(tmp_path, capsys):
    from merger.grid import FREE_S, OccupancyGrid

    y, _ = save_map(OccupancyGrid(np.full((60, 60), FREE_S, np.uint8), 0.05, (-1.5, -1.5)), tmp_path / "empty.yaml")
    rc = main(["align", str(y), str(y), "--center", "0,0", "--roi", "2", "--window", "0.2"])
    out = capsys.readouterr().out
    assert rc == 1 and out.startswith("no evidence") and "50 cells of support" in out
    # issue 36 item 4: the hint says how to choose the center and the ROI
    assert "walls of both maps within 1 m of it, or a larger ROI (--roi, merger.roi_m; real maps: 16 m)" in out
    rc = main(["align", str(y), str(y), "--center", "0,0", "--roi", "2", "--window", "0.2", "--json"])
    assert rc == 1 and json.loads(capsys.readouterr().out)["verdict"] == "no_evidence"


# --- issue 36 items 1-3: refusals that explain themselves, the evidence shown, align = merge ---


def test_a_refusal_names_its_rule_and_figures_in_text_json_and_title(off_center, tmp_path, capsys):
    """With a ±0.2 m window the pair passes verification but the guard beyond the window finds a better
    alignment outside it. merge printed the order "[accepted]", then "no verified merge", the reason only in
    the JSON's ambiguity field; align said ACCEPTED."""
    from merger.cli import overlay_title
    from merger.team.orders import MapInput, MergeParams, merge_team

    args, *_ = off_center
    y1, y2, c1, c2 = args[1], args[2], args[4], args[6]
    merge = ["merge", y1, y2, "--center", c1, "--center", c2, "-o", str(tmp_path / "m"), "--roi", "4",
             "--window", "0.2", "--verification", "contrast"]
    assert main([*merge, "--json"]) == 1
    res = json.loads(capsys.readouterr().out)
    assert (res["verdict"], res["rule"]) == ("rejected", "guard")
    assert res["reason"].startswith("beyond the window: mov's best alignment lies outside ±0.2 m")
    assert all(o["accepted"] for o in res["orders"])  # the order itself passed verification
    assert main(merge) == 1
    text = capsys.readouterr().out
    assert "[accepted]" not in text and "ACCEPTED" not in text
    assert "[verified, but the cycle is rejected by the guard beyond the window (below)]" in text
    assert "REJECTED by the guard beyond the window: mov's best alignment lies outside ±0.2 m" in text
    assert "inside the window: θ" in text and "widen the window" in text
    assert "nothing written (rejected by the guard beyond the window; --force" in text
    # align: the same checks, the same verdict and reason
    assert main([*args, "--window", "0.2", "--verification", "contrast", "--json"]) == 1
    al = json.loads(capsys.readouterr().out)
    assert (al["verdict"], al["rule"], al["reason"]) == ("rejected", "guard", res["reason"])
    assert al["verification"]["passed"]
    assert main([*args, "--window", "0.2", "--verification", "contrast"]) == 1
    text = capsys.readouterr().out
    assert "ACCEPTED" not in text and "verdict      REJECTED by the guard beyond the window: mov's best" in text
    # the overlay written with --force says it too
    maps = [MapInput("ref", load_map(y1), tuple(map(float, c1.split(",")))),
            MapInput("mov", load_map(y2), tuple(map(float, c2.split(","))))]
    title = overlay_title(merge_team(maps, MergeParams(roi_m=4, window_m=0.2, verification="contrast"),
                                     orders=[(0, 1)]))
    assert "REJECTED, written with --force: the guard beyond the window: mov's best alignment" in title


@pytest.mark.slow
def test_the_evidence_of_the_contrast_rule_is_shown(saved, tmp_path, capsys):
    """With --verification contrast the title read "nu: 0.34 ACCEPTED" (as if ν ≥ 0.5 had been broken) and the
    contrast, its rival and the support were printed nowhere."""
    d, paths, centers, _ = saved
    merge = ["merge", *map(str, paths), *sum((["--center", c] for c in centers), []), "-o", str(tmp_path / "m"),
             "--verification", "contrast"]
    assert main([*merge, "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    checks = res["chosen"]["checks"]
    assert len(checks) == 3 and all({"contrast", "fit", "rival_fit", "rival_offset_deg", "contrast_support"}
                                    <= set(c) for c in checks.values())
    assert main(merge) == 0
    text = capsys.readouterr().out
    pair, c = next(iter(checks.items()))
    assert f"{pair} contrast {c['contrast']:.2f} (fit {c['fit']:.3f} vs rival {c['rival_fit']:.3f} at " in text
    assert f"{c['contrast_support']} cells; ν {c['nu']:.2f})" in text
    assert "(accepted by contrast: " in text
    from merger.cli import overlay_title
    from merger.team.orders import MapInput, MergeParams, merge_team

    maps = [MapInput(p.stem, load_map(p), tuple(map(float, c.split(",")))) for p, c in zip(paths, centers, strict=True)]
    head, evidence = overlay_title(merge_team(maps, MergeParams(verification="contrast"))).split("\n")
    assert head.endswith("ACCEPTED by contrast") and evidence.count("contrast ") == 3 and "rival" in evidence


@pytest.mark.parametrize("window", ["0", "0.1", "0.2", "0.3"])
def test_align_and_a_merge_of_the_same_pair_agree(off_center, tmp_path, capsys, window):
    """align accepted (contrast 2.27) what merge refused (the guard): both now run every check of a merge, on
    the same search (MOVING onto REF; a merge of two maps searches the second onto the first)."""
    args, *_ = off_center
    y1, y2, c1, c2 = args[1], args[2], args[4], args[6]
    rc_a = main([*args, "--window", window, "--json"])
    al = json.loads(capsys.readouterr().out)
    rc_m = main(["merge", y1, y2, "--center", c1, "--center", c2, "-o", str(tmp_path / "m"), "--roi", "4",
                 "--window", window, "--json"])
    res = json.loads(capsys.readouterr().out)
    assert rc_a == rc_m and (al["verdict"], al["rule"], al["reason"]) == (res["verdict"], res["rule"], res["reason"])
    top = res["chosen"] or res["orders"][0]
    assert top["steps"][0]["theta_deg"] == al["theta_deg"] and top["steps"][0]["translation_m"] == al["translation_m"]


def test_align_help_lists_only_its_own_options():
    """Issue 36 item 10: align --help listed the merge-only --no-combine-orders; --measure, --method and demo
    --seed had no help."""
    p = build_parser()
    sub = next(a for a in p._actions if a.dest == "cmd").choices
    assert "--no-combine-orders" not in sub["align"].format_help()
    assert "--no-combine-orders" in sub["merge"].format_help()
    for cmd, opt in (("align", "--measure"), ("align", "--method"), ("merge", "--method"), ("demo", "--seed")):
        action = next(a for a in sub[cmd]._actions if opt in a.option_strings)
        assert action.help, (cmd, opt)
