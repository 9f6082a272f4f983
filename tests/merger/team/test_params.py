"""The one parameter set (issue 38, item 3): one default and one rule per setting, read by every caller."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

import merger
from merger.grid import OccupancyGrid
from merger.search import RotationProblem
from merger.search.problem import DEFAULT_ROI_M, DEFAULT_WINDOW_M, SettingError, check_roi, check_window
from merger.team import orders, params


def test_the_value_types_live_in_params_and_keep_their_old_paths():
    for name in ("MergeParams", "MapInput", "OrderResult", "TeamMergeResult", "Placement", "ORIGIN"):
        assert getattr(orders, name) is getattr(params, name), name
    assert merger.MergeParams is params.MergeParams and merger.MapInput is params.MapInput


def test_window_and_roi_have_one_default_everywhere():
    g = OccupancyGrid(np.zeros((4, 4), np.uint8))
    align = inspect.signature(merger.align).parameters
    for roi, window in ((params.MergeParams().roi_m, params.MergeParams().window_m),
                        (RotationProblem(g, g, (0, 0), (0, 0)).roi_m, RotationProblem(g, g, (0, 0), (0, 0)).window_m),
                        (align["roi_m"].default, align["window_m"].default)):
        assert (roi, window) == (DEFAULT_ROI_M, DEFAULT_WINDOW_M) == (8.0, 0.5)


def test_one_rule_each_named_by_its_caller():
    with pytest.raises(SettingError) as e:
        check_window(3.0, 8.0, "merger.window_m", "merger.roi_m")
    assert str(e.value).startswith("merger.window_m = 3 m is more than a quarter of merger.roi_m (8 m)")
    assert e.value.key == "merger.window_m" and "expected at most 2 m" in e.value.rest
    for bad in (True, "0.5", None, float("nan"), -1.0):
        with pytest.raises(SettingError, match="window_m"):
            check_window(bad, 8.0)
    assert check_window(1, 8.0) == 1.0 and isinstance(check_window(1, 8.0), float)
    with pytest.raises(SettingError, match=r"^--roi: expected a number in \(0, 100\], got 1000$"):
        check_roi(1000.0, key="--roi", limits=True)
    assert check_roi(1000.0) == 1000.0  # the library has no input limit, only the search's cells
    with pytest.raises(SettingError, match="expected a side of at most 4000 cells"):
        check_roi(41.0, 0.01)
    with pytest.raises(SettingError, match="expected a side of 10 to 4000 cells of m.yaml"):
        check_roi(0.2, 0.05, "--roi", limits=True, cells_of="m.yaml")
