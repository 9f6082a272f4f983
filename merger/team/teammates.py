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

The bodies move: the robots publish their maps at their own phases, so two maps hold the team at
different places on its ring. Compared as they are, the bodies turn the pair's rotation the team's way
(12-robot L room, seed 1, the maps robot K held at 1.8 s, published 0.2–0.9 s before its own: every
verified pair +1.0° to +3.1° off, whole-map ν peaking 2° from the truth, and 5–10 false merges 2–3° off
in the first 5 s). With ``until``, :func:`teammates_centred` moves the bodies on to a later instant, as
far round the center as the map's own robot turns in that time (:func:`angular_speed`): the team drives
its circle together. :func:`merger.team.tree.at_one_instant` moves the older map of a pair on to the
newer one's instant (those pairs then within ±1.2°; tests/merger/team/test_tree.py bounds them by 1.5°).

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


def teammates_centred(m: MapInput, shift_m: float, window_m: float, until: float | None = None,
                      faces: Faces | None = None) -> MapInput:
    """``m`` with the occupied cells on its team's ring (:func:`ring`, margin 2·``shift_m``) moved ``shift_m``
    farther along the line of sight from its robot (the last point of its path: the faces a map holds are the
    ones its robot sees now, older ones are cleared as it passes): a teammate's face moved towards the
    teammate's centreline; ``m`` itself when there is no ring or nothing on it. A static cell within the band
    (an object closer to the circle than the band's margin) moves as well.

    ``until`` (seconds, on the paths' clock; later than the map's time, its path's last row): the bodies
    moved on to where they stand then — turned about the center as far as the map's own robot turns in that
    time at its angular speed (:func:`angular_speed`): the team drives its circle together. Two maps of
    different instants hold the team at different places on the ring; compared as they are, the pair's
    rotation follows the bodies (the 12-robot L room's maps 0.2–0.9 s apart: +1.0° to +3.1°, all one
    way). ``faces``: :func:`centred_faces` of the same map and settings, computed once for every instant."""
    f = centred_faces(m, shift_m, window_m) if faces is None else faces
    if f is None:
        return m
    g = m.grid
    h, w = g.states.shape
    px, py = f.x, f.y
    if until is not None and until > map_time(m):
        a = angular_speed(m) * (until - map_time(m))
        ca, sa = np.cos(a), np.sin(a)
        dx, dy = px - m.center[0], py - m.center[1]
        px, py = m.center[0] + ca * dx - sa * dy, m.center[1] + sa * dx + ca * dy
    to_c = np.floor((px - g.origin[0]) / g.resolution).astype(np.int64)
    to_r = np.floor((py - g.origin[1]) / g.resolution).astype(np.int64)
    inside = (to_c >= 0) & (to_c < w) & (to_r >= 0) & (to_r < h)
    states = g.states.copy()
    states[f.rows, f.cols] = UNKNOWN_S
    states[to_r[inside], to_c[inside]] = OCCUPIED_S
    return dataclasses.replace(m, grid=OccupancyGrid(states, g.resolution, g.origin))


@dataclasses.dataclass(frozen=True, eq=False)
class Faces:
    """The occupied cells on a map's team ring (``rows``, ``cols``) and where :func:`teammates_centred` puts
    them at the map's instant (``x``, ``y``, metres: moved ``shift_m`` along the robot's line of sight)."""

    rows: np.ndarray
    cols: np.ndarray
    x: np.ndarray
    y: np.ndarray


def centred_faces(m: MapInput, shift_m: float, window_m: float) -> Faces | None:
    """The :class:`Faces` of ``m`` (None: no ring, or nothing on it) — the part of :func:`teammates_centred`
    that does not depend on the instant: a pair of maps of two instants moves one of them on, and each of a
    team's maps is moved on to as many instants as it has pairs."""
    band = ring(m, 2 * shift_m, window_m)
    if band is None:
        return None
    xs, ys, on = _on_ring(m, band)
    if not on.any():
        return None
    rows, cols = np.nonzero(on)
    seen_from = np.asarray(m.trajectory, np.float64)[-1, 1:3]  # where the robot is as it sends the map
    qx, qy = xs[cols] - seen_from[0], ys[rows] - seen_from[1]
    k = shift_m / np.maximum(np.hypot(qx, qy), 1e-9)
    return Faces(rows, cols, xs[cols] + k * qx, ys[rows] + k * qy)


def angular_speed(m: MapInput) -> float:
    """How fast the map's robot turns about the map's center, rad/s, counter-clockwise positive: over the last
    second of its path (0 without a path or before it moves)."""
    tr = m.trajectory
    if tr is None or len(tr) < 2:
        return 0.0
    k = max(int(np.searchsorted(tr[:, 0], tr[-1, 0] - 1.0, side="right")) - 1, 0)
    dt = float(tr[-1, 0] - tr[k, 0])
    if dt <= 0:
        return 0.0
    a0 = np.arctan2(tr[k, 2] - m.center[1], tr[k, 1] - m.center[0])
    a1 = np.arctan2(tr[-1, 2] - m.center[1], tr[-1, 1] - m.center[0])
    return float((a1 - a0 + np.pi) % (2 * np.pi) - np.pi) / dt


def map_time(m: MapInput) -> float | None:
    """The instant a map shows (its path's last row), or None without a path."""
    return None if m.trajectory is None or len(m.trajectory) == 0 else float(m.trajectory[-1, 0])
