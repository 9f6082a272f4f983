"""End-to-end runs of the bundled scenarios with real pymunk, checked against ground truth."""

import json
import math
import signal

import pytest

from circsim.cli import main
from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.events import Observer
from circsim.sim import Simulation

METRIC_KEYS = {"scenario", "seed", "params", "robots", "false_merges", "rejected_correct", "merge_cycle_ms",
               "realtime_factor"}
ROBOT_KEYS = {"first_merge_s", "first_merge_arc_deg", "final_angle_error_deg", "final_translation_error_m",
              "first_merge_translation_error_m"}


def scene(name, *sets):
    return load_scenario(bundled_scenarios()[name]).with_overrides(["merger.method=fast", *sets])


@pytest.mark.slow
@pytest.mark.parametrize("name", ["scene1", "scene2"])
def test_online_scene_merges_correctly_for_every_robot(name):
    sc = scene(name, "duration_s=20")
    cycles = []

    class Collect(Observer):
        def on_merge_cycle(self, c):
            cycles.append(c)

    sim = Simulation(sc, [Collect()])
    res = sim.run().to_dict()
    assert res["false_merges"] == 0
    for robot, r in res["robots"].items():
        assert r["first_merge_s"] is not None and r["first_merge_s"] <= sc.duration_s, robot
        assert 0 < r["first_merge_arc_deg"] < 90
    # the judged truth is the simulator's: θ*_ij = yaw_j(0) − yaw_i(0); re-derive it independently
    for c in cycles:
        if c.result.accepted:
            for j, th in c.result.chosen.theta_deg.items():
                true = math.degrees(sim.start_poses[j].yaw - sim.start_poses[c.robot].yaw)
                err = abs((th - true + 180) % 360 - 180)
                assert err <= sc.merger.correct_tol_deg, (c.t, c.robot, j, th, true)


@pytest.mark.slow
def test_four_robots_merge_in_all_six_orders():
    """The bench and the team merge are general in N: four robots, N(N−1)/2 = 6 orders per cycle of
    all four maps (a partial team's cycle merges the m < N maps it holds in m(m−1)/2 orders)."""
    sc = scene("scene1", "robots.names=[A,B,C,D]", "robots.start_angles_deg=[0,90,180,270]", "duration_s=6",
               "merger.strategy=orders")  # auto would take the tree for four robots
    orders = set()

    class Collect(Observer):
        def on_merge_cycle(self, c):
            orders.add((len(c.result.top.theta_deg), len(c.result.orders), c.complete))

    sim = Simulation(sc, [Collect()])
    res = sim.run().to_dict()
    assert (4, 6, True) in orders
    assert all(o == m * (m - 1) // 2 and complete == (m == 4) for m, o, complete in orders)
    assert res["false_merges"] == 0 and set(res["robots"]) == {"A", "B", "C", "D"}
    assert all(r["first_merge_s"] is not None for r in res["robots"].values())


@pytest.mark.slow
def test_same_scenario_and_seed_give_identical_metrics():
    def metrics():
        d = Simulation(scene("scene2", "duration_s=8")).run().to_dict()
        for k in ("wall_s", "realtime_factor", "merge_cycle_ms"):
            d.pop(k)
        return d

    a, b = metrics(), metrics()
    assert a == b
    c = Simulation(scene("scene2", "duration_s=8", "seed=99")).run().to_dict()
    assert c["params"] == a["params"] and c["seed"] == 99


@pytest.mark.slow
def test_reusing_unchanged_pair_alignments_changes_no_result():
    """Each robot reuses its own search of two unchanged maps (merger.team.online.TeamMerger.reuse); every
    merge cycle's evidence is the same as with every search done from scratch."""
    def run(reuse):
        cycles = []

        class Collect(Observer):
            def on_merge_cycle(self, c):
                cycles.append((c.t, c.robot, c.result.to_dict()["orders"], c.correct, c.first_correct))

        sim = Simulation(scene("scene1", "duration_s=8", "center_error.magnitude_m=0.05"), [Collect()])
        for r in sim.robots.values():
            r.merger.reuse = reuse
        d = sim.run().to_dict()
        for k in ("wall_s", "realtime_factor", "merge_cycle_ms"):
            d.pop(k)
        return d, cycles

    (a, ca), (b, cb) = run(True), run(False)
    assert a == b
    assert len(ca) == len(cb) > 10
    assert ca == cb


def test_interrupted_run_keeps_what_it_measured():
    class CtrlC(Observer):
        ended = None

        def on_tick(self, t, step, ticks):
            if step == 40:
                raise KeyboardInterrupt

        def on_end(self, result):
            CtrlC.ended = result

    res = Simulation(scene("scene1", "duration_s=20"), [CtrlC()]).run()
    assert res.interrupted and CtrlC.ended is res
    assert 3.5 <= res.sim_s < 4.1
    assert any(r.maps_published for r in res.robots.values())


def test_ctrl_c_stops_at_a_tick_boundary_so_every_observer_sees_the_same_events():
    """A real SIGINT delivered while the first observer (metrics) handles a merge cycle must not hide that
    cycle from the observers after it (the recorder): the run stops after the tick."""
    class PressCtrlC(Observer):  # runs right after metrics counted the cycle, before Count sees it
        def on_merge_cycle(self, cycle):
            if cycle.result.accepted:
                signal.raise_signal(signal.SIGINT)

    class Count(Observer):
        accepted = 0
        end_t = None

        def on_merge_cycle(self, cycle):
            Count.accepted += cycle.result.accepted
            Count.end_t = cycle.t

    outer = signal.getsignal(signal.SIGINT)  # a runner started with SIGINT ignored must not decide the test
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        res = Simulation(scene("scene1", "duration_s=20"), [PressCtrlC(), Count()]).run()
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, outer)
    assert res.interrupted and res.sim_s == pytest.approx(Count.end_t)
    assert sum(r.accepted for r in res.robots.values()) == Count.accepted > 0


