"""Three-order team merging and the online state, checked against the generated scenes' truth."""

import numpy as np
import pytest

from merger.grid import OccupancyGrid
from merger.search import angle_diff_deg
from merger.team.online import MapMessage, TeamMerger
from merger.team.orders import MapInput, MergeParams, merge_orders, merge_team


def test_merge_orders_are_the_three_pairs_and_general_in_n():
    assert merge_orders(3) == [(0, 1, 2), (0, 2, 1), (1, 2, 0)]
    # ranked by name: every robot evaluates the same orders, whichever map is its own (index 0)
    assert merge_orders(3, ["Nevers", "Auckland", "Lyon"]) == [(1, 2, 0), (1, 0, 2), (2, 0, 1)]
    assert merge_orders(3, ["Auckland", "Nevers", "Lyon"]) == [(0, 2, 1), (0, 1, 2), (2, 1, 0)]
    assert merge_orders(2) == [(0, 1)]
    orders = merge_orders(5)
    assert len(orders) == 10 and all(sorted(o) == list(range(5)) for o in orders)


def test_three_maps_merge_correctly(team_views):
    _, names, maps, truth = team_views
    inputs = [MapInput(n, g, c) for n, (g, c) in zip(names, maps, strict=True)]
    res = merge_team(inputs, MergeParams(roi_m=8.0))
    assert res.accepted and res.frame == "Lyon"
    assert len(res.orders) == 3
    assert res.chosen.nu_sum == max(o.nu_sum for o in res.orders if o.accepted)
    for n in names:
        assert abs(angle_diff_deg(res.chosen.theta_deg[n], truth[n])) <= 1.0
    assert set(res.chosen.nu) == {"Lyon|Auckland", "Lyon|Nevers", "Auckland|Nevers"}
    assert res.merged.count()["occupied"] > max(g.count()["occupied"] for g, _ in maps)
    assert set(res.layers) == set(names)


@pytest.mark.slow
def test_accepted_orders_that_agree_are_combined_into_their_verified_mean(team_views):
    """combine_orders (default): the chosen placement is the mean of the accepted orders within 10° and
    0.2 m of the highest-Σν one, verified again on the whole maps; off, the thesis's highest-Σν order."""
    import math

    _, names, maps, truth = team_views
    inputs = [MapInput(n, g, c) for n, (g, c) in zip(names, maps, strict=True)]
    raw = merge_team(inputs, MergeParams(roi_m=8.0, combine_orders=False))
    res = merge_team(inputs, MergeParams(roi_m=8.0))
    assert raw.chosen.combined == () and raw.chosen.nu_sum == max(o.nu_sum for o in raw.orders if o.accepted)
    agree = [o for o in raw.orders if o.accepted and all(
        abs(angle_diff_deg(o.theta_deg[n], raw.chosen.theta_deg[n])) <= 10.0
        and math.dist(o.translation(n), raw.chosen.translation(n)) <= 0.2 for n in names)]
    assert len(agree) >= 2
    c = res.chosen
    assert c in res.orders and c.order == raw.chosen.order and c.combined == tuple(o.order for o in agree)
    assert c.accepted and all(v.passed for v in c.checks.values()) and set(c.checks) == set(raw.chosen.checks)
    for n in names:
        mean = raw.chosen.theta_deg[n] + np.mean([angle_diff_deg(o.theta_deg[n], raw.chosen.theta_deg[n])
                                                  for o in agree])
        assert abs(angle_diff_deg(c.theta_deg[n], mean)) < 1e-9
        assert np.allclose(c.translation(n), np.mean([o.translation(n) for o in agree], axis=0), atol=1e-12)
        assert abs(angle_diff_deg(c.theta_deg[n], truth[n])) <= 1.0
    assert c.to_dict()["combined"] == [list(o.order) for o in agree]
    assert [o.order for o in res.orders] == [o.order for o in raw.orders]  # the other orders unchanged


def test_rejections_carry_their_reason(team_views):
    _, names, maps, _ = team_views
    inputs = [MapInput(n, g, c) for n, (g, c) in zip(names, maps, strict=True)]
    res = merge_team(inputs, MergeParams(roi_m=8.0, min_support=10**7))
    assert not res.accepted and res.merged is None
    assert all("min_support" in o.reason for o in res.rejected)
    assert res.top in res.orders


def test_online_state_keeps_last_accepted_alignment(team_views):
    _, names, maps, truth = team_views
    tm = TeamMerger("Lyon", tuple(names), MergeParams(roi_m=8.0))
    assert tm.update(MapMessage("Lyon", 1.0, *maps[0])) is None  # not all maps yet
    assert tm.update(MapMessage("Auckland", 1.0, *maps[1])) is None
    res = tm.update(MapMessage("Nevers", 1.5, *maps[2]))
    assert res is not None and res.accepted and tm.current is res
    # an older map arriving late is dropped, no cycle
    assert tm.update(MapMessage("Nevers", 1.2, *maps[2])) is None
    # a useless newer map (all unknown) makes the cycle reject; the good alignment is kept
    g, c = maps[1]
    blank = type(g).unknown(g.height, g.width, g.resolution, g.origin)
    res2 = tm.update(MapMessage("Auckland", 3.0, blank, c))
    assert res2 is not None and not res2.accepted
    assert tm.current is res and tm.cycles == 2
    assert abs(angle_diff_deg(tm.current.chosen.theta_deg["Nevers"], truth["Nevers"])) <= 1.0


