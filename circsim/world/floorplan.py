"""Generated floor plans (``world.generate: {kind: floorplan, ...}``): a building of rooms, corridors,
doors and furniture drawn from a seed, as an occupancy grid that a map world then uses exactly as it
uses a map file (:mod:`circsim.config.floorplanworld` hands it on as a ``MapGrid``).

The contract: :func:`generate` is a pure function of its arguments (one ``numpy.random.Generator`` from
``seed``; no global state), so one seed is one building, bit for bit. The building is ``size_m`` between
its outer walls' centre lines, lower-left corner at (0, 0) of the map frame, surrounded by unknown cells
(outside). A spine corridor runs along its long axis (a second, crossing one with ``corridors: 2``);
one room on a side of it, the *hall*, is sized for the robots' circle (a disc of ``keep_clear_m`` about
the common center, furniture kept off it); the remaining blocks are cut in two along their longer side
(binary space partition, rooms at least :data:`MIN_ROOM_M` wide inside) until there are ``rooms``
rooms. Doors: every room adjacent to a corridor opens onto it, the others onto a neighbour already
reached (a spanning tree: every room reachable), and a few more between neighbours. Furniture, about
``furniture`` pieces per room: cabinets and desks flush against walls, tables with chairs (legs one cell
each) standing free; none in a door's way or on the robots' disc, and a piece that would cut any free
cell off the rest is not placed. So the plan is closed (no free cell touches unknown space or the map's
edge) and connected (one 4-connected free component). The center: the given one, else a random point
of the hall at least ``keep_clear_m`` from its walls (not its middle: a room point-symmetric about the
center looks the same after a half turn). A request the building cannot hold raises
:class:`FloorplanError` naming the key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

UNKNOWN, FREE, OCCUPIED = 0, 1, 2  # merger.grid.Cell's codes
MIN_ROOM_M = 2.0  # a room's inside, at least, either way (an office is rarely narrower)
MARGIN_M = 0.5  # unknown space around the building
DOOR_ZONE_M = 0.9  # no furniture this deep on either side of a door
HALO_M = 0.45  # free space kept around a piece of furniture (a robot passes)
HALL_SPARE_M = 1.0  # the hall is this much wider than the robots' disc: furniture fits, the center varies


class FloorplanError(ValueError):
    """A request the plan cannot meet: ``key`` (of ``world.generate``) and what was expected."""

    def __init__(self, key: str, message: str) -> None:
        super().__init__(f"{key}: {message}")
        self.key, self.message = key, message


@dataclass(frozen=True)
class Plan:
    """A generated building: merger's cell codes (row 0 at the lowest y), metres per cell, the corner of
    cell (0, 0) in the map frame, the common center, and what was drawn (for the run's description)."""

    states: np.ndarray
    resolution: float
    origin: tuple[float, float]
    center: tuple[float, float]
    center_chosen: bool
    rooms: int
    doors: int
    furniture: int
    hall: tuple[float, float, float, float]  # x0, y0, x1, y1 of the hall's inside (m)


def _overlap(a0, a1, b0, b1):
    return max(a0, b0), min(a1, b1)


class _Canvas:
    """The plan in canonical cells: u along the long axis, v across; wall lines on integer coordinates,
    a wall ``t`` cells thick centred on its line; array index = coordinate + ``pad``."""

    def __init__(self, length: int, depth: int, t: int, pad: int) -> None:
        self.t, self.h, self.pad = t, t // 2, pad
        self.a = np.full((depth + 2 * pad, length + 2 * pad), UNKNOWN, np.uint8)
        self.rect(-self.h, -self.h, length - self.h + t, depth - self.h + t, OCCUPIED)

    def rect(self, u0, v0, u1, v1, value) -> None:
        p = self.pad
        self.a[v0 + p:v1 + p, u0 + p:u1 + p] = value

    def inside(self, r) -> tuple[int, int, int, int]:
        """The free cells of a region between wall lines ``(u0, v0, u1, v1)``: half-open cell ranges."""
        u0, v0, u1, v1 = r
        return u0 - self.h + self.t, v0 - self.h + self.t, u1 - self.h, v1 - self.h


def _door_span(c: _Canvas, lo: int, hi: int, width: int):
    """The range of a door's first cell along a shared wall from line ``lo`` to ``hi`` (clear of the
    walls that meet it at both ends, a cell to spare), or None when the door does not fit."""
    first, last = lo - c.h + c.t + 1, hi - c.h - 1 - width
    return (first, last) if last >= first else None


def _shared(c: _Canvas, r, s, width: int):
    """Where a door between regions ``r`` and ``s`` can go: (axis, line, first, last) or None."""
    for axis in (0, 1):  # 0: a vertical wall (u = line), 1: a horizontal one (v = line)
        lo_r, hi_r = r[axis], r[axis + 2]
        lo_s, hi_s = s[axis], s[axis + 2]
        line = hi_r if hi_r == lo_s else lo_r if lo_r == hi_s else None
        if line is None:
            continue
        lo, hi = _overlap(r[1 - axis], r[3 - axis], s[1 - axis], s[3 - axis])
        span = _door_span(c, lo, hi, width) if hi > lo else None
        if span:
            return axis, line, *span
    return None


def _split(rng, leaves, n_rooms, min_w, key_rooms, size_m):
    """Binary space partition: the largest splittable leaf cut across its longer side, until n_rooms."""
    while len(leaves) < n_rooms:
        ok = [(r[2] - r[0]) * (r[3] - r[1]) if max(r[2] - r[0], r[3] - r[1]) >= 2 * min_w else -1 for r in leaves]
        k = int(np.argmax(ok))
        if ok[k] < 0:
            raise FloorplanError(key_rooms, f"expected at most {len(leaves) + 1} rooms (the hall included) in a {size_m[0]:g} x "
                                 f"{size_m[1]:g} m building (rooms at least {MIN_ROOM_M:g} m wide inside; "
                                 f"this seed's layout), got {n_rooms + 1}")
        u0, v0, u1, v1 = leaves.pop(k)
        if u1 - u0 >= v1 - v0:
            cut = int(rng.integers(u0 + min_w, u1 - min_w + 1))
            leaves += [(u0, v0, cut, v1), (cut, v0, u1, v1)]
        else:
            cut = int(rng.integers(v0 + min_w, v1 - min_w + 1))
            leaves += [(u0, v0, u1, cut), (u0, cut, u1, v1)]
    return leaves


def _layout(rng, c: _Canvas, L, D, res, n_rooms, corridors, cw, min_w, hall_w, size_m):
    """Corridor rectangles, the hall and the other rooms (wall-line coordinates)."""
    least = 3 if corridors == 1 else 5  # the hall and the blocks the corridors leave, at most
    if n_rooms < least:
        raise FloorplanError("rooms", f"expected at least {least} rooms with {corridors} corridor"
                             f"{'s' if corridors > 1 else ''} (the hall and every block the corridors "
                             f"leave), got {n_rooms}")
    if D < hall_w + cw + min_w:
        raise FloorplanError("size_m", f"expected a building at least {(hall_w + cw + min_w) * res:.2f} m across "
                             f"(a hall for the robots' circle, {hall_w * res:.2f} m, a corridor and a row of "
                             f"rooms), got {size_m[0]:g} x {size_m[1]:g} m")
    hall_low = bool(rng.integers(2))
    d_hall = int(rng.integers(hall_w, D - cw - min_w + 1))
    s0 = d_hall if hall_low else D - cw - d_hall
    corr = [(0, s0, L, s0 + cw)]
    sides = [(0, s0), (s0 + cw, D)]
    hall_side = 0 if hall_low else 1
    spans = [(0, L)]
    if corridors == 2:
        # L >= D >= hall_w + cw + min_w (checked above): a crossing corridor always fits
        choices = list(range(min_w, L - cw - hall_w + 1)) + list(range(hall_w, L - cw - min_w + 1))
        uc = int(choices[int(rng.integers(len(choices)))])
        corr.append((uc, 0, uc + cw, D))
        spans = [(0, uc), (uc + cw, L)]
    rooms = []
    for k, (v0, v1) in enumerate(sides):
        pieces = [(a, b) for a, b in spans]
        if k == hall_side:
            fit = [p for p in pieces if p[1] - p[0] >= hall_w]
            a, b = fit[int(rng.integers(len(fit)))]
            pieces.remove((a, b))
            length = int(rng.integers(hall_w, min(b - a, int(hall_w * 1.5)) + 1))
            if rng.integers(2):
                hall, rest = (a, v0, a + length, v1), (a + length, b)
            else:
                hall, rest = (b - length, v0, b, v1), (a, b - length)
            if rest[1] - rest[0] < min_w:  # too narrow for a room: the hall takes it
                hall = (min(hall[0], rest[0]), v0, max(hall[2], rest[1]), v1)
            else:
                pieces.append(rest)
        rooms += [(a, v0, b, v1) for a, b in pieces]
    return corr, hall, _split(rng, rooms, n_rooms - 1, min_w, "rooms", size_m)


def _doors(rng, c: _Canvas, corr, rooms, dw, zone, extra=0.15):
    """Doors: rooms on a corridor open onto it, the rest onto a neighbour already reached, then a few
    more between neighbours; each door's no-furniture zone (index coordinates) is returned."""
    zones = []

    def put(axis, line, first, last):
        s = int(rng.integers(first, last + 1))
        if axis == 0:
            c.rect(line - c.h, s, line - c.h + c.t, s + dw, FREE)
            zones.append((line - c.h - zone, s - 4, line - c.h + c.t + zone, s + dw + 4))
        else:
            c.rect(s, line - c.h, s + dw, line - c.h + c.t, FREE)
            zones.append((s - 4, line - c.h - zone, s + dw + 4, line - c.h + c.t + zone))

    reached = [False] * len(rooms)
    for i, r in enumerate(rooms):
        for k in rng.permutation(len(corr)):
            w = _shared(c, r, corr[k], dw)
            if w:
                put(*w)
                reached[i] = True
                break
    pairs = [(i, j, w) for i in range(len(rooms)) for j in range(i + 1, len(rooms))
             if (w := _shared(c, rooms[i], rooms[j], dw))]
    while not all(reached):
        frontier = [(i, j, w) for i, j, w in pairs if reached[i] != reached[j]]
        if not frontier:  # cannot happen on a guillotine partition touching a corridor; kept as a guard
            raise FloorplanError("door_m", f"expected doors that reach every room; {dw} cells do not fit")
        i, j, w = frontier[int(rng.integers(len(frontier)))]
        put(*w)
        pairs.remove((i, j, w))
        reached[i] = reached[j] = True
    for _i, _j, w in pairs:
        if rng.random() < extra:
            put(*w)
    return zones


def _components(a: np.ndarray) -> int:
    import cv2

    n, _ = cv2.connectedComponents((a == FREE).astype(np.uint8), connectivity=4)
    return n - 1


def _furnish(rng, c: _Canvas, rooms, zones, disc, mean, res) -> int:
    """Pieces of furniture flush against walls or standing free (module docstring); the count placed."""
    a, p = c.a, c.pad
    keep = np.zeros(a.shape, bool)  # door zones and the robots' disc
    for u0, v0, u1, v1 in zones:
        keep[max(v0 + p, 0):v1 + p, max(u0 + p, 0):u1 + p] = True
    keep |= disc
    furn = np.zeros(a.shape, bool)
    halo, cells = int(round(HALO_M / res)), (lambda m: max(1, int(round(m / res))))
    placed = 0

    def free_box(v0, v1, u0, u1, margin, grid):
        return not grid[max(v0 - margin, 0):v1 + margin, max(u0 - margin, 0):u1 + margin].any()

    for r in rooms:
        iu0, iv0, iu1, iv1 = (x + p for x in c.inside(r))
        for _ in range(int(rng.poisson(mean))):
            for _try in range(12):
                if rng.random() < 0.65:  # against a wall: a cabinet, a desk, a shelf
                    length, depth = cells(rng.uniform(0.5, 2.0)), cells(rng.uniform(0.35, 0.8))
                    side = int(rng.integers(4))
                    along = (iu0, iu1) if side < 2 else (iv0, iv1)
                    if along[1] - along[0] <= length:
                        continue
                    s = int(rng.integers(along[0], along[1] - length))
                    if side == 0:
                        box = (iv0, iv0 + depth, s, s + length)
                    elif side == 1:
                        box = (iv1 - depth, iv1, s, s + length)
                    elif side == 2:
                        box = (s, s + length, iu0, iu0 + depth)
                    else:
                        box = (s, s + length, iu1 - depth, iu1)
                    legs = []
                    ok = free_box(*box, halo, furn) and free_box(*box, 0, a != FREE)
                else:  # a table standing free, with chairs
                    w, d = cells(rng.uniform(0.6, 1.6)), cells(rng.uniform(0.6, 1.2))
                    m = cells(0.7)
                    if iu1 - iu0 <= 2 * m + w or iv1 - iv0 <= 2 * m + d:
                        continue
                    u, v = int(rng.integers(iu0 + m, iu1 - m - w)), int(rng.integers(iv0 + m, iv1 - m - d))
                    box = (v, v + d, u, u + w)
                    ok = free_box(*box, cells(0.6), a != FREE)
                    sp, gap = cells(0.4), cells(0.15)
                    legs = []
                    for k in range(int(rng.integers(0, 3))):  # chairs below or above the table
                        cu = int(rng.integers(u, u + max(1, w - sp)))
                        cv = v - gap - sp if k == 0 else v + d + gap
                        legs += [(cv + dv, cu + du) for dv in (0, sp) for du in (0, sp)]
                ok = ok and not keep[box[0]:box[1], box[2]:box[3]].any()
                ok = ok and all(0 <= lv < a.shape[0] and 0 <= lu < a.shape[1] and a[lv, lu] == FREE
                                and not keep[lv, lu] for lv, lu in legs)
                if not ok:
                    continue
                before = a.copy()
                a[box[0]:box[1], box[2]:box[3]] = OCCUPIED
                for lv, lu in legs:
                    a[lv, lu] = OCCUPIED
                if _components(a) != 1:  # it would shut a free pocket off: not placed
                    a[:] = before
                    continue
                furn[box[0]:box[1], box[2]:box[3]] = True
                placed += 1
                break
    return placed


def generate(seed: int, size_m, rooms: int, corridors: int = 1, corridor_m: float = 1.6, door_m: float = 0.9,
             wall_m: float = 0.15, furniture: float = 3.0, resolution_m: float = 0.05,
             keep_clear_m: float = 2.2, center=None) -> Plan:
    """The plan of ``seed`` (module docstring). ``keep_clear_m``: the radius about the center kept free of
    furniture (the robots' circle plus their bodies and a margin); ``center`` (x, y) given, or None for
    the generator's choice in the hall."""
    rng = np.random.default_rng(int(seed))
    res = float(resolution_m)
    W, H = (int(round(float(x) / res)) for x in size_m)
    swap = H > W  # canonical: u along the long axis
    L, D = (H, W) if swap else (W, H)
    t = max(1, int(round(wall_m / res)))
    cw, min_w = int(round(corridor_m / res)) + t, int(math.ceil(MIN_ROOM_M / res)) + t
    hall_w = int(math.ceil((2 * keep_clear_m + HALL_SPARE_M) / res)) + t
    dw = int(round(door_m / res))
    if dw + t + 2 > min_w:
        raise FloorplanError("door_m", f"expected a door that fits a {MIN_ROOM_M:g} m room's wall with "
                             f"{wall_m:g} m walls, got {door_m:g}")
    pad = int(round(MARGIN_M / res)) + t
    c = _Canvas(L, D, t, pad)
    corr, hall, others = _layout(rng, c, L, D, res, int(rooms), int(corridors), cw, min_w, hall_w, size_m)
    all_rooms = [hall, *others]
    for r in [*corr, *all_rooms]:
        c.rect(*c.inside(r), FREE)
    zones = _doors(rng, c, corr, all_rooms, dw, int(round(DOOR_ZONE_M / res)))
    hu0, hv0, hu1, hv1 = c.inside(hall)
    k = keep_clear_m / res  # drawn whether or not a center is given: the chosen center given back is the same plan
    cu, cv = rng.uniform(hu0 + k, hu1 - k), rng.uniform(hv0 + k, hv1 - k)
    cu, cv = (round(x * res, 2) / res for x in (cu, cv))  # the center to the centimetre
    if center is not None:
        cu, cv = (center[1] / res, center[0] / res) if swap else (center[0] / res, center[1] / res)
    vv, uu = np.mgrid[0:c.a.shape[0], 0:c.a.shape[1]]
    disc = np.hypot(uu + 0.5 - pad - cu, vv + 0.5 - pad - cv) <= keep_clear_m / res + 1
    placed = _furnish(rng, c, all_rooms, zones, disc, float(furniture), res)
    states = c.a.T.copy() if swap else c.a
    x, y = (cv * res, cu * res) if swap else (cu * res, cv * res)
    hall_m = tuple(q * res for q in ((hv0, hu0, hv1, hu1) if swap else (hu0, hv0, hu1, hv1)))
    return Plan(np.ascontiguousarray(states), res, (-pad * res, -pad * res), (round(x, 6), round(y, 6)),
                center is None, len(all_rooms), len(zones), placed, hall_m)
