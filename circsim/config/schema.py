"""The scenario's sections, key by key: what each key of the world, the robots, the laser, the SLAM, the
center error, the network and the outputs must be (a check of :mod:`circsim.config.validate` per key).

The ``*_SCHEMA`` tables are what the loader (:mod:`circsim.config.scenario`) checks a section with and
what the reference (:mod:`circsim.config.reference_doc`) prints; a check raises
:class:`~circsim.config.validate.Invalid` naming the key path. The physical ranges (the laser, the
odometry, the matcher, the drift, the tick) name their source, a datasheet or a ROS package's default, in
the check's ``why``. Three sections are checked beyond their keys, one function each:
:func:`world_section` (a rectangular room or walls, not both, or a map file; the room centred on
``world.center`` unless given), :func:`robots_section` (unique printable names; start angles spread evenly from 90° when
names other than three come without them; one start angle and yaw offset per robot; bodies of at least
:data:`MIN_BODY_RADIUS_M` that do not overlap at their starts; at most :data:`MAX_SPEED_MPS`) and
:func:`center_error_section` (errors of known robots, each within half the ROI). What spans sections
(the circle in the map, the grid and tick limits, the ROI in cells, the scene's geometry) is the
loader's, and so is the merger section, beside its type (:class:`~circsim.config.scenario.MergerSettings`).
"""

from __future__ import annotations

import math
import unicodedata

from .floorplanworld import GENERATE
from .types import (
    SLAM_MODELS,
    Box,
    CenterErrorSpec,
    Chair,
    DriftConfig,
    LaserConfig,
    LogOddsConfig,
    MatcherConfig,
    NetworkConfig,
    OdometryConfig,
    OfflineMotion,
    OutputSpec,
    OverturnedChair,
    Pillar,
    RobotsSpec,
    Room,
    SlamConfig,
    WorldSpec,
)
from .validate import (
    Invalid,
    bad,
    choice,
    integer,
    join,
    number,
    optional,
    optional_path,
    section,
    seq,
    string,
    vec2,
)

MAX_BEAMS = 100_000
MAX_SPEED_MPS = 2.0  # a robot mapping a room indoors; faster, its scans blur and the laser SLAM is meaningless
MIN_BODY_RADIUS_M = 0.05  # a robot's body: at least 10 cm across (a 1 µm circle is a typo)

POSITIVE, NON_NEGATIVE = number(gt=0), number(ge=0)
OBJECT_SCHEMAS = {
    "chair": section(Chair, {"type": string, "center": vec2(), "yaw_deg": number(), "leg_spacing_m": POSITIVE,
                             "leg_radius_m": POSITIVE}, required=("center",)),
    "overturned_chair": section(OverturnedChair, {"type": string, "center": vec2(), "yaw_deg": number(),
                                                  "seat_m": POSITIVE, "back_m": POSITIVE}, required=("center",)),
    "box": section(Box, {"type": string, "center": vec2(), "size_m": vec2(gt=0), "yaw_deg": number()},
                   required=("center",)),
}


def _object(v, path):
    kind = v.get("type") if isinstance(v, dict) else None
    if not isinstance(kind, str) or kind not in OBJECT_SCHEMAS:  # (a list or mapping is not a type name)
        raise Invalid(join(path, "type") if isinstance(v, dict) else path,
                      f"expected an object type, one of {', '.join(map(repr, OBJECT_SCHEMAS))}, got {kind!r}")
    return OBJECT_SCHEMAS[kind](v, path)


_SEG = seq(number(), "a wall [ax, ay, bx, by] of four numbers", length=4)
ROOM_SCHEMA = {"size_m": vec2(gt=0), "center": vec2(), "walls": seq(_SEG, "a list of walls [ax, ay, bx, by]", 1)}


def _map_path(v, path):
    if not isinstance(v, str) or not v:
        raise bad(path, "a string, the path of a map file", v)
    return v


_map_path.expected = ("the path of a ROS map_server YAML (relative to the scenario file; its occupied and "
                      "unknown cells are solid, positions are in its frame) or of an image with "
                      "world.map_resolution_m (lower-left corner at (0, 0)); not with world.room")
_PILLAR = section(Pillar, {"center": vec2(), "radius": POSITIVE}, required=("center",))
WORLD_SCHEMA = {"center": vec2(), "room": lambda v, path: v, "pillars": seq(_PILLAR, "a list of pillars"),
          "objects": seq(_object, "a list of objects"), "map": _map_path, "generate": GENERATE,
          "map_resolution_m": number(ge=0.001, le=1, why="an image's cell size: map_server maps are 1–10 cm "
                                     "(gmapping and Cartographer save 5 cm)")}
ROBOTS_SCHEMA = {"names": seq(string, "a list of robot names", 1), "radius_m": POSITIVE,
           "start_angles_deg": seq(number(), "a list of numbers"), "heading": choice("center", "tangent"),
           "yaw_offsets_deg": seq(number(), "a list of numbers"), "speed_mps": POSITIVE,
           "motion": choice("online", "offline"),
           "offline": section(OfflineMotion, {"max_deg": number(gt=0, le=180), "step_deg": POSITIVE}),
           "body_radius_m": POSITIVE}
