"""circsim.events: what a run tells its observers — an observer overriding nothing runs, one recording
every hook gets start first, end last with the run's result, everything in simulated-time order, every
robot at every tick, maps received after their publication by the network's delay, and merge cycles
judged against the start poses' ground truth."""

from __future__ import annotations

import dataclasses
import math

import pytest

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.events import MergeCycle, Observer, RobotTick
from circsim.sim import Simulation
from merger.search import angle_diff_deg


class Recorder(Observer):
    def __init__(self):
        self.calls = []

    def on_start(self, sim):
        self.calls.append(("start", None, sim))

    def on_tick(self, t, step, ticks):
        self.calls.append(("tick", t, (step, ticks)))

    def on_map_published(self, t, robot, grid, center_given, center_true):
        self.calls.append(("pub", t, (robot, grid, center_given, center_true)))

    def on_map_received(self, t, recipient, sender, sent_s, stale=False):
        self.calls.append(("recv", t, (recipient, sender, sent_s, stale)))

    def on_merge_cycle(self, cycle):
        self.calls.append(("cycle", cycle.t, cycle))

    def on_event(self, t, level, text):
        self.calls.append(("event", t, (level, text)))

    def on_end(self, result):
        self.calls.append(("end", None, result))


@pytest.fixture(scope="module")
def run():
    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=4"])  # first merges ~2 s
    rec = Recorder()
    sim = Simulation(sc, [rec])
    result = sim.run()
    return sc, sim, result, rec.calls


def test_every_hook_of_the_base_observer_is_a_no_op():
    o = Observer()
    assert o.on_start(None) is None and o.on_tick(0.0, 0, []) is None and o.on_end(None) is None
    assert o.on_map_published(0.0, "a", None, (0, 0), (0, 0)) is None
    assert o.on_map_received(0.0, "a", "b", 0.0) is None and o.on_merge_cycle(None) is None
    assert o.on_hypothesis(0.0, "a", None) is None and o.on_event(0.0, "info", "x") is None
    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=0.5"])
    assert Simulation(sc, [Observer()]).run() is not None  # an observer of nothing does not disturb a run


def test_start_first_end_last_with_the_result_in_time_order(run):
    sc, sim, result, calls = run
    assert calls[0][0] == "start" and calls[0][2] is sim
    assert calls[-1][0] == "end" and calls[-1][2] is result
    assert sum(c[0] in ("start", "end") for c in calls) == 2
    times = [c[1] for c in calls[1:-1]]
    assert times == sorted(times)  # simulated-time order
    steps = [c[2][0] for c in calls if c[0] == "tick"]
    assert steps == list(range(len(steps))) and len(steps) >= 20


def test_every_tick_has_every_robot_on_its_circle(run):
    sc, sim, _, calls = run
    names = list(sc.robots.names)
    center = sc.world.center
    last_arc = dict.fromkeys(names, -1.0)
    for _, _t, (_, ticks) in (c for c in calls if c[0] == "tick"):
        assert [k.name for k in ticks] == names
        for k in ticks:
            assert isinstance(k, RobotTick) and len(k.true_pose) == len(k.est_pose) == 3
            r = math.hypot(k.true_pose[0] - center[0], k.true_pose[1] - center[1])
            assert r == pytest.approx(sc.robots.radius_m, abs=0.05)  # driving its circle
            assert k.arc_deg >= last_arc[k.name] - 1e-9  # arcs only grow
            last_arc[k.name] = k.arc_deg
    assert all(a > 0 for a in last_arc.values())
    with pytest.raises(dataclasses.FrozenInstanceError):
        ticks[0].arc_deg = 0.0


def test_maps_arrive_after_their_publication_by_the_networks_delay(run):
    sc, _, _, calls = run
    published = {(c[2][0], c[1]) for c in calls if c[0] == "pub"}
    received = [c for c in calls if c[0] == "recv"]
    assert received
    for _, t, (recipient, sender, sent, _) in received:
        assert (sender, sent) in published and recipient != sender
        assert t - sent >= sc.network.latency_s - 1e-9


def test_merge_cycles_are_judged_against_the_start_poses(run):
    sc, sim, _, calls = run
    cycles = [c[2] for c in calls if c[0] == "cycle"]
    assert cycles and all(isinstance(c, MergeCycle) for c in cycles)
    starts = {t.name: t.true_pose for t in next(c for c in calls if c[0] == "tick")[2][1]}
    tol = sc.merger.correct_tol_deg
    for c in cycles:
        top = c.result.top
        for k, th in c.truth_deg.items():
            # θ*_ij = yaw_j(0) − yaw_i(0): from the first tick's true poses
            assert abs(angle_diff_deg(th, math.degrees(starts[k][2] - starts[c.robot][2]))) < 1e-6
            assert c.angle_error_deg[k] == pytest.approx(abs(angle_diff_deg(top.theta_deg[k], th)), abs=1e-9)
        assert c.false_merge == (c.result.accepted and not c.correct)
        if c.correct:
            assert max(c.angle_error_deg.values()) <= tol + 1e-6
            assert max(c.translation_error_m.values()) <= sc.merger.correct_tol_m + 1e-6
    assert any(c.first_correct for c in cycles)  # scene 1 merges in its first seconds (README: by 5 s)
