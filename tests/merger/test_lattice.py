"""merger.lattice: the ROI lattice's compiled moving states equal their numpy specification."""

import numpy as np
import pytest

from merger.lattice import moving_states, moving_states_numpy, rotation_entries
from tests.strategies import random_grid, random_point


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("theta", [0.0, 1.0, 45.0, 90.0, 179.3, 270.0, -0.3])
def test_compiled_moving_states_equal_the_numpy_specification(seed, theta):
    rng = np.random.default_rng(seed)
    g = random_grid(rng, 30, res=0.05 if seed % 2 else 0.1)
    c = random_point(rng, g, ("any", "centre", "corner")[seed % 3])
    n = 24 + seed
    want = moving_states_numpy(g, theta, c, n, 0.05)
    dense = np.empty(n * n, np.uint8)
    no, nf = moving_states(g.states, g.resolution, g.origin[0], g.origin[1], c[0], c[1], n, 0.05,
                           *rotation_entries(theta), dense)
    np.testing.assert_array_equal(dense.reshape(n, n), want)
    assert (no, nf) == (int((want == 2).sum()), int((want == 1).sum()))
