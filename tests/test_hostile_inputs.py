"""Hostile inputs, documented limits and outputs that never destroy data (issue 26).

One test per class of case the issue found: crashes inside documented ranges, limits checked before any
allocation (ROI cells, map images, centers, scenario physics), YAML and file bombs, special files as
inputs, outputs that would destroy data (an input, another output, a link, a device), a full disk, and
the CLIs' rough edges (--version, a closed pipe). Each refusal is one line naming the file or option,
exit 2; the CLI cases run in a child process under a memory cap and a timeout (tests/subproc.py), and
those refused before any work assert a peak resident memory under 300 MB (docs/limits.md).
"""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from circsim.config.scenario import ScenarioError, bundled_scenarios, load_scenario, scenario_from_dict
from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid
from merger.io.mapio import check_outputs, load_map, map_files, save_map
from merger.io.mapread import MAX_MAP_CELLS, MapFileError
from merger.limits import MAX_YAML_BYTES, InputLimitError, YamlLimitError, load_yaml, read_input
from merger.search import MAX_ROI_CELLS, RotationProblem, search
from tests.paths import REAL_MAP
from tests.subproc import run_capped

BIN = Path(sys.executable).parent
REFUSED_PEAK_BYTES = 300 << 20  # a refused input costs no more than starting the program
OFFICE = REAL_MAP


def one_line_error(err: str, prog: str, *needles: str) -> str:
    """The child's stderr is exactly one line ``prog: error: ...`` containing every needle."""
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"{prog}: error: "), err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def small_map(path: Path, states=None) -> Path:
    g = OccupancyGrid(np.full((40, 50), FREE_S, np.uint8) if states is None else states, 0.05, (-1.0, -1.0))
    g.states[10:12, 5:40] = OCCUPIED_S
    return save_map(g, path)[0]


def laughs(levels: int = 9, key: str = "image") -> str:
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    lines += [f"a{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]" for i in range(1, levels + 1)]
    return "\n".join(lines) + f"\n{key}: *a{levels}\n"


# --- item 1: crashes inside documented ranges ----------------------------------------------------------
def test_refinement_of_a_dense_roi_with_more_occupied_cells_than_one_remap_call_takes():
    """cv2.remap asserts fewer than 32,767 columns: the sub-cell refinement of an ROI holding more occupied
    cells crashed (cv2.error ... dst.cols < SHRT_MAX). The refinement reads the field in its own kernel now."""
    rng = np.random.default_rng(0)
    st = np.where(rng.random((240, 240)) < 0.92, OCCUPIED_S, FREE_S).astype(np.uint8)
    g = OccupancyGrid(st, 0.05, (0.0, 0.0))
    assert (st[20:220, 20:220] == OCCUPIED_S).sum() > 32_766  # the 10 m ROI about (6, 6)
    al = search(RotationProblem(g, g, (6.0, 6.0), (6.0, 6.0), roi_m=10.0, window_m=0.0, refine=True), "fast")
    assert al.refined and min(al.theta_deg, 360 - al.theta_deg) < 0.2


def test_roi_side_in_cells_is_limited_before_any_table_is_built():
    g = OccupancyGrid(np.zeros((10, 10), np.uint8), 0.01, (0.0, 0.0))
    with pytest.raises(ValueError, match=f"at most {MAX_ROI_CELLS}"):
        RotationProblem(g, g, (0.0, 0.0), (0.0, 0.0), roi_m=100.0)
    RotationProblem(g, g, (0.0, 0.0), (0.0, 0.0), roi_m=MAX_ROI_CELLS * 0.01)  # the limit itself is fine


# --- item 4: memory bombs, special files --------------------------------------------------------------
def test_yaml_alias_bomb_and_recursive_alias_are_refused_before_construction():
    with pytest.raises(YamlLimitError, match="billion laughs"):
        load_yaml(laughs())
    with pytest.raises(YamlLimitError, match="recursive"):
        load_yaml("x: &a [1, *a]")
    assert load_yaml("a: &x [1, 2]\nb: *x\nc: 1e-1") == {"a": [1, 2], "b": [1, 2], "c": 0.1}  # aliases still work


