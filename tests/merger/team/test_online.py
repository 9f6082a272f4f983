"""merger.team.online: a robot's merger as maps arrive — the strategy, readiness, stale maps and a cycle."""

from types import SimpleNamespace

import numpy as np
import pytest

from merger.grid import OccupancyGrid
from merger.team import online
from merger.team.online import (
    STRATEGIES,
    STRATEGIES_BY_NAME,
    MapMessage,
    Strategy,
    TeamMerger,
    resolve_strategy,
    strategy_of,
)
from merger.team.orders import MergeParams


def test_auto_is_the_orders_up_to_three_robots_and_the_tree_beyond():
    assert [resolve_strategy("auto", n) for n in (2, 3, 4, 8)] == ["orders", "orders", "tree", "tree"]
    assert resolve_strategy("tree", 3) == "tree"


def test_the_strategies_are_one_table_of_objects():
    """Issue 45: a strategy per name with its cycle; "auto" chooses one of them by the team's size."""
    assert STRATEGIES == tuple(STRATEGIES_BY_NAME) == ("auto", "orders", "tree")
    assert [strategy_of("auto", n) for n in (2, 3, 4, 8)] == [STRATEGIES_BY_NAME[k] for k in ("orders", "orders",
                                                                                              "tree", "tree")]
    assert strategy_of("tree", 2) is STRATEGIES_BY_NAME["tree"] and strategy_of("orders", 9).name == "orders"
    assert STRATEGIES_BY_NAME["tree"].pairs and not STRATEGIES_BY_NAME["orders"].pairs
    with pytest.raises(ValueError, match=r"strategy must be one of \('auto', 'orders', 'tree'\), got 'star'"):
        strategy_of("star", 3)


def test_a_cycle_is_its_strategy_s_cycle(monkeypatch):
    """TeamMerger runs the cycle of the table's entry (looked up once, when the merger is made)."""
    calls = []

    def cycle(merger, inputs, clock, reuse):
        calls.append((merger.self_name, [m.name for m in inputs], clock, reuse is merger._pairs))
        return SimpleNamespace(accepted=False)

    monkeypatch.setitem(STRATEGIES_BY_NAME, "tree", Strategy("tree", cycle, pairs=True))
    tm = TeamMerger("a", ("a", "b"), strategy="tree")
    assert tm.strategy == "tree" and online.STRATEGIES_BY_NAME is STRATEGIES_BY_NAME
    g = OccupancyGrid(np.zeros((4, 4), np.uint8))
    tm.receive(MapMessage("a", 1.0, g, (0.0, 0.0)))
    tm.receive(MapMessage("b", 1.0, g, (0.0, 0.0)))
    assert not tm.cycle(now=2.5).accepted and tm.cycles == 1
    assert calls == [("a", ["a", "b"], 2.5, True)]


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
