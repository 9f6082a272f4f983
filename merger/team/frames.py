"""Placements between the maps' frames, and maps placed on another map's cell lattice.

A placement (θ, t) of map k onto map f's frame means x_f = c_f + t + R(θ)(x_k − c_k), with c each map's
common center in its own frame (:class:`merger.team.params.MapInput`). :func:`compose` expresses the
placements onto one map's frame onto another's; :func:`shifted` is c + t, where a placed map's center lands.

:class:`Warps` holds the maps of one merge cycle rotated onto another map's lattice, each warp computed once
and covering only the rotated map's footprint, and the whole-map checks of placed pairs
(:func:`merger.team.verify.check_pair`, each computed once). :func:`place_on_frame0` resamples every map onto
one canvas in map 0's frame (what is fused and drawn); :func:`fused_layers` does so from placements given by
map name. The strategies (:mod:`.orders`, :mod:`.tree`, :mod:`.follow`, :mod:`.shared`) place maps through
here; nothing here searches.
"""

from __future__ import annotations

import numpy as np

from ..grid import OccupancyGrid
from ..search import wrap_deg
from ..transform import canvas, footprint, paste, rotation, warp_grid
from .params import ORIGIN, MapInput, MergeParams, Placement
from .superpose import fuse_grids
from .verify import Verification, check_pair


def compose(onto_first: dict[int, Placement], first: int, base: int) -> dict[int, Placement]:
    """Placements onto the first map's frame → onto map ``base``'s frame.

    With x_f = c_f + t_fk + R(θ_fk)(x_k − c_k) for every k: θ_bk = θ_fk − θ_fb and
    t_bk = R(−θ_fb)(t_fk − t_fb)."""
    th_b, t_b = onto_first[base]
    r = rotation(-th_b)
    out = {}
    for k, (th, t) in onto_first.items():
        d = r @ (np.asarray(t, np.float64) - np.asarray(t_b, np.float64))
        out[k] = (wrap_deg(th - th_b), (float(d[0]), float(d[1])))
    out[base] = (0.0, ORIGIN)
    return out


def shifted(center, t) -> tuple[float, float]:
    """c + t (the point where a placed map's center lands)."""
    if t[0] == 0.0 and t[1] == 0.0:
        return (float(center[0]), float(center[1]))
    return (float(center[0]) + float(t[0]), float(center[1]) + float(t[1]))


class Warps:
    """The maps of one merge cycle rotated onto another map's cell lattice, each warp computed once.

    A warp covers only the rotated map's footprint (:func:`merger.transform.footprint`); every cell
    outside it is unknown. One warp therefore serves every canvas on that lattice (pasting it is exact),
    and a pair's whole-map ω̃ only needs the cells where the two footprints overlap (unknown cells count
    in neither agr̃ nor dis). Orders that share a rotation share its warp and its pair checks.
    """

    def __init__(self, maps: list[MapInput]) -> None:
        self.maps = maps
        self._known: dict[int, OccupancyGrid] = {}
        self._warps: dict[tuple[int, int, float], OccupancyGrid] = {}
        self._checks: dict[tuple, Verification] = {}

    def known(self, k: int) -> OccupancyGrid:
        """Map ``k``'s known cells (:meth:`OccupancyGrid.known_part`): what is warped and placed."""
        if k not in self._known:
            self._known[k] = self.maps[k].grid.known_part()
        return self._known[k]

    def placed(self, k: int, theta: float, t=ORIGIN) -> tuple[OccupancyGrid, float, tuple[float, float]]:
        """``(grid, θ, center)`` of map ``k`` for :func:`merger.transform.canvas` — with a translation
        t, the center is moved back by R(−θ)t so that the canvas's center c_f maps it to c_f + t."""
        return self.known(k), theta, _source_center(self.maps[k].center, theta, t)

    def get(self, frame: int, k: int, theta: float, t=ORIGIN) -> OccupancyGrid:
        """Map ``k`` placed by (θ, t) onto map ``frame``'s lattice: x_f = c_f + t + R(θ)(x_k − c_k)."""
        key = _warp_key(frame, k, theta, t)
        t = key[3]
        if k == frame and theta == 0.0 and t == ORIGIN:
            return self.maps[k].grid
        if key not in self._warps:
            base, m, g = self.maps[frame], self.maps[k], self.known(k)
            target = shifted(base.center, t)
            fp = footprint(base.grid, g, theta, m.center, target)
            self._warps[key] = warp_grid(g, theta, m.center, target, fp)
        return self._warps[key]

    def check(self, i: int, pi: Placement, j: int, pj: Placement, params: MergeParams) -> Verification:
        """ν_ij of maps i and j placed on map 0's frame (whole maps, with the acceptance rule)."""
        key = (i, pi[0], tuple(pi[1]), j, pj[0], tuple(pj[1]))
        if key not in self._checks:
            label = f"{self.maps[i].name}|{self.maps[j].name}"
            self._checks[key] = check_pair(self.get(0, i, *pi), self.get(0, j, *pj),
                                           shifted(self.maps[0].center, pj[1]), params, label)
        return self._checks[key]

    def kept_for(self, place0: dict[int, Placement]) -> Warps:
        """A Warps of the same maps holding only what placing them by ``place0`` on map 0's frame reads:
        their known parts and their warps onto map 0 (what :class:`Fusion` keeps, not every check's warp)."""
        out = Warps(self.maps)
        for k, (theta, t) in place0.items():
            if k in self._known:
                out._known[k] = self._known[k]
            key = _warp_key(0, k, theta, t)
            if key in self._warps:
                out._warps[key] = self._warps[key]
        return out


