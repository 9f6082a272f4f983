"""The graph of a team's pairs (merger.team.posegraph): the spanning tree, composed placements, the adjustment."""

import dataclasses

import numpy as np
import pytest

from merger.measures import Counts
from merger.search import angle_diff_deg
from merger.team.frames import compose
from merger.team.orders import MergeParams
from merger.team.posegraph import PairResult, adjust, chain, compose_tree, loop_edges, relative, spanning_tree
from merger.team.verify import Verification


def test_spanning_tree_is_maximum_and_deterministic():
    edges = {(0, 1): 0.6, (0, 2): 0.9, (1, 2): 0.8, (2, 3): 0.7, (1, 3): 0.7}
    assert spanning_tree(4, edges) == [(0, 2), (1, 2), (1, 3)]  # (1,3) before (2,3): equal weight, lower index
    assert spanning_tree(5, {(0, 1): 0.5, (3, 4): 0.9}) == [(3, 4), (0, 1)]  # a forest: 2 is alone
    assert spanning_tree(3, {}) == []


def _al(theta, t):
    class A:
        theta_deg = theta
        translation_m = t
    return A()


def test_relative_and_chain_compose_like_the_orders_placements():
    """Placing j onto i then i onto 0 agrees with merger.team.frames.compose, and a reversed pair undoes itself."""
    th, t = relative(_al(30.0, (0.2, -0.1)), reverse=False)
    back = relative(_al(30.0, (0.2, -0.1)), reverse=True)
    p = chain((th, t), back)  # i → j → i: the identity
    assert abs(angle_diff_deg(p[0], 0.0)) < 1e-9 and np.allclose(p[1], (0.0, 0.0), atol=1e-12)
    # onto map 1's frame: map 0 at 0, map 1 at (50°, t1), map 2 at (120°, t2); compose gives 2 onto 1
    onto0 = {0: (0.0, (0.0, 0.0)), 1: (50.0, (0.3, 0.1)), 2: (120.0, (-0.2, 0.4))}
    onto1 = compose(onto0, 0, 1)
    p2 = chain(onto0[1], onto1[2])  # 2 placed onto 1, 1 placed onto 0: 2 onto 0 again
    assert abs(angle_diff_deg(p2[0], 120.0)) < 1e-9 and np.allclose(p2[1], (-0.2, 0.4), atol=1e-12)


def test_adjust_spreads_a_loop_error_over_the_ring_and_leaves_a_tree_alone():
    """Four maps on a ring, true angles 0/90/180/270°, each chain pair off by +0.5°; the closing pair is
    exact. The tree (by ν) is the chain, whose far end is off by 1.5°; least squares spreads it."""
    def ver(nu):
        return Verification(nu, Counts(1000, 100), True)

    def pair(i, j, theta, nu):
        return PairResult(str(i), str(j), _al(theta, (0.0, 0.0)), ver(nu))

    pairs = {(0, 1): pair(0, 1, 90.5, 0.9), (1, 2): pair(1, 2, 90.5, 0.9), (2, 3): pair(2, 3, 90.5, 0.9),
             (0, 3): pair(0, 3, 270.0, 0.6)}
    tree = spanning_tree(4, {k: v.verification.nu for k, v in pairs.items()})
    assert (0, 3) not in tree
    names = [str(k) for k in range(4)]
    place, _ = compose_tree(4, tree, pairs, names)
    assert abs(angle_diff_deg(place[3][0], 270.0) - 1.5) < 1e-9
    adjusted = adjust(place, pairs, names)
    assert abs(angle_diff_deg(adjusted[3][0], 270.0)) < 0.6
    assert all(abs(angle_diff_deg(adjusted[k][0], 90.0 * k)) < 0.6 for k in range(4))
    assert adjusted[0] == (0.0, (0.0, 0.0))
    chain_only = {k: v for k, v in pairs.items() if k != (0, 3)}
    assert adjust(place, chain_only, names) == place


def test_pairs_that_did_not_verify_but_agree_with_the_tree_close_loops_in_the_adjustment():
    """A chain 0-1-2-3 of verified pairs, each off by +0.7° (the far end 2.1° off); the pairs 0|2, 0|3 and
    1|3 did not verify (too few cells) but their own searches are near the truth. With ``params`` they are
    weaker loops: the far end comes within 1°. A weak pair 10° or more from the tree, one under ν_min/2, and
    an ambiguous one are not used; without ``params`` only verified pairs count (a tree: unchanged)."""
    from merger.team.ambiguity import PairAmbiguity

    def pair(i, j, theta, nu, passed=True, support=1100):
        v = Verification(nu, Counts(support - 100, 100), passed, "" if passed else "support < min_support")
        return PairResult(str(i), str(j), _al(theta, (0.0, 0.0)), v)

    params = MergeParams(nu_min=0.5, min_support=200)
    chain_pairs = {(0, 1): pair(0, 1, 90.7, 0.6), (1, 2): pair(1, 2, 90.7, 0.6), (2, 3): pair(2, 3, 90.7, 0.6)}
    weak = {(0, 2): pair(0, 2, 180.1, 0.5, False, 150), (0, 3): pair(0, 3, 270.2, 0.45, False, 180),
            (1, 3): pair(1, 3, 180.0, 0.4, False, 120)}
    names = [str(k) for k in range(4)]
    tree = spanning_tree(4, {k: v.verification.nu for k, v in chain_pairs.items()})
    place, _ = compose_tree(4, tree, chain_pairs, names)
    assert abs(angle_diff_deg(place[3][0], 270.0) - 2.1) < 1e-9
    pairs = {**chain_pairs, **weak}
    assert adjust(place, pairs, names) == place  # verified pairs only: a tree
    edges = loop_edges(place, pairs, names, params)
    assert len(edges) == 6
    weights = {(i, j): w for i, j, _, w in edges}
    assert weights[(0, 2)] == pytest.approx(0.5 * 150 / 200) and weights[(1, 3)] == pytest.approx(0.4 * 120 / 200)
    adjusted = adjust(place, pairs, names, params)
    assert abs(angle_diff_deg(adjusted[3][0], 270.0)) < 1.0
    assert all(abs(angle_diff_deg(adjusted[k][0], 90.0 * k)) < 1.0 for k in range(4))
    assert adjusted[0] == (0.0, (0.0, 0.0))
    amb = PairAmbiguity.__new__(PairAmbiguity)
    excluded = {(0, 2): pair(0, 2, 192.0, 0.5, False, 150),  # 10.6° from the tree's 181.4°
                (0, 3): pair(0, 3, 270.2, 0.2, False, 180),  # ν < ν_min / 2
                (1, 3): dataclasses.replace(weak[(1, 3)], ambiguity=amb)}
    assert adjust(place, {**chain_pairs, **excluded}, names, params) == place
