"""Merging methods behind one interface, so that the bench judges them on the same truth (issue 35).

``ALGORITHMS``: ``thesis`` (the default: the thesis's rotation (× translation) search about the common
center, verified — :mod:`merger.team`), ``features`` (ROS m-explore map_merge's ORB / RANSAC pipeline,
:mod:`merger.algorithms.features`; no center) and ``hough`` (Carpin's Hough-spectrum merging,
:mod:`merger.algorithms.hough`; no center). Each answers :func:`align_pair` — two maps, their centers,
the settings → a placement about the centers, its evidence, or a refusal with a reason
(:class:`merger.algorithms.base.PairAnswer`) — and :func:`merge` merges a team with it
(a :class:`merger.team.orders.TeamMergeResult`, map 0's frame).
"""

from __future__ import annotations

from ..team.orders import MapInput, MergeParams, TeamMergeResult
from .base import PairAnswer

ALGORITHMS = ("thesis", "features", "hough")
DEFAULT = "thesis"


def _thesis_pair(ref: MapInput, mov: MapInput, params: MergeParams) -> PairAnswer:
    from ..team.orders import merge_team

    res = merge_team([ref, mov], params, orders=[(0, 1)])
    top = res.top
    th = top.theta_deg.get(mov.name)
    ev = {"nu": top.nu_sum, "support": sum(c.support for c in top.checks.values())}
    return PairAnswer(res.accepted, th, top.translation(mov.name), top.nu_sum, ev, res.reason)


def pair_function(algorithm: str):
    """``align(ref, mov, params) -> PairAnswer`` of an algorithm."""
    if algorithm == "thesis":
        return _thesis_pair
    if algorithm == "features":
        from .features import align
    elif algorithm == "hough":
        from .hough import align
    else:
        raise ValueError(f"merger algorithm must be one of {', '.join(ALGORITHMS)}, got {algorithm!r}")
    return align


def align_pair(algorithm: str, ref: MapInput, mov: MapInput, params: MergeParams = MergeParams()) -> PairAnswer:  # noqa: B008 (frozen)
    """Map ``mov`` onto map ``ref`` with ``algorithm``."""
    return pair_function(algorithm)(ref, mov, params)


def merge(algorithm: str, maps: list[MapInput], params: MergeParams = MergeParams(), *, cache: dict | None = None,  # noqa: B008 (frozen)
          **thesis_kwargs) -> TeamMergeResult:
    """Merge a team with ``algorithm`` (``thesis``: :func:`merger.team.orders.merge_team` with
    ``thesis_kwargs``; the others: :func:`merger.algorithms.team.merge_pairwise`)."""
    if algorithm == "thesis":
        from ..team.orders import merge_team

        return merge_team(maps, params, **thesis_kwargs)
    from .team import merge_pairwise

    return merge_pairwise(pair_function(algorithm), maps, params, cache=cache, name=algorithm)


def merge_every_map(algorithm: str, maps: list[MapInput], params: MergeParams = MergeParams()) -> TeamMergeResult:  # noqa: B008 (frozen)
    """:func:`merge` for a merge of files (``merger merge --algorithm``): accepted only when every map is
    placed (a pairwise algorithm may place a part of the team; the online bench keeps that partial merge)."""
    from dataclasses import replace

    res = merge(algorithm, maps, params, orders=[(0, 1)] if len(maps) == 2 else None) if algorithm == "thesis" \
        else merge(algorithm, maps, params)
    if res.chosen is None or len(res.chosen.theta_deg) == len(maps):
        return res
    missing = [m.name for m in maps if m.name not in res.chosen.theta_deg]
    top = replace(res.chosen, accepted=False, reason=f"{', '.join(missing)} not placed: {res.chosen.reason}")
    return replace(res, orders=(top,), chosen=None)
