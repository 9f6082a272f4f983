"""What a simulation run tells its observers (metrics, recording, progress).

The simulation loop (:mod:`circsim.sim`) knows nothing of rerun or files: it calls these hooks on
every observer it was given, in simulated-time order. Every hook has a no-op default, so an observer
implements only what it needs (Gymnasium-style composition instead of flags inside the loop).

Frames: world quantities are in the world frame W (metres, y up); a robot's map, SLAM pose and given
center are in its own map frame M_i (its start pose in W), see DESIGN.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from merger.grid import OccupancyGrid
from merger.team.orders import TeamMergeResult


@dataclass(frozen=True, eq=False)
class RobotTick:
    """One robot at one laser tick."""

    name: str
    true_pose: tuple[float, float, float]  # (x, y, yaw) in W
    est_pose: tuple[float, float, float]  # SLAM estimate (x, y, yaw) in M_i
    est_pose_world: tuple[float, float, float]  # the SLAM estimate drawn in W via the true start pose
    arc_deg: float  # degrees travelled on the circle so far
    scan: object  # circsim.world.laser.LaserScan


@dataclass(frozen=True, eq=False)
class MergeCycle:
    """One merge cycle of one robot, judged against ground truth.

    truth_deg : true rotation of every map onto the merging robot's frame (θ*_ij = yaw_j(0) − yaw_i(0)).
    correct : for the accepted hypothesis (or, if none, the best one): every angle error
        ≤ ``correct_tol_deg`` and every translation error ≤ ``correct_tol_m``.
    angle_error_deg : per map, |wrap(θ − θ*)| of that hypothesis.
    truth_translation_m : true translation of every map onto the merging robot's frame about the given
        centers, t*_ij = R(θ*_ij)·e_j − e_i (e_k: robot k's center error in its map frame), metres.
    translation_error_m : per map, |t − t*| (Euclidean, metres) of that hypothesis (x_i = c_i + t +
        R(θ)(x_j − c_j)); a rotation-only search has t = 0, so its error is |t*|.
    complete : the cycle merged every teammate's map (a partial team merges the maps it holds, ≥ 2).
    first_pair_correct : this cycle is the robot's first accepted correct merge of any ≥ 2 maps.
    teammates_placed : teammates that the alignment the robot holds after this cycle (accepted now or
        kept from earlier) places correctly, each within both tolerances.
    adopted_from : not a merge cycle of the robot's own but a teammate's hypothesis it adopted (shared
        hypotheses, :mod:`merger.team.shared`): the sender's name; "" for the robot's own cycles.
    est_truth_deg, est_angle_error_deg, est_translation_error_m, est_correct : the same judgement against
        the *estimated-frame* truth: the alignment the maps as their SLAMs built them call for (from the
        SLAMs' pose estimates when the held maps were published, :func:`circsim.sim.estimated_truth`). A
        placement wrong against the start frames but right here is limited by the SLAM's drift, not the
        merger's.
    map_stamps : per map held, its stamp (the version merged): a map version's latency to its first
        accepted merge is the cycle's time minus it (``RunResult.latency_s``).
    """

    t: float
    robot: str
    trigger: str  # name of the robot whose new map triggered the cycle
    result: TeamMergeResult
    truth_deg: dict[str, float]
    correct: bool
    angle_error_deg: dict[str, float]
    first_correct: bool  # this cycle is the robot's first accepted correct merge
    false_merge: bool  # accepted but not correct
    truth_translation_m: dict[str, tuple[float, float]] = field(default_factory=dict)
    translation_error_m: dict[str, float] = field(default_factory=dict)
    complete: bool = True
    first_pair_correct: bool = False
    teammates_placed: int = 0
    adopted_from: str = ""
    est_truth_deg: dict[str, float] = field(default_factory=dict)
    est_angle_error_deg: dict[str, float] = field(default_factory=dict)
    est_translation_error_m: dict[str, float] = field(default_factory=dict)
    est_correct: bool = True
    map_stamps: dict[str, float] = field(default_factory=dict)  # the stamp of every map held (its version)


class Observer:
    """Base class of run observers; override the hooks you need."""

    def on_start(self, sim) -> None:
        """Called once before the first tick; ``sim`` exposes scenario, world, robots, truth."""

    def on_tick(self, t: float, step: int, ticks: list[RobotTick]) -> None:
        """Every laser tick (all robots)."""

    def on_map_published(self, t: float, robot: str, grid: OccupancyGrid,
                         center_given: tuple[float, float], center_true: tuple[float, float]) -> None:
        """A robot published its SLAM map (its frame); ``center_given`` includes the injected error."""

    def on_map_received(self, t: float, recipient: str, sender: str, sent_s: float, stale: bool = False) -> None:
        """A teammate's map arrived over the network (delay = t − sent_s); ``stale``: the map held from that
        teammate is as new or newer (out-of-order or repeated delivery), so this one was dropped."""

    def on_merge_cycle(self, cycle: MergeCycle) -> None:
        """A robot ran a merge cycle (or adopted a teammate's hypothesis: ``cycle.adopted_from``)."""

    def on_hypothesis(self, t: float, recipient: str, adoption) -> None:
        """A teammate's hypothesis arrived (shared hypotheses) and was weighed: ``adoption`` is a
        :class:`merger.team.shared.Adoption` (adopted or refused, and why)."""

    def on_event(self, t: float, level: str, text: str) -> None:
        """A human-readable event (level: "info", "warn", "error")."""

    def on_end(self, result) -> None:
        """The run finished (or was interrupted); ``result`` is the :class:`circsim.metrics.RunResult`."""
