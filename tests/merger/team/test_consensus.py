"""The team's placement from mutually consistent measurements (merger.team.consensus, issue 43)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from merger.team.consensus import (
    SEPARATION_M,
    Measurement,
    Paths,
    apart,
    assemble,
    compose,
    inverse,
    single_bar,
)


def _truth(n, rng):
    """True placements of n maps onto map 0 (centered coordinates)."""
    return [(0.0, 0.0, 0.0)] + [(float(rng.uniform(0, 360)), *map(float, rng.uniform(-0.3, 0.3, 2)))
                                for _ in range(n - 1)]


def _meas(truth, i, j, nu=0.6, off=(0.0, 0.0, 0.0), names=None):
    """The measurement of map j onto map i: truth_i⁻¹ ∘ truth_j, moved by ``off`` (a wrong one)."""
    z = compose(off, compose(inverse(truth[i]), truth[j]))
    label = f"{names[i]}|{names[j]}" if names else f"{i}|{j}"
    return Measurement(i, j, z, nu, label)


def _names(n):
    return [f"R{k}" for k in range(n)]


def _placed_right(a, truth, k, tol=(0.5, 0.02)):
    dth, dt = apart(a.place[k], truth[k])
    return dth <= tol[0] and dt <= tol[1]


def test_two_clusters_joined_by_one_wrong_but_verified_pair_are_not_assembled():
    """Two clusters, each a consistent triangle; between them one pair verified at a wrong rotation with a
    ν below the bar for 15 tested pairs: map 0's cluster is placed, the other left out and said why."""
    rng = np.random.default_rng(1)
    truth = _truth(6, rng)
    names = _names(6)
    inside = [_meas(truth, i, j, 0.7, names=names) for i, j in ((0, 1), (0, 2), (1, 2), (3, 4), (3, 5), (4, 5))]
    wrong = _meas(truth, 2, 3, 0.6, off=(111.0, 0.1, -0.2), names=names)
    a = assemble(6, inside + [wrong], tested=15, nu_min=0.5, names=names)
    assert set(a.place) == {0, 1, 2}
    assert all(_placed_right(a, truth, k) for k in a.place)
    assert set(a.left_out) == {3, 4, 5} and "needs ν >=" in a.left_out[3]


def test_two_independent_consistent_pairs_join_the_clusters():
    rng = np.random.default_rng(2)
    truth = _truth(6, rng)
    names = _names(6)
    inside = [_meas(truth, i, j, 0.7, names=names) for i, j in ((0, 1), (0, 2), (1, 2), (3, 4), (3, 5), (4, 5))]
    one = [_meas(truth, 2, 3, 0.6, names=names)]
    assert set(assemble(6, inside + one, tested=15, nu_min=0.5, names=names).place) == {0, 1, 2}
    two = one + [_meas(truth, 1, 5, 0.55, names=names)]
    a = assemble(6, inside + two, tested=15, nu_min=0.5, names=names)
    assert set(a.place) == set(range(6)) and all(_placed_right(a, truth, k) for k in range(6))
    assert any("2 agreeing routes (2 direct)" in j for j in a.joins)


def test_a_wrong_cluster_joined_by_two_agreeing_wrong_pairs_is_not_joined_with_a_correct_rival():
    """Two wrong pairs agree on a wrong placement of the second cluster; two right ones agree on the
    true one: neither group has twice the other's routes, so nothing joins (a false rejection is cheap)."""
    rng = np.random.default_rng(3)
    truth = _truth(6, rng)
    names = _names(6)
    inside = [_meas(truth, i, j, 0.7, names=names) for i, j in ((0, 1), (0, 2), (1, 2), (3, 4), (3, 5), (4, 5))]
    off = (90.0, 0.0, 0.0)
    wrong = [_meas(truth, 0, 3, 0.9, off=_cluster_off(truth, 0, 3, off), names=names),
             _meas(truth, 1, 4, 0.9, off=_cluster_off(truth, 1, 4, off), names=names)]
    right = [_meas(truth, 2, 5, 0.6, names=names), _meas(truth, 1, 3, 0.6, names=names)]
    a = assemble(6, inside + wrong + right, tested=15, nu_min=0.5, names=names)
    assert set(a.place) == {0, 1, 2} and "against 2 placing it elsewhere" in a.left_out[3]


