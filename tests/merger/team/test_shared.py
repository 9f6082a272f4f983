"""Shared hypotheses (issue 10, item 4): adoption only on the receiver's own evidence; the consensus metric."""

import json
import math
from dataclasses import replace
from types import SimpleNamespace

import pytest

from circsim.events import MergeCycle
from circsim.metrics import MetricsObserver, RobotMetrics, RunResult, in_consensus, spread
from merger.search import angle_diff_deg
from merger.team.frames import compose
from merger.team.online import MapMessage, TeamMerger
from merger.team.orders import MergeParams
from merger.team.shared import HypothesisMessage, reframe
from tests.strategies import three_views

P = MergeParams(roi_m=8.0)


@pytest.fixture(scope="module")
def team():
    """Lyon has merged the three maps; Auckland holds the same maps and has run no cycle."""
    _, names, maps, truth = three_views(3)
    lyon = TeamMerger("Lyon", tuple(names), P)
    auck = TeamMerger("Auckland", tuple(names), P)
    for n, (g, c) in zip(names, maps, strict=True):
        lyon.receive(MapMessage(n, 1.0, g, c))
        auck.receive(MapMessage(n, 1.0, g, c))
    assert lyon.cycle(now=1.0).accepted
    return names, maps, truth, lyon, auck


def fresh(names, maps, who="Auckland"):
    tm = TeamMerger(who, tuple(names), P)
    for n, (g, c) in zip(names, maps, strict=True):
        tm.receive(MapMessage(n, 1.0, g, c))
    return tm


def bent(msg: HypothesisMessage, name: str, d_deg: float) -> HypothesisMessage:
    """``msg`` with map ``name`` turned by ``d_deg`` more."""
    place = dict(msg.placements)
    th, t = place[name]
    place[name] = ((th + d_deg) % 360.0, t)
    return replace(msg, placements=place)


def test_a_verified_hypothesis_is_adopted_in_the_receivers_frame(team):
    names, maps, truth, lyon, _ = team
    auck = fresh(names, maps)
    msg = lyon.hypothesis()
    assert msg.robot == "Lyon" and msg.placements["Lyon"] == (0.0, (0.0, 0.0))
    json.dumps(msg.to_dict())
    a = auck.consider(msg, now=2.0)
    assert a.adopted and a.nu_sum_current is None and "none held" in a.reason, a.reason
    held = auck.current.chosen
    assert auck.current.frame == "Auckland" and held.theta_deg["Auckland"] == 0.0 and auck.adopted == 1
    expected = reframe(msg.placements, "Lyon", "Auckland")
    for n in names:  # Lyon's placements, expressed in Auckland's frame, and true there
        assert held.theta_deg[n] == expected[n][0] and held.translation(n) == expected[n][1]
        assert abs(angle_diff_deg(held.theta_deg[n], truth[n] - truth["Auckland"])) <= 1.0
    # verified on Auckland's maps: every pair, on Auckland's frame
    assert set(held.checks) == {"Auckland|Lyon", "Auckland|Nevers", "Lyon|Nevers"} and held.accepted
    assert auck.current.merged is not None and auck.current_stamp == 2.0
    json.dumps(a.to_dict())


@pytest.mark.parametrize("name, d_deg", [("Nevers", 180.0), ("Nevers", 25.0), ("Auckland", 90.0)])
def test_a_wrong_hypothesis_is_refused(team, name, d_deg):
    names, maps, _, lyon, _ = team
    auck = fresh(names, maps)
    a = auck.consider(bent(lyon.hypothesis(), name, d_deg))
    assert not a.adopted and "fails on Auckland's maps" in a.reason and "ν" in a.reason, a.reason
    assert auck.current is None and auck.adopted == 0


