"""merger.inputs: a merge's input checks refuse what no merge can take, before any work, in one
MergeInputError line naming the input; maps of other resolutions are resampled onto the first map's cells
with a note, or refused when that would exceed the map limits."""

import numpy as np
import pytest

from merger.grid import OccupancyGrid
from merger.inputs import (
    MergeInputError,
    check_center,
    check_centers,
    checked_maps,
    params_of,
    same_resolution,
)
from merger.io.mapread import MAX_MAP_CELLS
from merger.team.params import MergeParams


def refused(fn, *args) -> MergeInputError:
    with pytest.raises(MergeInputError) as e:
        fn(*args)
    assert str(e.value) == e.value.key + e.value.rest and "\n" not in str(e.value)
    return e.value


def grid(h=40, w=60, res=0.05, origin=(0.0, 0.0)):
    return OccupancyGrid(np.ones((h, w), np.uint8), res, origin)


def test_settings_by_their_names_and_rules():
    assert params_of({"roi_m": 6.0, "window_m": 1.5}) == MergeParams(roi_m=6.0, window_m=1.5)
    assert refused(params_of, {"roi": 8}).key == "roi"
    e = refused(params_of, {"roi_m": 6.0, "window_m": 2.0})
    assert e.key == "window_m" and "quarter" in e.rest
    assert refused(params_of, {"roi_m": 1e9}).key == "roi_m"  # the inputs' limits: at most MAX_ROI_M
    assert str(e.named("--window")).startswith("--window = 2 m is more than a quarter")


def test_one_finite_center_per_map():
    assert check_centers([(1, 2), np.array([0.5, -1])], 2) == [(1.0, 2.0), (0.5, -1.0)]
    assert refused(check_centers, [(1, 2)], 2).key == "centers"
    assert refused(check_centers, 5, 2).key == "centers"
    assert refused(check_centers, [(1, 2), (1, 2, 3)], 2).key == "centers[1]"
    assert refused(check_centers, [(1, 2), ("a", 0)], 2).key == "centers[1]"
    assert refused(check_centers, [(float("nan"), 2), (0, 0)], 2).rest.startswith(": expected finite numbers")


def test_a_center_lies_within_half_the_roi_of_its_map():
    g = grid(origin=(-1.0, -1.0))  # spans x [-1, 2], y [-1, 1]
    check_center(g, (2.0 + 4.0, 1.0 + 4.0), 8.0, "centers[0]", "a.yaml")  # 4 m out: on the edge of the ROI
    e = refused(check_center, g, (6.01, 0.0), 8.0, "centers[0]", "a.yaml")
    assert str(e) == ("centers[0]: (6.01, 0) is outside a.yaml, which spans x [-1, 2], y [-1, 1] m: expected a "
                      "point within 4 m (half the ROI side) of the map, in its frame")


def test_other_resolutions_are_resampled_onto_the_first_maps_cells():
    a, b = grid(res=0.05), grid(h=20, w=30, res=0.1)
    out, notes = same_resolution(["a", "b"], [a, b])
    assert out[0].resolution == 0.05 and out[0].shape == (40, 60) and (out[0].states == 1).all()
    assert notes == ["b: resampled from 0.1 to 0.05 m per cell, the first map's (occupied where any occupied cell "
                     "falls, free where free cells cover half a cell; docs/real-maps.md)"]
    assert same_resolution(["a", "c"], [a, grid(res=0.05 * (1 + 1e-9))])[1] == []  # the same within 1e-6
    side = int(np.sqrt(MAX_MAP_CELLS)) // 2 + 10  # fine enough to exceed the limit at 1/4 the cell size
    coarse = OccupancyGrid(np.zeros((side, side), np.uint8), 0.2, (0.0, 0.0))
    e = refused(same_resolution, ["fine", "coarse"], [grid(res=0.05), coarse])
    assert e.key == "coarse" and e.rest.endswith("give the finer map first")


def test_checked_maps_runs_every_check():
    a, b = grid(), grid(res=0.1)
    grids, cs, notes = checked_maps(["a", "b"], [a, b], [(1, 1), (1, 1)], 8.0)
    assert [g.resolution for g in grids] == [0.05, 0.05] and cs == [(1.0, 1.0)] * 2 and len(notes) == 1
    assert refused(checked_maps, ["a"], [a], [(1, 1)], 8.0).rest == ": expected at least two maps, got 1"
    assert refused(checked_maps, ["a", "b"], [a, b], [(1, 1), (99, 1)], 8.0).key == "centers[1]"
    e = refused(checked_maps, ["a", "b"], [a, b], [(1, 1), (1, 1)], 0.3)  # 6 cells: below the ROI's floor
    assert e.key == "roi_m" and "of a at 0.05 m per cell" in e.rest
