"""Bounded caches: LRU order, entry and byte bounds, content keys; and the search's one cache
(:mod:`merger.caches`) staying within its bound over many merge cycles with changing maps (a long
run must not grow), its answers equal to those computed after :func:`merger.caches.clear_all`."""

import numpy as np
import pytest

from merger import caches
from merger.caches import BoundedCache, array_digest
from merger.grid import OccupancyGrid
from merger.team.online import MapMessage, TeamMerger
from merger.team.orders import MergeParams, merge_team
from tests.strategies import three_views


def test_bounded_cache_evicts_least_recently_used_by_count():
    c = BoundedCache(3, 10**9)
    for k in "abc":
        c.put(k, np.zeros(1))
    assert c.get("a") is not None  # a is now the most recent
    c.put("d", np.zeros(1))
    assert len(c) == 3 and c.get("b") is None and c.get("a") is not None and c.get("d") is not None


def test_bounded_cache_evicts_by_bytes_and_refuses_oversized_entries():
    c = BoundedCache(100, 1000)
    c.put("a", np.zeros(60, np.uint8))
    c.put("b", np.zeros(500, np.uint8))
    c.put("c", np.zeros(500, np.uint8))  # 1060 bytes: a goes
    assert c.get("a") is None and c.nbytes == 1000 and len(c) == 2
    c.put("big", np.zeros(1001, np.uint8))
    assert c.get("big") is None and c.nbytes == 1000
    c.put("b", np.zeros(10, np.uint8))  # replacing an entry updates the byte count
    assert c.nbytes == 510
    c.clear()
    assert len(c) == 0 and c.nbytes == 0


def test_array_digest_is_a_content_key():
    a = np.arange(12, dtype=np.uint8).reshape(3, 4)
    assert array_digest(a) == array_digest(a.copy())
    assert array_digest(a) != array_digest(a.reshape(4, 3))  # same bytes, other shape
    assert array_digest(a) != array_digest(a.astype(np.int8))
    b = a.copy()
    b[2, 3] += 1
    assert array_digest(a) != array_digest(b)
    assert array_digest(a[:, ::2]) == array_digest(np.ascontiguousarray(a[:, ::2]))


def _perturbed(grid: OccupancyGrid, rng) -> OccupancyGrid:
    """The grid with a few known cells near the center flipped between free and occupied: a new map."""
    s = grid.states.copy()
    known = np.argwhere(s > 0)
    for i, j in known[rng.choice(len(known), 20, replace=False)]:
        s[i, j] = 3 - s[i, j]
    return OccupancyGrid(s, grid.resolution, grid.origin)


@pytest.mark.parametrize("window_m", [0.0, pytest.param(0.2, marks=pytest.mark.slow)])
def test_caches_stay_within_their_bounds_over_many_cycles(window_m):
    """Every cycle brings a new map; the searcher cache never holds more than its bound, the pair reuse
    holds only the current pairs, and a cycle equals one computed with an empty cache."""
    _, names, maps, _ = three_views(3)
    # every version searched globally: the cycle is then comparable with merge_team from scratch
    params = MergeParams(roi_m=6.0, window_m=window_m, research="every_version")
    rng = np.random.default_rng(0)
    tm = TeamMerger("Lyon", tuple(names), params)
    for n, (g, c) in zip(names, maps, strict=True):
        tm.receive(MapMessage(n, 0.0, g, c))
    current = {n: g for n, (g, _) in zip(names, maps, strict=True)}
    for k in range(1, 13):
        n = names[k % 3]
        current[n] = _perturbed(current[n], rng)
        tm.receive(MapMessage(n, float(k), current[n], maps[names.index(n)][1]))
        res = tm.cycle()
        assert len(caches._SEARCHERS) <= caches.MAX_ENTRIES
        assert len(tm._pairs) <= 3
        if k == 6:
            cached = [o.to_dict() for o in res.orders]
            caches.clear_all()
            assert len(caches._SEARCHERS) == 0
            assert [o.to_dict() for o in merge_team(tm.inputs(), params).orders] == cached


@pytest.mark.parametrize("strategy", ["tree", "orders"])
def test_a_kept_result_does_not_keep_its_searches_frontiers(strategy):
    """A search's frontier (the regions its runner-up starts from) is read within the pair's computation
    and forgotten there: a result held afterwards (the simulation's memo holds thousands, each alignment
    holding its problem for the guard) keeps none of them — 338 MB in the 32-robot hall's first 3 s."""
    from merger.team.params import MapInput
    from merger.team.tree import merge_tree

    _, names, maps, truth = three_views(4)
    inputs = [MapInput(n, g, c) for n, (g, c) in zip(names, maps, strict=True)]
    params = MergeParams(roi_m=8.0)
    res = merge_tree(inputs, params) if strategy == "tree" else merge_team(inputs, params)
    steps = [al for o in res.orders for _, al in o.steps]
    problems = [al.beyond_query.problem for al in steps if al.beyond_query is not None]
    assert problems, "the searches' alignments hold their problems (for the guard beyond the window)"
    assert all(caches.frontier(p) is None for p in problems)
    assert res.accepted and all(abs(float(res.chosen.theta_deg[n]) - truth[n]) % 360 < 2.0 or
                                abs(float(res.chosen.theta_deg[n]) - truth[n]) % 360 > 358.0 for n in names)