def test_a_better_verified_hypothesis_is_adopted_and_a_worse_one_is_not(team):
    names, maps, _, lyon, _ = team
    auck = fresh(names, maps)
    good = lyon.hypothesis()
    worse = bent(good, "Nevers", 0.3)  # 0.3° off: it still verifies, with a lower ν
    first = auck.consider(worse)
    assert first.adopted, first.reason
    better = auck.consider(good)
    assert better.adopted and better.nu_sum_received > better.nu_sum_current, better.reason
    again = auck.consider(worse)
    assert not again.adopted and "scores no higher" in again.reason
    assert again.nu_sum_received < again.nu_sum_current
    # Auckland's own hypothesis, sent back to it (by a robot that adopted it), scores the same: not adopted
    back = auck.hypothesis()
    back = HypothesisMessage("Nevers", back.stamp, reframe(back.placements, "Auckland", "Nevers"), back.nu,
                             back.nu_sum)
    same = auck.consider(back)
    assert not same.adopted and abs(same.nu_sum_received - same.nu_sum_current) < 1e-9
    assert auck.adopted == 2


def test_a_robot_whose_own_cycle_holds_a_hypothesis_compares_against_it(team):
    names, maps, _, lyon, _ = team
    auck = fresh(names, maps)
    own = auck.cycle(now=1.0)
    assert own.accepted
    a = auck.consider(bent(lyon.hypothesis(), "Nevers", 0.3))
    assert not a.adopted and a.nu_sum_current == pytest.approx(own.chosen.nu_sum, abs=1e-9)


def test_a_hypothesis_without_the_receiver_or_from_a_stranger(team):
    names, maps, _, lyon, _ = team
    auck = fresh(names, maps)
    msg = lyon.hypothesis()
    a = auck.consider(replace(msg, placements={k: v for k, v in msg.placements.items() if k != "Auckland"}))
    assert not a.adopted and "does not place Auckland" in a.reason
    with pytest.raises(ValueError, match="not a teammate"):
        auck.consider(replace(msg, robot="Oslo"))
    empty = TeamMerger("Auckland", tuple(names), P)
    assert "no map of its own" in empty.consider(msg).reason


# --- the consensus metric ----------------------------------------------------------------------------------
TEAM = ("A", "B", "C")
ON_A = {"A": (0.0, (0.0, 0.0)), "B": (30.0, (0.10, 0.0)), "C": (100.0, (0.0, 0.20))}


def held_by_all(on_a=ON_A):
    return {r: compose(on_a, "A", r) for r in TEAM}


def test_consensus_of_hand_made_placements():
    held = held_by_all()
    assert spread(held, TEAM) == pytest.approx((0.0, 0.0), abs=1e-9) and in_consensus(held, TEAM)
    for d_deg, d_m, agree in [(0.05, 0.0, True), (0.0, 0.04, True), (0.2, 0.0, False), (0.0, 0.06, False)]:
        h = dict(held)
        th, t = h["B"]["C"]
        h["B"] = {**h["B"], "C": (th + d_deg, (t[0] + d_m, t[1]))}
        assert in_consensus(h, TEAM, tol_deg=0.1, tol_m=0.05) is agree, (d_deg, d_m)
        s = spread(h, TEAM)
        assert math.isclose(s[0], d_deg, abs_tol=1e-9) and math.isclose(s[1], d_m, abs_tol=1e-9)
    partial = {**held, "C": {k: v for k, v in held["C"].items() if k != "B"}}
    assert spread(partial, TEAM) is None and not in_consensus(partial, TEAM)
    assert not in_consensus({k: v for k, v in held.items() if k != "C"}, TEAM)


def cycle(t, robot, placements, *, accepted=True, adopted_from=""):
    chosen = SimpleNamespace(theta_deg={k: v[0] for k, v in placements.items()},
                             translation=lambda k: placements[k][1])
    res = SimpleNamespace(accepted=accepted, chosen=chosen if accepted else None, wall_ms=1.0, cost_ms=1.0)
    return MergeCycle(t, robot, "x", res, {}, True, {k: 0.0 for k in placements}, False, False,
                      translation_error_m={k: 0.0 for k in placements}, adopted_from=adopted_from)


