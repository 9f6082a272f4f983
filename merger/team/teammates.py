"""Teammates' bodies in a team's maps: the ring the team drives, left out of the pairs' evidence (issue 43).

A robot's laser sees its teammates, and its map holds their bodies where they drove. When the team drives
one circle about the common center (the thesis's set-up), those bodies lie on that circle in every map,
and two robots on opposite sides of it see opposite faces of the same bodies: placed exactly, the faces
lie a body's width apart, and the search, which maximises agreement, slides one face onto the other. In
the 12-robot L room (benchmarks/scenarios/lroom12.yaml, 2 s maps) the eight verified pairs across the
circle were all 10.6–14.9 cm off in one direction while the fifteen between neighbours were within 3.3 cm
(docs/experiments.md); with the teammates made invisible to the lasers, the same 30 s run had no false
merge instead of 40.

The ring is where the map's own robot drove: the radii of its path about the map's center, widened by
the teammates' body radius and by the center error the translation window allows (half the window: a
center off by e moves the circle by up to e in the map, and the pair's window covers both maps' errors).
A rotation about the center maps the ring onto itself, so one mask serves every hypothesis of the
search. Occupied cells on the ring become unknown; free cells stay (they are the team's evidence of free
space). Nothing static stands there: the robots drive through it.

Off by default (``MergeParams.teammate_radius_m`` 0): the teammates are also evidence. In a bare hall
(generated floor plan 28: two long walls) they are the only cue along the walls; without them the pairs
slid along the walls and placed 18 maps grossly in 6 s, where with them every robot merged by 4.6 s
with no gross merge. With the ring left out, a pair on such a ridge is therefore refused
(:func:`merger.team.ambiguity.ridge`, in :func:`merger.team.tree.pair_result`): plan 28 then has no
false merge, and no merge in its first 8 s.

Why the faces bias a pair, measured (12-robot L room, seed 1, 2 s maps): a robot sees a teammate across
the circle on its inner side and a teammate beside it on its flank. Two maps then hold the same body up to
a body's radius apart along the line between their robots, and the pair's best alignment pulls them
together: every map was placed 3–7 cm towards the center, in proportion to how far its robot stood from the
reference (pairs across the circle 10–16 cm off, neighbours within 3 cm). A team shrunk that way is
consistent around every cycle: no check of the assembly sees it. :func:`teammates_centred` therefore moves
each ring cell a fixed distance along its robot's line of sight, towards the teammate's centre line, so that
every map places the body alike (``MergeParams.teammate_shift_m``, by default 0.12 m, for the bench's 0.18 m
bodies): of those 2 s maps' verified pairs, 9 of 23 were more than 5 cm off, with it 1 of 21
(tests/merger/team/test_tree.py,
``test_teammates_faces_moved_to_their_centre_lines_undo_the_teams_shrinking_in_the_l_room``; more in
docs/experiments.md).

The ring is used only when the path is one: its radii span at most twice the ring's margin (a circle
about the center, up to the center error). A map without a trajectory, or whose robot wandered
(a real map of an independent run), is left as it is. Pure: arrays in, arrays out.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..grid import OCCUPIED_S, UNKNOWN_S, OccupancyGrid
from .params import MapInput


def ring(m: MapInput, radius_m: float, window_m: float) -> tuple[float, float] | None:
    """The band of distances from the map's center, metres, where its teammates' bodies may lie: the radii
    of its robot's path about the center ± (``radius_m`` + ``window_m`` / 2), or None (no trajectory, the
    setting off, or a path that is no circle about the center)."""
    if radius_m <= 0 or m.trajectory is None or len(m.trajectory) == 0:
        return None
    tr = m.trajectory
    r = np.hypot(tr[:, 1] - m.center[0], tr[:, 2] - m.center[1])
    margin = radius_m + window_m / 2
    lo, hi = float(r.min()), float(r.max())
    if hi - lo > 2 * margin:
        return None
    return max(lo - margin, 0.0), hi + margin


def _on_ring(m: MapInput, band: tuple[float, float]):
    """The map's cell centres (x per column, y per row, metres) and its occupied cells whose distance from
    the map's center lies within ``band``."""
    g = m.grid
    h, w = g.states.shape
    xs = g.origin[0] + (np.arange(w) + 0.5) * g.resolution
    ys = g.origin[1] + (np.arange(h) + 0.5) * g.resolution
    d2 = (xs[None, :] - m.center[0]) ** 2 + (ys[:, None] - m.center[1]) ** 2
    return xs, ys, (d2 >= band[0] ** 2) & (d2 <= band[1] ** 2) & (g.states == OCCUPIED_S)


def without_teammates(m: MapInput, radius_m: float, window_m: float) -> MapInput:
    """``m`` with the occupied cells on its team's ring (:func:`ring`) made unknown; ``m`` itself when
    there is no ring or nothing on it."""
    band = ring(m, radius_m, window_m)
    if band is None:
        return m
    g = m.grid
    _, _, on = _on_ring(m, band)
    if not on.any():
        return m
    states = g.states.copy()
    states[on] = UNKNOWN_S
    return dataclasses.replace(m, grid=OccupancyGrid(states, g.resolution, g.origin))


def teammates_centred(m: MapInput, shift_m: float, window_m: float) -> MapInput:
    """``m`` with the occupied cells on its team's ring (:func:`ring`, margin 2·``shift_m``) moved ``shift_m``
    farther along the line of sight from its robot (the last point of its path: the faces a map holds are the
    ones its robot sees now, older ones are cleared as it passes): a teammate's face moved towards the
    teammate's centreline; ``m`` itself when there is no ring or nothing on it. A static cell within the band
    (an object closer to the circle than the band's margin) moves as well."""
    band = ring(m, 2 * shift_m, window_m)
    if band is None:
        return m
    g = m.grid
    h, w = g.states.shape
    xs, ys, on = _on_ring(m, band)
    if not on.any():
        return m
    rows, cols = np.nonzero(on)
    seen_from = np.asarray(m.trajectory, np.float64)[-1, 1:3]  # where the robot is as it sends the map
    qx, qy = xs[cols] - seen_from[0], ys[rows] - seen_from[1]
    k = shift_m / np.maximum(np.hypot(qx, qy), 1e-9)
    to_c = np.floor((xs[cols] + k * qx - g.origin[0]) / g.resolution).astype(np.int64)
    to_r = np.floor((ys[rows] + k * qy - g.origin[1]) / g.resolution).astype(np.int64)
    inside = (to_c >= 0) & (to_c < w) & (to_r >= 0) & (to_r < h)
    states = g.states.copy()
    states[on] = UNKNOWN_S
    states[to_r[inside], to_c[inside]] = OCCUPIED_S
    return dataclasses.replace(m, grid=OccupancyGrid(states, g.resolution, g.origin))
