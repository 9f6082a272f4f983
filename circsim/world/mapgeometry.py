"""A map world's walls: the boundary between its free cells and its solid ones, as few segments as the
cells allow.

The contract: :func:`boundary_segments` takes a map's ``solid`` cells (occupied or unknown: unknown is
outside the building, so solid) and returns zero-thickness segments ``ax, ay, bx, by`` (map frame,
metres) lying exactly on the cell edges that separate a free cell from a solid one (beyond the map's
edge is solid too). Collinear neighbouring edges are merged into one segment (a run along a row or a
column), so a straight wall of 200 cells is one segment, not 200. A ray from a free point therefore
stops exactly where it enters the first solid cell, as a ray marched through the map does
(:func:`merger.synthetic.grid_ray_cast`), and the laser (:mod:`circsim.world.laser`) needs nothing new.
Only cell edges are drawn, never the inside of a solid block, so the number of segments grows with the
map's boundary, not its area. Pure numpy: :class:`circsim.world.world.World` adds the segments to
pymunk.
"""

from __future__ import annotations

import numpy as np


def _runs(edges: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs of True along the rows of ``edges`` (L, N): (line index, first, one past last)."""
    pad = np.zeros((edges.shape[0], 1), bool)
    d = np.diff(np.hstack([pad, edges, pad]).astype(np.int8), axis=1)
    line, first = np.nonzero(d == 1)
    _, stop = np.nonzero(d == -1)  # row-major order: the k-th stop closes the k-th start
    return line, first, stop


def boundary_segments(solid: np.ndarray, resolution: float, origin) -> np.ndarray:
    """(S, 4) segments on the edges between free and solid cells of ``solid`` (H, W) bool, row 0 at the
    lowest y; cells beyond the map's edge count as solid. Horizontal runs first (by row, then column),
    then vertical ones (by column, then row): deterministic."""
    s = np.pad(np.asarray(solid, bool), 1, constant_values=True)
    x0, y0, res = float(origin[0]), float(origin[1]), float(resolution)
    # horizontal edges: the line y = y0 + r * res lies between cell rows r - 1 and r (r = 0 .. H)
    h_edges = (s[:-1, 1:-1] != s[1:, 1:-1])
    r, c0, c1 = _runs(h_edges)
    hor = np.stack([x0 + c0 * res, y0 + r * res, x0 + c1 * res, y0 + r * res], axis=1)
    # vertical edges: the line x = x0 + c * res lies between cell columns c - 1 and c (c = 0 .. W)
    v_edges = (s[1:-1, :-1] != s[1:-1, 1:]).T
    c, r0, r1 = _runs(v_edges)
    ver = np.stack([x0 + c * res, y0 + r0 * res, x0 + c * res, y0 + r1 * res], axis=1)
    return np.vstack([hor, ver]).astype(np.float64).reshape(-1, 4)