def _cluster_off(truth, i, j, off):
    """The offset that makes measurement (i, j) place j's whole cluster moved by ``off`` in map 0's frame."""
    moved = compose(off, truth[j])
    return compose(compose(inverse(truth[i]), moved), inverse(compose(inverse(truth[i]), truth[j])))


def test_an_injected_inconsistent_measurement_is_rejected_and_named():
    rng = np.random.default_rng(4)
    truth = _truth(5, rng)
    names = _names(5)
    meas = [_meas(truth, i, j, 0.6, names=names) for i in range(5) for j in range(i + 1, 5)]
    meas[4] = _meas(truth, 1, 2, 0.95, off=(45.0, 0.2, 0.0), names=names)  # the strongest, and wrong
    a = assemble(5, meas, tested=10, nu_min=0.5, names=names)
    assert set(a.place) == set(range(5)) and all(_placed_right(a, truth, k) for k in range(5))
    assert set(a.rejected) == {"R1|R2"} and a.rejected["R1|R2"].startswith("inconsistent")
    assert len(a.used) == 9


def test_a_lone_measurement_joins_only_above_a_bar_that_grows_with_the_pairs_tested():
    assert single_bar(0.5, 6) == 0.55  # four robots: today's bridge margin
    assert single_bar(0.5, 28) < single_bar(0.5, 120) < single_bar(0.5, 496) < 0.9
    rng = np.random.default_rng(5)
    truth = _truth(2, rng)
    names = _names(2)
    strong = [_meas(truth, 0, 1, 0.7, names=names)]
    assert set(assemble(2, strong, tested=6, nu_min=0.5, names=names).place) == {0, 1}
    assert set(assemble(2, strong, tested=120, nu_min=0.5, names=names).place) == {0}


def test_a_lone_ambiguous_pair_joins_only_with_a_second_route():
    """A pair whose search had a rival within the margin, chosen between by whole-map ν, is a choice between
    two hypotheses: however high its ν it does not join two parts of a team alone (a half turn that a
    symmetric team in a symmetric room verifies better than the truth); a second agreeing route joins them,
    and the refusal names the rule."""
    rng = np.random.default_rng(6)
    truth = _truth(4, rng)
    names = _names(4)
    half = _meas(truth, 0, 2, 0.79, off=_cluster_off(truth, 0, 2, (180.0, 0.0, 0.0)), names=names)
    inside = [_meas(truth, 0, 1, 0.7, names=names), _meas(truth, 2, 3, 0.7, names=names)]
    plain = assemble(4, inside + [half], tested=6, nu_min=0.5, names=names)
    assert set(plain.place) == {0, 1, 2, 3}  # not ambiguous: its ν clears the bar, the half turn is placed
    assert apart(plain.place[2], truth[2])[0] > 170.0
    chosen = Measurement(half.i, half.j, half.z, half.nu, half.label, ambiguous=True)
    a = assemble(4, inside + [chosen], tested=6, nu_min=0.5, names=names)
    assert set(a.place) == {0, 1} and "a lone ambiguous pair" in a.left_out[2] and "second route" in a.left_out[3]
    # the truth's pair, ambiguous as well, with a second agreeing route (through map 1): joined, and right
    right = [Measurement(0, 2, _meas(truth, 0, 2).z, 0.72, "R0|R2", ambiguous=True), _meas(truth, 1, 3, 0.6, names=names)]
    b = assemble(4, inside + right, tested=6, nu_min=0.5, names=names)
    assert set(b.place) == set(range(4)) and all(_placed_right(b, truth, k) for k in range(4))


def _circle_paths(n, truth, radius=3.0, steps=20, dt=0.25):
    """Robots k driving one circle 360/n° apart, each path in its own map's centered coordinates."""
    out = []
    for k in range(n):
        t = dt * np.arange(steps)
        phi = np.radians(360.0 * k / n) + 0.05 * t
        world = np.stack([radius * np.cos(phi), radius * np.sin(phi)], axis=1)  # map 0's frame
        inv = inverse(truth[k])
        c, s = math.cos(math.radians(inv[0])), math.sin(math.radians(inv[0]))
        own = np.stack([inv[1] + c * world[:, 0] - s * world[:, 1], inv[2] + s * world[:, 0] + c * world[:, 1]], 1)
        out.append(np.column_stack([t, own]))
    return out


