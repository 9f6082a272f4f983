"""Hostile inputs, round 4 (issue 46): the bag, scoring and baseline surfaces keep the promise that nothing
is lost. Each test names its item of the issue; each failed on the code before it."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
import yaml

from tests.subproc import run_capped
from tests.test_hostile_inputs import one_line_error

BIN = Path(sys.executable).parent

needs_rosbags = pytest.mark.skipif(
    __import__("importlib").util.find_spec("rosbags") is None, reason="the ros extra (rosbags) is not installed")


def _cli(tmp_path, prog, *args, timeout_s=120, **kw):
    return run_capped([str(BIN / prog), *map(str, args)], tmp_path, timeout_s=timeout_s, **kw)


@needs_rosbags
def test_item1_a_bag_on_a_full_disk_keeps_the_figures_the_json_and_the_maps(tmp_path):
    """Files capped at 250 kB (RLIMIT_FSIZE: EFBIG, as ENOSPC on a full disk): the bag's MCAP passes it in
    the first simulated second; the JSON (8 kB) and the maps (100 kB each) fit. Before: the whole run was
    lost (``circsim: error: No space left on device``, no figures, no JSON, no maps, a hidden folder left)."""
    bag, js, maps = tmp_path / "bag" / "out", tmp_path / "m.json", tmp_path / "maps"
    code, out, err, _ = _cli(tmp_path, "circsim", "run", "scene1", "--set", "duration_s=3", "--quiet",
                             "--bag", bag, "--json", js, "--save-maps", maps, fsize_bytes=250_000)
    assert code == 2, err
    one_line_error(err, "circsim", f"--bag {bag}", "cannot write the bag", "figures are above")
    assert "false merges" in out and "metrics:" in out
    assert yaml.safe_load(js.read_text())["sim_s"] == pytest.approx(3.0)
    assert (maps / "Lyon.yaml").exists() and (maps / "centers.yaml").exists()
    assert not bag.exists() and list((tmp_path / "bag").iterdir()) == []


@needs_rosbags
@pytest.mark.parametrize("case", ["json_is_bag", "maps_are_bag", "json_in_bag", "rrd_in_bag", "maps_in_bag"])
def test_item3_outputs_that_clash_with_the_bag_are_refused_before_work_and_create_nothing(tmp_path, case):
    """`--bag X --json X` ran, then lost the JSON; `--bag D --save-maps D` left the bag in a hidden folder;
    `--bag D --json D/m.json` made an empty D and then refused it. Now refused before the first tick, and
    the check creates nothing."""
    d = tmp_path / "out" / "D"
    extra, needles = {
        "json_is_bag": (["--json", d], ["--json", "also written by --bag"]),
        "maps_are_bag": (["--save-maps", d], ["--save-maps", "also written by --bag"]),
        "json_in_bag": (["--json", d / "m.json"], ["--json", "inside the --bag folder"]),
        "rrd_in_bag": (["--rrd", d / "r.rrd"], ["--rrd", "inside the --bag folder"]),
        "maps_in_bag": (["--save-maps", d / "maps"], ["--save-maps", "inside the --bag folder"]),
    }[case]
    code, out, err, _ = _cli(tmp_path, "circsim", "run", "scene1", "--set", "duration_s=0.5", "--quiet",
                             "--bag", d, *extra, timeout_s=60)
    assert code == 2 and out == "", err
    one_line_error(err, "circsim", str(d), *needles)
    assert not (tmp_path / "out").exists()


def test_item3_a_refused_run_creates_no_output_folder(tmp_path):
    """The JSON's writability check made its folder before a later check refused the run."""
    code, out, err, _ = _cli(tmp_path, "circsim", "run", "scene1", "--quiet", "--json", tmp_path / "new" / "m.json",
                             "--rrd", tmp_path / "new" / "m.json", timeout_s=60)
    assert code == 2 and out == "", err
    one_line_error(err, "circsim", "also written by --rrd")
    assert not (tmp_path / "new").exists()