class Fusion:
    """:func:`merged_on_frame0` of given maps and placements, computed when called: a result's merged map
    built when it is read (:class:`merger.team.params.TeamMergeResult`). Keeps the maps, the placements and
    the warps onto map 0 already computed (:meth:`Warps.kept_for`); it pickles."""

    def __init__(self, maps: list[MapInput], place0: dict[int, Placement], warps: Warps | None = None) -> None:
        self.maps, self.place0 = maps, dict(place0)
        self.warps = warps.kept_for(self.place0) if warps is not None else None

    def __call__(self) -> tuple[OccupancyGrid, dict[str, OccupancyGrid]]:
        return merged_on_frame0(self.maps, self.place0, self.warps)


def _warp_key(frame: int, k: int, theta: float, t) -> tuple:
    """The key of a warp in :class:`Warps` (its translation as two floats)."""
    return (frame, k, theta, (float(t[0]), float(t[1])))


def _source_center(center, theta: float, t) -> tuple[float, float]:
    """c − R(−θ)t: with it, c_f + R(θ)(x − (c − R(−θ)t)) = c_f + t + R(θ)(x − c)."""
    if t[0] == 0.0 and t[1] == 0.0:
        return (float(center[0]), float(center[1]))
    d = rotation(-theta) @ np.asarray(t, np.float64)
    return (float(center[0]) - float(d[0]), float(center[1]) - float(d[1]))


def place_on_frame0(maps: list[MapInput], place0: dict[int, Placement],
                    warps: Warps | None = None) -> list[OccupancyGrid]:
    """All maps resampled onto one canvas in map 0's frame: map 0's grid and every other map's known
    cells (:meth:`Warps.known`), each placed by its (θ, t)."""
    warps = Warps(maps) if warps is None else warps
    base = maps[0]
    cv = canvas(base.grid, [warps.placed(i, *place0[i]) for i in range(1, len(maps))], base.center)
    return [paste(base.grid, cv)] + [paste(warps.get(0, i, *place0[i]), cv) for i in range(1, len(maps))]


def merged_on_frame0(maps: list[MapInput], place0: dict[int, Placement],
                     warps: Warps | None = None) -> tuple[OccupancyGrid, dict[str, OccupancyGrid]]:
    """The maps placed on map 0's frame (:func:`place_on_frame0`) and fused: the merged map a user gets
    (:func:`merger.team.superpose.fuse`) and each map's layer by name."""
    lay = place_on_frame0(maps, place0, warps)
    return fuse_grids(lay), {m.name: g for m, g in zip(maps, lay, strict=True)}


def fused_layers(maps: list[MapInput], theta_deg: dict[str, float],
                 translation_m: dict[str, tuple[float, float]] | None = None) -> list[OccupancyGrid]:
    """The maps placed on map 0's frame with given rotations and translations (e.g. a kept earlier
    alignment; translations default to none)."""
    tr = translation_m or {}
    return place_on_frame0(maps, {i: (theta_deg[m.name], tuple(tr.get(m.name, ORIGIN)))
                                  for i, m in enumerate(maps)})

