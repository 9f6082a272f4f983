"""merger.settings: each setting's one rule accepts its range and refuses the rest in one line naming the
setting as the caller knows it (``window_m``, ``--window``)."""

import math

import numpy as np
import pytest

from merger.limits import MAX_ROI_M, MIN_ROI_CELLS
from merger.settings import (
    MAX_ROI_CELLS,
    MAX_SUPPORT_FLOOR,
    SettingError,
    check_floor,
    check_measure,
    check_roi,
    check_window,
)


def refusal(rule, *args, **kw) -> str:
    with pytest.raises(SettingError) as e:
        rule(*args, **kw)
    msg = str(e.value)
    assert msg == e.value.key + e.value.rest and "\n" not in msg
    return msg


def test_window_is_at_most_a_quarter_of_the_roi():
    assert check_window(0) == 0.0 and check_window(2, 8.0) == 2.0 and isinstance(check_window(np.int64(1)), float)
    assert check_window(2.0 + 1e-13, 8.0) == 2.0 + 1e-13  # float noise on the boundary is not a refusal
    assert refusal(check_window, 2.01, 8.0, "--window", "the --roi side") == (
        "--window = 2.01 m is more than a quarter of the --roi side (8 m): expected at most 2 m (or a larger ROI)")
    assert refusal(check_window, -0.1).startswith("window_m must be a finite number >= 0, got -0.1")
    assert refusal(check_window, math.inf, 8.0).startswith("window_m must be a finite number >= 0, got inf")
    for bad in (True, "0.5", None):
        assert refusal(check_window, bad).startswith(f"window_m must be a number of metres, got {bad!r}")


def test_roi_rule_and_its_limits_in_cells():
    assert check_roi(8) == 8.0
    assert check_roi(1e9) == 1e9  # without the inputs' limits only > 0
    assert refusal(check_roi, 0) == "roi_m: expected a number > 0, got 0"
    assert refusal(check_roi, MAX_ROI_M + 1, key="--roi", limits=True) == (
        f"--roi: expected a number in (0, {MAX_ROI_M:g}], got {MAX_ROI_M + 1:g}")
    # in cells of a grid: at least MIN_ROI_CELLS with the limits, at most MAX_ROI_CELLS always
    assert check_roi(MIN_ROI_CELLS * 0.05, 0.05, limits=True) == pytest.approx(0.5)
    msg = refusal(check_roi, 0.3, 0.05, "--roi", limits=True, cells_of="a.yaml")
    assert msg.startswith(f"--roi: expected a side of {MIN_ROI_CELLS} to {MAX_ROI_CELLS} cells of a.yaml at 0.05 m")
    assert msg.endswith("got 0.3 m (6 cells)")
    assert refusal(check_roi, 0.01 * (MAX_ROI_CELLS + 1), 0.01).startswith(
        f"roi_m: expected a side of at most {MAX_ROI_CELLS} cells at 0.01 m")
    assert refusal(check_roi, "8").startswith("roi_m: expected a number of metres > 0, got '8'")


def test_measure_and_floor_rules():
    assert check_measure("ncc") == "ncc"
    assert refusal(check_measure, "NCC", "--measure") == (
        "--measure must be one of 'similarity', 'birk_carpin', 'ncc', got 'NCC'")
    assert check_floor(np.int32(50)) == 50 and type(check_floor(np.int32(50))) is int
    assert check_floor(MAX_SUPPORT_FLOOR - 1) == MAX_SUPPORT_FLOOR - 1
    for bad in (-1, MAX_SUPPORT_FLOOR, 2.0, True, "5"):
        assert refusal(check_floor, bad) == f"min_support must be a whole number of cells >= 0 (below 2^40), got {bad!r}"
