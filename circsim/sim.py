"""The simulation loop: robots drive, scan, map, exchange maps and merge; observers watch.

One tick every ``dt_s`` (the laser rate): every robot moves along its circle, scans (other robots are
obstacles), integrates the scan into its SLAM grid; every ``slam.publish_period_s`` a robot publishes
its map to itself (a new own map) and every ``network.period_s`` it sends its newest map to its
teammates through the simulated network. Every tick, each robot that received any new map (its own or
a teammate's) runs one merge cycle with :class:`merger.TeamMerger` over everything it holds, once it
holds ``merger.min_maps`` maps (default 2: a partial team merges what it has); maps arriving in the same
tick share one cycle, and those arriving within ``merger.cycle_period_s`` of its last cycle wait for the
next (by default the strategy's period: 0.5 s for the tree, 2 s once the robot's last cycle accepted a
placement of its whole team; 0 for the thesis's orders). Each cycle is
judged against ground truth: the rotation θ*_ij = yaw_j(0) − yaw_i(0) and the translation
t*_ij = R(θ*_ij)·e_j − e_i, e_k being robot k's center error (:func:`truth_translation`, :func:`circsim.judge.judge_placement`).

With ``merger.share_hypotheses`` every robot also sends the alignment it holds with each map it sends,
over a second network of the same latency, jitter and loss (its own random stream, so that sharing does
not change the maps' deliveries); after the tick's merge cycles each robot weighs what arrived
(:meth:`merger.TeamMerger.consider`), and an adopted hypothesis is judged like an accepted cycle.

The tick's merge cycles (the robots' side by side on the merger's pool, :mod:`merger.team.pool`) run on a
thread of their own while the next tick's robots move, scan and map — and, while the cycles still run,
the ticks after it (up to ``LOOKAHEAD_TICKS``; the world never reads a merge; a cycle reads only maps
already published) —, and are judged and told to the observers before that tick's events: the same
events in the same order as one thread would give (with ``merger.share_hypotheses``, or
``MERGER_THREADS=1``, the cycles run in the tick itself).

Randomness: one ``numpy.random.SeedSequence(seed)`` is split into independent streams per purpose
and robot (laser noise, SLAM drift, network, center error, publish phases), so the same scenario and
seed give the same run, and changing e.g. the network does not change the laser noise.
"""

from __future__ import annotations

import math
import signal
import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from merger.algorithms.online import make_merger
from merger.team.memo import Memo
from merger.team.online import MapMessage, TeamMerger
from merger.team.orders import MergeParams
from merger.team.pool import parallel_map
from merger.team.pool import threads as merger_threads

from .config.scenario import Scenario, scenario_to_dict
from .events import MergeCycle, Observer, RobotTick
from .judge import JUDGE_EPS_DEG, JUDGE_EPS_M, judge_placement
from .metrics import CONSENSUS_TOL_DEG, MetricsObserver, RobotMetrics, RunResult
from .network import Network
from .slam.models import Slam
from .world.laser import scan as laser_scan
from .world.motion import CircleTrajectory, trajectories
from .world.world import World

LOOKAHEAD_TICKS = 20  # the world's ticks computed ahead while a tick's merge cycles run (Simulation._run_ahead)
PATH_PERIOD_S = 0.25  # a robot's path travels with its map (merger.team.consensus), one pose per this


@dataclass
class Robot:
    """A robot's parts: its trajectory, laser noise stream, SLAM, merger state and given center."""

    name: str
    traj: CircleTrajectory
    slam: Slam
    merger: TeamMerger
    center_given: tuple[float, float]
    center_true: tuple[float, float]
    laser_rng: np.random.Generator
    publish_phase_s: float
    next_publish_s: float = 0.0
    next_send_s: float = 0.0
    first_correct: bool = False
    first_pair_correct: bool = False
    teammates_placed: int = 0  # by the alignment it holds
    inbox_new: list[str] = field(default_factory=list)
    cycle_period_s: float = 0.0  # merger.cycle_period_s for its merger's strategy
    settled_period_s: float = 0.0  # the same once its last cycle accepted a placement of its whole team
    settled: bool = False  # whether it did (what the robot knows: no ground truth)
    last_cycle_s: float = -math.inf
    path: list[tuple[float, float, float]] = field(default_factory=list)  # (t, x, y) of its SLAM pose, map frame


