"""merger.search.bnb: the branch and bound (Lemma 5), driven through its searcher, against the plain
loop over every element (angle × translation) of exact values: the first maximum in the reference's
order, the threshold ``above``, excluded elements, the budget, the upper envelope of per-angle values
and the frontier kept within ``keep`` of the answer (Lemma 5b)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from merger.search import searcher_for, translation_offsets
from tests.strategies import adversarial_problem

MEASURES = ("similarity", "birk_carpin", "ncc")
COARSE = np.arange(360.0)
SETTINGS = settings(max_examples=12, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


def exhaustive(p):
    """Exact values (angles 0..359 × translations in the tie order) by the searcher's per-angle values
    (the compiled counts, not the branch and bound); with the translations."""
    s = searcher_for(p)
    ts = translation_offsets(p.window_cells)
    return np.array([s.values(float(th), ts) for th in COARSE]), ts


def first_max(vals, ts, skip=frozenset(), above=-np.inf):
    """The first maximum in the reference's order (translations in tie order, then angles), strictly above
    ``above``, skipping (angle, (a, b)) elements: (value, angle, (a, b)) or None."""
    top = None
    for j, t in enumerate(ts):
        for x in range(vals.shape[0]):
            v = vals[x, j]
            if (x, t) in skip or v <= above:
                continue
            if top is None or v > top[0]:
                top = (float(v), x, t)
    return top


@SETTINGS
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), window=st.booleans())
def test_the_search_returns_the_first_maximum_of_the_exhaustive_loop(seed, measure, window):
    p = adversarial_problem(seed, measure, window)
    vals, ts = exhaustive(p)
    best, env = searcher_for(p).run(COARSE)
    want = first_max(vals, ts)
    assert (best.value, best.angle, (best.a, best.b)) == want
    # the counts it reports are those of that element
    value, counts = searcher_for(p).exact(float(best.angle), best.a, best.b)
    assert value == best.value and (counts.agree, counts.disagree) == (best.agr, best.dis)


@SETTINGS
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), window=st.booleans())
def test_the_envelope_bounds_every_angle_from_above_and_never_exceeds_the_answer(seed, measure, window):
    """Every element is evaluated or lies in a dropped region whose bound raised its angles' envelope:
    per angle, envelope ≥ the exact best over translations; and no envelope value exceeds the answer."""
    p = adversarial_problem(seed, measure, window)
    vals, _ = exhaustive(p)
    best, env = searcher_for(p).run(COARSE)
    assert np.all(env >= vals.max(axis=1) - 1e-12)
    assert np.all(env <= best.value + 1e-12)
    assert env[best.angle] == best.value


@SETTINGS
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), window=st.booleans())
def test_above_looks_only_for_an_element_strictly_better(seed, measure, window):
    p = adversarial_problem(seed, measure, window)
    vals, ts = exhaustive(p)
    s = searcher_for(p)
    top = first_max(vals, ts)
    none, _ = s.run(COARSE, above=top[0])
    assert none.angle == -1  # nothing scores strictly above the maximum
    lower = float(np.unique(vals)[-2]) if np.unique(vals).size > 1 else top[0] - 1.0
    found, _ = s.run(COARSE, above=lower)
    assert (found.value, found.angle, (found.a, found.b)) == top


@SETTINGS
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES))
def test_an_excluded_element_is_never_the_answer(seed, measure):
    """Excluding the answer's element (its angle × its translation) gives the next element in order."""
    p = adversarial_problem(seed, measure, True)
    vals, ts = exhaustive(p)
    s = searcher_for(p)
    top = first_max(vals, ts)
    k, side = p.window_cells, 2 * p.window_cells + 1
    excl_a = np.zeros(360, np.bool_)
    excl_a[top[1]] = True
    excl_t = np.zeros(side * side, np.bool_)
    excl_t[(top[2][1] + k) * side + top[2][0] + k] = True
    got, _ = s.run(COARSE, excl=(excl_a, excl_t))
    assert (got.value, got.angle, (got.a, got.b)) == first_max(vals, ts, skip={(top[1], top[2])})


@SETTINGS
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), budget=st.integers(1, 400))
def test_a_search_complete_within_its_budget_has_the_answer_and_a_tiny_budget_stops_it(seed, measure, budget):
    p = adversarial_problem(seed, measure, True)
    s = searcher_for(p)
    full, _ = s.run(COARSE)
    assert s.complete
    cut, _ = s.run(COARSE, budget=budget)
    if s.complete:
        assert cut == full
    s.run(COARSE, budget=1)  # one region split: 360 sectors cannot all be settled
    assert not s.complete


@SETTINGS
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), window=st.booleans(),
       keep=st.sampled_from([0.0, 0.05, 0.12, 0.3]))
def test_the_frontier_covers_every_element_within_keep_of_the_answer(seed, measure, window, keep):
    """Lemma 5b: every element whose exact value is ≥ answer − keep lies in a frontier region whose
    recorded bound is at least its value (regions in index space: angle lo..hi, a0..a1, b0..b1 with
    translation indices offset by the window K)."""
    p = adversarial_problem(seed, measure, window)
    vals, ts = exhaustive(p)
    s = searcher_for(p)
    best, _ = s.run(COARSE, keep=keep)
    nodes, bounds = s.frontier
    assert nodes.shape[1] == 6 and nodes.shape[0] == bounds.shape[0]
    k = p.window_cells
    for x, j in zip(*np.nonzero(vals >= best.value - keep), strict=True):
        a, b = ts[j][0] + k, ts[j][1] + k
        inside = ((nodes[:, 0] <= x) & (x <= nodes[:, 1]) & (nodes[:, 2] <= a) & (a <= nodes[:, 3])
                  & (nodes[:, 4] <= b) & (b <= nodes[:, 5]))
        assert inside.any(), (x, ts[j])
        assert bounds[inside].max() >= vals[x, j] - 1e-12


@pytest.mark.parametrize("measure", MEASURES)
def test_translation_and_angle_masks_restrict_the_search(measure):
    """Only allowed angles and translations are answers: the first maximum over that sub-grid."""
    p = adversarial_problem(7, measure, True)
    vals, ts = exhaustive(p)
    s = searcher_for(p)
    k, side = p.window_cells, 2 * p.window_cells + 1
    amask = (COARSE % 3) == 1
    allowed = [t for t in ts if t[0] >= 0 and t[1] <= 0]
    tmask = np.zeros(side * side, np.bool_)
    for a, b in allowed:
        tmask[(b + k) * side + a + k] = True
    got, _ = s.run(COARSE, amask=amask, tmask=tmask)
    skip = {(x, t) for x in range(360) for t in ts if not amask[x] or t not in allowed}
    assert (got.value, got.angle, (got.a, got.b)) == first_max(vals, ts, skip=skip)