def test_the_observer_times_the_first_consensus_and_how_long_it_holds():
    run = RunResult("hand", 0, {}, {r: RobotMetrics() for r in TEAM})
    obs = MetricsObserver(run, lambda r, t: 0.0, cell_m=0.05)
    held = held_by_all()
    off = held_by_all({**ON_A, "C": (100.5, (0.0, 0.20))})  # C half a degree elsewhere
    obs.on_merge_cycle(cycle(1.0, "A", held["A"]))
    obs.on_merge_cycle(cycle(2.0, "B", held["B"]))
    obs.on_merge_cycle(cycle(3.0, "C", off["C"]))
    assert run.consensus_s is None
    obs.on_merge_cycle(cycle(4.0, "C", held["C"], accepted=False))  # a rejected cycle changes nothing held
    assert run.consensus_s is None
    obs.on_merge_cycle(cycle(5.0, "C", held["C"], adopted_from="A"))  # C adopts A's: consensus
    assert run.consensus_s == 5.0 and run.consensus_final
    assert run.robots["C"].cycles == 2 and run.robots["C"].accepted == 2  # the adoption is no cycle
    obs.on_merge_cycle(cycle(7.5, "B", off["B"]))
    assert not run.consensus_final
    obs.on_merge_cycle(cycle(9.0, "B", held["B"]))
    run.sim_s = 10.0
    obs.on_end(run)
    assert run.consensus_s == 5.0 and run.consensus_final and run.consensus_held_s == pytest.approx(2.5 + 1.0)
    d = run.to_dict()
    assert (d["consensus_s"], d["consensus_final"], d["consensus_held_s"]) == (5.0, True, pytest.approx(3.5))


# --- end to end -------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_sharing_end_to_end_on_scene1(tmp_path):
    """scene1, seed 1, 12 s: with sharing the robots weigh each other's hypotheses and adopt some, never a
    false one; they reach consensus no later than without (measured: 2.3 s both ways — the robots' first
    merges of the same first maps already agree); the maps travel exactly as without sharing (the
    hypotheses have their own random stream); the run is deterministic; the recording has the lines."""
    from circsim.cli import main
    from circsim.config.scenario import bundled_scenarios, load_scenario
    from circsim.record.jsonout import rounded
    from circsim.record.viewer import read_recording
    from circsim.sim import Simulation

    def run(share):
        sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(
            ["duration_s=12", f"merger.share_hypotheses={share}"])
        d = rounded(Simulation(sc).run().to_dict())  # as the JSON file writes its floats
        for k in ("wall_s", "realtime_factor", "merge_cycle_ms"):
            d.pop(k)
        return d

    off = run("false")
    rrd, js = tmp_path / "share.rrd", tmp_path / "share.json"
    assert main(["run", "scene1", "--set", "duration_s=12", "--set", "merger.share_hypotheses=true",
                 "--rrd", str(rrd), "--json", str(js), "--quiet"]) == 0
    on = json.loads(js.read_text())
    assert all(r["hypotheses_received"] == 0 for r in off["robots"].values())
    assert all(r["hypotheses_received"] > 0 for r in on["robots"].values())
    assert sum(r["hypotheses_adopted"] for r in on["robots"].values()) > 0
    assert on["false_merges"] == 0 == off["false_merges"]
    assert off["consensus_s"] is not None and on["consensus_s"] is not None
    assert on["consensus_s"] <= off["consensus_s"]
    for n, r in on["robots"].items():
        assert (r["maps_received"], r["maps_stale"]) == (off["robots"][n]["maps_received"],
                                                         off["robots"][n]["maps_stale"])
    again = run("true")
    assert {k: v for k, v in again.items() if k != "outputs"} == {k: v for k, v in on.items() if k in again and k != "outputs"}
    rec = read_recording(rrd)
    events = {n: [r["TextLog:text"][0] for r in rec[f"/events/{n}"] if not r["static"]] for n in on["robots"]}
    adopted = sum(x.startswith("adopted ") and "'s hypothesis: θ" in x for ev in events.values() for x in ev)
    assert adopted == sum(r["hypotheses_adopted"] for r in on["robots"].values())
    assert any(x.startswith("refused ") for ev in events.values() for x in ev)
    sim_events = [r["TextLog:text"][0] for r in rec["/events/sim"] if not r["static"]]
    assert sum(x.startswith("CONSENSUS: every robot holds the same global alignment") for x in sim_events) == 1