def merge_params(sc: Scenario) -> MergeParams:
    """The scenario's merge parameters: every MergeParams setting of its ``merger`` section."""
    return sc.merger.params()


def truth_translation(theta_deg: float, e_i, e_j) -> tuple[float, float]:
    """True translation t*_ij of map j onto map i: R(θ*_ij)·e_j − e_i.

    With e_k = c_given_k − c_true_k (robot k's center error, in its map frame) and the true placement
    x_i − c_true_i = R(θ*)(x_j − c_true_j), the alignment x_i = c_given_i + t + R(θ*)(x_j − c_given_j)
    is exact for t = R(θ*)·e_j − e_i (θ* in degrees)."""
    a = math.radians(theta_deg)
    c, s = math.cos(a), math.sin(a)
    return (c * e_j[0] - s * e_j[1] - e_i[0], s * e_j[0] + c * e_j[1] - e_i[1])


def estimated_truth(frame_i, frame_j, c_i, c_j) -> tuple[float, tuple[float, float]]:
    """The alignment of map j onto map i that the maps *as built* call for: θ̂ (degrees in [0, 360)) and t̂
    about the given centers, from each map's frame as its SLAM built it (:meth:`circsim.slam.models.Slam.
    map_frame_estimate`, poses in W). With T = F_i⁻¹ ∘ F_j (map j's coordinates to map i's),
    x_i = c_i + t̂ + R(θ̂)(x_j − c_j) holds for θ̂ = yaw(T) and t̂ = R(θ̂)·c_j + p_T − c_i. With exact SLAM
    (F = the start poses) this is the start-frame truth (θ*, t*)."""
    yaw = frame_j[2] - frame_i[2]
    ci, si = math.cos(frame_i[2]), math.sin(frame_i[2])
    dx, dy = frame_j[0] - frame_i[0], frame_j[1] - frame_i[1]
    px, py = ci * dx + si * dy, -si * dx + ci * dy
    c, s = math.cos(yaw), math.sin(yaw)
    return math.degrees(yaw) % 360.0, (c * c_j[0] - s * c_j[1] + px - c_i[0], s * c_j[0] + c * c_j[1] + py - c_i[1])


def run_params(sc: Scenario) -> dict:
    """The parameters a sweep varies, flattened for the run record."""
    d = scenario_to_dict(sc)
    return {"center_error": d["center_error"], "network": d["network"], "merger": d["merger"],
            "duration_s": sc.duration_s, "dt_s": sc.dt_s, "motion": sc.robots.motion,
            "speed_mps": sc.robots.speed_mps, "radius_m": sc.robots.radius_m,
            "slam_model": sc.slam.model, "odometry": d["slam"]["odometry"], "drift": d["slam"]["drift"],
            "laser_noise_std_m": sc.laser.noise_std_m}


@dataclass
class _WorldTick:
    """One tick of the world (:meth:`Simulation._world_tick`): the robots' ticks and the maps published."""

    k: int
    ticks: list
    published: dict  # robot -> (MapMessage, its SLAM's map frame in W)