def test_map_yaml_bomb_special_files_and_size_limits(tmp_path):
    (tmp_path / "bomb.yaml").write_text(laughs() + "resolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match=r"bomb\.yaml: not valid YAML: expands"):
        load_map(tmp_path / "bomb.yaml")
    os.mkfifo(tmp_path / "fifo.yaml")
    with pytest.raises(MapFileError, match=r"fifo\.yaml: expected a regular map YAML file, got a FIFO"):
        load_map(tmp_path / "fifo.yaml")  # refused without blocking on the open
    with pytest.raises(MapFileError, match="/dev/zero: expected a regular map YAML file, got a device"):
        load_map("/dev/zero")
    (tmp_path / "big.yaml").write_bytes(b"#" * (MAX_YAML_BYTES + 1))
    with pytest.raises(MapFileError, match=f"expected a map YAML file of at most {MAX_YAML_BYTES} bytes"):
        load_map(tmp_path / "big.yaml")
    with pytest.raises(InputLimitError, match="a folder"):
        read_input(tmp_path, 10)


def test_scenario_bomb_and_special_files(tmp_path):
    (tmp_path / "s.yaml").write_text(laughs(key="description"))
    with pytest.raises(ScenarioError, match=r"^s\.yaml: invalid YAML: expands"):
        load_scenario(tmp_path / "s.yaml")
    os.mkfifo(tmp_path / "f.yaml")
    with pytest.raises(ScenarioError, match="got a FIFO"):
        load_scenario(tmp_path / "f.yaml")
    with pytest.raises(ScenarioError, match="/dev/zero: expected a regular scenario file, got a device"):
        load_scenario("/dev/zero")


def _png_header_only(w: int, h: int) -> bytes:
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)

    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0" * 100)) + chunk(b"IEND", b""))