@pytest.mark.slow
def test_out_of_order_maps_are_counted_as_stale_not_received():
    """With jitter as large as the send period, maps overtake each other: a map no newer than the one
    held is dropped (``maps_stale``); ``maps_received`` counts only the maps a robot took. Every send
    carries the map published in the same tick (both periods 2 s, same phase), so a map is stale
    exactly when one sent later arrived first."""
    class Deliveries(Observer):
        def __init__(self):
            self.newest, self.expect = {}, {}

        def on_map_received(self, t, recipient, sender, sent_s, stale=False):
            key = (recipient, sender)
            late = key in self.newest and sent_s <= self.newest[key]
            assert stale == late
            self.newest[key] = max(sent_s, self.newest.get(key, sent_s))
            self.expect.setdefault(recipient, [0, 0])[int(stale)] += 1

    obs = Deliveries()
    res = Simulation(scene("scene1", "duration_s=30", "network.jitter_s=2.0"), [obs]).run()
    for n, (fresh, stale) in obs.expect.items():
        assert (res.robots[n].maps_received, res.robots[n].maps_stale) == (fresh, stale)
    assert sum(r.maps_stale for r in res.robots.values()) > 0


def test_cli_run_json_has_every_field(tmp_path, capsys):
    out = tmp_path / "m.json"
    rc = main(["run", "scene1", "--set", "duration_s=6", "--set", "merger.method=fast", "--json", str(out),
               "--quiet"])
    text = capsys.readouterr().out
    assert rc == 0 and "first merge" in text
    d = json.loads(out.read_text())
    assert METRIC_KEYS <= set(d)
    assert set(d["robots"]) == {"Lyon", "Auckland", "Nevers"}
    for r in d["robots"].values():
        assert ROBOT_KEYS <= set(r)
    assert {"median", "p95"} <= set(d["merge_cycle_ms"])