class Simulation:
    """A run of one scenario. ``Simulation(sc, observers).run()`` returns the :class:`RunResult`."""

    def __init__(self, scenario: Scenario, observers: list[Observer] = (), *, share_searches: bool = True) -> None:
        sc = self.scenario = scenario
        # the robots hold the same teammates' maps and would search the same pairs: each is computed once
        # and its time charged to every robot that takes it (merger.team.memo; results and metrics unchanged)
        n = len(sc.robots.names)  # entries: a few map versions of every pair (older ones are never asked again)
        self.memo = Memo(max(32, 3 * n * (n - 1))) if share_searches else None
        self.seed = int(sc.seed)
        self.robot_names = list(sc.robots.names)
        ss = np.random.SeedSequence(self.seed)
        streams = iter(ss.spawn(3 + 2 * len(self.robot_names)))
        self.network = Network(sc.network, np.random.default_rng(next(streams)))
        # spawned after the others: the existing streams stay what they were before sharing existed
        self.hypothesis_network = Network(sc.network, np.random.default_rng(ss.spawn(1)[0]))
        self.share = bool(sc.merger.share_hypotheses)
        self._consensus_told = False
        self._assembly_told: dict[str, tuple[set, set]] = {}  # per robot: rejected pairs, left-out maps last told
        # the last tick's merge cycles, running while this tick's robots scan: (t, [(robot, trigger)], future)
        self._pending = None
        self._cycles_thread: ThreadPoolExecutor | None = None
        self._ahead: deque[_WorldTick] = deque()  # the world's next ticks, computed while cycles ran
        self._last_k = -1  # the run's last tick (set by run: nothing is computed ahead before)
        self._stop = lambda: False  # Ctrl-C pressed (set by run)
        err_rng = np.random.default_rng(next(streams))
        phase_rng = np.random.default_rng(next(streams))
        self.world = World.from_scenario(sc)
        self.center_world = tuple(map(float, sc.world.center))
        self.circle_radius = float(sc.robots.radius_m)
        trajs = trajectories(sc)
        self.start_poses = {n: trajs[n].start_pose() for n in self.robot_names}
        errors = sc.center_error.vectors(self.robot_names, err_rng)
        params = merge_params(sc)
        self.robots: dict[str, Robot] = {}
        for n in self.robot_names:
            slam = Slam(sc.slam, self.start_poses[n], np.random.default_rng(next(streams)))
            c_true = tuple(float(v) for v in slam.true_to_map(np.array(self.center_world)))
            c_given = (c_true[0] + errors[n][0], c_true[1] + errors[n][1])
            phase = float(phase_rng.uniform(0.0, sc.slam.publish_period_s))
            tm = make_merger(sc.merger.algorithm, n, tuple(self.robot_names), params, min_maps=sc.merger.min_maps,
                             strategy=sc.merger.strategy, memo=self.memo)
            self.robots[n] = Robot(n, trajs[n], slam, tm, c_given,
                                   c_true, np.random.default_rng(next(streams)), phase,
                                   next_publish_s=phase, next_send_s=phase,
                                   cycle_period_s=sc.merger.cycle_period_for(tm.strategy),
                                   settled_period_s=sc.merger.cycle_period_for(tm.strategy, settled=True))
        self.centers_given = {n: r.center_given for n, r in self.robots.items()}
        # θ*_ij = yaw_j(0) − yaw_i(0): rotation of map j onto map i
        self.truth_deg = {i: {j: math.degrees(self.start_poses[j].yaw - self.start_poses[i].yaw) % 360.0
                              for j in self.robot_names} for i in self.robot_names}
        # t*_ij = R(θ*_ij)·e_j − e_i: translation of map j onto map i about the given centers
        self.center_errors = {n: (r.center_given[0] - r.center_true[0], r.center_given[1] - r.center_true[1])
                              for n, r in self.robots.items()}
        self.truth_translation_m = {i: {j: truth_translation(self.truth_deg[i][j], self.center_errors[i],
                                                             self.center_errors[j])
                                        for j in self.robot_names} for i in self.robot_names}
        # per robot, the frame its SLAM had built its map in (W) when it published it, by the map's stamp
        self.map_frames: dict[str, dict[float, tuple[float, float, float]]] = {n: {} for n in self.robot_names}
        self.result = RunResult(sc.name, self.seed, run_params(sc),
                                {n: RobotMetrics() for n in self.robot_names})
        self.observers = [MetricsObserver(self.result, self.arc_deg, cell_m=sc.slam.resolution_m,
                                          tol_deg=sc.merger.correct_tol_deg, tol_m=sc.merger.correct_tol_m),
                          *observers]

    def arc_deg(self, robot: str, t: float) -> float:
        """Degrees of its circle the robot has travelled by ``t`` (0 unless it drives: motion online)."""
        if self.scenario.robots.motion != "online":
            return 0.0
        return self.robots[robot].traj.arc_travelled_deg(t)

    def _emit(self, hook: str, *args) -> None:
        for o in self.observers:
            getattr(o, hook)(*args)

    def pose(self, robot: Robot, t: float):
        return robot.traj.pose_at(t) if self.scenario.robots.motion == "online" else robot.traj.start_pose()

    def _world_tick(self, k: int, t: float) -> _WorldTick:
        """Tick ``k`` (at ``t``) of the world alone: every robot moves, scans and maps, and publishes its map
        when its period has come (the map message, with its SLAM's frame). Nothing here reads a merge or
        the network, so ticks can be computed ahead of the merge cycles (:meth:`_run_ahead`)."""
        sc = self.scenario
        poses = {n: self.pose(r, t) for n, r in self.robots.items()}
        for n, p in poses.items():
            self.world.set_robot_pose(n, *p)
        ticks = []
        for n, r in self.robots.items():
            s = laser_scan(self.world, n, poses[n], r.laser_rng, config=sc.laser, stamp=t)
            est = r.slam.update(poses[n], s)
            if not r.path or t >= r.path[-1][0] + PATH_PERIOD_S - 1e-9:
                r.path.append((t, float(est[0]), float(est[1])))
            ticks.append(RobotTick(n, tuple(poses[n]), tuple(est), self._est_in_world(n, est),
                                   self.arc_deg(n, t), s))
        published = {}
        for n, r in self.robots.items():
            if t + 1e-9 >= r.next_publish_s and r.slam.updates:
                r.next_publish_s += sc.slam.publish_period_s
                published[n] = (MapMessage(n, t, r.slam.grid(), r.center_given, self._path_until(r, t)),
                                tuple(r.slam.map_frame_estimate()))
        return _WorldTick(k, ticks, published)

    def _run_ahead(self, k: int) -> None:
        """While the last tick's merge cycles run, the world's next ticks (at most :data:`LOOKAHEAD_TICKS`,
        not past the run's last tick): the main thread would otherwise wait idle. The world never reads a
        merge, so a tick computed ahead is the tick computed in its turn; its events are told in their
        turn."""
        pending = self._pending
        nxt = k + 1 + len(self._ahead)
        while (pending is not None and not pending[2].done() and len(self._ahead) < LOOKAHEAD_TICKS
               and nxt <= self._last_k):
            self._ahead.append(self._world_tick(nxt, nxt * self.scenario.dt_s))
            nxt += 1

    def step(self, k: int, t: float) -> bool:
        """One tick; False when Ctrl-C came while the last tick's cycles were told (the run then ends
        with that tick: nothing of this one reaches the observers)."""
        world = self._ahead.popleft() if self._ahead else self._world_tick(k, t)
        if world.k != k:
            raise RuntimeError(f"tick {k} stepped while tick {world.k} was next (the world runs ahead: step in order)")
        self._run_ahead(k)
        self._finish_merges()  # the last tick's cycles (they ran while these robots scanned)
        if self._stop():
            return False
        self._emit("on_tick", t, k, world.ticks)
        self._exchange(t, world.published)
        jobs = []
        for r in self.robots.values():
            period = r.settled_period_s if r.settled else r.cycle_period_s
            if r.inbox_new and t + 1e-9 >= r.last_cycle_s + period:  # sooner: the maps wait
                trigger = ",".join(dict.fromkeys(r.inbox_new))
                r.inbox_new.clear()
                if r.merger.ready():
                    r.last_cycle_s = t
                    jobs.append((r, trigger))
        if jobs and self._cycles_thread is not None:
            # the robots' cycles side by side on the merger's pool (each a pure function of what its robot
            # holds; told in robot order): a tick's cycles no longer run one after the other
            self._pending = (t, jobs, self._cycles_thread.submit(
                lambda: parallel_map(lambda job: job[0].merger.cycle(now=t), jobs)))
        else:
            for r, trigger in jobs:
                self._judge(r, t, trigger, r.merger.cycle(now=t))
        if self.share:
            self._weigh_hypotheses(t)
        return True

    def _finish_merges(self) -> None:
        """Judge the cycles started in the last tick (in robot order) and tell the observers."""
        pending, self._pending = self._pending, None
        if pending is not None:
            t, jobs, future = pending
            for (r, trigger), res in zip(jobs, future.result(), strict=True):
                self._judge(r, t, trigger, res)

    @staticmethod
    def _path_until(r: Robot, t: float) -> np.ndarray:
        """The path a map message carries: the robot's kept poses and, when the last is older, its pose
        estimate at the map's instant ``t`` (as a ROS robot's tf at the map's stamp): the path's last row is
        the instant the map shows (merger.team.teammates.map_time)."""
        path = np.array(r.path, np.float64)
        if path[-1, 0] < t - 1e-9:
            est = r.slam.estimated_pose()
            path = np.vstack([path, [t, est.x, est.y]])
        return path

    def _est_in_world(self, name: str, est) -> tuple[float, float, float]:
        s = self.start_poses[name]
        c, si = math.cos(s.yaw), math.sin(s.yaw)
        return (s.x + c * est[0] - si * est[1], s.y + si * est[0] + c * est[1], s.yaw + est[2])

    def _exchange(self, t: float, published: dict) -> None:
        """The tick's maps: each robot's own published map (``published``: per robot, its map message and
        its SLAM's frame, from :meth:`_world_tick`) and the network's sends and deliveries."""
        eps = 1e-9
        for n, r in self.robots.items():
            if n in published:
                msg, self.map_frames[n][t] = published[n]
                r.merger.receive(msg)
                r.inbox_new.append(n)
                self._emit("on_map_published", t, n, msg.grid, r.center_given, r.center_true)
            if t + eps >= r.next_send_s and n in r.merger.maps:
                r.next_send_s += self.scenario.network.period_s
                self.network.broadcast(n, self.robot_names, r.merger.maps[n], t)
                hyp = r.merger.hypothesis() if self.share else None
                if hyp is not None:
                    self.hypothesis_network.broadcast(n, self.robot_names, hyp, t)
        for n, r in self.robots.items():
            for m in self.network.deliver(n, t + eps):
                fresh = r.merger.receive(m.payload)
                if fresh:
                    r.inbox_new.append(m.sender)
                self._emit("on_map_received", t, n, m.sender, m.sent_s, not fresh)

    def _weigh_hypotheses(self, t: float) -> None:
        for n, r in self.robots.items():
            for m in self.hypothesis_network.deliver(n, t + 1e-9):
                a = r.merger.consider(m.payload, now=t)
                self._emit("on_hypothesis", t, n, a)
                if a.adopted:
                    self._judge(r, t, m.sender, a.result, adopted_from=m.sender)

    def _judge(self, r: Robot, t: float, trigger: str, res, adopted_from: str = "") -> None:
        """Judge a merge result against ground truth and tell the observers (a :class:`MergeCycle`)."""
        held = [k for k in r.merger.team if k in r.merger.maps]
        truth = {k: self.truth_deg[r.name][k] for k in held}
        truth_t = {k: self.truth_translation_m[r.name][k] for k in held}
        m = self.scenario.merger
        top = res.top
        found_t = {k: top.translation(k) for k in top.theta_deg}
        errors, t_errors, correct = judge_placement(top.theta_deg, found_t, truth, truth_t, m.correct_tol_deg,
                                                    m.correct_tol_m)
        est_truth, est_truth_t = {}, {}
        frame_i = self.map_frames[r.name][r.merger.maps[r.name].stamp]
        for k in held:
            est_truth[k], est_truth_t[k] = estimated_truth(frame_i, self.map_frames[k][r.merger.maps[k].stamp],
                                                           r.center_given, self.centers_given[k])
        est_errors, est_t_errors, est_correct = judge_placement(top.theta_deg, found_t, est_truth, est_truth_t,
                                                                m.correct_tol_deg, m.correct_tol_m)
        complete = len(top.theta_deg) == len(r.merger.team)
        first = res.accepted and correct and complete and not r.first_correct
        r.first_correct |= first
        first_pair = res.accepted and correct and not r.first_pair_correct
        r.first_pair_correct |= first_pair
        r.settled = bool(res.accepted and complete)
        if res.accepted:
            r.teammates_placed = sum(1 for k in top.theta_deg if k != r.name
                                     and errors[k] <= m.correct_tol_deg + JUDGE_EPS_DEG
                                     and t_errors[k] <= m.correct_tol_m + JUDGE_EPS_M)
        self._emit("on_merge_cycle", MergeCycle(t, r.name, trigger, res, truth, correct, errors, first,
                                                res.accepted and not correct, truth_translation_m=truth_t,
                                                translation_error_m=t_errors, complete=complete,
                                                first_pair_correct=first_pair,
                                                teammates_placed=r.teammates_placed, adopted_from=adopted_from,
                                                est_truth_deg=est_truth, est_angle_error_deg=est_errors,
                                                est_translation_error_m=est_t_errors, est_correct=est_correct,
                                                map_stamps={k: r.merger.maps[k].stamp for k in held}))
        self._tell_assembly(r, t, res)
        tracker = r.merger.tracker
        for when, text in tracker.take_events() if tracker is not None else ():
            self._emit("on_event", t, "info", f"{r.name}: {text} at {when:.1f} s")
        if self.result.consensus_s == t and not self._consensus_told:
            self._consensus_told = True
            self._emit("on_event", t, "info", f"CONSENSUS: every robot holds the same global alignment (within "
                                              f"{CONSENSUS_TOL_DEG:g}° and one cell) at {t:.1f} s")

    def _tell_assembly(self, r: Robot, t: float, res) -> None:
        """The run log's lines on the consensus assembly (merger.team.consensus): a measurement newly rejected
        or a map newly left out, with why; told when the robot's sets change, not every cycle."""
        asm = getattr(res, "assembly", None)
        if asm is None:
            return
        seen = self._assembly_told.setdefault(r.name, (set(), set()))
        for label, why in asm.rejected.items():
            if label not in seen[0]:
                self._emit("on_event", t, "info", f"{r.name}: pair {label} rejected: {why}")
        for name, why in asm.left_out.items():
            if name not in seen[1]:
                self._emit("on_event", t, "info", f"{r.name}: map {name} left out: {why}")
        self._assembly_told[r.name] = (set(asm.rejected), set(asm.left_out))

    def run(self) -> RunResult:
        """Run to ``duration_s``. Ctrl-C stops the run at the end of the current tick (so every observer
        has seen the same events); a second Ctrl-C interrupts at once."""
        sc = self.scenario
        n_steps = int(math.floor(sc.duration_s / sc.dt_s + 1e-9))
        self._last_k = n_steps
        self._emit("on_start", self)
        t0 = time.perf_counter()
        if not self.share and merger_threads() >= 2:
            self._cycles_thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="merge-cycles")
        try:
            with _sigint_at_tick_boundary() as stop:
                self._stop = stop
                for k in range(n_steps + 1):
                    t = k * sc.dt_s
                    if not self.step(k, t):
                        raise KeyboardInterrupt
                    self.result.sim_s = t
                    if stop():
                        raise KeyboardInterrupt
                self._finish_merges()
        except KeyboardInterrupt:
            self._finish_merges()  # the interrupted tick's cycles: every observer sees the whole tick
            self.result.interrupted = True
            self._emit("on_event", self.result.sim_s, "warn", "run interrupted (Ctrl-C)")
        finally:
            self._stop = lambda: False
            if self._cycles_thread is not None:
                self._cycles_thread.shutdown(wait=True)
                self._cycles_thread = None
            self.result.wall_s = time.perf_counter() - t0
        self.result.tracking = {n: r.merger.tracker.stats() for n, r in self.robots.items()
                                if r.merger.tracker is not None}
        self._emit("on_end", self.result)
        return self.result


@contextmanager
def _sigint_at_tick_boundary():
    """Within the block, the first SIGINT only sets a flag (read with the yielded callable); the second
    raises KeyboardInterrupt as usual. Outside the main thread (signals cannot be caught there) the flag
    is never set and Ctrl-C behaves as Python's default."""
    pressed = []
    if threading.current_thread() is not threading.main_thread() \
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield lambda: False  # someone else owns SIGINT (e.g. a sweep worker ignores it)
        return

    def handler(signum, frame):
        if pressed:
            raise KeyboardInterrupt
        pressed.append(True)

    signal.signal(signal.SIGINT, handler)
    try:
        yield lambda: bool(pressed)
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def run_scenario(scenario: Scenario, observers: list[Observer] = ()) -> RunResult:
    """Run ``scenario`` with ``observers`` and return its result."""
    return Simulation(scenario, observers).run()