# Physical ranges: what a real robot's laser and odometry can be (the source is each check's `why`, which
# the scenario reference prints). Beyond them a run measures nothing real (issue 37: a laser σ of 10⁶ m made
# 19 false merges in 5 s, alphas of 10⁶ a SLAM error of 331 m, a 1 nm range an empty map) or never ends
# (a 100 m matcher window, 10⁶ ticks).
DT_S = number(ge=0.01, le=1, why="one scan per tick: 2D lidars scan at 1–100 Hz (RPLIDAR A1 5.5 Hz, "
              "URG-04LX 10 Hz, UTM-30LX 40 Hz, SICK LMS1xx 50 Hz)")
ALPHA = number(ge=0, le=0.2, why="ROS amcl's default odom_alpha 0.2 taken in the corrected form: σ = 0.45·δ "
                "per scan, odometry already nearly worthless (types.OdometryConfig)")
LASER_SCHEMA = section(LaserConfig, {
    "fov_deg": number(gt=0, le=360), "beams": integer(ge=2, le=MAX_BEAMS),
    "range_max_m": number(ge=1, le=100, why="LDS-01 (TurtleBot3) 3.5 m, URG-04LX 5.6 m, UTM-30LX 30 m, "
                          "SICK LMS511 80 m, Velodyne VLP-16 100 m"),
    "range_min_m": number(ge=0, le=1, why="URG-04LX 0.02 m, UTM-30LX 0.1 m, LDS-01 0.12 m, RPLIDAR A1 0.15 m"),
    "rate_hz": number(ge=1, le=100, why="as dt_s (which sets the scan rate)"),
    "noise_std_m": number(ge=0, le=0.2, why="URG-04LX ±30 mm; ROS amcl's laser_sigma_hit default 0.2 m, a "
                          "deliberately wide sensor model"),
    "dropout": number(ge=0, le=0.5, why="amcl's laser_z_max and laser_z_rand 0.05 each: a laser loses a few "
                      "per cent of its beams (more on glass and black surfaces)"),
    "noise_rel": number(ge=0, le=0.1, why="URG-04LX ±3 % of the range beyond 1 m, LDS-01 ±5 % beyond 0.5 m")})
SLAM_SCHEMA = section(SlamConfig, {
    "model": choice(*SLAM_MODELS), "size_m": POSITIVE,
    "resolution_m": number(ge=0.01, le=0.5, why="gmapping's delta 0.05 m, Cartographer's 0.05 m; 1–50 cm "
                           "grids are used"),
    "odometry": section(OdometryConfig, {f"alpha{k}": ALPHA for k in range(1, 6)}),
    "matcher": section(MatcherConfig, {
        "linear_window_m": number(ge=0, le=0.5, why="Cartographer's real-time matcher 0.1 m; slam_toolbox's "
                                  "correlation_search_space_dimension 0.5 m"),
        "angular_window_deg": number(ge=0, le=45, why="Cartographer's real-time matcher 20°, its constraint "
                                     "builder 30°"),
        "max_points": integer(ge=3, le=MAX_BEAMS), "point_sigma_m": POSITIVE, "min_log_odds": NON_NEGATIVE,
        "evidence_clamp": POSITIVE}),
    "drift": section(DriftConfig, {
        "xy_m_per_m": number(ge=0, le=0.1, why="gmapping's srr 0.1 (translation error per translation)"),
        "yaw_deg_per_m": number(ge=0, le=5.7, why="gmapping's str 0.1 rad (rotation error per metre)")}),
    "log_odds": section(LogOddsConfig, {"hit": POSITIVE, "miss": number(lt=0), "clamp": POSITIVE}),
    "occupied_thresh": number(gt=0, lt=1), "free_thresh": number(gt=0, lt=1), "publish_period_s": POSITIVE,
    "linear_update_m": NON_NEGATIVE, "angular_update_rad": NON_NEGATIVE})
NETWORK_SCHEMA = section(NetworkConfig, {"period_s": POSITIVE, "latency_s": NON_NEGATIVE, "jitter_s": NON_NEGATIVE,
                                   "loss": number(ge=0, lt=1)})
OUTPUT_SCHEMA = section(OutputSpec, {"rrd": optional_path, "scan_log_hz": POSITIVE, "json": optional_path,
                               "merged_log_period_s": optional(NON_NEGATIVE)})


