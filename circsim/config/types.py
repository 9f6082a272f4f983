"""The scenario's sections as typed, frozen values — the configuration every bench module reads.

The contract: plain frozen dataclasses with their defaults and units, and nothing else: no loading, no
validation, no import of circsim or merger (the world, the laser, the SLAM and the network import their
configuration from here, so the loader in :mod:`circsim.config.scenario` can import them without a
cycle). Validation happens once, at the boundary (:mod:`circsim.config.scenario`,
:mod:`circsim.config.validate`); inside, these values are trusted. Where a default is the merger's
(the map thresholds), a test checks that the two agree.

* the world: :class:`Room`, :class:`Pillar`, :class:`Chair`, :class:`OverturnedChair`, :class:`Box`,
  :class:`WorldSpec`; the robots: :class:`RobotsSpec`, :class:`OfflineMotion`;
* the sensors and the SLAM: :class:`LaserConfig`, :class:`SlamConfig` (with :class:`OdometryConfig`,
  :class:`MatcherConfig`, :class:`DriftConfig`, :class:`LogOddsConfig`);
* the center error, the network and the outputs: :class:`CenterErrorSpec`, :class:`NetworkConfig`,
  :class:`OutputSpec`. The merger's settings (:class:`circsim.config.scenario.MergerSettings`) default to
  the merger's own constants, so they live with the loader.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

Vec2 = tuple[float, float]


@dataclass(frozen=True)
class Room:
    """Walls: a rectangle (``size_m`` [w, h] around ``center``) or explicit ``walls`` segments."""

    size_m: Vec2 | None = (8.0, 6.0)
    center: Vec2 | None = None
    walls: tuple[tuple[float, float, float, float], ...] = ()

    def wall_segments(self) -> tuple[tuple[float, float, float, float], ...]:
        """All walls as (ax, ay, bx, by)."""
        if self.size_m is None:
            return self.walls
        (cx, cy), (w, h) = self.center or (0.0, 0.0), self.size_m
        c = [(cx - w / 2, cy - h / 2), (cx + w / 2, cy - h / 2), (cx + w / 2, cy + h / 2),
             (cx - w / 2, cy + h / 2)]
        return tuple((*c[i], *c[(i + 1) % 4]) for i in range(4))


@dataclass(frozen=True)
class Pillar:
    center: Vec2
    radius: float = 0.2


@dataclass(frozen=True)
class Chair:
    """A chair of which only the four legs (circles on a square) are in the laser plane."""

    type: ClassVar[str] = "chair"
    center: Vec2
    yaw_deg: float = 0.0
    leg_spacing_m: float = 0.4
    leg_radius_m: float = 0.02


@dataclass(frozen=True)
class OverturnedChair:
    """A chair lying on its side: seat and back are two segments forming an L."""

    type: ClassVar[str] = "overturned_chair"
    center: Vec2
    yaw_deg: float = 0.0
    seat_m: float = 0.42
    back_m: float = 0.45


@dataclass(frozen=True)
class Box:
    type: ClassVar[str] = "box"
    center: Vec2
    size_m: Vec2 = (0.5, 0.5)
    yaw_deg: float = 0.0


@dataclass(frozen=True, eq=False)
class MapGrid:
    """A map world's cells as read from its file (the loader's, :mod:`circsim.config.mapworld`): ``states``
    (H, W) uint8, merger's cell codes (0 unknown, 1 free, 2 occupied: ``merger.grid.Cell``), row 0 at the
    lowest y (ROS order); ``resolution`` metres per cell; ``origin`` (x, y) of cell (0, 0)'s corner in
    the map frame. ``solid``: occupied or unknown (unknown is outside the building)."""

    FREE: ClassVar[int] = 1
    states: np.ndarray
    resolution: float
    origin: Vec2

    @property
    def solid(self) -> np.ndarray:
        return self.states != self.FREE


@dataclass(frozen=True)
class FloorplanSpec:
    """``world.generate``: a building generated from ``seed`` (:mod:`circsim.world.floorplan`): ``size_m``
    between the outer walls' centre lines (lower-left corner at (0, 0)), ``rooms`` rooms (the hall for the
    robots' circle included), ``corridors`` (1: a spine along the long axis; 2: and one crossing it) of
    ``corridor_m`` inside, doors ``door_m`` wide, walls ``wall_m`` thick, about ``furniture`` pieces per
    room, cells of ``resolution_m``."""

    kind: str = "floorplan"
    seed: int = 0
    size_m: Vec2 = (24.0, 16.0)
    rooms: int = 8
    corridors: int = 1
    corridor_m: float = 1.6
    door_m: float = 0.9
    wall_m: float = 0.15
    furniture: float = 3.0
    resolution_m: float = 0.05


@dataclass(frozen=True)
class WorldSpec:
    """The world: a ``room`` (rectangle or walls), a ``map`` file (a ROS map_server YAML, or an image
    of ``map_resolution_m`` cells; absolute once loaded) or a ``generate``d floor plan, whose cells
    ``map_grid`` holds; pillars and objects on top. Positions are in the room's or the map's frame, metres."""

    center: Vec2 = (0.0, 0.0)
    room: Room = Room()
    pillars: tuple[Pillar, ...] = ()
    objects: tuple[Chair | OverturnedChair | Box, ...] = ()
    map: str | None = None
    map_resolution_m: float | None = None
    generate: FloorplanSpec | None = None
    map_grid: MapGrid | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class OfflineMotion:
    max_deg: float = 60.0
    step_deg: float = 1.0


@dataclass(frozen=True)
class RobotsSpec:
    """The robots on the circle (see :mod:`circsim.world.motion` for the heading rules)."""

    names: tuple[str, ...] = ("Lyon", "Auckland", "Nevers")
    radius_m: float = 1.75
    start_angles_deg: tuple[float, ...] = (90.0, 210.0, 330.0)
    heading: str = "center"
    yaw_offsets_deg: tuple[float, ...] = (0.0, 0.0, 0.0)
    speed_mps: float = 0.2
    motion: str = "online"
    offline: OfflineMotion = OfflineMotion()
    body_radius_m: float = 0.18

@dataclass(frozen=True)
class CenterErrorSpec:
    """Error on the common center given to each robot, metres in its map frame."""

    magnitude_m: float = 0.0
    per_robot: dict[str, Vec2] = field(default_factory=dict)

    def vectors(self, names, rng: np.random.Generator) -> dict[str, Vec2]:
        """Each robot's error: ``per_robot`` if given, else ``magnitude_m`` in a direction from ``rng``."""
        angles = rng.uniform(0.0, 2.0 * math.pi, size=len(names))  # drawn for all: stable streams
        return {n: self.per_robot.get(n, (self.magnitude_m * math.cos(a), self.magnitude_m * math.sin(a)))
                for n, a in zip(names, angles, strict=True)}

