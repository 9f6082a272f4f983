"""merger — occupancy-grid map merging for robots that share a common center.

Implements section 3.3 of the thesis ("Merging of Occupancy Grid Maps with Common Center"): exhaustive
rotation search maximizing the modified similarity index ω̃ on a region of interest around the center,
verification on the whole maps, three (in general N(N−1)/2) merge orders and the choice of the best
verified one. numpy, OpenCV and numba kernels: no I/O in the algorithms (file formats live in :mod:`merger.io.mapio`).

The one way to merge maps from Python is :func:`merge` (map files or grids, a center per map, any
:class:`MergeParams` setting by name) → :class:`MergeResult` (the verdict in ``merger merge``'s words, each
map's :class:`Pose` in the first map's frame, the merged map). :func:`search_pair` is the search alone,
unverified; :class:`Cell` names the state codes ``OccupancyGrid.states`` holds (the ROS values are
``ROS_UNKNOWN``, ``ROS_FREE``, ``ROS_OCCUPIED``).
"""

from __future__ import annotations

from .api import MergeResult, merge
from .grid import ROS_FREE, ROS_OCCUPIED, ROS_UNKNOWN, Cell, OccupancyGrid
from .inputs import MergeInputError
from .measures import Counts, Similarity, birk_carpin, ncc, similarity_index
from .pose import Pose
from .search import SEARCH_METHODS, Alignment, RotationProblem, register_method, search
from .settings import DEFAULT_MEASURE, DEFAULT_ROI_M, DEFAULT_WINDOW_M, ROI_MIN_SUPPORT
from .team.online import MapMessage, TeamMerger
from .team.orders import merge_orders, merge_team
from .team.params import DEFAULT_METHOD, DEFAULT_REFINE, MapInput, MergeParams, OrderResult, TeamMergeResult
from .team.superpose import fuse, superpose
from .team.verify import Verification, verify

__all__ = [
    "merge", "MergeResult", "MergeInputError", "Pose",
    "Cell", "ROS_FREE", "ROS_OCCUPIED", "ROS_UNKNOWN", "OccupancyGrid", "MapMessage", "TeamMerger", "SEARCH_METHODS",
    "Alignment", "RotationProblem", "register_method", "search", "Counts", "Similarity", "birk_carpin",
    "ncc", "similarity_index", "fuse", "superpose", "MapInput", "MergeParams", "OrderResult",
    "TeamMergeResult", "merge_orders", "merge_team", "Verification", "verify", "search_pair", "align", "load_map",
    "save_map",
]


def search_pair(ref: OccupancyGrid, moving: OccupancyGrid, *, center_ref, center_moving=None,
                roi_m: float = DEFAULT_ROI_M, measure: str = DEFAULT_MEASURE, method: str = DEFAULT_METHOD,
                window_m: float = DEFAULT_WINDOW_M, refine: bool = DEFAULT_REFINE,
                roi_min_support: int = ROI_MIN_SUPPORT) -> Alignment:
    """The search's answer for one pair: the rotation θ (and translation t) of ``moving`` about its center
    onto ``ref`` that maximizes the measure on the ROI — **not verified** (no whole-map check, no ambiguity
    rule, no guard). To merge maps, verified, use :func:`merge` (what ``merger merge`` and ``merger align``
    run).

    Every default is a merge's (:class:`MergeParams` reads the same constants); each value is checked by its
    setting's one rule when the :class:`RotationProblem` is built (``method`` by :func:`search`).

    Parameters
    ----------
    ref, moving : the two grids, each in its own frame.
    center_ref, center_moving : the common center as (x, y) metres in each grid's frame
        (``center_moving`` defaults to ``center_ref``).
    roi_m : side of the square region of interest around the center, metres.
    measure : "similarity" (ω̃, eq. 3.11), "birk_carpin" (ω, eq. 2.21) or "ncc".
    method : "fast" (default: the reference's answer by branch and bound — :mod:`merger.search`),
        "reference" (the exhaustive search, compiled: the thesis's 380 rotations, times every one-cell
        translation of the window), "spec" (the same in plain numpy) or another registered method.
    window_m : the centers are trusted to ±window_m metres: the search covers every translation t of
        at most window_m on each axis (one-cell steps) jointly with the rotation. 0 is the thesis's
        rotation-only search; at most roi_m / 4.
    refine : refine θ and t below the search grid (plateau middle or parabolic peak fit); False gives
        the grid answer (θ on the thesis's 0.1° grid, t in whole cells).
    roi_min_support : the support floor, cells: placements whose ROI support agr̃ + dis is below it
        score 0, so no answer rests on a handful of cells; 0 searches the measure as the thesis defines it.
        An answer with ``score`` 0 means no evidence: no placement reached the floor with an agreeing cell.

    Returns
    -------
    Alignment with ``theta_deg`` in [0, 360) and ``translation_m`` = (tx, ty) such that
    x_ref = c_ref + t + R(θ)(x_moving − c_moving); ``score``, counts, the coarse profile and the
    runner-up peak (``theta_grid_deg`` / ``translation_grid_m``: the grid answer before refinement).
    """
    cm = center_ref if center_moving is None else center_moving
    problem = RotationProblem(ref, moving, tuple(map(float, center_ref)), tuple(map(float, cm)), roi_m, measure,
                              window_m, refine, roi_min_support)
    return search(problem, method)


def align(*args, **kwargs) -> Alignment:
    """The old name of :func:`search_pair` (the unverified search; ``merger align`` on the command line
    runs every check, as :func:`merge`): warns, then answers as :func:`search_pair`."""
    import warnings

    warnings.warn("merger.align is the unverified search, now named merger.search_pair; merger.merge verifies",
                  DeprecationWarning, stacklevel=2)
    return search_pair(*args, **kwargs)


def load_map(path):
    """Read a ROS map_server map (YAML + PGM) into an :class:`OccupancyGrid`."""
    from .io.mapio import load_map as _load

    return _load(path)


def save_map(grid: OccupancyGrid, path, **kw):
    """Write a ROS map_server map (YAML + PGM) of ``grid``."""
    from .io.mapio import save_map as _save

    return _save(grid, path, **kw)