def world_section(v) -> WorldSpec:
    w = section(lambda **kw: kw, WORLD_SCHEMA)(v, "world")  # room is checked below: it needs the center
    center = w.get("center", WorldSpec.center)
    if "generate" in w:
        other = [k for k in ("room", "map", "map_resolution_m") if k in w]
        if other:
            raise Invalid(f"world.{other[0]}", "expected either world.generate or world." + other[0] +
                          ", not both (a generated world's walls are its plan's)")
        return WorldSpec(w.get("center"), Room(None, None, ()), w.get("pillars", ()), w.get("objects", ()),
                         generate=w["generate"])  # center None: the generator chooses it
    if "map" in w:
        if "room" in w:
            raise Invalid("world.room", "expected either world.room or world.map, not both (a map world's "
                          "walls are its map's occupied and unknown cells)")
        return WorldSpec(center, Room(None, None, ()), w.get("pillars", ()), w.get("objects", ()),
                         w["map"], w.get("map_resolution_m"))
    if "map_resolution_m" in w:
        raise Invalid("world.map_resolution_m", "expected only with world.map (an image's cell size)")
    room = w.get("room") or {}
    if not isinstance(room, dict):
        raise bad("world.room", "a mapping with size_m and center, or walls", room)
    r = section(lambda **kw: kw, ROOM_SCHEMA)(room, "world.room")
    if "walls" in r and ("size_m" in r or "center" in r):
        raise Invalid("world.room", "expected either size_m (and center) or walls, not both")
    room_obj = Room(None, None, r["walls"]) if "walls" in r else \
        Room(r.get("size_m", Room.size_m), r.get("center", center))
    return WorldSpec(center, room_obj, w.get("pillars", ()), w.get("objects", ()))


def robots_section(v) -> RobotsSpec:
    r = section(lambda **kw: kw, ROBOTS_SCHEMA)(v, "robots")
    names = r.get("names", RobotsSpec.names)
    for i, name in enumerate(names):  # names head the summary's rows and the recording's entities
        if not name.strip() or any(unicodedata.category(ch) == "Cc" for ch in name):
            raise bad(f"robots.names[{i}]", "a name of printable characters (not empty; no newline, tab or "
                      "other control character)", name)
    n = len(names)
    if len(set(names)) != n:
        raise bad("robots.names", "unique robot names", list(names))
    if n < 2:
        raise bad("robots.names", "at least two robots (merging needs two maps)", list(names))
    if "names" in r and n != 3 and "start_angles_deg" not in r:
        r["start_angles_deg"] = tuple((90.0 + k * 360.0 / n) % 360.0 for k in range(n))  # in [0, 360)
    r.setdefault("yaw_offsets_deg", (0.0,) * n)
    for key in ("start_angles_deg", "yaw_offsets_deg"):
        if key in r and len(r[key]) != n:
            raise bad(f"robots.{key}", f"a list of {n} numbers (one per robot)", list(r[key]))
    spec = RobotsSpec(**r)
    if spec.body_radius_m >= spec.radius_m:
        raise bad("robots.body_radius_m", f"a number < robots.radius_m ({spec.radius_m:g})",
                  spec.body_radius_m)
    if spec.body_radius_m < MIN_BODY_RADIUS_M:
        raise bad("robots.body_radius_m", f"a number >= {MIN_BODY_RADIUS_M:g} (a robot's body radius, metres)",
                  spec.body_radius_m)
    if spec.speed_mps > MAX_SPEED_MPS:
        raise bad("robots.speed_mps", f"a number in (0, {MAX_SPEED_MPS:g}] (metres per second of a robot "
                  "mapping indoors)", spec.speed_mps)
    starts = [(spec.radius_m * math.cos(math.radians(a)), spec.radius_m * math.sin(math.radians(a)))
              for a in spec.start_angles_deg]
    for i in range(n):
        for j in range(i):
            d = math.dist(starts[i], starts[j])
            if d < 2 * spec.body_radius_m:
                raise bad("robots.start_angles_deg", f"robots that do not overlap at their starts: "
                          f"{names[j]} and {names[i]} are {d:.3f} m apart, bodies of radius "
                          f"{spec.body_radius_m:g} m (fewer robots, a larger robots.radius_m or other angles)",
                          list(spec.start_angles_deg))
    return spec


def center_error_section(v, names, roi_m: float) -> CenterErrorSpec:
    """Errors up to half the ROI side: farther, the ROI about the given center misses the true one (and a
    kilometre's error asked the merge canvas for terabytes)."""
    top = roi_m / 2
    r = section(lambda **kw: kw, {"magnitude_m": number(ge=0, le=top), "per_robot": lambda x, p: x})(
        v, "center_error")
    per = r.get("per_robot") or {}
    if not isinstance(per, dict):
        raise bad("center_error.per_robot", "a mapping robot name -> [dx, dy]", per)
    out = {}
    for k, x in per.items():
        if k not in names:
            raise bad(f"center_error.per_robot.{k}", f"a robot name (one of {', '.join(names)})", k)
        out[k] = vec2()(x, f"center_error.per_robot.{k}")
        if math.hypot(*out[k]) > top:
            raise bad(f"center_error.per_robot.{k}", f"an error [dx, dy] of at most {top:g} m (half of "
                      f"merger.roi_m)", list(out[k]))
    return CenterErrorSpec(r.get("magnitude_m", 0.0), out)
