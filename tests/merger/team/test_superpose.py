"""merger.team.superpose: the thesis's superposition and the user's merged map, cell by cell against their
definitions (every pair of states)."""

import itertools

import numpy as np
import pytest

from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S
from merger.team.superpose import fuse, fuse_grids, superpose

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


def test_fuse_grids_fuses_the_states_on_the_shared_canvas():
    from merger.grid import OccupancyGrid

    rng = np.random.default_rng(3)
    layers = [OccupancyGrid(rng.integers(0, 3, (7, 9)).astype(np.uint8), 0.05, (-1.5, 2.25)) for _ in range(3)]
    out = fuse_grids(layers)
    assert np.array_equal(out.states, fuse([g.states for g in layers]))
    assert out.resolution == 0.05 and tuple(out.origin) == (-1.5, 2.25)
    with pytest.raises(ValueError, match="at least one"):
        fuse_grids([])


def test_merged_on_frame0_is_the_placed_layers_fused():
    """The one place where maps are placed on map 0's frame and fused (tree, orders, follow, shared)."""
    from merger.team.frames import merged_on_frame0, place_on_frame0
    from merger.team.params import MapInput
    from tests.strategies import three_views

    _, names, maps, truth = three_views(3)
    inputs = [MapInput(n, g, c) for n, (g, c) in zip(names, maps, strict=True)]
    place = {k: (truth[n], (0.0, 0.0)) for k, n in enumerate(names)}
    merged, layers = merged_on_frame0(inputs, place)
    lay = place_on_frame0(inputs, place)
    assert list(layers) == names
    assert all(np.array_equal(layers[n].states, g.states) for n, g in zip(names, lay, strict=True))
    assert np.array_equal(merged.states, fuse([g.states for g in lay]))
    # the merged map knows every cell some placed map knows, and holds every map's occupied cells
    assert merged.count()["occupied"] >= max(g.count()["occupied"] for g in lay)
