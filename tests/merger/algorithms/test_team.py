"""merger.algorithms.team: a team merged by a pairwise algorithm — with answers that are the true relative
placements of random maps, every map the accepted pairs reach from map 0 is placed at its truth whatever
tree the scores pick, the others are left out with their reasons; the answer cache keys on map versions."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from merger.algorithms.base import PairAnswer
from merger.algorithms.team import merge_pairwise
from merger.grid import OccupancyGrid
from merger.search import angle_diff_deg
from merger.team.orders import MapInput, MergeParams

G = OccupancyGrid(np.ones((10, 10), np.uint8), 0.05, (0.0, 0.0))


def _maps(n, version=1):
    return [MapInput(f"m{k}", G, (0.25, 0.25), version=version) for k in range(n)]


def _relative(pi, pj) -> PairAnswer:
    """Map j onto map i from both placements onto frame 0: θ_ij = θ_j − θ_i, t_ij = R(−θ_i)(t_j − t_i)."""
    a = math.radians(-pi[0])
    dx, dy = pj[1][0] - pi[1][0], pj[1][1] - pi[1][1]
    return PairAnswer(True, (pj[0] - pi[0]) % 360.0, (math.cos(a) * dx - math.sin(a) * dy,
                                                      math.sin(a) * dx + math.cos(a) * dy))


def _reach(n, ok):
    seen, todo = {0}, [0]
    while todo:
        i = todo.pop()
        for j in range(n):
            if j not in seen and ok.get((min(i, j), max(i, j))):
                seen.add(j)
                todo.append(j)
    return seen


@settings(max_examples=40, deadline=None)
@given(data=st.data(), n=st.integers(2, 5))
def test_every_reachable_map_is_placed_at_its_truth_and_the_rest_left_out(data, n):
    truth = [(0.0, (0.0, 0.0))] + [
        (data.draw(st.floats(0, 359.9)), (data.draw(st.floats(-3, 3)), data.draw(st.floats(-3, 3))))
        for _ in range(n - 1)]
    ok = {(i, j): data.draw(st.booleans()) for i in range(n) for j in range(i + 1, n)}
    scores = {p: data.draw(st.floats(0.1, 10.0)) for p in ok}

    def align(ref, mov, params):
        i, j = int(ref.name[1:]), int(mov.name[1:])
        a = _relative(truth[i], truth[j])
        reason = "" if ok[(i, j)] else f"test: {mov.name} onto {ref.name} refused"
        return PairAnswer(ok[(i, j)], a.theta_deg, a.translation_m, scores[(i, j)], {}, reason)

    res = merge_pairwise(align, _maps(n), MergeParams(), name="test")
    reach = _reach(n, ok)
    if len(reach) == 1:
        assert res.chosen is None and not res.accepted
        return
    ch = res.chosen
    assert res.accepted and set(ch.theta_deg) == {f"m{k}" for k in reach} and ch.order[0] == "m0"
    for k in reach:
        assert abs(angle_diff_deg(ch.theta_deg[f"m{k}"], truth[k][0])) < 1e-7
        assert ch.translation(f"m{k}") == pytest.approx(truth[k][1], abs=1e-9)
    assert set(res.layers) == set(ch.theta_deg) and res.merged is not None
    for k in set(range(n)) - reach:  # every map left out names the refusals that kept it out
        assert f"m{k}: onto m0: test: m{k} onto m0 refused" in ch.reason


def test_the_cache_keys_on_map_versions():
    calls = []

    def align(ref, mov, params):
        calls.append((ref.name, mov.name))
        return PairAnswer(True, 10.0, (0.1, 0.0), 1.0)

    cache: dict = {}
    merge_pairwise(align, _maps(3), MergeParams(), cache=cache, name="a")
    assert len(calls) == 3
    merge_pairwise(align, _maps(3), MergeParams(), cache=cache, name="a")
    assert len(calls) == 3  # unchanged versions: nothing aligned again
    newer = _maps(3)
    newer[2] = MapInput("m2", G, (0.25, 0.25), version=2)
    merge_pairwise(align, newer, MergeParams(), cache=cache, name="a")
    assert sorted(calls[3:]) == [("m0", "m2"), ("m1", "m2")]  # only the pairs of the new version
    merge_pairwise(align, _maps(3), MergeParams(), cache=cache, name="b")
    assert len(calls) == 8  # another algorithm's name: its own answers
    merge_pairwise(align, _maps(3, version=None), MergeParams(), cache=cache, name="a")
    merge_pairwise(align, _maps(3, version=None), MergeParams(), cache=cache, name="a")
    assert len(calls) == 14  # maps without versions are never taken from the cache


def test_refused_answers_still_give_the_best_hypothesis_tree():
    """Nothing accepted: the tree of the best refused answers is the cycle's hypothesis (placed at their
    placements), not chosen, and the reason lists, per map left out, the refusals onto map 0 (the only map
    an accepted pair placed)."""
    def align(ref, mov, params):
        i, j = int(ref.name[1:]), int(mov.name[1:])
        score = {(0, 1): 0.9, (0, 2): 0.2, (1, 2): 0.8}[(i, j)]
        return PairAnswer(False, 30.0 * (j - i), (0.0, 0.0), score, reason=f"x: {i}{j}")

    res = merge_pairwise(align, _maps(3), MergeParams())
    assert res.chosen is None and not res.accepted
    top = res.top
    assert top.order == ("m0", "m1", "m2")  # m1 via the 0.9 edge, then m2 via m1's 0.8 edge, not 0.2
    assert top.theta_deg == pytest.approx({"m0": 0.0, "m1": 30.0, "m2": 60.0})
    assert top.reason == "m1: onto m0: x: 01; m2: onto m0: x: 02"


def test_a_pair_with_an_unversioned_map_is_aligned_again():
    def align(ref, mov, params):
        return PairAnswer(True, float(mov.grid.states.sum() % 360), (0.0, 0.0), 1.0)

    cache: dict = {}
    other = OccupancyGrid(np.full((10, 10), 2, np.uint8), 0.05, (0.0, 0.0))  # another map j, no version
    first = [MapInput("m0", G, (0.25, 0.25), version=1), MapInput("m1", G, (0.25, 0.25))]
    second = [MapInput("m0", G, (0.25, 0.25), version=1), MapInput("m1", other, (0.25, 0.25))]
    merge_pairwise(align, first, MergeParams(), cache=cache)
    res = merge_pairwise(align, second, MergeParams(), cache=cache)
    assert res.chosen.theta_deg["m1"] == float(other.states.sum() % 360)
