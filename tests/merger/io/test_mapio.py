"""ROS map_server files: round trips with map_saver's values, the real TurtleBot3 map, bad files."""

from pathlib import Path

import numpy as np
import pytest

from merger.grid import OccupancyGrid
from merger.io.mapio import load_map, save_map, save_overlay
from merger.io.mapread import MapFileError
from tests.paths import REAL_MAP

REAL = REAL_MAP
U, F, O = 0, 1, 2


def write_pgm(path: Path, img: np.ndarray):
    h, w = img.shape
    path.write_bytes(f"P5\n{w} {h}\n255\n".encode() + img.astype(np.uint8).tobytes())


def test_map_saver_values_read_as_ros_expects(tmp_path):
    # image rows are top = max y: the first image row is the last grid row
    write_pgm(tmp_path / "m.pgm", np.array([[254, 0, 205], [205, 254, 0]]))
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\n"
                                     "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    g = load_map(tmp_path / "m.yaml")
    assert g.states.tolist() == [[U, F, O], [F, O, U]]
    assert g.origin == (-1.0, 2.0) and g.resolution == 0.05
    assert g.to_ros().tolist() == [[-1, 0, 100], [0, 100, -1]]


def test_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    g = OccupancyGrid(rng.integers(0, 3, (37, 53)).astype(np.uint8), 0.05, (-3.25, 1.5))
    y, img = save_map(g, tmp_path / "out" / "map.yaml")
    data = img.read_bytes()
    assert data.startswith(b"P5")
    assert set(np.frombuffer(data[-37 * 53:], np.uint8).tolist()) == {0, 205, 254}
    g2 = load_map(y)
    np.testing.assert_array_equal(g2.states, g.states)
    assert g2.origin == g.origin and g2.resolution == g.resolution


def test_negate_and_raw_modes(tmp_path):
    write_pgm(tmp_path / "n.pgm", np.array([[0, 255, 128]]))
    (tmp_path / "n.yaml").write_text("image: n.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 1\n")
    assert load_map(tmp_path / "n.yaml").states.tolist() == [[F, O, U]]
    write_pgm(tmp_path / "r.pgm", np.array([[0, 100, 255, 50]]))
    (tmp_path / "r.yaml").write_text("image: r.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: raw\n")
    assert load_map(tmp_path / "r.yaml").states.tolist() == [[F, O, U, U]]


def test_real_turtlebot3_map():
    g = load_map(REAL)
    assert g.shape == (384, 384) and g.resolution == pytest.approx(0.05) and g.origin == (-10.0, -10.0)
    c = g.count()
    assert c["occupied"] > 1000 and c["free"] > 10000 and c["unknown"] > 0


