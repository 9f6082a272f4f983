"""merger.search.prepared: the compiled bookkeeping equals its numpy definition."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from merger.grid import FREE_S, OCCUPIED_S
from merger.search.prepared import _occupied_near, _pool_level, class_sat


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 30), st.integers(1, 30), st.data())
def test_class_sat_and_occupied_cells_equal_their_numpy_definition(seed, h, w, data):
    states = np.random.default_rng(seed).integers(0, 3, (h, w)).astype(np.uint8)
    r0 = data.draw(st.integers(0, h - 1))
    r1 = data.draw(st.integers(r0 + 1, h))
    c0 = data.draw(st.integers(0, w - 1))
    c1 = data.draw(st.integers(c0 + 1, w))
    box = states[r0:r1, c0:c1]
    want = np.zeros((r1 - r0 + 1, c1 - c0 + 1), np.int64)
    mask = (box == OCCUPIED_S).astype(np.int64) << 32 | (box == FREE_S).astype(np.int64)
    want[1:, 1:] = np.cumsum(np.cumsum(mask, axis=0), axis=1)
    assert np.array_equal(class_sat(states, r0, r1, c0, c1), want)

    origin, res, cm, half = (-0.37, 0.21), 0.05, (0.1, 0.45), data.draw(st.floats(0.0, 1.0))
    rr, cc = np.nonzero(states == OCCUPIED_S)
    ox = origin[0] + (cc + 0.5) * res - cm[0]
    oy = origin[1] + (rr + 0.5) * res - cm[1]
    near = (np.abs(ox) <= half + res) & (np.abs(oy) <= half + res)
    got_x, got_y = _occupied_near(states, origin[0], origin[1], res, cm[0], cm[1], half)
    assert np.array_equal(got_x, ox[near]) and np.array_equal(got_y, oy[near])  # same floats, same order


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 2, 4, 8, 16]))
def test_pooled_blocks_equal_their_numpy_definition(seed, s):
    """Blocks of s × s occupied cells: first row and column, count, count × the most reads of a row and a
    column, and whether no skipped row or column crosses the block — in (block row, block column) order."""
    rng = np.random.default_rng(seed)
    rlo, clo = int(rng.integers(0, 5)), int(rng.integers(0, 5))
    nr, nc = int(rng.integers(1, 40)), int(rng.integers(1, 40))
    cells = rng.random((nr, nc)) < 0.3
    cells[rng.integers(0, nr), rng.integers(0, nc)] = True
    qr, qc = np.nonzero(cells)
    qr, qc = qr.astype(np.int64) + rlo, qc.astype(np.int64) + clo
    wr_cell, wc_cell = rng.integers(0, 3, nr).astype(np.int64), rng.integers(0, 3, nc).astype(np.int64)
    skip_r, skip_c = rng.random(nr) < 0.1, rng.random(nc) < 0.1
    key = (qr // s) * (1 << 31) + qc // s
    uk, inv, cnt = np.unique(key, return_inverse=True, return_counts=True)
    wr = np.zeros(uk.size, np.int64)
    wc = np.zeros(uk.size, np.int64)
    np.maximum.at(wr, inv, wr_cell[qr - rlo])
    np.maximum.at(wc, inv, wc_cell[qc - clo])
    r0, c0 = (uk >> 31) * s, (uk & ((1 << 31) - 1)) * s
    bad = np.zeros(uk.size, np.bool_)
    for d in range(s):
        rr, cc = r0 + d - rlo, c0 + d - clo
        bad |= ((rr >= 0) & (rr < nr)) & skip_r[np.clip(rr, 0, nr - 1)]
        bad |= ((cc >= 0) & (cc < nc)) & skip_c[np.clip(cc, 0, nc - 1)]
    want = np.stack([r0, c0, cnt, cnt * wr * wc, (~bad).astype(np.int64)], axis=1)
    assert np.array_equal(_pool_level(qr, qc, s, wr_cell, wc_cell, skip_r, skip_c, rlo, clo), want)
