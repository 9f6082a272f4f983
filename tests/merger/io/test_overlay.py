"""merger.io.overlay: the colour overlay computed in blocks of rows is the overlay computed at once, and a
large canvas's picture does not hold float copies of it (issue 37, item 6: 1.7 GB for three 4224² maps)."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

import merger.io.overlay as OV
from merger.grid import FREE_S, OCCUPIED_S


def _at_once(layers, names):
    """overlay_rgb as it was: one float64 sum over the whole canvas."""
    acc = np.zeros((*layers[0].shape, 3), np.float64)
    known = np.zeros(layers[0].shape, np.float64)
    for states, (occ, free) in zip(layers, OV.colours_for(names), strict=True):
        for mask, col in ((states == OCCUPIED_S, occ), (states == FREE_S, free)):
            acc[mask] += col
            known[mask] += 1
    out = np.empty_like(acc, dtype=np.uint8)
    seen = known > 0
    out[seen] = np.rint(acc[seen] / known[seen, None]).astype(np.uint8)
    out[~seen] = OV.UNKNOWN_RGB
    return out


@pytest.mark.parametrize("cells", [1, 53 * 5 + 7, 1 << 20])
def test_the_overlay_in_blocks_is_the_overlay_at_once(monkeypatch, cells):
    rng = np.random.default_rng(cells)
    layers = [rng.integers(0, 3, (71, 53)).astype(np.uint8) for _ in range(4)]
    names = ["a", "b", "c", "d"]
    monkeypatch.setattr(OV, "OVERLAY_BLOCK_CELLS", cells)
    assert np.array_equal(OV.overlay_rgb(layers, names), _at_once(layers, names))


@pytest.mark.slow
def test_the_picture_of_a_large_canvas_is_cropped_and_coloured_in_blocks():
    layers = [np.zeros((3000, 3000), np.uint8) for _ in range(3)]
    for k, st in enumerate(layers):
        st[500 + 100 * k:2400, 700:2600 - 50 * k] = FREE_S
        st[1000:1010, 800:2000] = OCCUPIED_S
    tracemalloc.start()
    try:
        pic = OV.overlay_picture(layers, ["a", "b", "c"], 0.05)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert pic.shape[1] == 1900 + 20 and pic.dtype == np.uint8  # the known columns plus the margins, 1 px a cell
    assert peak < 120 << 20, peak / 2**20  # at once: ~900 MB of float sums, masks and indices