@needs_rosbags
def test_item4_a_killed_run_s_bag_part_is_removed_by_the_next_run(tmp_path):
    """A run killed outright left a 13 MB `.NAME.XXXX/` that no later run removed. The part of a run still
    writing (its lock held) is left alone."""
    from circsim.config.scenario import bundled_scenarios, load_scenario
    from circsim.record.bag import BagRecorder
    from circsim.record.parts import BAG_SUFFIX, claim_bag_part, remove_stale_bag_parts
    from circsim.sim import Simulation

    target = tmp_path / "out"
    stale = tmp_path / f".out.dead1234{BAG_SUFFIX}"
    (stale / "out").mkdir(parents=True)
    (stale / "out" / "out_0.mcap").write_bytes(b"x" * 1000)
    live, fd = claim_bag_part(target)  # another run, still writing
    other = tmp_path / f".other.dead5678{BAG_SUFFIX}"  # another bag's part: not ours to judge
    other.mkdir()
    try:
        sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=0.3"])
        bag = BagRecorder(target)
        Simulation(sc, [bag]).run()
        assert bag.write_error is None and (target / "metadata.yaml").exists()
        assert not stale.exists() and live.is_dir() and other.is_dir()
    finally:
        os.close(fd)
    assert remove_stale_bag_parts(target) == [live] and not live.exists()  # that run ended: its part goes too


@needs_rosbags
def test_item2_an_output_inside_the_input_bag_is_refused_before_work(tmp_path):
    """`merger merge --bag B ... -o B/metadata` replaced the bag's metadata.yaml (exit 0; the bag unreadable)."""
    import numpy as np

    from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid
    from tests.merger.io.test_bagio import write_bag

    g = OccupancyGrid(np.full((60, 60), FREE_S, np.uint8), 0.05, (-1.5, -1.5))
    g.states[10:12, 5:50] = OCCUPIED_S
    g.states[20:50, 40:42] = OCCUPIED_S
    b = tmp_path / "B"
    write_bag(b, {"/a/map": [g], "/b/map": [g]})
    before = {p.name: p.read_bytes() for p in b.iterdir()}
    for out in [b / "metadata", b / "sub" / "m"]:
        code, stdout, err, _ = _cli(tmp_path, "merger", "merge", "--bag", b, "--topics", "/a/map,/b/map",
                                    "--center", "0,0", "--center", "0,0", "-o", out, timeout_s=60)
        assert code == 2 and stdout == "", err
        one_line_error(err, "merger", "-o", f"inside the input bag {b}")
    assert {p.name: p.read_bytes() for p in b.iterdir()} == before


def _grid_msg(**info):
    import numpy as np
    from rosbags.typesys import Stores, get_typestore

    from merger.grid import OccupancyGrid
    from tests.merger.io.test_bagio import _msg

    m = _msg(get_typestore(Stores.ROS2_HUMBLE), OccupancyGrid(np.zeros((3, 4), np.uint8), 0.05, (1.0, -2.0)))
    for k, v in info.items():
        if k == "data":
            m.data = np.asarray(v, np.int8)
        elif k == "x":
            m.info.origin.position.x = v
        else:
            setattr(m.info, k, v)
    return m


@needs_rosbags
@pytest.mark.parametrize("info, needle", [
    ({"resolution": 1e-30}, "info.resolution: expected a cell size in [0.001, 1000] m, got 1e-30"),
    ({"resolution": 3e38}, "info.resolution: expected a cell size in [0.001, 1000] m"),
    ({"data": [0] * 11 + [127]}, "data: expected cell values in -1..100 (-1 unknown, 0..100 occupancy), got 127 "
                                 "(cell 11; 1 such cells)"),
    ({"data": [-2] + [0] * 11}, "got -2 (cell 0"),
    ({"x": 1e300}, "info.origin.position: expected finite numbers within 1e+06 m"),
])
def test_items5_8_occupancy_grid_messages_outside_the_map_limits_are_refused(info, needle):
    """Item 5: `resolution 1e-30` gave an IndexError in circsim/locate.py; item 8: `resolution 3e38`, or cells
    of 127, were accepted (charging the merger false merges; `merge --bag` read 127 as occupied)."""
    from merger.io.bagio import grid_from_message
    from merger.io.mapread import MapFileError

    with pytest.raises(MapFileError) as e:
        grid_from_message(_grid_msg(**info), "m: topic /map")
    assert str(e.value).startswith("m: topic /map: ") and needle in str(e.value)


@pytest.fixture(scope="module")
def run_bag(tmp_path_factory):
    """A run of scene1 (1 s) as a bag, for `circsim score`."""
    pytest.importorskip("rosbags", reason="the ros extra (rosbags) is not installed")
    from circsim.config.scenario import bundled_scenarios, load_scenario
    from circsim.record.bag import BagRecorder
    from circsim.sim import Simulation

    out = tmp_path_factory.mktemp("run") / "scene1"
    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=1"])
    Simulation(sc, [BagRecorder(out)]).run()
    return out


