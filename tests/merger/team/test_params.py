"""The one parameter set (issue 38, item 3): one default and one rule per setting, read by every caller."""

from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest

import merger
from merger.grid import OccupancyGrid
from merger.search import RotationProblem
from merger.settings import DEFAULT_ROI_M, DEFAULT_WINDOW_M, SettingError, check_roi, check_window
from merger.team import orders, params


def test_the_value_types_live_in_params_and_keep_their_old_paths():
    for name in ("MergeParams", "MapInput", "OrderResult", "TeamMergeResult", "Placement", "ORIGIN"):
        assert getattr(orders, name) is getattr(params, name), name
    assert merger.MergeParams is params.MergeParams and merger.MapInput is params.MapInput


def test_window_and_roi_have_one_default_everywhere():
    g = OccupancyGrid(np.zeros((4, 4), np.uint8))
    align = inspect.signature(merger.search_pair).parameters
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


def test_every_setting_has_one_default_shared_by_align_and_the_search():
    """align's defaults are MergeParams's; the search's settings (ROI, measure, window) RotationProblem's too;
    RotationProblem's refine and floor are the thesis's plain problem, and a merge passes its own."""
    g = OccupancyGrid(np.zeros((4, 4), np.uint8))
    d, prob = params.MergeParams(), RotationProblem(g, g, (0, 0), (0, 0))
    align = inspect.signature(merger.search_pair).parameters
    for name in ("roi_m", "measure", "method", "window_m", "refine", "roi_min_support"):
        assert align[name].default == getattr(d, name), name
    assert (prob.roi_m, prob.measure, prob.window_m) == (d.roi_m, d.measure, d.window_m) == (8.0, "similarity", 0.5)
    assert (prob.refine, prob.min_support) == (False, 0) and (d.refine, d.roi_min_support) == (True, 50)
    merge = orders.problem_for(g, (0, 0), params.MapInput("m", g, (0, 0)), d)  # the merge's problem: its values
    assert (merge.refine, merge.min_support, merge.measure) == (d.refine, d.roi_min_support, d.measure)


def test_one_rule_per_setting_and_its_ranges():
    assert list(params.RULES) == [f.name for f in dataclasses.fields(params.MergeParams)]
    # nu_min: ν is ω̃ on the whole maps (every measure), in [0, 1]; score_min: the ROI score, NCC in [-1, 1]
    for ok in ({"nu_min": 0}, {"nu_min": 1.0}, {"score_min": -1.0}, {"score_min": 1}, {"research_period_s": 1e6},
               {"roi_min_support": np.int64(3)}, {"refine": np.bool_(False)}, {"ambiguity_margin": None}):
        params.MergeParams(**ok)
    for name, bad in (("nu_min", -0.01), ("nu_min", 1.01), ("score_min", -1.01), ("research_period_s", 0.0),
                      ("research_drop", 2.5), ("min_support", True), ("tolerance_m", float("inf")),
                      ("refine", 1), ("measure", "sad"), ("method", "slow"), ("roi_min_support", 2 ** 40)):
        with pytest.raises(SettingError) as e:
            params.MergeParams(**{name: bad})
        assert e.value.key == name and str(e.value) == f"{name} must be {params.RULES[name].expected}, got {bad!r}"
    # the same rule, named by its caller, and the search's floor and measure are RotationProblem's rules
    with pytest.raises(SettingError, match=r"^--nu-min must be a number in \[0, 1\], got 5$"):
        params.RULES["nu_min"](5, "--nu-min")
    assert params.RULES["nu_min"](1, "x") == 1.0 and isinstance(params.RULES["min_support"](np.int32(2), "x"), int)
    g = OccupancyGrid(np.zeros((4, 4), np.uint8))
    for kw, text in (({"min_support": -1}, "min_support must be a whole number of cells"),
                     ({"measure": "sad"}, "measure must be one of 'similarity'")):
        with pytest.raises(SettingError, match=text):
            RotationProblem(g, g, (0, 0), (0, 0), **kw)
