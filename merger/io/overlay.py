"""Colour overlay of aligned maps in the thesis's scheme (figure 3.15).

Each robot has its own colour pair: occupied darker, free lighter (Lyon: magenta / light green,
Nevers: dark green / light red, Auckland: yellow / blue); a cell known to several robots shows the mean
of their colours (so superpositions give other colours); grey where every robot is unknown.
"""

from __future__ import annotations

import numpy as np

from ..grid import FREE_S, OCCUPIED_S

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


def overlay_picture(layers: list[np.ndarray], names: list[str], resolution: float, *, title: str = "",
                    cell_px: int | None = None, max_px: int = 2000, margin_cells: int = 10) -> np.ndarray:
    """The overlay as a picture for people: (H, W, 3) uint8 RGB, top row = max y (as an image is shown).

    Cropped to the cells some robot knows (plus ``margin_cells``), each cell ``cell_px`` pixels (default:
    4, fewer when the picture would exceed ``max_px``), under ``title`` (one line per "\\n": e.g. θ and the
    verdict, then its evidence), over a legend of each robot's occupied and free colours and a 1 m scale bar.
    """
    import cv2

    rgb = overlay_rgb(layers, names)
    rows, cols = np.nonzero(np.any(np.stack(layers) > 0, axis=0))
    if rows.size:
        r0, r1 = max(rows.min() - margin_cells, 0), rows.max() + margin_cells + 1
        c0, c1 = max(cols.min() - margin_cells, 0), cols.max() + margin_cells + 1
        rgb = rgb[r0:r1, c0:c1]
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
