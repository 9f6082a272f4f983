"""Measures on hand-made grids; the expected counts are worked out by hand in the comments."""

import math

import numpy as np
import pytest

from merger.measures import birk_carpin, count_cells, ncc, similarity_index

U, F, O = 0, 1, 2
A = np.array([[O, O, F, U],
              [F, F, O, O],
              [U, O, F, F]], np.uint8)
B = np.array([[O, F, F, O],
              [F, O, U, O],
              [O, O, F, U]], np.uint8)
# cell by cell (A,B): (O,O) agr  (O,F) dis  (F,F) ff  (U,O) -
#                     (F,F) ff   (F,O) dis  (O,U) -   (O,O) agr
#                     (U,O) -    (O,O) agr  (F,F) ff  (F,U) -
# agr~ = 3, dis = 2, free/free = 3


def test_counts_by_hand():
    c = count_cells(A, B)
    assert (c.agree, c.disagree, c.free_agree, c.support) == (3, 2, 3, 5)


def test_modified_similarity_index():
    s = similarity_index(A, B)
    assert s.value == pytest.approx(3 / 5)


def test_birk_carpin_counts_free_agreement():
    assert birk_carpin(A, B).value == pytest.approx((3 + 3) / (3 + 3 + 2))


def test_ncc_by_hand():
    a = (A == O).astype(float).ravel()
    b = (B == O).astype(float).ravel()
    # 12 cells, a has 5 ones, b has 6 ones, 3 in common
    num = 3 - 5 * 6 / 12
    den = math.sqrt((5 - 25 / 12) * (6 - 36 / 12))
    assert ncc(A, B).value == pytest.approx(num / den)
    assert np.corrcoef(a, b)[0, 1] == pytest.approx(num / den)


def test_symmetric_and_degenerate_cases():
    assert similarity_index(A, B).value == similarity_index(B, A).value
    empty = np.zeros_like(A)
    assert similarity_index(A, empty).value == 0.0 and similarity_index(A, empty).counts.support == 0
    assert ncc(A, empty).value == 0.0
    assert similarity_index(A, A).value == 1.0
    with pytest.raises(ValueError):
        similarity_index(A, B[:2])


def test_free_agreement_does_not_count_in_modified_index():
    a = np.array([[F, F, F, O]], np.uint8)
    b = np.array([[F, F, F, F]], np.uint8)
    assert similarity_index(a, b).value == 0.0  # 0 agr~, 1 dis
    assert birk_carpin(a, b).value == pytest.approx(3 / 4)