@pytest.mark.parametrize("res", [1e-30, 3e38])
def test_item5_score_of_a_merged_bag_with_an_absurd_resolution_is_one_line(run_bag, tmp_path, res, capsys):
    """`circsim score RUN --merged-bag M` with `resolution 1e-30`: IndexError after a cast warning."""
    import numpy as np

    from circsim.cli import main
    from merger.grid import OCCUPIED_S, OccupancyGrid
    from tests.circsim.test_score import _write_merged_bag

    g = OccupancyGrid(np.zeros((40, 40), np.uint8), res, (0.0, 0.0))
    g.states[5:7, 5:30] = OCCUPIED_S
    _write_merged_bag(tmp_path / "M", [(0.5, g)])
    assert main(["score", str(run_bag), "--merged-bag", str(tmp_path / "M")]) == 2
    captured = capsys.readouterr()
    one_line_error(captured.err, "circsim", str(tmp_path / "M"), "topic /map", "info.resolution")


@pytest.mark.parametrize("algorithm", ["features", "hough", "thesis"])
@pytest.mark.parametrize("shape", [(1, 400), (400, 1), (1, 1), (62, 300)])
def test_item6_every_algorithm_refuses_a_map_too_small_for_it_with_its_rule(algorithm, shape):
    """`merger merge A B --algorithm features` on a 1×400 map: `cv2.error ... inv_scale_x > 0` (OpenCV's ORB
    pyramid). Each algorithm answers or refuses naming its rule (the same map twice may well be placed);
    features says which map is too small and the size it needs."""
    import numpy as np

    from merger.algorithms import align_pair
    from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid
    from merger.team.orders import MapInput, MergeParams

    g = OccupancyGrid(np.full(shape, FREE_S, np.uint8), 0.05, (0.0, 0.0))
    g.states[::3, ::7] = OCCUPIED_S
    ans = align_pair(algorithm, MapInput("a", g, (0.0, 0.0)), MapInput("b", g, (0.0, 0.0)), MergeParams())
    assert ans.accepted or ans.reason  # an answer, or a refusal naming its rule: never an exception
    if algorithm == "features":
        assert not ans.accepted and f"a is {shape[0]} × {shape[1]} cells" in ans.reason and "at least 63 cells a side" in ans.reason


def test_item6_merge_of_a_thin_map_with_features_is_a_refusal_not_a_traceback(tmp_path):
    import numpy as np

    from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid
    from merger.io.mapio import save_map

    g = OccupancyGrid(np.full((1, 400), FREE_S, np.uint8), 0.05, (0.0, 0.0))
    g.states[:, ::7] = OCCUPIED_S
    a, b = save_map(g, tmp_path / "a")[0], save_map(g, tmp_path / "b")[0]
    code, out, err, _ = _cli(tmp_path, "merger", "merge", a, b, "--center", "0,0", "--center", "0,0",
                             "--algorithm", "features", "-o", tmp_path / "m", timeout_s=60)
    assert code == 1 and err == "", err
    assert "63 cells a side" in out and not (tmp_path / "m.yaml").exists()


def _rows(run_bag, tmp_path, text: str, name="t.csv"):
    from circsim.score import load_truth, read_transforms

    f = tmp_path / name
    f.write_text(text)
    truth = load_truth(run_bag)
    return read_transforms(f, truth), truth


@pytest.mark.parametrize("rows, needle", [
    ("1e6,Lyon,Nevers,0,0,0", "line 2: t_s: expected a time of the run, in [0, 1] s (the run's length), got 1e+06"),
    ("-50,Lyon,Nevers,0,0,0", "line 2: t_s: expected a time of the run, in [0, 1] s"),
    ("1e308,Lyon,Nevers,0,0,0", "got 1e+308"),
    ("0.5,Lyon,Nevers,0,0,0\n0.5,Lyon,Nevers,90,0,0", "line 3: map Nevers: placed twice in one estimate of Lyon "
                                                     "(at 0.5 s; first at line 2)"),
    ("0.5,Lyon,Nevers,nan,0,0", "line 2: yaw_deg: expected finite numbers, got 'nan'"),
])
def test_item7_transforms_outside_the_run_or_twice_in_an_estimate_are_refused(run_bag, tmp_path, rows, needle):
    """Rows at 1e6 s or -50 s were scored as first merges at those times (1e308 printed a 300-digit time);
    the same map twice in one estimate was taken (the last row won)."""
    from circsim.score import ScoreError

    with pytest.raises(ScoreError) as e:
        _rows(run_bag, tmp_path, "t_s,robot,map,yaw_deg,x_m,y_m\n" + rows + "\n")
    assert needle in str(e.value), str(e.value)


