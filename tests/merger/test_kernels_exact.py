"""The compiled kernels of the whole-map checks and the tracker give their numpy references' answers exactly
(issue 43, item 3: work that held the GIL moved into nogil kernels): the cell counts of ω̃, the ROI change,
and the warp's border cells — on random states, non-contiguous views, and coordinates on cell borders."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from merger.grid import OccupancyGrid
from merger.measures import count_cells, count_cells_reference
from merger.team.track import roi_change, roi_change_reference
from merger.transform import _fix_borders, _fix_borders_reference, warp_grid, warp_grid_numpy

shapes = st.tuples(st.integers(1, 40), st.integers(1, 40))


@settings(max_examples=150, deadline=None)
@given(shape=shapes, seed=st.integers(0, 2**31), step=st.integers(1, 3))
def test_counts_and_roi_change_are_their_references(shape, seed, step):
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 3, (shape[0] * step, shape[1] * step)).astype(np.uint8)
    b = rng.integers(0, 3, a.shape).astype(np.uint8)
    b[rng.random(a.shape) < 0.5] = 0  # many unknown cells
    for x, y in ((a, b), (a[::step, ::step], b[::step, ::step]), (a.ravel(), b.ravel()), (a[:0], b[:0])):
        assert count_cells(x, y) == count_cells_reference(x, y)
        assert roi_change(x, y) == roi_change_reference(x, y)
    assert roi_change(None, a) == roi_change_reference(None, a) == 1.0


@settings(max_examples=150, deadline=None)
@given(h=st.integers(1, 50), w=st.integers(1, 50), mh=st.integers(1, 50), mw=st.integers(1, 50),
       seed=st.integers(0, 2**31), quantum=st.sampled_from([0.0, 0.5, 0.25, 0.125]),
       eps=st.sampled_from([1 / 512, 0.3, 0.25, 1e-9]))
def test_the_border_cells_kernel_is_its_reference(h, w, mh, mw, seed, quantum, eps):
    """Coordinates on a quarter- or eighth-cell lattice put many lookups exactly on cell borders, and
    the wrap-around of the fractional parts (−1, 0, +1) is crossed."""
    rng = np.random.default_rng(seed)
    states = rng.integers(0, 3, (mh, mw)).astype(np.uint8)
    a, c = rng.uniform(-5, mw + 5, w), rng.uniform(-5, mh + 5, w)
    b, d = rng.uniform(-5, 5, h), rng.uniform(-5, 5, h)
    if quantum:
        a, b, c, d = (np.round(v / quantum) * quantum for v in (a, b, c, d))
        d = -d
    out1 = rng.integers(0, 3, (h, w)).astype(np.uint8)
    out2 = out1.copy()
    i1, j1 = _fix_borders(out1, states, a, b, c, d, eps, 1e-9)
    i2, j2 = _fix_borders_reference(out2, states, a, b, c, d, eps, 1e-9)
    assert np.array_equal(out1, out2)
    assert set(zip(i1.tolist(), j1.tolist(), strict=True)) == set(zip(i2.tolist(), j2.tolist(), strict=True))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), theta=st.sampled_from([0.0, 90.0, 180.0, 270.0, 45.0, 33.3, -0.0]),
       on_lattice=st.booleans())
def test_the_warp_is_the_numpy_warp(seed, theta, on_lattice):
    """warp_grid (OpenCV and the border kernel) against the numpy yardstick, with centres and origins on
    cell centres and borders (every lookup of a right-angle turn on a border)."""
    rng = np.random.default_rng(seed)
    r = 0.05
    q = (lambda v: np.round(v / (r / 2)) * (r / 2)) if on_lattice else (lambda v: v)
    mov = OccupancyGrid(rng.integers(0, 3, tuple(rng.integers(3, 90, 2))).astype(np.uint8), r,
                        tuple(map(float, q(rng.uniform(-3, 3, 2)))))
    target = OccupancyGrid(np.zeros(tuple(rng.integers(3, 90, 2)), np.uint8), r,
                           tuple(map(float, np.round(rng.uniform(-3, 3, 2) / r) * r)))
    cm, ct = tuple(map(float, q(rng.uniform(-1, 1, 2)))), tuple(map(float, q(rng.uniform(-1, 1, 2))))
    assert np.array_equal(warp_grid(mov, theta, cm, ct, target).states,
                          warp_grid_numpy(mov, theta, cm, ct, target).states)
