"""merger.team.follow: the thesis's merge orders under the tracker, called directly — the first cycle is
the global search's answer, the next ones re-align the chosen order locally about it and stay on the
generated scene's truth, a different set of maps restarts the track, the staleness period forces a
global search again; the placements and mean ν it reads off a result."""

from __future__ import annotations

import math

import pytest

from merger.search import angle_diff_deg
from merger.team.follow import local_cycle, mean_nu, merge_team_tracked, team_placement
from merger.team.orders import MapInput, MergeParams, merge_team
from merger.team.track import Tracker

P = MergeParams(roi_m=8.0, research="on_change", research_period_s=10.0)


@pytest.fixture(scope="module")
def inputs(team_views):
    _, names, maps, truth = team_views
    return [MapInput(n, g, c) for n, (g, c) in zip(names, maps, strict=True)], truth


@pytest.fixture(scope="module")
def glob(inputs):
    res = merge_team(inputs[0], P)
    assert res.accepted
    return res


def _max_error(place, truth):
    return max(abs(angle_diff_deg(th, truth[n])) for n, (th, _) in place.items())


def test_team_placement_and_mean_nu_of_an_accepted_result(inputs, glob):
    maps, truth = inputs
    place = team_placement(glob)
    assert set(place) == {m.name for m in maps}
    assert _max_error(place, truth) <= 1.0
    assert place["Lyon"][0] == 0.0 and place["Lyon"][1] == (0.0, 0.0)  # the frame's own map
    assert all(isinstance(t, tuple) and len(t) == 2 for _, t in place.values())
    checks = glob.top.checks
    assert mean_nu(glob) == pytest.approx(sum(v.nu for v in checks.values()) / len(checks))
    assert 0.0 < mean_nu(glob) <= 1.0


def test_a_local_cycle_about_the_global_answer_reaches_the_same_placements(inputs, glob):
    maps, truth = inputs
    res = local_cycle(maps, P, glob, None)
    assert res.accepted
    assert all(a.method.endswith("-local") for _, a in res.chosen.steps)
    place, before = team_placement(res), team_placement(glob)
    assert _max_error(place, truth) <= 1.0
    for n, (th, t) in place.items():
        assert abs(angle_diff_deg(th, before[n][0])) <= 0.5 and math.dist(t, before[n][1]) <= 0.05


def test_the_tracked_cycles_follow_the_first_global_answer_until_it_is_stale(inputs, glob):
    maps, truth = inputs
    tracker = Tracker.from_params(P)
    first = merge_team_tracked(maps, P, tracker, 0.0)
    assert first.accepted and team_placement(first) == team_placement(glob)  # a global search: the same
    assert not any(a.method.endswith("-local") for _, a in first.chosen.steps)
    for now in (2.0, 5.0):
        res = merge_team_tracked(maps, P, tracker, now)
        assert res.accepted and all(a.method.endswith("-local") for _, a in res.chosen.steps)
        assert _max_error(team_placement(res), truth) <= 1.0
    assert tracker.track("team").locals == 2
    stale = merge_team_tracked(maps, P, tracker, 10.5)  # the period since the last global search is over
    assert stale.accepted and not any(a.method.endswith("-local") for _, a in stale.chosen.steps)
    assert _max_error(team_placement(stale), truth) <= 1.0
    assert tracker.track("team").locals == 2


def test_other_maps_than_the_hypothesiss_restart_the_track(inputs):
    maps, truth = inputs
    tracker = Tracker.from_params(P)
    assert merge_team_tracked(maps[:2], P, tracker, 0.0).accepted
    res = merge_team_tracked(maps, P, tracker, 1.0)  # a third map joined: no local cycle for it
    assert res.accepted and not any(a.method.endswith("-local") for _, a in res.chosen.steps)
    assert set(team_placement(res)) == {m.name for m in maps}
    assert _max_error(team_placement(res), truth) <= 1.0
    nxt = merge_team_tracked(maps, P, tracker, 2.0)  # now the track is the three maps' and is followed
    assert nxt.accepted and all(a.method.endswith("-local") for _, a in nxt.chosen.steps)
