"""Colour overlay of aligned maps (after the thesis's figure 3.15, in one qualitative palette).

Each robot has one hue, by its place in the list of maps: matplotlib's tab10 (without its grey,
:data:`PALETTE`), occupied in the full colour, free in the same hue lightened (:data:`FREE_LIGHTEN`
of the way to white). A cell known to several robots shows the mean of their colours (so
superpositions give other colours); grey where every robot is unknown. The rerun recording
(``circsim.record``) draws each robot in the same colour. (The thesis paired unrelated hues — Lyon
magenta occupied and light green free, Nevers dark green and light red, Auckland yellow and blue —
which a reader could not tell apart by robot.)
"""

from __future__ import annotations

import numpy as np

from ..grid import FREE_S, OCCUPIED_S

UNKNOWN_RGB = (128, 128, 128)
PALETTE = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75),
           (227, 119, 194), (188, 189, 34), (23, 190, 207)]  # matplotlib's tab10 without its grey
FREE_LIGHTEN = 0.6  # a robot's free cells: its colour this far towards white


def colours_for(names: list[str]) -> list[tuple[tuple[int, int, int], tuple[int, int, int]]]:
    """(occupied RGB, free RGB) per robot, by position: :data:`PALETTE` in order (repeating after nine)."""
    out = []
    for i in range(len(names)):
        occ = PALETTE[i % len(PALETTE)]
        out.append((occ, tuple(int(round(c + FREE_LIGHTEN * (255 - c))) for c in occ)))
    return out


OVERLAY_BLOCK_CELLS = 1 << 20  # cells coloured at once: the float sums of a block, not of a 4224² canvas (1.7 GB)


def overlay_rgb(layers: list[np.ndarray], names: list[str]) -> np.ndarray:
    """(H, W, 3) uint8 RGB in ROS row order (row 0 = lowest y) of aligned state layers (computed in blocks of
    rows: each cell's colour is its own mean)."""
    if len(layers) != len(names):
        raise ValueError("one name per layer")
    h, w = layers[0].shape
    out = np.empty((h, w, 3), np.uint8)
    colours = colours_for(names)
    step = max(1, OVERLAY_BLOCK_CELLS // max(w, 1))
    for r0 in range(0, h, step):
        acc = np.zeros((min(step, h - r0), w, 3), np.float64)
        known = np.zeros(acc.shape[:2], np.float64)
        for states, (occ, free) in zip(layers, colours, strict=True):
            block = states[r0:r0 + step]
            for mask, col in ((block == OCCUPIED_S, occ), (block == FREE_S, free)):
                acc[mask] += col
                known[mask] += 1
        part = out[r0:r0 + step]
        seen = known > 0
        part[seen] = np.rint(acc[seen] / known[seen, None]).astype(np.uint8)
        part[~seen] = UNKNOWN_RGB
    return out


def overlay_picture(layers: list[np.ndarray], names: list[str], resolution: float, *, title: str = "",
                    cell_px: int | None = None, max_px: int = 2000, margin_cells: int = 10) -> np.ndarray:
    """The overlay as a picture for people: (H, W, 3) uint8 RGB, top row = max y (as an image is shown).

    Cropped to the cells some robot knows (plus ``margin_cells``), each cell ``cell_px`` pixels (default:
    4, fewer when the picture would exceed ``max_px``), under ``title`` (one line per "\\n": e.g. θ and the
    verdict, then its evidence), over a legend of each robot's occupied and free colours and a 1 m scale bar.
    """
    import cv2

    known = np.zeros(layers[0].shape, bool)
    for states in layers:
        known |= states > 0
    rows, cols = np.flatnonzero(known.any(axis=1)), np.flatnonzero(known.any(axis=0))
    if rows.size:  # each cell's colour is its own: crop first, colour the crop
        r0, r1 = max(rows.min() - margin_cells, 0), rows.max() + margin_cells + 1
        c0, c1 = max(cols.min() - margin_cells, 0), cols.max() + margin_cells + 1
        layers = [states[r0:r1, c0:c1] for states in layers]
    rgb = overlay_rgb(layers, names)
    h, w = rgb.shape[:2]
    px = cell_px or max(1, min(4, max_px // max(h, w, 1)))
    body = cv2.resize(np.ascontiguousarray(np.flipud(rgb)), None, fx=px, fy=px, interpolation=cv2.INTER_NEAREST)
    font, white, black = cv2.FONT_HERSHEY_SIMPLEX, (255, 255, 255), (0, 0, 0)
    width = max(body.shape[1], 420)
    # legend: one row of swatches (occupied, free) and names; then the scale bar
    x, lines, line = 8, [], []
    for n, (occ, free) in zip(names, colours_for(names), strict=True):
        tw = cv2.getTextSize(n, font, 0.45, 1)[0][0]
        need = 2 * 14 + 6 + tw + 18
        if line and x + need > width:
            lines.append(line)
            line, x = [], 8
        line.append((x, n, occ, free))
        x += need
    if line:
        lines.append(line)
    titles = title.split("\n") if title else []
    title_h, legend_h = (20 * len(titles) + 4 if titles else 0), 22 * len(lines) + 30
    out = np.full((title_h + body.shape[0] + legend_h, width, 3), 255, np.uint8)
    out[title_h:title_h + body.shape[0], :body.shape[1]] = body
    for i, text in enumerate(titles):  # each line shrunk to the width if need be
        scale = min(0.5, 0.5 * (width - 12) / max(cv2.getTextSize(text, font, 0.5, 1)[0][0], 1))
        cv2.putText(out, text, (6, 17 + 20 * i), font, scale, black, 1, cv2.LINE_AA)
    y = title_h + body.shape[0] + 6
    for line in lines:
        for x, n, occ, free in line:
            cv2.rectangle(out, (x, y), (x + 13, y + 13), tuple(int(v) for v in occ), -1)
            cv2.rectangle(out, (x + 14, y), (x + 27, y + 13), tuple(int(v) for v in free), -1)
            cv2.putText(out, n, (x + 33, y + 12), font, 0.45, black, 1, cv2.LINE_AA)
        y += 22
    bar = int(round(px / resolution))  # pixels per metre
    y += 8
    cv2.rectangle(out, (8, y), (8 + bar, y + 6), black, -1)
    label = f"1 m   ({px} px per {resolution * 100:g} cm cell; occupied darker, free lighter, grey unknown)"
    cv2.putText(out, label, (14 + bar, y + 7), font, 0.4, black, 1, cv2.LINE_AA)
    if bar > width - 16:  # a coarse picture of a big map: the bar does not fit, say so instead
        out[y:y + 7] = white
        cv2.putText(out, f"1 m = {bar} px", (8, y + 7), font, 0.4, black, 1, cv2.LINE_AA)
    return out