@dataclass(frozen=True)
class OutputSpec:
    rrd: str | None = None
    scan_log_hz: float = 2.0
    json: str | None = None
    merged_log_period_s: float | None = None  # None: the SLAM publish period; 0: every accepted merge

@dataclass(frozen=True)
class LaserConfig:
    """Scanner parameters (defaults: Hokuyo URG-04LX).

    Parameters
    ----------
    fov_deg : field of view, centred on the robot's heading; 360 gives a full turn.
    beams : number of beams; 667 over 240° gives an increment of 0.36°.
    range_max_m, range_min_m : measurable range in metres.
    rate_hz : scan rate (the simulation step is chosen by the scenario's ``dt_s``).
    noise_std_m : standard deviation of additive Gaussian range noise on returns.
    noise_rel : ... and at least this fraction of the range (σ = max(noise_std_m, noise_rel · r)); the
        URG-04LX's datasheet accuracy is ±30 mm up to 1 m and ±3% of the range beyond. 0: constant σ.
    dropout : probability that a beam returns an erroneous reading (``NaN``).
    """

    fov_deg: float = 240.0
    beams: int = 667
    range_max_m: float = 5.6
    range_min_m: float = 0.02
    rate_hz: float = 10.0
    noise_std_m: float = 0.01
    dropout: float = 0.0
    noise_rel: float = 0.0

    @property
    def angle_increment(self) -> float:
        """Radians between beams (a full turn has no duplicate beam at +180°)."""
        fov = math.radians(self.fov_deg)
        return fov / self.beams if self.fov_deg >= 360.0 else fov / (self.beams - 1)

    @property
    def angle_min(self) -> float:
        return -math.radians(self.fov_deg) / 2.0

    @property
    def angle_max(self) -> float:
        return self.angle_min + (self.beams - 1) * self.angle_increment

    def angles(self) -> np.ndarray:
        """Beam angles in the laser frame, radians, ``angle_min + k * angle_increment``."""
        return self.angle_min + np.arange(self.beams) * self.angle_increment

