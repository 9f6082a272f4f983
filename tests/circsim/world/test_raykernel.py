"""circsim.world.raykernel: the compiled segment loop gives the numpy path's ranges bit for bit (the same
beams per segment, Chipmunk's arithmetic), hits a wall at its analytic distance, and only ever lowers
the ranges it is given."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from circsim.world.laser import raycast
from circsim.world.raykernel import segments_alpha


def _kernel(origin, start, inc, beams, range_max, seg, alpha=None):
    ax, ay = origin
    a = start + np.arange(beams) * inc
    bx, by = ax + range_max * np.cos(a), ay + range_max * np.sin(a)
    alpha = np.full(beams, np.inf) if alpha is None else alpha
    segments_alpha(ax, ay, start, inc, bx, by, np.ascontiguousarray(seg, np.float64), alpha)
    return alpha * range_max


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(1, 64), ox=st.floats(-2, 2), oy=st.floats(-2, 2),
       start=st.floats(-4, 4), beams=st.integers(2, 400), full=st.booleans())
def test_the_kernel_equals_the_numpy_path_bit_for_bit(seed, n, ox, oy, start, beams, full):
    """Up to 64 segments raycast takes its numpy path: the kernel's ranges are the same floats."""
    seg = np.random.default_rng(seed).uniform(-5, 5, (n, 4))
    inc = (2 * math.pi if full else math.radians(240)) / beams
    want = raycast((ox, oy), start, inc, beams, 5.6, seg, np.zeros((0, 3)))
    assert np.array_equal(_kernel((ox, oy), start, inc, beams, 5.6, seg), want)


def test_a_wall_at_its_analytic_distance():
    inc = math.radians(1.0)
    r = _kernel((0.5, -0.2), math.radians(-30), inc, 61, 10.0, np.array([[4.0, -20.0, 4.0, 20.0]]))
    a = math.radians(-30) + inc * np.arange(61)
    assert np.allclose(r, 3.5 / np.cos(a), atol=1e-12)


def test_it_only_lowers_the_ranges_given():
    """A beam already nearer (another obstacle) keeps its range; a beam with nothing yet gets the wall."""
    seg = np.array([[2.0, -5.0, 2.0, 5.0]])
    prior = np.array([0.1, np.inf, 0.9])  # fractions of range_max = 4: 0.4 m, none, 3.6 m
    r = _kernel((0.0, 0.0), -0.1, 0.1, 3, 4.0, seg, prior)
    assert r[0] == 0.4
    assert r[1] == 2.0  # the middle beam at 0°
    assert r[2] == 2.0 / math.cos(0.1)
