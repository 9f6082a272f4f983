"""merger.search.searcher: one problem's searcher — its exact values and counts equal the numpy
definition (the ROIs cut and rotated by :class:`RotationProblem`, counted by :mod:`merger.measures`),
its per-angle sums are the moving ROI's counts, its first maximum is the plain loop, one searcher per
problem object, and concurrent searches on it answer as one alone."""

from __future__ import annotations

import math
import threading

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from merger.grid import FREE_S, OCCUPIED_S
from merger.search import RotationProblem, searcher_for, translation_offsets
from tests.strategies import adversarial_problem

MEASURES = ("similarity", "birk_carpin", "ncc")
SETTINGS = settings(max_examples=12, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), window=st.booleans(),
       theta=st.floats(0.0, 359.9), pick=st.integers(0, 10**6))
def test_exact_values_and_counts_are_the_numpy_definition(seed, measure, window, theta, pick):
    """At (θ, t): the rotation-only problem about c_ref + t (``problem.at``) evaluated on whole ROIs."""
    p = adversarial_problem(seed, measure, window)
    s = searcher_for(p)
    ts = translation_offsets(p.window_cells)
    a, b = ts[pick % len(ts)]
    value, counts = s.exact(theta, a, b)
    want = p.at(a, b).evaluate(theta)
    assert (counts.agree, counts.disagree, counts.free_agree) == \
        (want.counts.agree, want.counts.disagree, want.counts.free_agree)
    assert math.isclose(value, want.value, rel_tol=1e-12, abs_tol=1e-12)
    # the same value by the batch calls, at one angle and at one translation
    assert s.values(theta, [(a, b)])[0] == value
    assert s.values_at_angles([theta, theta], (a, b)).tolist() == [value, value]


@SETTINGS
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES))
def test_angle_sums_are_the_moving_rois_occupied_or_free_cells(seed, measure):
    """NCC reads the moving ROI's occupied lattice points per angle, Birk–Carpin its free ones; the
    similarity index needs none (zeros)."""
    p = adversarial_problem(seed, measure, False)
    s = searcher_for(p)
    angles = np.array([0.0, 17.0, 90.0, 181.5, 300.2])
    s.select(angles)
    sums = s.angle_sums()
    state = {"ncc": OCCUPIED_S, "birk_carpin": FREE_S}.get(measure)
    want = [0 if state is None else int(np.count_nonzero(p.moving_roi(float(th)) == state)) for th in angles]
    assert sums.tolist() == want


@SETTINGS
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES))
def test_first_max_ties_to_the_first_angle_given_then_raster_order(seed, measure):
    """Over angles in the order given (wrapping at 360°) × translations in raster order (b, then a):
    the first strict maximum of the plain loop; None for no angle or no translation."""
    p = adversarial_problem(seed, measure, True)
    s = searcher_for(p)
    k = p.window_cells
    ts = [(a, b) for b in range(-k, k + 1) for a in range(-k, k + 1) if (a + b) % 2 == 0]
    angles = [358.0, 359.0, 0.0, 1.0, 120.0]
    top = None
    for i, th in enumerate(angles):
        for t in ts:
            v = s.values(th, [t])[0]
            if top is None or v > top[0]:
                top = (float(v), i, t)
    assert s.first_max(angles, ts) == top
    assert s.first_max([], ts) is None and s.first_max(angles, []) is None


def test_one_searcher_per_problem_object():
    p = adversarial_problem(1, "similarity", True)
    assert searcher_for(p) is searcher_for(p)
    twin = RotationProblem(p.ref, p.moving, p.center_ref, p.center_moving, p.roi_m, p.measure, p.window_m)
    assert searcher_for(twin) is not searcher_for(p)
    assert searcher_for(twin).run(np.arange(360.0))[0] == searcher_for(p).run(np.arange(360.0))[0]


def test_initial_regions_are_every_whole_degree_with_its_polar_bound_only_without_a_window():
    rot = adversarial_problem(2, "similarity", False)
    nodes, bounds = searcher_for(rot).initial_regions()
    assert nodes.shape == (360, 6) and bounds.shape == (360,)
    assert nodes[:, 0].tolist() == list(range(360)) and (nodes[:, 0] == nodes[:, 1]).all()
    assert not nodes[:, 2:].any()  # the one translation (0, 0)
    assert searcher_for(adversarial_problem(2, "similarity", True)).initial_regions() is None


def test_translation_mask_marks_exactly_the_translations_given():
    p = adversarial_problem(4, "similarity", True)
    k = p.window_cells
    side = 2 * k + 1
    m = searcher_for(p).translation_mask([(-k, -k), (0, 0), (k, 1)])
    assert m.shape == (side * side,)
    assert sorted(np.flatnonzero(m).tolist()) == sorted([0, k * side + k, (1 + k) * side + 2 * k])


def test_concurrent_searches_on_one_searcher_answer_as_alone():
    """One searcher's scratch is shared: threads searching other angle arrays at once must not mix."""
    p = adversarial_problem(9, "similarity", True)
    s = searcher_for(p)
    coarse, fine = np.arange(360.0), np.round(np.arange(40.0, 60.05, 0.1), 1)
    alone = {0: s.run(coarse)[0], 1: s.run(fine)[0]}
    got, errors = [], []

    def work(i):
        try:
            for _ in range(3):
                got.append((i, s.run(coarse if i == 0 else fine)[0]))
        except Exception as e:  # pragma: no cover - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(i % 2,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert len(got) == 12 and all(best == alone[i] for i, best in got)