@dataclass(frozen=True)
class NetworkConfig:
    """Map exchange parameters.

    period_s : how often robots send their map (used by the simulation loop; the thesis used 2 s).
    latency_s : smallest one-way delay.
    jitter_s : scale of the extra delay ``jitter_s * |N(0, 1)|`` added to the latency (never subtracted).
    loss : probability that a message is lost.
    """

    period_s: float = 2.0
    latency_s: float = 0.1
    jitter_s: float = 0.0
    loss: float = 0.0

SLAM_MODELS = ("scan_matching", "odometry_only")

@dataclass(frozen=True)
class DriftConfig:
    """Odometry drift as a random walk in the distance travelled.

    ``xy_m_per_m`` and ``yaw_deg_per_m`` are the standard deviations of the accumulated drift after
    1 m of travel; after L metres they are ``value * sqrt(L)``, whatever the step size.
    """

    xy_m_per_m: float = 0.005
    yaw_deg_per_m: float = 0.1


@dataclass(frozen=True)
class OdometryConfig:
    """Wheel-odometry noise of the ``scan_matching`` model: Probabilistic Robotics' α1–α4 (table 5.6) and
    amcl's α5 for the sideways slip of a holonomic base, in the corrected form σ = √(α·δ²).

    alpha1 : rotation noise from rotation (rad²/rad²); alpha2 : rotation noise from translation (rad²/m²);
    alpha3 : translation noise from translation (m²/m²); alpha4 : translation (and sideways) noise from
    rotation (m²/rad²); alpha5 : sideways noise from translation (m²/m²) — ROS amcl's ``odom_alpha1``–``5``.

    Defaults: the noise of ROS amcl's defaults (every ``odom_alpha`` 0.2 with its default models
    ``diff``/``omni``, which draw σ = α·δ², the form its ``*-corrected`` models fix: the ROS wiki warns
    that these need "a lot smaller" α) at amcl's own update step (``update_min_d`` 0.2 m,
    ``update_min_a`` π/6), written in the corrected form: α' = (0.2·δ)², 0.0016 for the terms in
    translation (δ = 0.2 m), 0.011 for those in rotation (δ = π/6). That is σ = 0.008 rad of yaw and
    8 mm per 0.2 m driven, as amcl assumes. Taking 0.2 itself in the corrected form (σ = 0.45·δ, about
    0.6° of yaw per 10 Hz scan) makes odometry nearly worthless: with eight robots on one circle, which
    all turn together and so look still to each other, the matcher then follows the formation instead
    of the room (hall8 drifted 7° in 3 s). The noise is drawn once per scan, so its effect over a path
    depends on ``dt_s``.
    """

    alpha1: float = 0.011
    alpha2: float = 0.0016
    alpha3: float = 0.0016
    alpha4: float = 0.011
    alpha5: float = 0.0016