@pytest.mark.parametrize("text, key", [
    ("resolution: 0.05\norigin: [0, 0, 0]\n", "image"),
    ("image: m.pgm\norigin: [0, 0, 0]\n", "resolution"),
    ("image: m.pgm\nresolution: -1\norigin: [0, 0, 0]\n", "resolution"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0]\nmode: fancy\n", "mode"),
    ("image: m.pgm\nresolution: 0.05\norigin: zero\n", "origin"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0.5]\n", "origin"),
    ("image: missing.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "image"),
    ("image: [unclosed\n", "YAML"),
    ("image: m.pgm\nresolution: 0.05\norigin: [.inf, 0, 0]\n", "origin"),
    ("image: m.pgm\nresolution: 0.05\norigin: [.nan, 0, 0]\n", "origin"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, -.inf, 0]\n", "origin"),
    ("image: m.pgm\nresolution: 0.05\norigin: [1e300, 0, 0]\n", "origin"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nwhen: 2001-13-01\n", "YAML"),
])
def test_bad_files_name_file_and_key(tmp_path, text, key):
    write_pgm(tmp_path / "m.pgm", np.zeros((2, 2)))
    (tmp_path / "bad.yaml").write_text(text)
    with pytest.raises(MapFileError) as e:
        load_map(tmp_path / "bad.yaml")
    msg = str(e.value)
    assert "bad.yaml" in msg and key in msg and "\n" not in msg


def test_overlay_png_colours(tmp_path):
    import cv2

    a = OccupancyGrid(np.array([[O, F, U]], np.uint8))
    b = OccupancyGrid(np.array([[U, U, U]], np.uint8))
    p = save_overlay([a, b], ["Lyon", "Nevers"], tmp_path / "o.png")
    rgb = cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2RGB)  # 4 px per cell, no title: cells from (0, 0)
    assert rgb[0, 0].tolist() == rgb[3, 3].tolist() == [31, 119, 180]  # the first map occupied: tab10 blue
    assert rgb[0, 4].tolist() == [165, 201, 225]  # its free cells: the same blue, 60 % towards white
    assert rgb[0, 8].tolist() == [128, 128, 128]  # unknown to all: grey


def test_overlay_picture_title_legend_scale_bar(tmp_path):
    """Issue 12: upscaled cells, a title line, each robot's colours in a legend and a 1 m scale bar."""
    from merger.io.overlay import colours_for, overlay_picture

    states = np.zeros((60, 80), np.uint8)
    states[10:50, 10:70] = F
    states[10, 10:70] = O
    plain = overlay_picture([states], ["Lyon"], 0.05)
    titled = overlay_picture([states], ["Lyon"], 0.05, title="theta 12.0 deg  nu 0.71  ACCEPTED")
    assert titled.shape[0] == plain.shape[0] + 24 and titled.shape[1] == plain.shape[1]
    # cropped to the known cells + 10 cells of margin, 4 px per cell: 60 x 80 cells → 240 x 320 px
    assert plain.shape[1] == max(80 * 4, 420) and plain.shape[0] > 60 * 4
    legend = plain[60 * 4:]
    (occ, free), = colours_for(["Lyon"])
    assert (legend == occ).all(axis=2).sum() >= 13 * 13 and (legend == free).all(axis=2).sum() >= 13 * 13
    bar_rows = np.nonzero((legend == 0).all(axis=2).sum(axis=1) >= 80)[0]  # 1 m = 20 cells = 80 px of black
    assert bar_rows.size >= 5
    assert titled[:24].min() == 0  # the title's text is drawn


def test_yaml_1_2_exponent_numbers(tmp_path):
    """``5e-2`` is a number (YAML 1.1, PyYAML's default, would read a string and refuse the map)."""
    write_pgm(tmp_path / "m.pgm", np.zeros((2, 3)))
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 5e-2\norigin: [-1e1, 2E0, 0]\n")
    g = load_map(tmp_path / "m.yaml")
    assert g.resolution == 0.05 and g.origin == (-10.0, 2.0)


def test_resolution_contradicting_the_pgm_header_is_refused(tmp_path):
    """map_saver states the resolution in the PGM's comment: a YAML saying 0.1 for a 0.05 m image is a
    wrong map (merged as is, it would be twice its size)."""
    g = OccupancyGrid(np.zeros((4, 5), np.uint8), 0.05, (0.0, 0.0))
    y, img = save_map(g, tmp_path / "m.yaml")
    assert b"0.05 m/pix" in img.read_bytes()[:64]
    y.write_text(y.read_text().replace("resolution: 0.05", "resolution: 0.1"))
    with pytest.raises(MapFileError, match=r"m.yaml: key 'resolution': 0.1 m per cell, but its image m.pgm was "
                                           r"saved at 0.05 m/pix"):
        load_map(y)
    # map_saver's own header, 3 decimals: 0.050 for a YAML 0.05 is the same resolution
    img.write_bytes(img.read_bytes().replace(b"# CREATOR: merger 0.05 m/pix", b"# CREATOR: map_saver.cpp 0.050 m/pix"))
    y.write_text(y.read_text().replace("resolution: 0.1", "resolution: 0.05"))
    assert load_map(y).resolution == 0.05
    write_pgm(tmp_path / "plain.pgm", np.zeros((2, 2)))  # no comment: nothing to compare
    (tmp_path / "plain.yaml").write_text("image: plain.pgm\nresolution: 0.3\norigin: [0, 0, 0]\n")
    assert load_map(tmp_path / "plain.yaml").resolution == 0.3


def test_small_resolutions_round_trip(tmp_path):
    g = OccupancyGrid(np.zeros((3, 3), np.uint8), 0.0125, (0.0, 0.0))
    assert load_map(save_map(g, tmp_path / "fine")[0]).resolution == 0.0125


def test_written_files_are_readable_by_others_and_leave_no_temporary(tmp_path):
    import os

    g = OccupancyGrid(np.zeros((3, 3), np.uint8), 0.05, (0.0, 0.0))
    y, img = save_map(g, tmp_path / "m")
    umask = os.umask(0)
    os.umask(umask)
    assert (y.stat().st_mode & 0o777) == (0o666 & ~umask)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.pgm", "m.yaml"]


def test_write_files_all_or_none(tmp_path):
    """A file that cannot be written leaves none of the others (and no temporary file) behind."""
    from merger.io.mapio import write_files

    (tmp_path / "blocker").write_text("a file where a folder is needed")
    with pytest.raises(MapFileError, match="blocker"):
        write_files({tmp_path / "a.yaml": b"a", tmp_path / "blocker" / "b.png": b"b"})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["blocker"]
    assert write_files({tmp_path / "a.yaml": b"a"}) == [tmp_path / "a.yaml"]
    assert (tmp_path / "a.yaml").read_bytes() == b"a"


def _check_often(folder: str, n: int) -> int:
    from merger.io.mapio import ensure_output_dir
    from merger.io.mapread import MapFileError

    failed = 0
    for _ in range(n):
        try:
            ensure_output_dir(folder, "--out")
        except MapFileError:
            failed += 1
    return failed


def test_two_processes_checking_one_output_folder_both_pass(tmp_path):
    """ensure_output_dir created and deleted a fixed DIR/.write-test: two processes checking the same folder
    deleted each other's probe (9,199 of 40,000 calls failed, `cannot write there (No such file or
    directory)`). The probe now has a unique name, and none is left behind."""
    import multiprocessing

    with multiprocessing.get_context("spawn").Pool(2) as pool:
        failed = pool.starmap(_check_often, [(str(tmp_path), 3000)] * 2)
    assert failed == [0, 0]
    assert list(tmp_path.iterdir()) == []


def test_one_qualitative_palette_in_the_overlay_and_the_recording():
    """Issue 36 item 10: each robot's occupied and free colours were unrelated hues (the thesis's pairs);
    now one hue per robot (tab10), its free cells lighter, and the rerun recording draws the same."""
    import colorsys

    from merger.io.overlay import PALETTE, colours_for

    pairs = colours_for(["Lyon", "Auckland", "Nevers", "D", "E"])
    assert [occ for occ, _ in pairs] == PALETTE[:5]
    for occ, free in pairs:
        h_occ, _, _ = colorsys.rgb_to_hls(*(c / 255 for c in occ))
        h_free, l_free, _ = colorsys.rgb_to_hls(*(c / 255 for c in free))
        assert min(abs(h_occ - h_free), 1 - abs(h_occ - h_free)) < 0.02 and l_free > colorsys.rgb_to_hls(*(c / 255 for c in occ))[1]
    import circsim.record.rerun as recording  # the recorder draws robots with it

    assert recording.PALETTE is PALETTE


def _states_by_the_rule(grey: np.ndarray, meta: dict) -> np.ndarray:
    """map_server's rule on float grey levels, as load_map applied it to a float64 copy of the image."""
    if meta["mode"] == "raw":
        raw = np.rint(grey).astype(np.int16)
        from merger.grid import states_from_ros

        return states_from_ros(np.where(raw <= 100, raw, -1), occupied_thresh=meta["occupied_thresh"],
                               free_thresh=meta["free_thresh"])
    p = grey / 255.0 if meta["negate"] else (255.0 - grey) / 255.0
    return np.where(p < meta["free_thresh"], F, np.where(p > meta["occupied_thresh"], O, U)).astype(np.uint8)


@pytest.mark.parametrize("mode, negate", [("trinary", 0), ("trinary", 1), ("raw", 0)])
@pytest.mark.parametrize("bits", [8, 16])
def test_the_grey_level_lookup_gives_the_rule_s_states(tmp_path, mode, negate, bits):
    """load_map applies map_server's rule once per grey level and looks the image up (issue 37: the float64
    copies of a 4224² image took 0.45 GB); every level of an 8-bit image and a spread of 16-bit ones give
    the states of the rule itself, thresholds on level boundaries included."""
    import cv2

    if bits == 8:
        img = np.arange(256, dtype=np.uint8).reshape(16, 16)
        name = "m.pgm"
    else:
        img = np.concatenate([np.arange(0, 65536, 97), [65535, 257 * 50, 257 * 166]]).astype(np.uint16)
        img = np.resize(img, (26, 27))
        name = "m.png"
    cv2.imwrite(str(tmp_path / name), img)
    meta = {"mode": mode, "negate": negate, "occupied_thresh": 166 / 255, "free_thresh": 50 / 255}
    (tmp_path / "m.yaml").write_text(f"image: {name}\nresolution: 0.05\norigin: [0, 0, 0]\nmode: {mode}\n"
                                     f"negate: {negate}\noccupied_thresh: {166 / 255!r}\nfree_thresh: {50 / 255!r}\n")
    grey = img / 257.0 if bits == 16 else img.astype(np.float64)
    want = np.flipud(_states_by_the_rule(grey, meta))
    assert np.array_equal(load_map(tmp_path / "m.yaml").states, want)


def test_loading_a_large_map_makes_no_float_copy_of_its_image(tmp_path):
    import tracemalloc

    g = OccupancyGrid(np.tile(np.array([[U, F], [O, F]], np.uint8), (1000, 1000)), 0.05, (0.0, 0.0))
    path = save_map(g, tmp_path / "big")[0]
    tracemalloc.start()
    try:
        assert np.array_equal(load_map(path).states, g.states)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20 << 20, peak / 2**20  # 4 M cells: the states (4 MB) and masks; float64 copies were 96 MB


def test_an_interrupt_while_writing_leaves_no_temporary_file(tmp_path, monkeypatch):
    """Ctrl-C between two renames (merger now exits at once on it): the temporary files went only on an
    OSError, and a KeyboardInterrupt left `.NAME.XXXX.part` files behind."""
    import os

    from merger.io import mapio

    real, calls = os.replace, []

    def replace(a, b):
        calls.append(b)
        if len(calls) == 2:
            raise KeyboardInterrupt
        real(a, b)

    monkeypatch.setattr(mapio.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        mapio.write_files({tmp_path / "a.txt": b"a", tmp_path / "b.txt": b"b", tmp_path / "c.txt": b"c"})
    assert sorted(p.name for p in tmp_path.iterdir()) == []
