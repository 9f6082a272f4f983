"""Colour overlay of aligned maps in the thesis's scheme (figure 3.15).

Each robot has its own colour pair: occupied darker, free lighter (Lyon: magenta / light green,
Nevers: dark green / light red, Auckland: yellow / blue); a cell known to several robots shows the mean
of their colours (so superpositions give other colours); grey where every robot is unknown.
"""

from __future__ import annotations

import numpy as np

from .grid import FREE_S, OCCUPIED_S

UNKNOWN_RGB = (128, 128, 128)
THESIS_COLOURS = {  # name: (occupied RGB, free RGB)
    "Lyon": ((200, 0, 200), (170, 235, 170)),
    "Nevers": ((0, 110, 0), (250, 170, 170)),
    "Auckland": ((215, 195, 0), (150, 170, 250)),
}
EXTRA_COLOURS = [((0, 90, 200), (190, 225, 250)), ((180, 80, 0), (250, 215, 170)),
                 ((90, 0, 160), (220, 200, 250)), ((0, 140, 140), (190, 245, 240))]


def colours_for(names: list[str]) -> list[tuple[tuple[int, int, int], tuple[int, int, int]]]:
    """Colour pairs: the thesis's for its robots' names, then a fixed palette for the others."""
    extra = iter(EXTRA_COLOURS * (len(names) // len(EXTRA_COLOURS) + 1))
    return [THESIS_COLOURS[n] if n in THESIS_COLOURS else next(extra) for n in names]


def overlay_rgb(layers: list[np.ndarray], names: list[str]) -> np.ndarray:
    """(H, W, 3) uint8 RGB in ROS row order (row 0 = lowest y) of aligned state layers."""
    if len(layers) != len(names):
        raise ValueError("one name per layer")
    acc = np.zeros((*layers[0].shape, 3), np.float64)
    known = np.zeros(layers[0].shape, np.float64)
    for states, (occ, free) in zip(layers, colours_for(names), strict=True):
        for mask, col in ((states == OCCUPIED_S, occ), (states == FREE_S, free)):
            acc[mask] += col
            known[mask] += 1
    out = np.empty_like(acc, dtype=np.uint8)
    seen = known > 0
    out[seen] = np.rint(acc[seen] / known[seen, None]).astype(np.uint8)
    out[~seen] = UNKNOWN_RGB
    return out