@pytest.mark.parametrize("args, needle", [
    (["run", "nope.yaml"], "nope.yaml"),
    (["run", "scene1", "--set", "robots.speed_mps=fast"], "robots.speed_mps"),
    (["run", "scene1", "--set", "laser.colour=red"], "laser.colour"),
    (["run", "scene1", "--set", "novalue"], "key.path=value"),
    (["run", "scene1", "--rrd", "/proc/circsim-nope/run.rrd"], "cannot write the recording"),
    (["run", "scene1", "--json", "/proc/circsim-nope/m.json"], "cannot write the metrics JSON"),
    (["run", "scene1", "--set", "robots.motion=offline"], "circsim offline scene1"),
])
def test_cli_user_errors_exit_2_one_line(args, needle, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err and "Traceback" not in err


def test_offline_motion_travels_no_arc():
    """motion: offline keeps every robot at its start: a first merge happens at 0° of arc."""
    sc = scene("scene1", "robots.motion=offline", "duration_s=6")
    arcs = []

    class Collect(Observer):
        def on_tick(self, t, step, ticks):
            arcs.extend(k.arc_deg for k in ticks)

    res = Simulation(sc, [Collect()]).run().to_dict()
    assert arcs and set(arcs) == {0.0}
    merged = [r for r in res["robots"].values() if r["first_merge_s"] is not None]
    assert merged and all(r["first_merge_arc_deg"] == 0.0 for r in merged)


@pytest.mark.slow
@pytest.mark.parametrize("name, sets", [
    ("scene1", ("duration_s=8", "merger.window_m=0.5", "center_error.magnitude_m=0.25")),  # orders, windowed
    ("hall4", ("duration_s=8",)),  # tree
])
def test_sharing_searches_between_robots_changes_no_result(name, sets):
    """The robots of a run share the pair searches they would all compute (merger.team.memo): every merge
    cycle's evidence and every metric is the same as with each robot computing alone, the memo does share
    results, and a cycle that took shared results is charged their computing time."""
    def run(share):
        cycles = []

        class Collect(Observer):
            def on_merge_cycle(self, c):
                cycles.append((c.t, c.robot, c.result.to_dict()["orders"], c.correct, c.first_correct))
                costs.append((c.result.wall_ms, c.result.charged_ms))

        costs = []
        sim = Simulation(scene(name, *sets), [Collect()], share_searches=share)
        d = sim.run().to_dict()
        for k in ("wall_s", "realtime_factor", "merge_cycle_ms"):
            d.pop(k)
        return d, cycles, costs, sim.memo

    (a, ca, costs_a, memo), (b, cb, costs_b, none) = run(True), run(False)
    assert none is None and memo.shared > 0 and memo.computed > 0
    assert a == b
    assert len(ca) == len(cb) > 5 and ca == cb
    assert any(charged > 0 for _, charged in costs_a)
    assert all(charged == 0.0 for _, charged in costs_b)


@pytest.mark.slow
def test_cycles_beside_the_next_tick_tell_the_same_events_in_the_same_order_as_one_thread(monkeypatch):
    """A tick's merge cycles run while the next tick's robots scan; observers still see every event in
    the order a single thread gives (``MERGER_THREADS=1`` runs the cycles in their own tick), with the
    same results."""
    def events(threads):
        monkeypatch.setenv("MERGER_THREADS", threads)
        seen = []

        class Log(Observer):
            def on_tick(self, t, k, ticks):
                seen.append(("tick", k, tuple((r.name, r.est_pose) for r in ticks)))

            def on_map_received(self, t, recipient, sender, sent_s, stale=False):
                seen.append(("received", t, recipient, sender, sent_s, stale))

            def on_merge_cycle(self, c):
                seen.append(("cycle", c.t, c.robot, c.trigger, c.result.accepted, c.correct,
                             tuple(sorted(c.result.top.theta_deg.items())),
                             tuple(sorted(c.angle_error_deg.items())), c.first_correct))

        res = Simulation(scene("hall4", "duration_s=6", "merger.window_m=0.5", "merger.strategy=auto",
                               "center_error=0.15"), [Log()]).run()
        return seen, res.false_merges, {n: r.first_merge_s for n, r in res.robots.items()}

    one, two = events("1"), events("2")
    assert sum(e[0] == "cycle" for e in one[0]) > 10
    assert one == two


def test_the_world_computed_ahead_of_slow_cycles_tells_the_same_events(monkeypatch):
    """While a tick's merge cycles run, the main thread computes the world's next ticks (robots move, scan,
    map and publish: nothing there reads a merge). Made slow, the cycles leave it time to: the ticks it
    computed ahead, the maps they published and every cycle reach the observers as in one thread."""
    import time

    import circsim.sim as S
    from merger.team.online import TeamMerger

    cycle = TeamMerger.cycle

    def slow_cycle(self, *a, **k):
        time.sleep(0.03)
        return cycle(self, *a, **k)

    monkeypatch.setattr(TeamMerger, "cycle", slow_cycle)
    world_tick = S.Simulation._world_tick

    def events(threads):
        monkeypatch.setenv("MERGER_THREADS", threads)
        seen, ahead = [], []

        def counted(sim, k, t):
            ahead.append(k > sim.result.sim_s / sim.scenario.dt_s + 1.5)  # beyond the tick being stepped
            return world_tick(sim, k, t)

        monkeypatch.setattr(S.Simulation, "_world_tick", counted)

        class Log(Observer):
            def on_tick(self, t, k, ticks):
                seen.append(("tick", k, tuple((r.name, r.true_pose, r.est_pose, r.scan.ranges.tobytes())
                                              for r in ticks)))

            def on_map_published(self, t, robot, grid, center_given, center_true):
                seen.append(("published", t, robot, grid.states.tobytes(), center_given))

            def on_map_received(self, t, recipient, sender, sent_s, stale=False):
                seen.append(("received", t, recipient, sender, sent_s, stale))

            def on_merge_cycle(self, c):
                seen.append(("cycle", c.t, c.robot, c.trigger, c.result.accepted, c.correct,
                             tuple(sorted(c.result.top.theta_deg.items())), c.first_correct))

        res = Simulation(scene("hall4", "duration_s=5", "merger.window_m=0.5", "merger.strategy=tree",
                               "center_error=0.15"), [Log()]).run()
        return seen, res.to_dict()["false_merges"], sum(ahead)

    one, two = events("1"), events("2")
    assert one[2] == 0 and two[2] > 10  # one thread never runs ahead; beside slow cycles the world does
    assert sum(e[0] == "cycle" for e in one[0]) > 5 and sum(e[0] == "published" for e in one[0]) > 10
    assert one[:2] == two[:2]


def test_the_assembly_s_rejections_reach_the_metrics_and_the_run_log_once(monkeypatch):
    """Every tree cycle's consensus assembly (merger.team.consensus) is counted in the robot's metrics, and
    a rejected pair is told in the run log when it is newly rejected, not at every cycle."""
    import merger.team.tree as tree

    real = tree.assemble

    def with_a_rejection(*args, **kw):
        a = real(*args, **kw)
        a.rejected["X|Y"] = "inconsistent: injected"
        return a

    monkeypatch.setattr(tree, "assemble", with_a_rejection)
    events, cycles = [], {}

    class Collect(Observer):
        def on_event(self, t, level, text):
            events.append(text)

        def on_merge_cycle(self, c):
            cycles[c.robot] = cycles.get(c.robot, 0) + 1
            assert c.result.assembly is not None and "X|Y" in c.result.assembly.rejected

    d = Simulation(scene("hall4", "duration_s=5", "merger.strategy=tree"), [Collect()]).run().to_dict()
    assert cycles and all(n > 1 for n in cycles.values())
    for robot, n in cycles.items():
        assert d["robots"][robot]["assembly_inconsistent"] >= n  # every cycle counted
        told = [e for e in events if e.startswith(f"{robot}: pair X|Y rejected: inconsistent: injected")]
        assert len(told) == 1  # told once
        assert d["robots"][robot]["consistent_set"]


class _CycleLog(Observer):
    def __init__(self):
        self.cycles = []  # (t, robot, trigger)
        self.received = []  # (t, recipient, sender, stale)

    def on_merge_cycle(self, c):
        self.cycles.append((c.t, c.robot, c.trigger))
        self.placed = getattr(self, "placed", [])
        self.placed.append((c.t, c.robot, c.result.accepted and c.complete))

    def on_map_received(self, t, recipient, sender, sent_s, stale=False):
        self.received.append((t, recipient, sender, stale))


@pytest.mark.slow
def test_a_tree_robot_merges_at_most_once_per_cycle_period_and_no_map_is_skipped():
    """merger.cycle_period_s (default 0.5 s with the tree strategy): a robot's merge cycles are at least the
    period apart; maps arriving sooner wait and the next cycle names them in its trigger; with 0, a cycle
    comes in every tick that brought a map, as before — and then cycles closer than the period occur."""
    def run(*sets):
        log = _CycleLog()
        sim = Simulation(scene("hall4", "duration_s=8", *sets), [log])
        sim.run()
        return log, sim

    log, sim = run()
    assert {r.cycle_period_s for r in sim.robots.values()} == {0.5}
    by_robot = {}
    for t, n, trig in log.cycles:
        by_robot.setdefault(n, []).append((t, trig))
    assert len(by_robot) == 4
    waited = 0
    for n, cyc in by_robot.items():
        times = [t for t, _ in cyc]
        assert all(b - a >= 0.5 - 1e-9 for a, b in zip(times, times[1:], strict=False)), (n, times)
        # every fresh map the robot received is named by its next cycle's trigger: none is skipped
        for t, r, sender, stale in log.received:
            if r == n and not stale and times[0] <= t <= times[-1]:
                nxt = next((tc, trig) for tc, trig in cyc if tc >= t - 1e-9)
                assert sender in nxt[1].split(","), (n, t, sender, nxt)
                waited += nxt[0] > t + 1e-9
    assert waited > 0, "no map waited for a cycle"

    every, sim0 = run("merger.cycle_period_s=0")
    assert {r.cycle_period_s for r in sim0.robots.values()} == {0.0}
    times0 = {}
    for t, n, _ in every.cycles:
        times0.setdefault(n, []).append(t)
    assert any(b - a < 0.5 - 1e-9 for ts in times0.values() for a, b in zip(ts, ts[1:], strict=False))
    assert len(every.cycles) >= len(log.cycles)


@pytest.mark.slow
def test_a_tree_robot_that_placed_its_whole_team_merges_once_per_settled_period():
    """Once a robot's last cycle accepted a placement of its whole team (what it knows, not the truth), its
    next cycle comes ``Strategy.settled_period_s`` (2 s) later at the earliest; after any other cycle, 0.5 s.
    Until its first full merge the cycles are those of a fixed 0.5 s period, so every robot's first full
    merge is the same as with ``merger.cycle_period_s: 0.5`` (which keeps 0.5 s once placed); no map is skipped."""
    def run(*sets):
        log = _CycleLog()
        res = Simulation(scene("hall4", "duration_s=16", *sets), [log]).run()
        return log, res.to_dict()

    log, d = run()
    fixed, d_fixed = run("merger.cycle_period_s=0.5")
    gaps = {True: [], False: []}
    for n in {c[1] for c in log.placed}:
        mine = [(t, placed) for t, r, placed in log.placed if r == n]
        for (a, placed), (b, _) in zip(mine, mine[1:], strict=False):
            gaps[placed].append(b - a)
        times = [t for t, _ in mine]
        for t, r, sender, stale in log.received:
            if r == n and not stale and times[0] <= t <= times[-1]:
                nxt = next(trig for tc, rr, trig in log.cycles if rr == n and tc >= t - 1e-9)
                assert sender in nxt.split(","), (n, t, sender)
    assert gaps[True] and gaps[False], "both kinds of cycles must occur"
    assert min(gaps[True]) >= 2.0 - 1e-9 and min(gaps[False]) >= 0.5 - 1e-9
    assert min(gaps[False]) < 2.0 - 1e-9  # a robot still searching merges sooner
    first = {n: r["first_merge_s"] for n, r in d["robots"].items()}
    assert all(v is not None for v in first.values())
    assert first == {n: r["first_merge_s"] for n, r in d_fixed["robots"].items()}
    settled_fixed = [b - a for n in first for (a, p), (b, _) in zip(*(lambda m: (m, m[1:]))(
        [(t, placed) for t, r, placed in fixed.placed if r == n]), strict=False) if p]
    assert settled_fixed and min(settled_fixed) < 2.0 - 1e-9  # a number: that period, placed or not
    assert len(log.cycles) < len(fixed.cycles)


def test_the_thesis_orders_merge_at_every_new_map_by_default():
    """A three-robot scene (the thesis's orders under ``strategy: auto``) keeps a cycle per new map: its
    default cycle period is 0, so its runs are those of before the setting."""
    sim = Simulation(scene("scene1", "duration_s=1"))
    assert {r.merger.strategy for r in sim.robots.values()} == {"orders"}
    assert {r.cycle_period_s for r in sim.robots.values()} == {0.0}
    sim = Simulation(scene("scene1", "duration_s=1", "merger.cycle_period_s=0.7"))
    assert {r.cycle_period_s for r in sim.robots.values()} == {0.7}


def test_cycle_period_must_be_a_number_at_least_zero(capsys):
    assert main(["run", "hall4", "--set", "merger.cycle_period_s=-1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "merger.cycle_period_s" in err and ">= 0" in err