def test_item7_yaml_booleans_are_not_numbers(run_bag, tmp_path):
    """YAML `true`/`false` were read as 1.0/0.0."""
    from circsim.score import ScoreError

    with pytest.raises(ScoreError, match=r"transforms\[0\]: yaw_deg, x_m: expected finite numbers, got True, False"):
        _rows(run_bag, tmp_path, "- {t_s: 0.5, robot: Lyon, map: Nevers, yaw_deg: true, x_m: false, y_m: 0}\n",
              "t.yaml")
    est, _ = _rows(run_bag, tmp_path, "- {t_s: 0.5, robot: Lyon, map: Nevers, yaw_deg: 1, x_m: 0, y_m: 0}\n", "u.yaml")
    assert est[0].placements == {"Nevers": (1.0, 0.0, 0.0)}


@pytest.mark.parametrize("key, value, needle", [
    ("yaw_deg", ".nan", "truth.Lyon.Nevers.yaw_deg: expected a finite number, got nan"),
    ("theta_deg", "true", "truth.Lyon.Nevers.theta_deg: expected a finite number, got True"),
    ("t_m", "[0, .inf]", "truth.Lyon.Nevers.t_m: expected a finite number, got inf"),
])
def test_item7_a_truth_file_with_nan_is_refused(run_bag, tmp_path, key, value, needle):
    """A truth file with `yaw_deg: .nan` was accepted (every estimate then judged against NaN)."""
    import shutil

    from circsim.score import ScoreError, load_truth

    d = yaml.safe_load((run_bag / "circsim_truth.yaml").read_text())
    d["truth"]["Lyon"]["Nevers"][key] = "@@"
    run = tmp_path / "run"
    shutil.copytree(run_bag, run)
    (run / "circsim_truth.yaml").write_text(yaml.safe_dump(d, sort_keys=False).replace("'@@'", value))
    with pytest.raises(ScoreError) as e:
        load_truth(run)
    assert needle in str(e.value) and str(run / "circsim_truth.yaml") in str(e.value), str(e.value)


@pytest.mark.parametrize("every", ["nan", "inf", "0", "-1"])
def test_item7_every_must_be_a_finite_positive_number(run_bag, every, capsys):
    """`--every nan` was accepted while 0 and -1 were refused."""
    from circsim.cli import main

    assert main(["score", str(run_bag), "--merged-bag", str(run_bag), "--every", every]) == 2
    one_line_error(capsys.readouterr().err, "circsim", "--every: expected a finite number of seconds > 0")


@pytest.mark.parametrize("kind, needle", [("folder", "got a folder"), ("fifo", "got a FIFO"),
                                          ("device", "got a device"), ("missing", "no such transforms file")])
def test_item11_a_transforms_path_that_is_no_file_is_named_for_what_it_is(run_bag, tmp_path, kind, needle, capsys):
    """A folder, a FIFO and /dev/zero all read "no such transforms file"."""
    from circsim.cli import main

    f = {"folder": tmp_path, "fifo": tmp_path / "fifo.csv", "device": Path("/dev/zero"),
         "missing": tmp_path / "none.csv"}[kind]
    if kind == "fifo":
        os.mkfifo(f)
    assert main(["score", str(run_bag), "--transforms", str(f)]) == 2
    one_line_error(capsys.readouterr().err, "circsim", str(f), needle)


@pytest.mark.parametrize("value", ["99999999999999999999", "2_0", "+3", "\u0663", "1e3", "1000000"])
@pytest.mark.parametrize("cmd", [["merger", "align", "a.yaml", "b.yaml", "--center", "0,0"],
                                 ["circsim", "run", "scene1", "--set", "duration_s=1"]])
def test_item9_merger_threads_is_a_bounded_count_of_plain_digits(tmp_path, cmd, value):
    """`MERGER_THREADS=99999999999999999999` and `2_0` (= 20) were accepted by both command lines."""
    from merger.team.pool import max_threads

    code, out, err, _ = _cli(tmp_path, *cmd, timeout_s=60, env={**os.environ, "MERGER_THREADS": value})
    assert code == 2 and out == "", err
    one_line_error(err, cmd[0], "MERGER_THREADS", f"<= {max_threads()}", "decimal digits only")


def test_item9_a_count_within_the_bound_is_taken(monkeypatch):
    from merger.team.pool import max_threads, threads

    for v in ["1", " 3 ", str(max_threads())]:
        monkeypatch.setenv("MERGER_THREADS", v)
        assert threads() == int(v)
