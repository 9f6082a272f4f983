"""merger.team.evidence: the contrast verification on maps degraded as real maps from independent runs are
(thick walls in one, doubled walls in the other), against the simulator's truth: correct placements
stand above their rivals, placements 20°–180° off and point-symmetric scenes do not."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from merger import MapInput, MergeParams, merge_team
from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid
from merger.search import angle_diff_deg
from merger.team.evidence import CONTRAST_MIN, FIT_AGREE_DEG, contrast
from merger.team.frames import Warps, shifted
from merger.team.orders import refine_chosen
from merger.team.verify import check_pair, verify_contrast
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
    """6° off the truth is still in the truth's basin (contrast well above 1), but the whole maps fit best
    at least 5° away from it (the local fit's limit), beyond FIT_AGREE_DEG: refused, not accepted degrees wrong."""
    maps, truth = noisy
    placed = Warps(maps).get(0, 1, (truth + 6.0) % 360.0)
    v = verify_contrast(maps[0].grid, placed, maps[0].center, tolerance_m=0.2, contrast_min=CONTRAST_MIN,
                        min_support=200)
    full = contrast(maps[0].grid, placed, maps[0].center, 0.2)  # every rival computed
    assert full.contrast >= CONTRAST_MIN and v.contrast.best_at[0] <= -FIT_AGREE_DEG - 0.5
    assert not v.passed and "fit best" in v.reason
    assert math.isnan(v.contrast.rival)  # the rule refused on the angle: its rivals were not computed
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


def test_the_default_rule_accepts_noisy_maps_the_thesis_rule_refuses_and_refuses_wrong_placements(noisy):
    """Verification auto (the default): on maps degraded as real maps are, the thesis's rule refuses the
    truth (ν below 0.5) and the contrast rule accepts it, so auto accepts it, with the contrast evidence;
    placements 20–180° off are refused by both, and the refusal names both rules."""
    maps, truth = noisy
    w = Warps(maps)
    at = {rule: check_pair(maps[0].grid, w.get(0, 1, truth), maps[0].center, MergeParams(verification=rule))
          for rule in ("whole_map", "contrast", "auto")}
    assert not at["whole_map"].passed and at["contrast"].passed
    assert at["auto"].passed and at["auto"].contrast is not None
    for off in (20.0, 90.0, 180.0):
        v = check_pair(maps[0].grid, w.get(0, 1, (truth + off) % 360.0), maps[0].center, MergeParams())
        assert not v.passed and "ν_min" in v.reason and v.contrast is not None, off  # both rules refused
    res = merge_team(maps, MergeParams(window_m=0.0))
    assert res.accepted and abs(angle_diff_deg(res.chosen.theta_deg[maps[1].name], truth)) <= 2.0, res.reason


def test_the_default_rule_on_maps_that_agree_cell_by_cell_is_the_thesis_rule():
    """Clean views of one scene (the simulator's maps): the thesis's rule passes the truth and auto returns its
    verdict without computing the contrast (no contrast evidence, the same ν)."""
    _, names, views, truth = three_views(4)
    maps = [MapInput(n, g, c) for n, (g, c) in zip(names[:2], views[:2], strict=True)]
    placed = Warps(maps).get(0, 1, truth[names[1]])
    thesis = check_pair(maps[0].grid, placed, maps[0].center, MergeParams(verification="whole_map"))
    auto = check_pair(maps[0].grid, placed, maps[0].center, MergeParams())
    assert thesis.passed and auto.passed and auto.contrast is None and auto.nu == thesis.nu


def test_the_accepted_placement_is_refined_on_the_whole_maps_and_the_search_placement_kept(noisy):
    """refine_chosen: a placement of the noisy maps (accepted by the contrast rule) 1.5° and 0.15 m off the
    truth is refined back to within 0.5° and 5 cm of it; the result keeps the given placement as the
    search's; refine_whole off leaves it, and a rotation-only search (window 0) is refined in angle only."""
    maps, truth = noisy
    res = merge_team(maps, MergeParams(window_m=0.0))
    assert all(v.contrast is not None and v.passed for v in res.chosen.checks.values())
    place = {0: (0.0, (0.0, 0.0)), 1: ((truth + 1.5) % 360.0, (0.15, 0.0))}
    chosen, out = refine_chosen(maps, place, Warps(maps), MergeParams(), res.chosen)
    name = maps[1].name
    assert abs(angle_diff_deg(out[1][0], truth)) <= 0.5 and math.hypot(*out[1][1]) <= 0.05, out
    assert chosen.theta_deg[name] == out[1][0] and chosen.translation(name) == out[1][1]
    assert chosen.search_theta_deg[name] == place[1][0] and chosen.search_translation_m[name] == (0.15, 0.0)
    same, kept = refine_chosen(maps, place, Warps(maps), MergeParams(refine_whole=False), res.chosen)
    assert same is res.chosen and kept == place
    _, turned = refine_chosen(maps, place, Warps(maps), MergeParams(window_m=0.0), res.chosen)
    assert math.dist(turned[1][1], (0.15, 0.0)) < 1e-12  # the translation kept; the angle refined alone


def test_a_pair_the_thesis_rule_accepts_keeps_the_search_placement():
    """Maps that agree cell by cell (clean views): ν accepts, and the merge stays at the search's
    placement (the tolerant fit is coarser than the search's cell-exact optimum)."""
    _, names, views, _ = three_views(4)
    maps = [MapInput(n, g, c) for n, (g, c) in zip(names[:2], views[:2], strict=True)]
    res = merge_team(maps, MergeParams(window_m=0.5))
    assert res.accepted and all(v.contrast is None for v in res.chosen.checks.values())
    assert res.chosen.search_theta_deg == {}


def test_verification_auto_and_the_refinement_are_the_defaults():
    d = MergeParams()
    assert d.verification == "auto" and d.refine_whole


def test_auto_skips_the_contrast_only_where_it_must_refuse(noisy):
    """Below min_support cells of agr̃ + dis the contrast's own support (b's occupied cells on a's known
    cells, never more) is below it too: auto refuses without computing it, the same verdict as the
    contrast rule's."""
    maps, truth = noisy
    placed = Warps(maps).get(0, 1, truth)
    nu = check_pair(maps[0].grid, placed, maps[0].center, MergeParams(verification="whole_map"))
    floor = nu.counts.support + 1
    k = check_pair(maps[0].grid, placed, maps[0].center, MergeParams(verification="contrast", min_support=floor))
    auto = check_pair(maps[0].grid, placed, maps[0].center, MergeParams(min_support=floor))
    assert k.contrast.support <= nu.counts.support and not k.passed and "support" in k.reason
    assert not auto.passed and auto.contrast is None and "support" in auto.reason


def _rule_on_full_contrast(k, min_support=200):
    """The contrast rule's verdict from the complete evidence (every rival computed): the reference for the
    rule that stops early."""
    if k.support < min_support:
        return False, "support"
    if abs(k.best_at[0]) > FIT_AGREE_DEG:
        return False, "fit best"
    return k.contrast >= CONTRAST_MIN, "contrast"


@pytest.mark.parametrize("off", [0.0, 1.5, 3.0, 6.0, 10.0, 25.0, 90.0, 180.0])
def test_the_rule_that_stops_early_gives_the_verdicts_of_the_complete_evidence(noisy, off):
    maps, truth = noisy
    for g1 in (maps[1].grid, OccupancyGrid(np.where(maps[1].grid.states == OCCUPIED_S, FREE_S, maps[1].grid.states)
                                           .astype(np.uint8), maps[1].grid.resolution, maps[1].grid.origin)):
        m = [maps[0], MapInput(maps[1].name, g1, maps[1].center)]
        placed = Warps(m).get(0, 1, (truth + off) % 360.0)
        want_pass, why = _rule_on_full_contrast(contrast(m[0].grid, placed, m[0].center, 0.2))
        v = verify_contrast(m[0].grid, placed, m[0].center, tolerance_m=0.2, contrast_min=CONTRAST_MIN,
                            min_support=200)
        assert v.passed == want_pass, (off, v.reason)
        assert v.passed or why in v.reason, (off, why, v.reason)  # refused by the same test
