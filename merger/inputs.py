"""The checks of a merge's inputs, before any work: the settings, the centers, the maps' resolutions and
the limits (docs/limits.md). :func:`merger.merge.merge` runs them on every call, so a Python caller and
both command lines (``merger merge``, ``merger align``) are refused by the same rule in the same words.

A refusal is a :class:`MergeInputError`, one line ``key`` + ``rest``: ``key`` names the input as a Python
caller knows it (``centers[1]``, ``roi_m``, ``maps``, a map's file), ``rest`` says what was expected and
what was given. The command lines name the same input by their option (``--center (map 2)``, ``--roi``)
with :meth:`MergeInputError.named`. Pure: the maps arrive as grids, each with a label for the messages
(its file, or ``maps[i]``); reading files is :mod:`merger.io.inputs`.
"""

from __future__ import annotations

import math

from .grid import OccupancyGrid
from .io.mapread import MAX_MAP_CELLS, MAX_MAP_SIDE
from .settings import SettingError, check_roi, check_window
from .team.params import MergeParams
from .transform import resample


class MergeInputError(ValueError):
    """An input :func:`merger.merge` refuses: the message is ``key + rest``, one line naming the input and
    what was expected."""

    def __init__(self, key: str, rest: str) -> None:
        super().__init__(key + rest)
        self.key, self.rest = key, rest

    def named(self, key: str) -> MergeInputError:
        """The same refusal with the input named ``key`` (a command line's option)."""
        return MergeInputError(key, self.rest)


def params_of(settings: dict) -> MergeParams:
    """:class:`MergeParams` of ``settings`` (its field names), each value checked by its setting's rule and
    the ROI by the inputs' limits (:func:`merger.settings.check_roi` with ``limits``)."""
    known = MergeParams.__dataclass_fields__
    unknown = [k for k in settings if k not in known]
    if unknown:
        raise MergeInputError(unknown[0], f": not a setting of a merge: expected one of {', '.join(known)}")
    try:
        if "roi_m" in settings:
            check_roi(settings["roi_m"], key="roi_m", limits=True)
        params = MergeParams(**settings)
        check_window(params.window_m, params.roi_m)
    except SettingError as e:
        raise MergeInputError(e.key, e.rest) from None
    return params


def check_centers(centers, n: int) -> list[tuple[float, float]]:
    """One center (x, y) per map, finite numbers of metres."""
    try:
        got = len(centers)
    except TypeError:
        got = None
    if got != n:
        raise MergeInputError("centers", f": expected one (x, y) per map ({n}), got {centers!r}")
    out = []
    for i, c in enumerate(centers):
        try:
            x, y = (float(v) for v in c)
        except (TypeError, ValueError):
            raise MergeInputError(f"centers[{i}]", f": expected (x, y) in metres, got {c!r}") from None
        if not (math.isfinite(x) and math.isfinite(y)):
            raise MergeInputError(f"centers[{i}]", f": expected finite numbers, got {c!r}")
        out.append((x, y))
    return out


def check_center(grid: OccupancyGrid, center, roi_m: float, key: str, label: str) -> None:
    """A common center must lie within half the ROI side of its map's extent: beyond, the ROI holds none
    of the map (a typo, or a center in another frame), and the canvas of the merged maps would span the
    distance (a center at (1e7, 0) asked for 46 GiB)."""
    x0, x1, y0, y1 = grid.extent
    m = roi_m / 2
    if not (x0 - m <= center[0] <= x1 + m and y0 - m <= center[1] <= y1 + m):
        raise MergeInputError(key, f": ({center[0]:g}, {center[1]:g}) is outside {label}, which spans x [{x0:g}, "
                                   f"{x1:g}], y [{y0:g}, {y1:g}] m: expected a point within {m:g} m (half the ROI "
                                   "side) of the map, in its frame")


def check_roi_cells(roi_m: float, resolution: float, label: str) -> None:
    """The ROI in cells of the maps' resolution, with the inputs' limits (:func:`merger.settings.check_roi`)."""
    try:
        check_roi(roi_m, resolution, "roi_m", limits=True, cells_of=str(label))
    except SettingError as e:
        raise MergeInputError(e.key, e.rest) from None


def same_resolution(labels: list[str], grids: list[OccupancyGrid]) -> tuple[list[OccupancyGrid], list[str]]:
    """``grids[1:]`` on the first map's cells (:func:`merger.transform.resample`, whose docstring gives the
    rule for the three states), and one note per resampled map. A resampled map larger than the map limits
    is refused."""
    r0, out, notes = grids[0].resolution, [], []
    for p, g in zip(labels[1:], grids[1:], strict=True):
        if not math.isclose(g.resolution, r0, rel_tol=1e-6):
            h, w = (round(n * g.resolution / r0) for n in g.shape)
            if h * w > MAX_MAP_CELLS or max(h, w) > MAX_MAP_SIDE:
                raise MergeInputError(str(p), f": resolution {g.resolution:g} m per cell, {labels[0]} has {r0:g}: "
                                      f"on {r0:g} m cells it would be {w} x {h} cells, beyond the limit of "
                                      f"{MAX_MAP_CELLS:,} cells ({MAX_MAP_SIDE} a side); give the finer map first")
            notes.append(f"{p}: resampled from {g.resolution:g} to {r0:g} m per cell, the first map's "
                         "(occupied where any occupied cell falls, free where free cells cover half a cell; "
                         "docs/real-maps.md)")
            g = resample(g, r0)
        out.append(g)
    return out, notes


def checked_maps(labels: list[str], grids: list[OccupancyGrid], centers, roi_m: float):
    """The maps on the first one's cells, each center near its map and the ROI within the cell limits:
    (grids, centers, notes)."""
    if len(grids) < 2:
        raise MergeInputError("maps", f": expected at least two maps, got {len(grids)}")
    cs = check_centers(centers, len(grids))
    rest, notes = same_resolution(labels, grids)
    grids = [grids[0], *rest]
    for i, (label, g, c) in enumerate(zip(labels, grids, cs, strict=True)):
        check_center(g, c, roi_m, f"centers[{i}]", label)
    check_roi_cells(roi_m, grids[0].resolution, labels[0])
    return grids, cs, notes
