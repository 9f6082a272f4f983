"""merger.team.online: a robot's merger as maps arrive — the strategy, readiness, stale maps and a cycle."""

import pytest

from merger.team.online import MapMessage, TeamMerger, resolve_strategy
from merger.team.orders import MergeParams


def test_auto_is_the_orders_up_to_three_robots_and_the_tree_beyond():
    assert [resolve_strategy("auto", n) for n in (2, 3, 4, 8)] == ["orders", "orders", "tree", "tree"]
    assert resolve_strategy("tree", 3) == "tree"


def test_the_team_is_checked():
    with pytest.raises(ValueError, match="not in the team"):
        TeamMerger("Lyon", ("Auckland", "Nevers"))
    with pytest.raises(ValueError, match="unique"):
        TeamMerger("Lyon", ("Lyon", "Lyon"))
    with pytest.raises(ValueError, match="strategy"):
        TeamMerger("Lyon", ("Lyon", "Nevers"), strategy="star")


def test_maps_arrive_a_stale_one_is_dropped_and_the_full_team_merges(team_views):
    _, names, maps, _ = team_views
    tm = TeamMerger("Lyon", tuple(names), MergeParams(roi_m=8.0))
    assert tm.update(MapMessage("Lyon", 1.0, *maps[0])) is None  # one map: not ready
    assert tm.update(MapMessage("Auckland", 2.0, *maps[1])) is None  # the whole team by default
    assert not tm.receive(MapMessage("Auckland", 1.5, *maps[1]))  # older than the one held
    res = tm.update(MapMessage("Nevers", 3.0, *maps[2]))
    assert res is not None and tm.cycles == 1 and [m.name for m in tm.inputs()] == names
    assert res.accepted and tm.current is res  # the three views of one room merge: the answer is held