def test_a_team_stacked_on_one_spot_is_refused_by_the_robots_paths():
    """The 32-robot failure: every map placed at the identity is consistent around every cycle (each map
    shows the central objects ahead), but it puts every robot on map 0's robot's path."""
    n = 8
    truth = [(360.0 * k / n, 0.0, 0.0) for k in range(n)]  # maps at their robot's angle on the circle
    names = _names(n)
    stacked = [Measurement(i, j, (0.0, 0.0, 0.0), 0.8, f"{names[i]}|{names[j]}") for i in range(n) for j in range(i + 1, n)]
    assert set(assemble(n, stacked, tested=28, nu_min=0.5, names=names).place) == set(range(n))  # blind
    a = assemble(n, stacked, tested=28, nu_min=0.5, names=names, trajectories=_circle_paths(n, truth))
    assert set(a.place) == {0} and all(r.startswith("impossible: it places") for r in a.rejected.values())
    # the true placements on the same paths: every robot placed
    right = [_meas(truth, i, j, 0.8, names=names) for i in range(n) for j in range(i + 1, n)]
    b = assemble(n, right, tested=28, nu_min=0.5, names=names, trajectories=_circle_paths(n, truth))
    assert set(b.place) == set(range(n)) and not b.rejected


def test_paths_without_common_instants_say_nothing():
    a = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    b = np.array([[5.0, 0.0, 0.0], [6.0, 0.0, 0.0]])  # another day's run: the same spot, never at once
    assert Paths([a, b]).conflict([0], [1], (0.0, 0.0, 0.0), ["A", "B"]) == ""
    near = np.array([[0.0, SEPARATION_M * 0.5, 0.0], [0.5, SEPARATION_M * 0.5, 0.0], [1.0, SEPARATION_M * 0.5, 0.0]])
    assert "within" in Paths([a, near]).conflict([0], [1], (0.0, 0.0, 0.0), ["A", "B"])
    far = near.copy()
    far[:, 1] = 1.0
    assert Paths([a, far]).conflict([0], [1], (0.0, 0.0, 0.0), ["A", "B"]) == ""