def _same_result(a, b):
    assert [o.to_dict() for o in a.orders] == [o.to_dict() for o in b.orders]
    assert (a.chosen is None) == (b.chosen is None)
    if a.merged is not None:
        assert np.array_equal(a.merged.states, b.merged.states)


@pytest.mark.slow
def test_online_cycles_reuse_the_search_of_an_unchanged_pair_with_the_same_result(monkeypatch):
    """A cycle after one map changed searches 5 of 6 alignments: the pair of the two unchanged maps is
    reused from the previous cycle; every figure equals a cycle computed from scratch."""
    import merger.team.orders as team
    from tests.strategies import three_views

    _, names, maps, _ = three_views(3)
    _, _, maps_later, _ = three_views(3, arc=25.0)  # the same robots, having seen more
    calls = []
    real_search = team.search
    monkeypatch.setattr(team, "search", lambda *a, **k: calls.append(1) or real_search(*a, **k))
    tm = TeamMerger("Lyon", tuple(names), MergeParams(roi_m=8.0, research="every_version"))
    for n, (g, c) in zip(names, maps, strict=True):
        tm.receive(MapMessage(n, 1.0, g, c))
    first = tm.cycle()
    assert len(calls) == 6
    calls.clear()
    tm.receive(MapMessage("Lyon", 2.0, *maps_later[0]))  # only Lyon's map changed
    second = tm.cycle()
    assert len(calls) == 5  # Auckland/Nevers pair reused
    auck_nev = [o for o in second.orders if o.order[:2] == ("Auckland", "Nevers")][0]
    assert auck_nev.steps[0][1] is [o for o in first.orders if o.order[:2] == ("Auckland", "Nevers")][0].steps[0][1]
    scratch = merge_team(tm.inputs(), tm.params)
    _same_result(second, scratch)
    # a new center for the same stamp is a different problem: both pairs with Nevers are searched again,
    # only the unchanged Lyon/Auckland pair is reused
    calls.clear()
    g, c = maps[2]
    tm.maps["Nevers"] = MapMessage("Nevers", 1.0, g, (c[0] + 0.3, c[1]))
    third = tm.cycle()
    assert len(calls) == 5
    _same_result(third, merge_team(tm.inputs(), tm.params))
    assert len(tm._pairs) == 3  # only the current pairs are kept


def test_merge_team_without_versions_never_reuses(team_views):
    _, names, maps, _ = team_views
    inputs = [MapInput(n, g, c) for n, (g, c) in zip(names, maps, strict=True)]
    reuse = {}
    merge_team(inputs, MergeParams(roi_m=8.0), reuse=reuse)
    assert reuse == {}


def _order(order, theta, t, nus):
    from merger.measures import Counts
    from merger.team.orders import OrderResult
    from merger.team.verify import Verification

    checks = {k: Verification(v, Counts(500, 100), True) for k, v in nus.items()}
    return OrderResult(order, theta, (), checks, True, "", t)


def test_ambiguity_rule_rejects_close_rival_placements():
    from merger.team.orders import MergeParams, _ambiguity

    names = ("A", "B", "C")
    good = _order(names, {"A": 0.0, "B": 120.0, "C": 240.0}, {"A": (0, 0), "B": (0.01, 0), "C": (0, 0.02)},
                  {"A|B": 0.80, "A|C": 0.79, "B|C": 0.68})
    flip = _order(names, {"A": 0.0, "B": 300.0, "C": 240.0}, {"A": (0, 0), "B": (-0.2, -0.31), "C": (0, 0.02)},
                  {"A|B": 0.80, "A|C": 0.71, "B|C": 0.67})
    shifted = _order(names, {"A": 0.0, "B": 120.5, "C": 240.0}, {"A": (0, 0), "B": (0.35, 0), "C": (0, 0.02)},
                     {"A|B": 0.60, "A|C": 0.79, "B|C": 0.60})
    near = _order(names, {"A": 0.0, "B": 120.3, "C": 240.1}, {"A": (0, 0), "B": (0.03, 0), "C": (0, 0.0)},
                  {"A|B": 0.80, "A|C": 0.79, "B|C": 0.68})
    results = [good, flip, shifted, near]
    # a half-turn rival within 0.03 of mean ν: ambiguous (it names the map and both ν)
    why = _ambiguity(results, [0, 1], 0, 0.05)
    assert "ambiguous" in why and "B" in why and "180.0°" in why
    # the same rival beaten by more than the margin: not ambiguous
    assert _ambiguity(results, [0, 1], 0, 0.02) == ""
    # a rival 0.35 m away (same angle) counts too; one that agrees within 10° / 0.2 m does not
    assert "0.34 m" in _ambiguity(results, [0, 2], 0, 0.2)
    assert _ambiguity(results, [0, 3], 0, 0.5) == ""
    # margin 0 is the thesis's rule: the highest sum wins
    assert _ambiguity(results, [0, 1], 0, 0.0) == ""
    assert MergeParams(window_m=0.0).margin == 0.0 and MergeParams(window_m=0.5).margin == 0.05
    assert MergeParams(window_m=0.0, ambiguity_margin=0.1).margin == 0.1
    with pytest.raises(ValueError, match="ambiguity_margin"):
        MergeParams(ambiguity_margin=float("nan"))


@pytest.mark.parametrize("center", [(float("nan"), 0.0), (0.0, float("inf")), (1.0,), "a,b", None])
def test_map_input_with_a_bad_center_names_the_map(center):
    g = OccupancyGrid(np.zeros((4, 4), np.uint8), 0.05, (0.0, 0.0))
    with pytest.raises(ValueError, match="map 'Nevers': center must be two finite numbers"):
        MapInput("Nevers", g, center)
