"""The thesis's merge orders under the tracker (``research: on_change``, :mod:`merger.team.track`).

With the ``orders`` strategy a cycle's hypothesis is one merge order's placements of every held map. Once a
cycle is accepted, the robot follows that hypothesis: at each new map version it re-aligns the chosen
order step by step with the exact local search about the tracked placements (each step onto the
superposition of the maps before it, as the order's global search does) and verifies the result on the
whole maps like any order (:func:`merger.team.orders.order_result`). That is the cycle's answer when
it passes and its mean ν is within ``research_drop`` of the last global cycle's; otherwise — and when
the tracker says a global search is due (a map's ROI changed, the staleness period, a candidate to
confirm), or the held maps are not the hypothesis's — the cycle is the thesis's: every order searched
globally (:func:`merger.team.orders.merge_team`), arbitrated against the tracked one by
:func:`merger.team.track.decide`.
"""

from __future__ import annotations

import time

from .frames import Warps, compose, merged_on_frame0
from .memo import Memo
from .orders import align_order, merge_team, order_result, refine_chosen
from .params import MapInput, MergeParams, TeamMergeResult
from .pool import start_clock
from .track import Tracker, decide

TEAM = "team"


def team_placement(result: TeamMergeResult) -> dict:
    """The search's placements (θ, t) per map of an accepted result (before any whole-map refinement)."""
    c = result.chosen
    th = c.search_theta_deg or c.theta_deg
    tt = c.search_translation_m or c.translation_m
    return {k: (float(th[k]), tuple(map(float, tt.get(k, (0.0, 0.0))))) for k in th}


def mean_nu(result: TeamMergeResult) -> float:
    top = result.top
    return top.nu_sum / max(len(top.checks), 1)


def local_cycle(maps: list[MapInput], params: MergeParams, tracked: TeamMergeResult, memo: Memo | None):
    """The tracked hypothesis's order re-aligned by local searches about its placements and verified."""
    t0, clock = time.perf_counter(), start_clock()
    names = [m.name for m in maps]
    place = team_placement(tracked)
    order = tuple(names.index(n) for n in tracked.chosen.order)
    onto0 = {names.index(n): p for n, p in place.items()}
    around = compose(onto0, 0, order[0])  # the placements onto the order's first map
    warps = Warps(maps)
    place0, steps, amb = align_order(maps, order, params, None, warps, memo, around=around)
    res = order_result(maps, order, params, place0, steps, warps, amb)
    chosen, merged, layers = None, None, {}
    if res.accepted:
        chosen, place0 = refine_chosen(maps, place0, warps, params, res)
        merged, layers = merged_on_frame0(maps, place0, warps)
    return TeamMergeResult(maps[0].name, (chosen or res,), chosen, merged, layers, (time.perf_counter() - t0) * 1e3,
                           "", (), memo.take_charged_ms() if memo is not None else 0.0, cpu_ms=clock.ms())


def merge_team_tracked(maps: list[MapInput], params: MergeParams, tracker: Tracker, now: float, *,
                       reuse: dict | None = None, memo: Memo | None = None) -> TeamMergeResult:
    """One merge cycle of the orders strategy under ``tracker`` (see the module notes)."""
    tr = tracker.track(TEAM)
    local, local_ok = None, False
    same_maps = tr.tracked is not None and set(tr.tracked.chosen.theta_deg) == {m.name for m in maps}
    if same_maps:
        if memo is not None:
            memo.take_charged_ms()
        local = local_cycle(maps, params, tr.tracked, memo)
        local_ok = local.accepted and mean_nu(local) >= tr.nu_ref - tracker.drop
        # as for a pair (merger.team.tree): a local answer that walked away from where the hypothesis was found
        local_ok = local_ok and tr.near_anchor(team_placement(local))
        if local_ok and not tracker.due(tr, maps, params.roi_m, now):
            tr.locals += 1
            tr.tracked, tr.placement = local, team_placement(local)
            tracker.accepted(tr, tr.placement)
            return local
    glob = merge_team(maps, params, reuse=reuse, memo=memo)
    tracker.searched(tr, maps, params.roi_m, now)
    if local is None and tr.tracked is not None and glob.accepted:
        tr.tracked = None  # the held maps are not the hypothesis's: the global answer starts the track
        tr.placement = None
    out = decide(tracker, TEAM, tr, local, local_ok, glob, glob.accepted, now,
                 team_placement, mean_nu)
    if out.accepted:
        tracker.accepted(tr, team_placement(out))
    return out
