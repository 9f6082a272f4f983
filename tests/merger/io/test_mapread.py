"""merger.io.mapread: a map_server YAML parsed with map_server's defaults, every bad key refused in one
line naming the file, the key and what was expected; an image checked from its header before decoding
(missing, a folder, a FIFO, not an image, too large); colour images averaged to grey; the resolution a
map_saver PGM states in its header compared with the YAML's."""

from __future__ import annotations

import os

import cv2
import numpy as np
import pytest

from merger.io.mapread import (
    MAX_MAP_CELLS,
    MAX_MAP_SIDE,
    MapFileError,
    check_image_file,
    check_image_resolution,
    pgm_resolution,
    read_image,
    read_metadata,
)


def _yaml(tmp_path, text, name="m.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_defaults_are_map_servers(tmp_path):
    meta = read_metadata(_yaml(tmp_path, "image: m.pgm\nresolution: 0.05\norigin: [1, -2]\n"))
    assert meta == {"image": "m.pgm", "resolution": 0.05, "origin": [1.0, -2.0, 0.0], "negate": 0,
                    "occupied_thresh": 0.65, "free_thresh": 0.196, "mode": "trinary"}
    meta = read_metadata(_yaml(tmp_path, "image: a.png\nresolution: 1e-1\norigin: [0, 0, 0.0]\nnegate: 1\n"
                                          "occupied_thresh: 0.9\nfree_thresh: 0\nmode: scale\n"))
    assert meta["negate"] == 1 and meta["occupied_thresh"] == 0.9 and meta["free_thresh"] == 0.0
    assert meta["mode"] == "scale" and meta["resolution"] == 0.1


BASE = "image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"


@pytest.mark.parametrize("text, expect", [
    ("- a\n- b\n", "expected a YAML mapping with keys image, resolution, origin"),
    ("image: ''\nresolution: 0.05\norigin: [0, 0]\n", "key 'image': expected the image file name, got ''"),
    ("image: 3\nresolution: 0.05\norigin: [0, 0]\n", "key 'image': expected the image file name, got 3"),
    ("image: m.pgm\norigin: [0, 0]\n", "missing key 'resolution'"),
    ("image: m.pgm\nresolution: fine\norigin: [0, 0]\n", "key 'resolution': expected a number, got 'fine'"),
    ("image: m.pgm\nresolution: true\norigin: [0, 0]\n", "key 'resolution': expected a number, got True"),
    ("image: m.pgm\nresolution: 0\norigin: [0, 0]\n", "key 'resolution': expected a number in (0.0, 1000.0], got 0"),
    ("image: m.pgm\nresolution: 0.0001\norigin: [0, 0]\n",
     "key 'resolution': expected a cell size of at least 0.001 m, got 0.0001"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0]\n", "key 'origin': expected [x, y, yaw] of finite numbers"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, true]\n", "key 'origin': expected [x, y, yaw]"),
    ("image: m.pgm\nresolution: 0.05\norigin: [2000000, 0]\n", "(|x|, |y| at most 1e+06 m)"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0.1]\n", "key 'origin': a rotated origin (yaw 0.1) is not supported"),
    (BASE + "mode: fancy\n", "key 'mode': expected one of trinary, scale, raw, got 'fancy'"),
    (BASE + "negate: 2\n", "key 'negate': expected 0 or 1, got 2"),
    (BASE + "occupied_thresh: 1.5\n", "key 'occupied_thresh': expected a number in (0.0, 1.0], got 1.5"),
    (BASE + "free_thresh: .nan\n", "key 'free_thresh': expected a number, got nan"),
    (BASE + "occupied_thresh: 0.3\nfree_thresh: 0.3\n", "key 'free_thresh': expected < occupied_thresh (0.3), got 0.3"),
    ("image: [unclosed\n", "not valid YAML"),
])
def test_a_bad_key_is_one_line_naming_the_file_the_key_and_the_expectation(tmp_path, text, expect):
    p = _yaml(tmp_path, text, "bad.yaml")
    with pytest.raises(MapFileError) as e:
        read_metadata(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}: ") and expect in msg and "\n" not in msg