@dataclass(frozen=True)
class MatcherConfig:
    """The scan matcher of the ``scan_matching`` model (:mod:`circsim.slam.scanmatch`).

    linear_window_m, angular_window_deg : the largest correlative window (± on each axis, ± in yaw):
        Cartographer's ``real_time_correlative_scan_matcher`` defaults (0.1 m, 20°). The window used is
        three standard deviations of the odometry's uncertainty since the last matched scan, within these
        caps, at least one cell and one angular step.
    max_points : scan points matched at most (every k-th valid return); Cartographer's adaptive voxel
        filter aims at 200.
    point_sigma_m : the standard deviation of a scan point's distance to the map's wall (the laser's
        noise and the map's own); it weighs the scan against the odometry: the refinement is the most
        probable pose given N such points and the odometry's prediction with its accumulated variance.
        0.03 m, measured on the bundled scenes (10-minute runs): 0.02 lets hall8's co-rotating
        teammates pull the poses (1.2° in 2 s), 0.05 trusts the odometry so much that hall4's poses ran
        away after five minutes (57 cm, 7.8°); at 0.03 hall4 held 8 cm / 1.2° for 7 minutes.
    min_log_odds : cells below this log-odds (of the matcher's copy, below) are not matched: 3.5, about
        five hits net of misses (half a second of a surface seen at every 10 Hz scan; the published map's
        clamp, so a cell as certain as the published map can hold it). While the map has fewer
        integrated scans the floor is 0.99·hit per scan integrated, so the first scans match what there
        is. This is what keeps teammates out of the match: a teammate that drives with the robot round
        the circle looks still to it, but in the map its body crosses a cell in about as many scans as
        the cell needs to reach the floor, and its trace is then cleared by the beams that pass through.
        Measured (SLAM only, 180–300 s, the scenarios' seeds): with 0.5 (one hit) the first seconds'
        matches against teammates' fresh traces lag behind the robot's turn, and the map's frame is
        baked in off by 0.9° (hall4) to 1.4° (hall8) within the first minute; with 3.5 both stay within
        0.8°. 6 and 10 measured the same within the seeds' spread. (Until 2026-12-02 a cell hit while the
        map held it free was never matched again; that rule also dropped the cells in front of every
        surface, where returns with negative noise land after grazing beams cleared them: the walls left
        lay ~3.5 mm behind the true surface on average and pulled every robot towards the objects in
        its view, 0.8 cm off on hall4's exact map. It is gone: the floor does its work.)
    evidence_clamp : the clamp of the matcher's own copy of the log-odds grid (the published map keeps
        ``log_odds.clamp``). gmapping keeps per-cell hit and visit counts without bound, so a wall seen
        for laps is not rewritten by a few scans at a slightly drifted pose; with the published map's
        clamp 3.5 (hit 0.85, miss −0.4) nine misses turn any wall cell free, the map follows the pose's
        small errors and the drift becomes self-consistent. 1000 (about 1200 hits: unbounded over a
        10-minute run, as gmapping's counts). Measured on hall4 (600 s, SLAM only, before the
        ``min_log_odds`` change): with 3.5 the worst pose error crept from 6.1 cm / 0.93° (minute 0) to
        7.8 cm / 1.30° (minute 9), hall8's from 6.6 cm / 1.42° to 17.5 cm / 1.75°; with 1000 they stay
        at their first lap's 5.9 cm / 1.08° and 6.9 cm / 1.56°, as with the map frozen after the first
        lap.
    """

    linear_window_m: float = 0.1
    angular_window_deg: float = 20.0
    max_points: int = 200
    point_sigma_m: float = 0.03
    min_log_odds: float = 3.5
    evidence_clamp: float = 1000.0


@dataclass(frozen=True)
class LogOddsConfig:
    """Inverse sensor model increments and the symmetric clamp |l| ≤ clamp."""

    hit: float = 0.85
    miss: float = -0.4
    clamp: float = 3.5


@dataclass(frozen=True)
class SlamConfig:
    """Grid and noise parameters of the synthetic SLAM.

    model : ``scan_matching`` (odometry corrected by matching each scan to the map) or
        ``odometry_only`` (the random-walk drift, never corrected: a stress option).
    resolution_m : cell size.
    size_m : side of the square grid, centred on the start pose (must hold the robot's circle plus
        the laser range that matters: the room).
    odometry, matcher : the ``scan_matching`` model's odometry noise and scan matcher.
    drift : the ``odometry_only`` model's random-walk drift.
    log_odds : inverse sensor model.
    occupied_thresh, free_thresh : probability thresholds to ternary (map_server's rule).
    publish_period_s : how often the robot publishes its map (used by the simulation loop; gmapping's
        ``map_update_interval``, default 5 s).
    linear_update_m, angular_update_rad : integrate a scan only after the robot has moved this far or
        turned this much since the last integrated one (gmapping's ``linearUpdate`` = 1.0 m and
        ``angularUpdate`` = 0.5 rad by default); the first scan is always integrated. 0 and 0 (the
        default here): every scan is integrated.
    """

    model: str = "scan_matching"
    resolution_m: float = 0.05
    size_m: float = 16.0
    odometry: OdometryConfig = field(default_factory=OdometryConfig)
    matcher: MatcherConfig = field(default_factory=MatcherConfig)
    drift: DriftConfig = field(default_factory=DriftConfig)
    log_odds: LogOddsConfig = field(default_factory=LogOddsConfig)
    occupied_thresh: float = 0.65  # merger.grid.DEFAULT_OCCUPIED_THRESH (a test checks)
    free_thresh: float = 0.196  # merger.grid.DEFAULT_FREE_THRESH
    publish_period_s: float = 2.0
    linear_update_m: float = 0.0
    angular_update_rad: float = 0.0
