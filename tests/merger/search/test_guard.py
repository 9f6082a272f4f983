"""merger.search.guard: the guard beyond the window finds a known better placement just outside the
translation window (a map against itself with the moving center off by more than the window), says
None when the window holds the truth or there is no ring to look in, equals its exhaustive yardstick
without a budget, and is what an Alignment's lazy ``beyond`` answers."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from merger.search import (
    BeyondQuery,
    RotationProblem,
    angle_diff_deg,
    beyond_window,
    fast_search,
    reference_beyond,
    reference_search,
)
from merger.synthetic import arc_viewpoints, partial_view, room_scene
from tests.strategies import adversarial_problem

RES = 0.05


@pytest.fixture(scope="module")
def view():
    """A partial view of a generated room in the world frame (the center, (0, 0), at the frame's origin)."""
    scene = room_scene(np.random.default_rng(4))
    g, c = partial_view(scene, (0.0, 0.0, 0.0), arc_viewpoints(90.0, 40.0, 1.8, k=3), size_m=8.0)
    assert c == (0.0, 0.0)
    return g


def _shifted(view, cells, window_m, roi_m=4.0):
    """The view against itself, the moving center told ``cells`` (a, b) off: the truth is θ = 0 and
    t = the offset in metres (x_ref = c_ref + t + (x_m − c_m) with c_m = c_ref + t)."""
    off = (cells[0] * RES, cells[1] * RES)
    return RotationProblem(view, view, (0.0, 0.0), off, roi_m, "similarity", window_m), off


@pytest.mark.parametrize("cells", [(4, 0), (0, -4), (4, 4), (-4, 3)])
def test_a_better_placement_just_outside_the_window_is_found_at_the_truth(view, cells):
    """Window ±2 cells, the guard's ring 3..4 cells; the truth 4 cells off on one axis: at least 2 cells
    from every placement in the window, so apart from whatever the window's answer is (a truth within 1.5
    steps of it would count as the answer's own peak, cut by the window's edge)."""
    p, off = _shifted(view, cells, 0.1)
    ans = reference_search(p)
    best = float(ans.profile.max())
    assert best < 1.0  # the window cannot reach the truth
    th = int(round(ans.theta_grid_deg)) % 360
    found = beyond_window(p, best, (th, ans.cells), budget=0)
    assert found is not None
    theta, t, score = found
    # 1° turns the 4 m ROI's farthest lattice point by 3.5 cm, under a cell: the map on itself scores 1
    # on a plateau of a degree or so about θ = 0
    assert abs(angle_diff_deg(theta, 0.0)) <= 1.0
    assert math.isclose(t[0], off[0], abs_tol=1e-9) and math.isclose(t[1], off[1], abs_tol=1e-9)
    assert score == 1.0 > best  # the map on itself: every occupied cell agrees
    assert found == reference_beyond(p, best, (th, ans.cells))
    assert beyond_window(p, best, (th, ans.cells)) == found  # within the default budget too


def test_nothing_beyond_when_the_window_holds_the_truth(view):
    p, off = _shifted(view, (1, -2), 0.15)
    ans = reference_search(p)
    assert ans.score == 1.0 and abs(angle_diff_deg(ans.theta_deg, 0.0)) <= 1.0
    assert np.allclose(ans.translation_m, off)
    best = float(ans.profile.max())
    th = int(round(ans.theta_grid_deg)) % 360
    assert beyond_window(p, best, (th, ans.cells), budget=0) is None
    assert reference_beyond(p, best, (th, ans.cells)) is None


def test_no_ring_without_a_window_or_at_the_largest_window(view):
    p, _ = _shifted(view, (0, 0), 0.0)
    assert beyond_window(p, -1.0, (0, (0, 0))) is None and reference_beyond(p, -1.0, (0, (0, 0))) is None
    assert fast_search(p).beyond is None
    big, _ = _shifted(view, (0, 0), 1.0)  # a quarter of the 4 m ROI: the ring would be no wider
    assert beyond_window(big, -1.0, (0, (0, 0))) is None


@settings(max_examples=10, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(["similarity", "birk_carpin", "ncc"]),
       drop=st.sampled_from([0.0, 0.05, 0.2]))
def test_without_a_budget_the_guard_is_its_exhaustive_yardstick(seed, measure, drop):
    """Adversarial problems, the threshold at or below the answer's best coarse value: the branch and bound
    over the ring reports the exhaustive guard's placement; what it reports always scores above the
    threshold and lies apart (more than 1.5 steps) from the answer."""
    p = adversarial_problem(seed, measure, True)
    ans = reference_search(p)
    th = int(round(ans.theta_grid_deg)) % 360
    thr = float(ans.profile.max()) - drop
    got = beyond_window(p, thr, (th, ans.cells), budget=0)
    want = reference_beyond(p, thr, (th, ans.cells))
    assert (got is None) == (want is None)
    if got is not None:
        assert got[2] == want[2] > thr  # the same best score (ties may pick another placement)
        apart_deg = abs(angle_diff_deg(got[0], th)) > 1.5
        apart_t = math.dist((got[1][0] / p.ref.resolution, got[1][1] / p.ref.resolution), ans.cells) > 1.5
        assert apart_deg or apart_t


def test_an_alignment_answers_its_guard_lazily_and_once(view):
    p, off = _shifted(view, (4, 0), 0.1)
    al = fast_search(p)
    calls = []

    def guard(problem, best_value, answer):
        calls.append((best_value, answer))
        return (7, (np.float32(0.5), 1), np.float64(0.25))

    al2 = dataclasses.replace(al, beyond_query=BeyondQuery(p, 0.3, (1.0, (0, 0)), guard))
    assert calls == []
    assert al2.beyond == (7.0, (0.5, 1.0), 0.25)
    assert al2.beyond == (7.0, (0.5, 1.0), 0.25)
    assert calls == [(0.3, (1.0, (0, 0)))]  # asked once, with the query's question
    assert all(type(v) is float for v in (al2.beyond[0], *al2.beyond[1], al2.beyond[2]))
    # the default guard: the fast search's own question answered by beyond_window
    theta, t, score = al.beyond
    assert abs(angle_diff_deg(theta, 0.0)) <= 1.0 and np.allclose(t, off) and score == 1.0


def test_a_guard_rebuilding_its_problem_answers_as_the_one_that_kept_it(view):
    """Alignment.guard_rebuilding: the unanswered guard keeps no problem (no grid) and asks for it once,
    when answered; its answer is the kept problem's. An answered guard is kept as it is."""
    p, _ = _shifted(view, (4, 0), 0.1)
    kept, light = fast_search(p), fast_search(p)
    built = []

    def problem_of():
        built.append(1)
        return dataclasses.replace(p, ref=dataclasses.replace(p.ref), moving=dataclasses.replace(p.moving))

    light = light.guard_rebuilding(problem_of)
    assert light.beyond_query.problem is None and built == []
    assert light.theta_deg == kept.theta_deg and light.cells == kept.cells
    assert light.beyond == kept.beyond and kept.beyond is not None
    assert light.beyond == kept.beyond and built == [1]
    assert kept.guard_rebuilding(problem_of) is kept  # answered: nothing left to ask
