"""merger.search.counts: the compiled exact counts equal their numpy definition. At any angle θ and
translation (a, b) of adversarial problems (tests/strategies.py): the moving ROI the kernels fill is
:func:`merger.lattice.moving_states_numpy`'s, its occupied points (dense or sparse, one angle or all) are
that ROI's, and (agr̃, dis, ff) are :func:`merger.measures.count_cells` of the reference ROI at c_ref + t
against it — the counts every search method's score is made of."""

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from merger.grid import FREE_S, OCCUPIED_S
from merger.lattice import moving_states_numpy, rotation_entries
from merger.measures import count_cells
from merger.search.counts import (
    exact_counts,
    exact_counts_sparse,
    fill_moving,
    moving_points_all,
    sparse_moving,
)
from merger.search.prepared import Prepared
from tests.strategies import adversarial_problem


def entries(theta: float) -> np.ndarray:
    return np.array(rotation_entries(theta), np.float64)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**6), theta=st.one_of(st.integers(0, 359).map(float), st.floats(0, 360, exclude_max=True)),
       data=st.data())
def test_counts_at_one_placement_equal_count_cells_of_the_two_rois(seed, theta, data):
    p = adversarial_problem(seed, "birk_carpin", True)  # birk_carpin: the kernels count free/free too
    prep = Prepared(p)
    t, n, k = prep.tables, p.n, prep.k
    a, b = data.draw(st.integers(-k, k)), data.draw(st.integers(-k, k))
    mov = moving_states_numpy(p.moving, theta, p.center_moving, n, p.ref.resolution)
    ref = p.at(a, b).ref_roi()

    dense, pocc = np.empty(n * n, np.uint8), np.empty(n * n, np.int32)
    n_occ, n_free = fill_moving(t, entries(theta), dense, pocc)
    np.testing.assert_array_equal(dense.reshape(n, n), mov)
    assert (n_occ, n_free) == (np.count_nonzero(mov == OCCUPIED_S), np.count_nonzero(mov == FREE_S))
    np.testing.assert_array_equal(pocc[:n_occ], np.flatnonzero(mov == OCCUPIED_S))

    want = count_cells(ref, mov)
    got = exact_counts(t, dense, pocc, n_occ, a + k, b + k, True)
    assert got == (want.agree, want.disagree, want.free_agree)
    assert exact_counts(t, dense, pocc, n_occ, a + k, b + k, False)[:2] == (want.agree, want.disagree)

    mark, sp = np.zeros(n * n, np.int32), np.empty(n * n, np.int32)
    c = sparse_moving(t, entries(theta), mark, 1, sp)
    np.testing.assert_array_equal(np.sort(sp[:c]), np.flatnonzero(mov == OCCUPIED_S))
    assert exact_counts_sparse(t, sp, c, a + k, b + k, entries(theta)) == (want.agree, want.disagree)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**6))
def test_the_occupied_points_at_every_angle_at_once(seed):
    """moving_points_all: per angle, the occupied lattice points of that angle's moving ROI (its buffer
    grown as needed), in the order sparse_moving finds them."""
    p = adversarial_problem(seed, "similarity", False)
    t, n = Prepared(p).tables, p.n
    angles = np.arange(0.0, 360.0, 7.5)
    rot = np.array([rotation_entries(a) for a in angles], np.float64)
    start, cnt, buf = moving_points_all(t, rot)
    assert start[0] == 0 and np.array_equal(start[1:], np.cumsum(cnt)[:-1]) and buf.size == cnt.sum()
    for x, a in enumerate(angles):
        mov = moving_states_numpy(p.moving, a, p.center_moving, n, p.ref.resolution)
        got = buf[start[x]:start[x] + cnt[x]]
        np.testing.assert_array_equal(np.sort(got), np.flatnonzero(mov == OCCUPIED_S))
        assert np.unique(got).size == got.size  # each point once
