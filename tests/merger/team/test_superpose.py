"""merger.team.superpose: the thesis's superposition and the user's merged map, cell by cell against their
definitions (every pair of states)."""

import itertools

import numpy as np
import pytest

from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S
from merger.team.superpose import fuse, superpose

STATES = (UNKNOWN_S, FREE_S, OCCUPIED_S)


def test_superpose_is_occupied_if_either_free_only_if_both():
    pairs = list(itertools.product(STATES, STATES))
    a = np.array([p[0] for p in pairs], np.uint8).reshape(3, 3)
    b = np.array([p[1] for p in pairs], np.uint8).reshape(3, 3)
    want = [OCCUPIED_S if OCCUPIED_S in p else FREE_S if p == (FREE_S, FREE_S) else UNKNOWN_S for p in pairs]
    np.testing.assert_array_equal(superpose(a, b), np.array(want, np.uint8).reshape(3, 3))


def test_fuse_is_known_where_any_map_is_and_occupied_first():
    pairs = list(itertools.product(STATES, STATES))
    a = np.array([p[0] for p in pairs], np.uint8).reshape(3, 3)
    b = np.array([p[1] for p in pairs], np.uint8).reshape(3, 3)
    want = [OCCUPIED_S if OCCUPIED_S in p else FREE_S if FREE_S in p else UNKNOWN_S for p in pairs]
    np.testing.assert_array_equal(fuse([a, b]), np.array(want, np.uint8).reshape(3, 3))
    np.testing.assert_array_equal(fuse([a]), a)  # one layer: itself


def test_the_boundaries():
    assert superpose(np.zeros((0, 4), np.uint8), np.zeros((0, 4), np.uint8)).shape == (0, 4)
    with pytest.raises(ValueError, match="shapes differ"):
        superpose(np.zeros((2, 2), np.uint8), np.zeros((2, 3), np.uint8))
    with pytest.raises(ValueError, match="at least one layer"):
        fuse([])
