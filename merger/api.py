"""One call merges maps from Python: :func:`merge` → :class:`MergeResult`.

::

    res = merger.merge(["r1.yaml", "r2.yaml"], centers=[(1.2, 0.4), (0.9, -0.3)], roi_m=16)
    res.accepted, res.rule, res.reason      # the verdict in ``merger merge``'s words
    res.poses["r2"]                         # Pose(x, y, yaw_deg) of r2's frame in r1's frame

Every input check of ``merger merge`` runs here, before any work (:mod:`merger.inputs`: the settings'
rules, the maps on the first one's cells, each center near its map, the limits), and a refusal is one
:class:`~merger.inputs.MergeInputError` line; ``merger merge`` and ``merger align`` call this function.
Two maps are one order (the second searched onto the first, as ``merger align FIRST SECOND``), N maps
every merge order (:func:`merger.team.orders.merge_team`), or a pairwise ``algorithm``
(:mod:`merger.algorithms`). Files are read by :mod:`merger.io.inputs`; the merge itself is pure.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .algorithms import ALGORITHMS, merge_every_map
from .grid import OccupancyGrid
from .inputs import MergeInputError, checked_maps, params_of
from .io.inputs import read_inputs
from .pose import Pose, pose_of_placement
from .team.params import MapInput, OrderResult, TeamMergeResult
from .team.verify import Verification
from .verdict import verdict_words


@dataclass(frozen=True, eq=False)
class MergeResult:
    """What :func:`merge` answers.

    accepted : whether the merge passed every check (``merged`` is then the merged map).
    rule : the rule that decided, in ``merger merge``'s words: accepted by "contrast" or "whole-map ν"
        (the verification of every pair; a pairwise algorithm: its own rule), refused by "verification",
        "no evidence", "the ambiguity rule" or "the guard beyond the window".
    reason : that rule's figures (accepted: each pair's, e.g. ``r1|r2 contrast 3.10 (fit 0.412 vs rival
        0.133 at +90°, 812 cells; ν 0.46)``; refused: why).
    evidence : per pair ``"A|B"``, the :class:`~merger.team.verify.Verification` of the placement the
        verdict is about (ν, support, the contrast rule's figures).
    poses : per map name, the pose of its frame in the first map's frame: p_first = R(yaw)·p_map + (x, y);
        the first map's is the identity. Accepted: the chosen placement (where ``merged`` is drawn);
        refused: the best refused hypothesis, for the record (``accepted`` says not to use it). A map no
        hypothesis placed (a pairwise algorithm's refusal) has none.
    search_poses : the search's own answer, apart from the chosen one: the placement before its refinement
        on the whole maps (equal to ``poses`` when the chosen placement is the search's).
    merged : the merged map in the first map's frame (None when refused).
    names : the maps' names (file stems, or ``map1``, ``map2``, ... for grids; ``names=`` to choose).
    notes : one line per map resampled onto the first map's cells.
    team : every order searched and its checks (:class:`~merger.team.params.TeamMergeResult`).
    """

    accepted: bool
    rule: str
    reason: str
    evidence: dict[str, Verification]
    poses: dict[str, Pose]
    search_poses: dict[str, Pose]
    merged: OccupancyGrid | None = field(repr=False)
    names: tuple[str, ...]
    notes: tuple[str, ...]
    team: TeamMergeResult = field(repr=False)
    maps: tuple[MapInput, ...] = field(repr=False, default=())

    @property
    def frame(self) -> str:
        """The first map's name: every pose is in its frame."""
        return self.names[0]

    def to_dict(self) -> dict:
        return {"accepted": self.accepted, "rule": self.rule, "reason": self.reason, "frame": self.frame,
                "poses": {k: p.to_dict() for k, p in self.poses.items()},
                "search_poses": {k: p.to_dict() for k, p in self.search_poses.items()},
                "evidence": {k: v.to_dict() for k, v in self.evidence.items()}, "notes": list(self.notes)}


def poses_of(order: OrderResult, maps: list[MapInput], search: bool = False) -> dict[str, Pose]:
    """Each placed map's pose in the first map's frame from an order's placement (``search``: the
    search's own placement when the order holds its refinement)."""
    theta = order.search_theta_deg if search and order.search_theta_deg else order.theta_deg
    trans = order.search_translation_m if search and order.search_theta_deg else order.translation_m
    c0 = maps[0].center
    return {m.name: pose_of_placement(theta[m.name], trans.get(m.name, (0.0, 0.0)), c0, m.center)
            for m in maps if m.name in theta}


def result_of(team: TeamMergeResult, maps: list[MapInput], notes=()) -> MergeResult:
    """The :class:`MergeResult` of a merge cycle's result (for callers of :func:`merger.team.orders.merge_team`)."""
    rule, reason = verdict_words(team)
    order = team.top
    return MergeResult(team.accepted, rule, reason, dict(order.checks), poses_of(order, maps),
                       poses_of(order, maps, search=True), team.merged, tuple(m.name for m in maps),
                       tuple(notes), team, tuple(maps))


def prepare(maps, centers, *, names=None, labels=None, **settings):
    """The checked inputs of :func:`merge`: (MapInput list, MergeParams, notes). Every check of ``merger
    merge`` (:mod:`merger.inputs`) runs here; a refusal is a :class:`~merger.inputs.MergeInputError`.
    ``labels``: how messages name the maps (default: their paths, or ``maps[i]`` for grids)."""
    params = params_of(settings)
    grids, names, own = read_inputs(maps, names)
    grids, cs, notes = checked_maps(own if labels is None else list(labels), grids, centers, params.roi_m)
    return [MapInput(n, g, c) for n, g, c in zip(names, grids, cs, strict=True)], params, notes


def merge_inputs(inputs: list[MapInput], params, notes=(), algorithm: str = "thesis") -> MergeResult:
    """Merge maps :func:`prepare` checked (the command lines make their output folder in between)."""
    return result_of(merge_every_map(algorithm, inputs, params), inputs, notes)


def merge(maps, centers, *, names=None, algorithm: str = "thesis", **settings) -> MergeResult:
    """Merge 2 to N maps of robots that share a common center.

    Parameters
    ----------
    maps : map files (ROS map_server YAML, as ``str`` or ``Path``) or :class:`~merger.grid.OccupancyGrid`
        objects, each in its own frame; the first map's frame is the result's.
    centers : the common center in each map's own frame, one (x, y) in metres per map.
    names : optional names of the maps (default: file stems, ``map1``, ``map2``, ... for grids).
    algorithm : "thesis" (default: the search about the common center, verified), "features" or
        "hough" (:mod:`merger.algorithms`; no center used).
    **settings : any :class:`~merger.team.params.MergeParams` setting by its name (``roi_m``,
        ``window_m``, ``verification``, ``nu_min``, ...), with its default. Real maps often need
        ``roi_m=16`` (docs/real-maps.md).

    Returns
    -------
    MergeResult : the verdict (``accepted``, ``rule``, ``reason``, ``evidence``), each map's pose in the
    first map's frame and the merged map.

    Raises
    ------
    MergeInputError : an input no merge can take (a setting out of its range, a file that cannot be read,
        a center far from its map, a map beyond the limits), before any work; one line naming the input.
    """
    if algorithm not in ALGORITHMS:
        raise MergeInputError("algorithm", f": expected one of {', '.join(ALGORITHMS)}, got {algorithm!r}")
    inputs, params, notes = prepare(maps, centers, names=names, **settings)
    return merge_inputs(inputs, params, notes, algorithm)
