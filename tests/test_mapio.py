"""ROS map_server files: round trips with map_saver's values, the real TurtleBot3 map, bad files."""

from pathlib import Path

import numpy as np
import pytest

from merger.grid import OccupancyGrid
from merger.mapio import MapFileError, load_map, save_map, save_overlay

REAL = Path(__file__).resolve().parent / "data" / "real-maps" / "turtlebot3_office.yaml"
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
    rgb = cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2RGB)
    assert rgb[0, 0].tolist() == [200, 0, 200]  # Lyon occupied: magenta
    assert rgb[0, 1].tolist() == [170, 235, 170]  # Lyon free: light green
    assert rgb[0, 2].tolist() == [128, 128, 128]  # unknown to all: grey