@pytest.mark.parametrize("name,data", [
    ("big.png", _png_header_only(16000, 16000)),  # decodes to 256 M cells (the 275 kB PNG)
    ("big.pgm", b"P5\n20000 2000\n255\n" + b"\0" * 64),
])
def test_image_decoded_size_is_checked_from_its_header(tmp_path, name, data):
    (tmp_path / name).write_bytes(data)
    (tmp_path / "m.yaml").write_text(f"image: {name}\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match=f"expected at most {MAX_MAP_CELLS} cells"):
        load_map(tmp_path / "m.yaml")


def test_image_that_is_a_folder_or_device_is_named_as_such(tmp_path):
    (tmp_path / "d.yaml").write_text("image: sub\nresolution: 0.05\norigin: [0, 0, 0]\n")
    (tmp_path / "sub").mkdir()
    with pytest.raises(MapFileError, match="key 'image': .*sub is a folder"):
        load_map(tmp_path / "d.yaml")
    (tmp_path / "z.yaml").write_text("image: /dev/zero\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match="is not a regular file"):
        load_map(tmp_path / "z.yaml")


def test_absurd_resolution_is_refused(tmp_path):
    (tmp_path / "m.png").write_bytes(cv2.imencode(".png", np.full((4, 4), 254, np.uint8))[1].tobytes())
    (tmp_path / "tiny.yaml").write_text("image: m.png\nresolution: 1e-9\norigin: [0, 0, 0]\n")
    with pytest.raises(MapFileError, match="key 'resolution': expected a cell size of at least 0.001 m"):
        load_map(tmp_path / "tiny.yaml")


# --- item 2: outputs that destroy data ------------------------------------------------------------------
def test_output_paths_that_would_destroy_data_are_refused(tmp_path):
    a = small_map(tmp_path / "a.yaml")
    with pytest.raises(MapFileError, match=r"-o .*a\.yaml: is also an input \(map "):
        check_outputs({tmp_path / "a.yaml": "-o"}, {a: "map"})
    with pytest.raises(MapFileError, match=r"--json .*x\.rrd: is also written by --rrd"):
        check_outputs([(tmp_path / "x.rrd", "--rrd"), (tmp_path / "x.rrd", "--json")])
    (tmp_path / "target").write_text("keep")
    (tmp_path / "link.json").symlink_to(tmp_path / "target")
    with pytest.raises(MapFileError, match="symbolic link"):
        check_outputs({tmp_path / "link.json": "--json"})
    with pytest.raises(MapFileError, match="not a regular file"):
        check_outputs({Path("/dev/null"): "--json"})
    with pytest.raises(MapFileError, match="a folder"):
        check_outputs({tmp_path: "--json"})
    check_outputs({tmp_path / "new.json": "--json", tmp_path / "target": "--rrd"}, {a: "map"})  # plain files


def test_a_stem_keeps_its_dots(tmp_path):
    g = OccupancyGrid(np.full((4, 4), FREE_S, np.uint8), 0.05, (0.0, 0.0))
    assert sorted(p.name for p in map_files(g, tmp_path / "run_w0.5")) == ["run_w0.5.pgm", "run_w0.5.yaml"]
    assert sorted(p.name for p in map_files(g, tmp_path / "run_w0.25.yaml")) == ["run_w0.25.pgm",
                                                                                 "run_w0.25.yaml"]


def test_an_incomplete_recording_replaces_nothing(tmp_path):
    from circsim.record.rerun import RerunRecorder

    final = tmp_path / "run.rrd"
    final.write_bytes(b"the previous good recording")
    rec = RerunRecorder(final)
    rec.part = str(tmp_path / ".run.rrd.x.part.rrd")
    Path(rec.part).write_bytes(b"RRF2" + b"\0" * 100)  # a writer that stopped before the footer
    rec._place_recording()
    assert final.read_bytes() == b"the previous good recording"
    assert "cannot write the recording" in rec.write_error and rec.part is None
    assert not list(tmp_path.glob(".*part*"))


def test_a_sweep_folder_has_one_writer(tmp_path):
    from circsim.experiments.plan import SweepError
    from circsim.experiments.store import lock_out

    held = lock_out(tmp_path)
    try:
        with pytest.raises(SweepError, match="another sweep is writing there"):
            lock_out(tmp_path)
    finally:
        held.close()
    lock_out(tmp_path).close()  # released with its holder
    assert not list(tmp_path.iterdir())  # the folder itself is locked: no lock file left behind


def test_a_malformed_resume_row_is_named_by_file_and_line(tmp_path):
    from circsim.experiments.plan import SweepError
    from circsim.experiments.store import read_rows

    p = tmp_path / "runs.jsonl"
    p.write_text('{"run_key": "a"}\n{"run_key": "b", "torn\n[1]\n')
    with pytest.raises(SweepError, match=r"runs\.jsonl: line 3: expected a run's row"):
        read_rows(p)
    p.write_text('{"run_key": "a"}\n{"run_key": "b", "torn\n')
    assert read_rows(p) == [{"run_key": "a"}]  # a torn line (a killed sweep) is skipped


def test_grid_and_set_parse_values_alike():
    from circsim.experiments.plan import parse_grid

    base = load_scenario(bundled_scenarios()["scene1"])
    (axis,) = parse_grid(["center_error=1e-1,0.2"])
    assert axis.values == (0.1, 0.2)
    assert base.with_overrides(["center_error=1e-1"]).center_error.magnitude_m == 0.1


# --- items 5 and 6: absurd numbers, nonsense scenarios ------------------------------------------------
BASE = load_scenario(bundled_scenarios()["scene1"])


@pytest.mark.parametrize("sets,needle", [
    (["dt_s=1", "duration_s=0.5"], "dt_s: expected a number <= duration_s"),
    (["robots.speed_mps=1e6"], "robots.speed_mps: expected a number in (0, 2]"),
    (["robots.body_radius_m=1e-7"], "robots.body_radius_m: expected a number >= 0.05"),
    (["center_error.magnitude_m=1e6"], "center_error.magnitude_m: expected a number in [0, 4]"),
    (["center_error.per_robot={Lyon: [1e9, 0]}"], "center_error.per_robot.Lyon: expected an error"),
    (["world.pillars=[{center: [0, -1.6], radius: 0.2}]"], "world.pillars[0]: expected clear of the robots' circle"),
    (["world.objects=[{type: box, center: [1.6, 0], size_m: [0.3, 0.3]}]"],
     "world.objects[0]: expected clear of the robots' circle"),
    (["merger.roi_m=0.1", "merger.window_m=0"], "merger.roi_m: expected a side of 10 to 4000 cells"),
])
def test_nonsense_scenarios_are_refused_in_one_line(sets, needle):
    with pytest.raises(ScenarioError) as e:
        BASE.with_overrides(sets)
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_overlapping_robots_are_refused():
    names = [f"r{i}" for i in range(50)]
    with pytest.raises(ScenarioError, match="robots.start_angles_deg: expected robots that do not overlap"):
        scenario_from_dict({"robots": {"names": names}}, source="s.yaml")


def test_a_pillar_off_the_offline_arcs_is_fine_and_robots_never_reach_one():
    """A pillar on the circle is refused for online robots (they drive the whole circle, without avoiding
    obstacles); offline robots only sweep ±max_deg about their starts, so one between their arcs stays."""
    sc = BASE.with_overrides(["robots.motion=offline", "robots.offline.max_deg=30",
                              "world.pillars=[{center: [0, -1.6], radius: 0.2}]"])  # at 270°, arcs 60-120 ...
    assert sc.world.pillars[0].center == (0.0, -1.6)
    with pytest.raises(ScenarioError, match="robot Auckland's arc"):
        BASE.with_overrides(["robots.motion=offline", "robots.offline.max_deg=60",
                             "world.pillars=[{center: [0, -1.6], radius: 0.2}]"])


# --- the CLIs, in a child process under a memory cap ----------------------------------------------------
def _cli(tmp_path, prog, *args, timeout_s=60, **kw):
    return run_capped([str(BIN / prog), *map(str, args)], tmp_path, timeout_s=timeout_s, **kw)


@pytest.mark.parametrize("prog", ["merger", "circsim"])
def test_version(tmp_path, prog):
    code, out, err, _ = _cli(tmp_path, prog, "--version")
    assert code == 0 and out.startswith(f"{prog} ") and not err


def test_a_closed_pipe_is_not_an_error(tmp_path):
    """`circsim scenarios | head -1`: the reader leaves; no "circsim: error: : Broken pipe", no exit 2."""
    proc = subprocess.Popen([str(BIN / "circsim"), "scenarios"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # before the child writes: its first flush meets a closed pipe
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) in (0, 1) and "error" not in err, err


@pytest.mark.slow
def test_refused_map_inputs_cost_no_memory_and_never_hang(tmp_path):
    office = small_map(tmp_path / "office.yaml")
    os.mkfifo(tmp_path / "fifo.yaml")
    cases = [
        (["align", office.with_suffix(".pgm"), office, "--center", "0,0"], "office.pgm", "an image"),
        (["align", tmp_path / "fifo.yaml", office, "--center", "0,0"], "fifo.yaml", "FIFO"),
        (["align", "/dev/zero", office, "--center", "0,0"], "/dev/zero", "a device"),
        (["align", office, office, "--center", "1e308,0"], "--center", "outside"),
        (["align", office, office, "--center", "1e7,0"], "--center", "office.yaml"),
        (["align", office, office, "--center", "0,0", "--roi", "1e-9", "--window", "0"], "--roi",
         "a side of 10 to 4000 cells"),
        (["demo", "--center-error", "1e308", "-o", tmp_path / "d"], "--center-error", "[0, 4]"),
        (["demo", "--radius", "1e308", "-o", tmp_path / "d"], "--radius", "(0, 2.4]"),
        (["demo", "--seed", "-1", "-o", tmp_path / "d"], "--seed", ">= 0"),
        (["demo", "--real", office, "--real-center", "50,50", "-o", tmp_path / "d"], "--real-center", "outside"),
        (["merge", office, office.with_name("other.yaml"), "--center", "0,0", "-o", tmp_path / "office"],
         "-o", "also an input"),
        (["merge", office, office, "--center", "0,0", "-o", "."], "-o", "expected an output file stem"),
    ]
    small_map(tmp_path / "other.yaml")
    (tmp_path / "bomb.yaml").write_text(laughs() + "resolution: 0.05\norigin: [0, 0, 0]\n")
    cases.append((["align", tmp_path / "bomb.yaml", office, "--center", "0,0"], "bomb.yaml", "expands"))
    before = office.read_bytes()
    for args, *needles in cases:
        code, _, err, peak = _cli(tmp_path, "merger", *args, timeout_s=30, mem_bytes=2 << 30)
        assert code == 2, (args, err)
        one_line_error(err, "merger", *needles)
        assert peak < REFUSED_PEAK_BYTES, (args, peak)
    assert office.read_bytes() == before and not (tmp_path / "d").exists()


@pytest.mark.slow
def test_refused_run_outputs_and_inputs(tmp_path):
    sc = tmp_path / "s.yaml"
    sc.write_text(bundled_scenarios()["scene1"].read_text())
    os.mkfifo(tmp_path / "fifo.yaml")
    (tmp_path / "D").mkdir()
    cases = [
        (["run", sc, "--rrd", tmp_path / "x.rrd", "--json", tmp_path / "x.rrd"], "--json", "--rrd"),
        (["run", sc, "--save-maps", tmp_path / "D", "--json", tmp_path / "D" / "Lyon.yaml"], "Lyon.yaml",
         "--save-maps"),
        (["run", sc, "--json", sc], "--json", "also an input"),
        (["run", sc, "--json", "/dev/null"], "/dev/null", "not a regular file"),
        (["run", tmp_path / "fifo.yaml"], "fifo.yaml", "FIFO"),
        (["run", "/dev/zero"], "/dev/zero", "a device"),
    ]
    before = sc.read_bytes()
    for args, *needles in cases:
        code, _, err, peak = _cli(tmp_path, "circsim", *args, timeout_s=30, mem_bytes=2 << 30)
        assert code == 2, (args, err)
        one_line_error(err, "circsim", *needles)
        assert peak < REFUSED_PEAK_BYTES, (args, peak)
    assert sc.read_bytes() == before and not list((tmp_path / "D").iterdir())


@pytest.mark.parametrize("fsize", [pytest.param(400_000, marks=pytest.mark.slow), 20_000])
def test_a_full_disk_under_rrd_is_an_error_and_keeps_the_previous_recording(tmp_path, fsize):
    """Writes capped (RLIMIT_FSIZE: EFBIG, as ENOSPC on a full disk). At 400 kB the disk fills during the
    run: its figures are printed and its JSON written, then one error line names the recording, exit 2.
    At 20 kB it fills while rerun starts the file, where rerun 0.41 may block for good (the issue's hang,
    which ignored SIGTERM): one error line, exit 2, within the attach timeout. The earlier recording is
    untouched either way."""
    rrd, js = tmp_path / "run.rrd", tmp_path / "run.json"
    rrd.write_bytes(b"previous recording")
    code, out, err, _ = _cli(tmp_path, "circsim", "run", "scene1", "--set", "duration_s=2", "--set",
                             "merger.method=fast", "--quiet", "--rrd", rrd, "--json", js, timeout_s=120,
                             fsize_bytes=fsize)
    assert code == 2, err
    mine = [ln for ln in err.splitlines() if ln.startswith("circsim: error: ")]
    assert len(mine) == 1 and str(rrd) in mine[0] and "cannot write the recording" in mine[0], err
    assert rrd.read_bytes() == b"previous recording"
    if "false merges" in out:  # the run ran: its figures are kept
        assert yaml.safe_load(js.read_text())["sim_s"] > 0
    else:
        assert fsize < 100_000 and not js.exists()  # refused at the start: nothing was computed
    assert not list(tmp_path.glob(".*part*"))


@pytest.mark.slow
def test_a_huge_value_is_not_echoed_whole(tmp_path):
    """An error echoing a user's value is cut (a megabyte-long `image:` printed whole before)."""
    (tmp_path / "m.yaml").write_text("image: [" + ", ".join(["x"] * 200_000) + "]\nresolution: 0.05\n"
                                     "origin: [0, 0, 0]\n")
    with pytest.raises(MapFileError) as e:
        load_map(tmp_path / "m.yaml")
    assert "key 'image'" in str(e.value) and len(str(e.value)) < 2100 and "characters)" in str(e.value)


def test_a_fifo_as_a_bag_is_refused_without_blocking(tmp_path):
    """`merger merge --bag x.mcap` on a FIFO waited forever in the bag reader."""
    pytest.importorskip("rosbags", reason="the bag extra (rosbags) is not installed")
    from merger.io.bagio import read_bag_maps

    os.mkfifo(tmp_path / "x.mcap")
    with pytest.raises(MapFileError, match=r"x\.mcap: expected a ROS bag file .*got a FIFO"):
        read_bag_maps(tmp_path / "x.mcap", ["/a/map", "/b/map"])
    (tmp_path / "bag").mkdir()
    os.mkfifo(tmp_path / "bag" / "bag_0.mcap")
    with pytest.raises(MapFileError, match=r"bag_0\.mcap: expected a ROS bag file"):
        read_bag_maps(tmp_path / "bag", ["/a/map", "/b/map"])


def test_sweep_and_offline_outputs_that_are_special_files_are_refused(tmp_path, capsys):
    """A FIFO as OUT/runs.jsonl blocked the resume check's read; a link as OUT/offline.json was replaced."""
    from circsim.cli import main

    (tmp_path / "sw").mkdir()
    os.mkfifo(tmp_path / "sw" / "runs.jsonl")
    assert main(["sweep", "scene1", "--seeds", "1", "--out", str(tmp_path / "sw"), "--quiet"]) == 2
    one_line_error(capsys.readouterr().err, "circsim", "runs.jsonl", "not a regular file")
    (tmp_path / "off").mkdir()
    (tmp_path / "off" / "offline.json").symlink_to(tmp_path / "elsewhere.json")
    assert main(["offline", "scene1", "--out", str(tmp_path / "off"), "--quiet"]) == 2
    one_line_error(capsys.readouterr().err, "circsim", "offline.json", "symbolic link")
