"""Combining aligned maps that share a frame.

* :func:`superpose` is the thesis's superposition (3.3.1), used while merging: occupied if either map
  is occupied; free only if both are free; unknown otherwise.
* :func:`fuse` is the merged map a user gets: occupied if any map is occupied, free if any map is free
  (and none occupied), unknown only where every map is unknown — the "grey: unknown to all robots" of
  the thesis's figures.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid

# superposition of states a and b at index 3a + b (codes unknown 0, free 1, occupied 2), for cv2.LUT
_SUPERPOSE = np.zeros(256, np.uint8)
_SUPERPOSE[:9] = [UNKNOWN_S, UNKNOWN_S, OCCUPIED_S,
                  UNKNOWN_S, FREE_S, OCCUPIED_S,
                  OCCUPIED_S, OCCUPIED_S, OCCUPIED_S]


def superpose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Superposition with occupied priority: occupied if either; free only if both free; else unknown."""
    if a.shape != b.shape:
        raise ValueError(f"shapes differ: {a.shape} vs {b.shape}")
    if a.size == 0:
        return np.zeros(a.shape, np.uint8)
    idx = cv2.scaleAdd(np.ascontiguousarray(a, np.uint8), 3.0, np.ascontiguousarray(b, np.uint8))
    return cv2.LUT(idx, _SUPERPOSE).reshape(a.shape)


def fuse(layers: list[np.ndarray]) -> np.ndarray:
    """Union of aligned maps with occupied priority (state codes order unknown < free < occupied)."""
    if not layers:
        raise ValueError("fuse needs at least one layer")
    return np.maximum.reduce([np.asarray(x, np.uint8) for x in layers])


def fuse_grids(grids: list[OccupancyGrid]) -> OccupancyGrid:
    """:func:`fuse` of grids that share one canvas (same shape, resolution and origin: e.g. the layers of
    :func:`merger.team.frames.place_on_frame0`), as a grid on that canvas."""
    if not grids:
        raise ValueError("fuse_grids needs at least one grid")
    return OccupancyGrid(fuse([g.states for g in grids]), grids[0].resolution, grids[0].origin)
