"""The local search: the exhaustive search restricted to its region, exactly (merger/search/local.py)."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from merger.search import FINE_HALF_WIDTH_DEG, angle_diff_deg, reference_search, search
from merger.search.local import LOCAL_HALF_CELLS, LOCAL_HALF_DEG, local_search, reference_local, region
from merger.search.prepared import translation_offsets
from tests.strategies import adversarial_problem

MEASURES = ("similarity", "birk_carpin", "ncc")


def _key(al):
    return (al.theta_deg, al.cells, al.score, al.counts.agree, al.counts.disagree)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), window=st.booleans(),
       theta=st.sampled_from([0.0, 0.4, 2.0, 359.6, 181.0, 97.3]), da=st.integers(-6, 6), db=st.integers(-6, 6))
def test_the_local_search_is_the_exhaustive_search_restricted_to_its_region(seed, measure, window, theta, da, db):
    p = adversarial_problem(seed, measure, window)
    k = p.window_cells
    cells = (max(-k, min(k, da)), max(-k, min(k, db)))
    fast, ref = local_search(p, theta, cells), reference_local(p, theta, cells)
    assert _key(fast) == _key(ref)
    assert fast.counts == ref.counts
    # the answer lies in the region (its coarse angle there, the 0.1° step within 1° of it)
    _, ts = region(p, theta, cells)
    assert abs(angle_diff_deg(fast.theta_grid_deg, round(theta) % 360)) <= LOCAL_HALF_DEG + FINE_HALF_WIDTH_DEG + 1e-9
    assert fast.cells in ts


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), window=st.booleans())
def test_about_the_global_answer_the_local_search_returns_it(seed, measure, window):
    # the global answer is the first maximum of the whole grid: it is also the region's first maximum
    p = adversarial_problem(seed, measure, window)
    g = reference_search(p)
    th_c = float(g.beyond_query.answer[0]) if g.beyond_query is not None else round(g.theta_deg)
    loc = local_search(p, th_c, g.cells)
    assert _key(loc) == _key(g)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(MEASURES), da=st.integers(-4, 4), db=st.integers(-4, 4))
def test_the_local_search_is_the_same_with_its_points_computed_or_kept_by_a_global_search(seed, measure, da, db):
    # a local search reads 7 of the 360 coarse angles: it computes their points itself unless a global search
    # of the same moving map kept all of them
    p = adversarial_problem(seed, measure, True)
    k = p.window_cells
    cells, theta = (max(-k, min(k, da)), max(-k, min(k, db))), 97.3
    alone = local_search(p, theta, cells)
    search(p, "fast")
    after = local_search(p, theta, cells)
    ref = reference_local(p, theta, cells)
    assert _key(alone) == _key(after) == _key(ref)


def test_the_region_spans_the_set_half_widths_and_wraps_at_zero():
    p = adversarial_problem(3, "similarity", True)
    amask, ts = region(p, 359.7, (0, 0))
    assert set(np.flatnonzero(amask)) == {(360 + d) % 360 for d in range(-LOCAL_HALF_DEG, LOCAL_HALF_DEG + 1)}
    k = p.window_cells
    h = min(k, LOCAL_HALF_CELLS)
    assert len(ts) == (2 * h + 1) ** 2
    assert ts == [t for t in translation_offsets(k) if t in set(ts)]  # the reference's order