@settings(max_examples=60, deadline=None)
@given(n=st.integers(4, 12), seed=st.integers(0, 10_000), wrong=st.integers(0, 3), density=st.floats(0.5, 1.0))
def test_wrong_minority_measurements_never_move_a_placed_map(n, seed, wrong, density):
    """Random teams, random subsets of true measurements and a few wrong ones (rotations ≥ 20° off, and
    ≥ 20° from each other: independent wrong answers) whose ν stays below the lone measurement's bar (a
    wrong pair above it is the risk the bar accepts, as two wrong pairs that agree are the risk of the two
    routes' rule: drawn at random, two of map 0's three pairs once fell 6° and 0.2 m apart and placed the
    team by them): every map placed is placed right — a wrong measurement joins nothing alone and cannot
    outvote the cycles."""
    rng = np.random.default_rng(seed)
    truth = _truth(n, rng)
    names = _names(n)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n) if rng.random() < density]
    bad = set(map(tuple, rng.permutation(pairs)[:wrong])) if pairs else set()
    meas, k = [], 0
    for i, j in pairs:
        off = (0, 0, 0)
        if (i, j) in bad:  # the k-th wrong one in its own 90° band: 20-110°, 130-220°, 240-330°
            off, k = (float(rng.uniform(20, 110)) + 110.0 * k, *map(float, rng.uniform(-0.5, 0.5, 2))), k + 1
        meas.append(_meas(truth, i, j, float(rng.uniform(0.5, 0.9)), off=off, names=names))
        if (i, j) in bad:
            meas[-1] = Measurement(i, j, meas[-1].z, single_bar(0.5, n * (n - 1) // 2) - 0.01, meas[-1].label)
    a = assemble(n, meas, tested=n * (n - 1) // 2, nu_min=0.5, names=names)
    for k in a.place:
        if k:
            dth, dt = apart(a.place[k], truth[k])
            assert dth <= 10.0 and dt <= 0.2, (k, a.joins, a.rejected)


@settings(max_examples=80, deadline=None)
@given(n=st.integers(3, 16), seed=st.integers(0, 10_000), wrong=st.integers(0, 6), density=st.floats(0.3, 1.0),
       stacked=st.booleans(), paths=st.booleans())
def test_each_join_evaluated_once_gives_the_assembly_evaluated_afresh(n, seed, wrong, density, stacked, paths):
    """The assembly keeps a join's evaluation between rounds (only the pairs with the grown cluster are
    evaluated again): on random teams with wrong measurements of every strength, impossible ones (a team
    stacked on one spot, with the robots' paths) and partial measurement sets, the same placements,
    rejections with their reasons, left-out maps and joins as evaluating every pair afresh each round."""
    import merger.team.consensus as consensus

    rng = np.random.default_rng(seed)
    truth = [(360.0 * k / n, *map(float, rng.uniform(-0.2, 0.2, 2))) for k in range(n)]
    names = _names(n)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n) if rng.random() < density]
    bad = set(map(tuple, rng.permutation(pairs)[:wrong])) if pairs else set()
    meas = []
    for i, j in pairs:
        if stacked and (i, j) in bad:  # the identity: every robot on one spot
            meas.append(Measurement(i, j, (0.0, 0.0, 0.0), float(rng.uniform(0.5, 0.99)), f"{names[i]}|{names[j]}"))
            continue
        off = (float(rng.uniform(20, 340)), *map(float, rng.uniform(-0.5, 0.5, 2))) if (i, j) in bad else (0, 0, 0)
        meas.append(_meas(truth, i, j, float(rng.uniform(0.5, 0.99)), off=off, names=names))
    traj = _circle_paths(n, truth) if paths else None
    kw = dict(tested=n * (n - 1) // 2, nu_min=0.5, names=names, trajectories=traj)
    once = assemble(n, meas, **kw)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(consensus, "_EVALUATE_ONCE", False)
        fresh = assemble(n, meas, **kw)
    assert once.place == fresh.place
    assert [m.label for m in once.used] == [m.label for m in fresh.used]
    assert once.rejected == fresh.rejected and once.left_out == fresh.left_out and once.joins == fresh.joins


@settings(max_examples=150, deadline=None)
@given(n_a=st.integers(1, 5), n_b=st.integers(1, 5), steps=st.integers(1, 30), seed=st.integers(0, 10_000),
       spread=st.sampled_from([0.05, 0.3, 1.0, 3.0]), grid=st.booleans())
def test_the_compiled_conflict_check_says_what_the_numpy_one_says(n_a, n_b, steps, seed, spread, grid):
    """Paths.conflict (the compiled kernel) against Paths.conflict_reference (numpy) on random paths: robots
    with partial, shifted or no common time, close and far, on a coarse lattice (ties in distance), placed
    by random turns — the same sentence, to the character."""
    rng = np.random.default_rng(seed)
    trajs = []
    for _ in range(n_a + n_b):
        if rng.random() < 0.15:
            trajs.append(None)
            continue
        t0 = float(rng.integers(0, 5)) * 0.5
        t = t0 + 0.5 * np.arange(steps)
        xy = rng.normal(0.0, spread, (steps, 2))
        if grid:
            xy = np.round(xy / 0.05) * 0.05
        trajs.append(np.column_stack([t, xy]))
    paths = Paths(trajs)
    names = [f"R{k}" for k in range(n_a + n_b)]
    ka, kb = list(range(n_a)), list(range(n_a, n_a + n_b))
    for _ in range(3):
        z = (float(rng.uniform(0, 360)), float(rng.normal(0, spread)), float(rng.normal(0, spread)))
        assert paths.conflict(ka, kb, z, names) == paths.conflict_reference(ka, kb, z, names)
    z = (0.0, 0.0, 0.0)
    assert paths.conflict(ka, kb, z, names) == paths.conflict_reference(ka, kb, z, names)


def test_the_compiled_conflict_check_says_each_of_its_three_answers_as_the_numpy_one():
    """Two robots side by side 0.25 m apart (close at every instant), 0.05 m apart (touching), 2 m apart
    (nothing): the kernel's sentence is numpy's each time."""
    t = np.arange(10) * 0.5
    for gap, says in ((0.25, "within"), (0.05, "m apart at"), (2.0, "")):
        paths = Paths([np.column_stack([t, t * 0.1, 0 * t]), np.column_stack([t, t * 0.1, 0 * t + gap])])
        got = paths.conflict([0], [1], (0.0, 0.0, 0.0), ["A", "B"])
        assert got == paths.conflict_reference([0], [1], (0.0, 0.0, 0.0), ["A", "B"])
        assert (says in got) if says else got == "", got