def test_a_missing_yaml_and_an_image_given_for_a_yaml(tmp_path):
    with pytest.raises(MapFileError, match=r"nope.yaml: cannot read"):
        read_metadata(tmp_path / "nope.yaml")
    pgm = tmp_path / "m.pgm"
    pgm.write_bytes(b"P5\n2 2\n255\n\xff\x00\xfe\x01")
    with pytest.raises(MapFileError, match=r"got binary data \(this is an image: give the map's YAML"):
        read_metadata(pgm)


def test_images_refused_before_decoding(tmp_path):
    y = tmp_path / "m.yaml"
    with pytest.raises(MapFileError, match=r"m.yaml: key 'image': file .*none.pgm does not exist"):
        check_image_file(tmp_path / "none.pgm", y)
    (tmp_path / "dir.pgm").mkdir()
    with pytest.raises(MapFileError, match=r"key 'image': .*dir.pgm is a folder: expected an image file"):
        check_image_file(tmp_path / "dir.pgm", y)
    os.mkfifo(tmp_path / "fifo.pgm")  # opening it to read would block: the check must not
    with pytest.raises(MapFileError, match=r"fifo.pgm is not a regular file"):
        check_image_file(tmp_path / "fifo.pgm", y)
    (tmp_path / "text.pgm").write_text("hello")
    with pytest.raises(MapFileError, match=r"text.pgm: not a readable image"):
        check_image_file(tmp_path / "text.pgm", y)


@pytest.mark.parametrize("w, h", [(6000, 6000), (MAX_MAP_SIDE + 1, 10)])
def test_a_header_declaring_too_many_cells_is_refused_without_its_pixels(tmp_path, w, h):
    """A PGM header alone (no pixel data, a few bytes): the declared size is enough to refuse it."""
    p = tmp_path / "huge.pgm"
    p.write_bytes(f"P5\n{w} {h}\n255\n".encode())
    with pytest.raises(MapFileError) as e:
        check_image_file(p, tmp_path / "m.yaml")
    assert f"expected at most {MAX_MAP_CELLS} cells and {MAX_MAP_SIDE} a side (checked before decoding)" in str(e.value)
    assert f"{w} x {h} cells" in str(e.value)


def test_grey_and_colour_images_read_as_grey_levels(tmp_path):
    grey = np.array([[0, 128], [205, 254]], np.uint8)
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    assert read_image(tmp_path / "g.png", tmp_path / "m.yaml").tolist() == grey.tolist()
    bgra = np.zeros((2, 2, 4), np.uint8)
    bgra[0, 0] = (30, 60, 90, 0)  # the alpha channel is ignored: the mean of 30, 60, 90
    bgra[1, 1] = (255, 255, 255, 255)
    cv2.imwrite(str(tmp_path / "c.png"), bgra)
    img = read_image(tmp_path / "c.png", tmp_path / "m.yaml")
    assert img.shape == (2, 2) and img[0, 0] == 60.0 and img[1, 1] == 255.0 and img[0, 1] == 0.0


@pytest.mark.parametrize("header, res", [
    (b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n2 2\n255\n", 0.05),
    (b"P5\n# CREATOR: merger 5e-2 m/pix\n2 2\n255\n", 0.05),
    (b"P2\n# 0.1 m/pix\n2 2\n255\n", 0.1),
    (b"P5\n2 2\n255\n", None),  # no comment
    (b"\x89PNG\r\n# 0.05 m/pix", None),  # not a PGM
])
def test_the_resolution_a_pgm_states(tmp_path, header, res):
    p = tmp_path / "m.pgm"
    p.write_bytes(header + b"\x00" * 4)
    assert pgm_resolution(p) == res
    assert pgm_resolution(tmp_path / "absent.pgm") is None


def test_a_yaml_resolution_is_checked_against_its_pgm_within_map_savers_rounding(tmp_path):
    p = tmp_path / "m.pgm"
    p.write_bytes(b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n2 2\n255\n" + b"\x00" * 4)
    check_image_resolution({"resolution": 0.05}, p, tmp_path / "m.yaml")
    check_image_resolution({"resolution": 0.0504}, p, tmp_path / "m.yaml")  # under 0.0005: 3-decimal rounding
    with pytest.raises(MapFileError, match=r"m.yaml: key 'resolution': 0.1 m per cell, but its image m.pgm was "
                                           r"saved at 0.05 m/pix \(header comment\); correct the YAML"):
        check_image_resolution({"resolution": 0.1}, p, tmp_path / "m.yaml")
