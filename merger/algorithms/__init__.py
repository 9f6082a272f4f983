"""Merging methods behind one interface, so that the bench judges them on the same truth (issue 35).

``ALGORITHMS``: ``thesis`` (the default: the thesis's rotation (× translation) search about the common
center, verified — :mod:`merger.team`), ``features`` (ROS m-explore map_merge's ORB / RANSAC pipeline,
:mod:`merger.algorithms.features`; no center) and ``hough`` (Carpin's Hough-spectrum merging,
:mod:`merger.algorithms.hough`; no center). Each answers :func:`align_pair` — two maps, their centers,
the settings → a placement about the centers, its evidence, or a refusal with a reason
(:class:`merger.algorithms.base.PairAnswer`) — and :func:`merge` merges a team with it
(a :class:`merger.team.orders.TeamMergeResult`, map 0's frame).

They are one table, :data:`ALGORITHMS_BY_NAME` (an :class:`Algorithm` per name: its pair function and how a
team is merged with it); the ``algorithm`` setting's allowed values are its keys (:data:`ALGORITHMS`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from ..team.orders import MapInput, MergeParams, TeamMergeResult
from .base import PairAnswer

DEFAULT = "thesis"


@dataclass(frozen=True)
class Algorithm:
    """A merging method (the ``algorithm`` setting).

    load : returns its pair function ``align(ref, mov, params) -> PairAnswer`` (imported when first asked:
        the pairwise methods need OpenCV's feature pipeline or the Hough spectrum).
    pairwise : a team is merged from its pair answers (:func:`merger.algorithms.team.merge_pairwise`; no
        center used); False: the method merges a team itself (``thesis``: :func:`merger.team.orders.merge_team`,
        every order verified) and its online merger is :class:`merger.team.online.TeamMerger`.
    """

    name: str
    load: Callable[[], Callable]
    pairwise: bool = True

    @property
    def align(self) -> Callable:
        """``align(ref, mov, params) -> PairAnswer``."""
        return self.load()


def _thesis_pair(ref: MapInput, mov: MapInput, params: MergeParams) -> PairAnswer:
    from ..team.orders import merge_team

    res = merge_team([ref, mov], params, orders=[(0, 1)])
    top = res.top
    th = top.theta_deg.get(mov.name)
    ev = {"nu": top.nu_sum, "support": sum(c.support for c in top.checks.values())}
    return PairAnswer(res.accepted, th, top.translation(mov.name), top.nu_sum, ev, res.reason)


def _features():
    from .features import align

    return align


def _hough():
    from .hough import align

    return align


ALGORITHMS_BY_NAME: dict[str, Algorithm] = {a.name: a for a in (
    Algorithm("thesis", lambda: _thesis_pair, pairwise=False),
    Algorithm("features", _features),
    Algorithm("hough", _hough),
)}
ALGORITHMS = tuple(ALGORITHMS_BY_NAME)  # the algorithm setting's allowed values


def algorithm_of(name: str) -> Algorithm:
    """The :class:`Algorithm` named ``name`` (ValueError naming the choices when there is none)."""
    try:
        return ALGORITHMS_BY_NAME[name]
    except (KeyError, TypeError):
        raise ValueError(f"merger algorithm must be one of {', '.join(ALGORITHMS)}, got {name!r}") from None


def pair_function(algorithm: str):
    """``align(ref, mov, params) -> PairAnswer`` of an algorithm."""
    return algorithm_of(algorithm).align


def align_pair(algorithm: str, ref: MapInput, mov: MapInput, params: MergeParams = MergeParams()) -> PairAnswer:  # noqa: B008 (frozen)
    """Map ``mov`` onto map ``ref`` with ``algorithm``."""
    return pair_function(algorithm)(ref, mov, params)


def merge(algorithm: str, maps: list[MapInput], params: MergeParams = MergeParams(), *, cache: dict | None = None,  # noqa: B008 (frozen)
          **thesis_kwargs) -> TeamMergeResult:
    """Merge a team with ``algorithm`` (``thesis``: :func:`merger.team.orders.merge_team` with
    ``thesis_kwargs``; the others: :func:`merger.algorithms.team.merge_pairwise`)."""
    alg = algorithm_of(algorithm)
    if not alg.pairwise:
        from ..team.orders import merge_team

        return merge_team(maps, params, **thesis_kwargs)
    from .team import merge_pairwise

    return merge_pairwise(alg.align, maps, params, cache=cache, name=alg.name)


def merge_every_map(algorithm: str, maps: list[MapInput], params: MergeParams = MergeParams()) -> TeamMergeResult:  # noqa: B008 (frozen)
    """:func:`merge` for a merge of files (``merger merge --algorithm``): accepted only when every map is
    placed (a pairwise algorithm may place a part of the team; the online bench keeps that partial merge)."""
    from dataclasses import replace

    res = merge(algorithm, maps, params, orders=[(0, 1)] if len(maps) == 2 else None) \
        if not algorithm_of(algorithm).pairwise else merge(algorithm, maps, params)
    if res.chosen is None or len(res.chosen.theta_deg) == len(maps):
        return res
    missing = [m.name for m in maps if m.name not in res.chosen.theta_deg]
    top = replace(res.chosen, accepted=False, reason=f"{', '.join(missing)} not placed: {res.chosen.reason}")
    return replace(res, orders=(top,), chosen=None)
