"""merger.team.evidence: the contrast verification on maps degraded as real maps from independent runs are
(thick walls in one, doubled walls in the other), against the simulator's truth: correct placements
stand above their rivals, placements 20°–180° off and point-symmetric scenes do not."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from merger import MapInput, MergeParams, merge_team
from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid
from merger.search import angle_diff_deg
from merger.team.evidence import CONTRAST_MIN, contrast
from merger.team.orders import Warps, shifted
from merger.team.verify import verify_contrast
from tests.strategies import three_views


def thick(g: OccupancyGrid) -> OccupancyGrid:
    """Walls one cell thicker on every side (a coarser sensor, another SLAM's blur)."""
    occ = cv2.dilate((g.states == OCCUPIED_S).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    st = g.states.copy()
    st[occ] = OCCUPIED_S
    return OccupancyGrid(st, g.resolution, g.origin)


def doubled(g: OccupancyGrid) -> OccupancyGrid:
    """Every wall also two cells off (a second pass of a drifting run)."""
    st = g.states.copy()
    st[np.roll(g.states == OCCUPIED_S, 2, axis=0) & (st != UNKNOWN_S)] = OCCUPIED_S
    return OccupancyGrid(st, g.resolution, g.origin)


@pytest.fixture(scope="module")
def noisy():
    _, names, maps, truth = three_views(4)
    (g0, c0), (g1, c1) = maps[0], maps[1]
    return [MapInput(names[0], thick(g0), c0), MapInput(names[1], doubled(g1), c1)], truth[names[1]]


def placed_contrast(maps, theta):
    w = Warps(maps)
    return contrast(maps[0].grid, w.get(0, 1, theta), shifted(maps[0].center, (0.0, 0.0)))


def test_a_correct_placement_of_noisy_maps_stands_above_its_rivals_and_wrong_ones_do_not(noisy):
    maps, truth = noisy
    right = placed_contrast(maps, truth)
    assert right.contrast >= CONTRAST_MIN and right.support >= 200
    for off in (20.0, 45.0, 90.0, 180.0):
        wrong = placed_contrast(maps, (truth + off) % 360.0)
        assert wrong.contrast < 1.0, off  # the truth is its rival


def test_a_placement_a_few_degrees_off_stands_above_its_rivals_but_is_refused_by_the_agreement(noisy):
    """4° off the truth is still in the truth's basin (contrast well above 1), but the whole maps fit best
    about 4° away from it: refused, not accepted a few degrees wrong."""
    maps, truth = noisy
    placed = Warps(maps).get(0, 1, (truth + 4.0) % 360.0)
    v = verify_contrast(maps[0].grid, placed, maps[0].center, tolerance_m=0.2, contrast_min=CONTRAST_MIN,
                        min_support=200)
    assert v.contrast.contrast >= CONTRAST_MIN and abs(v.contrast.best_at[0] + 4.0) <= 1.0
    assert not v.passed and "fit best" in v.reason
    right = verify_contrast(maps[0].grid, Warps(maps).get(0, 1, truth), maps[0].center, tolerance_m=0.2,
                            contrast_min=CONTRAST_MIN, min_support=200)
    assert right.passed, right.reason


def test_merge_cycles_with_the_contrast_rule_accept_noisy_maps_at_the_true_angle(noisy):
    maps, truth = noisy
    res = merge_team(maps, MergeParams(verification="contrast", window_m=0.0))
    assert res.accepted, res.reason
    assert abs(angle_diff_deg(res.chosen.theta_deg[maps[1].name], truth)) <= 2.0
    check = next(iter(res.chosen.checks.values()))
    assert check.contrast is not None and check.contrast.contrast >= CONTRAST_MIN


def test_a_point_symmetric_room_is_refused():
    """A rectangular room centred on the center looks the same after a half turn: the rival is as good
    as the placement, so the contrast rule refuses what no evidence can decide."""
    st = np.full((120, 160), UNKNOWN_S, np.uint8)
    st[10:110, 10:150] = FREE_S
    st[10, 10:150] = st[109, 10:150] = OCCUPIED_S
    st[10:110, 10] = st[10:110, 149] = OCCUPIED_S
    g = OccupancyGrid(st, 0.05, (-4.0, -3.0))
    maps = [MapInput("a", g, (0.0, 0.0)), MapInput("b", g, (0.0, 0.0))]
    k = placed_contrast(maps, 0.0)
    assert k.contrast < CONTRAST_MIN and abs(angle_diff_deg(k.rival_at[0], 180.0)) <= 6.0
    res = merge_team(maps, MergeParams(verification="contrast", window_m=0.0, roi_m=6.0))
    assert not res.accepted and "contrast" in res.reason
