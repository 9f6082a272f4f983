"""Scenario files: YAML validated into typed, frozen dataclasses.

A scenario is one experiment: the room and its objects, the robots on their circle, the laser, the
SLAM, the center error, the network, the merger parameters and the outputs. Every section has
defaults, so a scenario can be short (see ``circsim/scenarios/scene1.yaml``). Validation happens here,
at the boundary: an unknown key, a wrong type or an out-of-range value raises :class:`ScenarioError`
with one line naming the file, the key path and what was expected, e.g.
``scene1.yaml: robots.speed_mps: expected a number > 0, got 'fast'``. Numbers follow YAML 1.2 (``1e1``
is ten). Beyond types, the loader refuses what would run but could not mean anything: an empty file;
a room that does not hold the center, the robots' circle (plus their bodies), a pillar or an object; a
pillar or object on a robot's start; sizes that would not fit in memory or take hours (a grid above
:data:`MAX_GRID_CELLS` cells a side, more than :data:`MAX_TICKS` ticks, a ROI above
``merger.limits.MAX_ROI_M``); a laser, odometry or matcher setting no real robot has (each range names
its source: a datasheet, a ROS package's default). A room given as ``walls`` (which need not close) has no inside to check.
A ``world.map`` (map file) is read here, relative to the scenario file's folder (:mod:`circsim.config.mapworld`); a
``world.generate`` plan is drawn here (:mod:`circsim.config.floorplanworld`).

Here: the loader, the overrides, the merger section (its type and checks) and the checks that span
sections; every other section's keys are checked in :mod:`circsim.config.schema` (the reference,
:mod:`circsim.config.reference_doc`, is generated from both), the sections' types are in
:mod:`circsim.config.types`, the scene's geometry checks in :mod:`circsim.config.geometry`.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any

import yaml

from merger.algorithms import ALGORITHMS
from merger.algorithms import DEFAULT as DEFAULT_ALGORITHM
from merger.limits import (
    MAX_ROI_M,
    MAX_YAML_BYTES,
    InputLimitError,
    load_yaml,
    one_line,
    read_input,
)
from merger.settings import check_roi
from merger.team.online import STRATEGIES, STRATEGIES_BY_NAME, TeamMerger
from merger.team.params import RULES, MergeParams

from .floorplanworld import generate_world
from .geometry import check_geometry
from .mapworld import load_world_map
from .schema import (
    DT_S,
    LASER_SCHEMA,
    NETWORK_SCHEMA,
    NON_NEGATIVE,
    OUTPUT_SCHEMA,
    POSITIVE,
    SLAM_SCHEMA,
    center_error_section,
    robots_section,
    world_section,
)
from .types import (
    CenterErrorSpec,
    LaserConfig,
    NetworkConfig,
    OutputSpec,
    RobotsSpec,
    Room,
    SlamConfig,
    WorldSpec,
)
from .validate import (
    Invalid,
    bad,
    boolean,
    choice,
    integer,
    join,
    optional,
    refused,
    ruled,
    section,
    string,
)

MAX_GRID_CELLS = 4000  # cells on a side of a robot's grid (200 m at 5 cm): 64 MB of log-odds per robot
MAX_TICKS = 36_000  # duration_s / dt_s: an hour at 10 Hz, minutes of wall time (docs/limits.md)
SCENARIO_DIR = Path(__file__).resolve().parents[1] / "scenarios"


class ScenarioError(ValueError):
    """A scenario that cannot be used; the message is one line: file, key path, expectation (control
    characters of echoed user text escaped)."""

    def __init__(self, message: str) -> None:
        super().__init__(one_line(message))


@dataclass(frozen=True)
class MergerSettings(MergeParams):
    """The ``merger`` section: every setting of ``merger.MergeParams`` (the same names, defaults and rules:
    constructing it checks them, :class:`merger.team.params.MergeParams`) and the bench's own keys below;
    :meth:`params` is the MergeParams the simulation merges with.

    correct_tol_deg, correct_tol_m : ground truth, not merger parameters: an accepted alignment is correct
        when every angle error is ≤ ``correct_tol_deg`` and every translation error ≤ ``correct_tol_m``.
    min_maps : a robot runs merge cycles once it holds this many maps, its own included (2: whatever it
        holds, a partial team; null, the default, or more than the team: only with every teammate's map,
        as in the thesis — a 2-map cycle has no rival order for the ambiguity rule to weigh).
    cycle_period_s : a robot runs at most one merge cycle per this many simulated seconds, over everything
        it holds then; maps that arrive sooner wait for it (ROS multirobot_map_merge's ``estimation_rate``).
        Null (default): the period of the strategy the robot's merger runs (``Strategy.cycle_period_s``:
        0.5 s for the tree, four robots or more with ``strategy: auto``, and 2 s once the robot's last cycle
        accepted a placement of its whole team, ``Strategy.settled_period_s``; 0 for the thesis's orders,
        where every new map triggers a cycle, thesis 3.3.1); 0: a cycle in every tick that brings a new map.
        A number: that period, placed or not.
    algorithm : "thesis" (default: the search about the common center, verified), "features" (ROS
        m-explore map_merge's ORB / RANSAC pipeline) or "hough" (Carpin's Hough-spectrum merging): the
        merging method (:mod:`merger.algorithms`; the other merger keys apply to "thesis").
    strategy : "auto" (default: "orders" for teams of up to three robots, "tree" beyond), "orders" (the
        thesis: every merge order of the maps held) or "tree" (pairwise alignments kept per map version,
        the team assembled along a maximum spanning tree of the verified pairs): the online merger's
        (``merger.team.online.STRATEGIES``, its default ``TeamMerger``'s).
    share_hypotheses : robots broadcast the alignment they hold (with its evidence) with every map they
        send, over the same simulated network; a robot adopts a received one only when it verifies on its
        own maps and scores a higher Σν there than its own (:mod:`merger.team.shared`). Off (default): every
        robot computes alone, as in the thesis.

    The merge settings as the thesis scenes pin them: ``verification: whole_map`` (the thesis: ω̃ ≥
    ``nu_min`` on ``min_support`` cells), ``refine_whole: false``, ``research: every_version`` (every map
    version searched globally; the default ``on_change`` re-verifies a held answer by a local search,
    :mod:`merger.team.track`); ``window_m: 0`` is the thesis's rotation-only search.
    """

    correct_tol_deg: float = 2.0
    correct_tol_m: float = 0.1
    min_maps: int | None = None
    cycle_period_s: float | None = None
    strategy: str = TeamMerger.strategy  # the online merger's default ("auto"; its dataclass field's)
    algorithm: str = DEFAULT_ALGORITHM
    share_hypotheses: bool = False

    def params(self, keys=None, **given) -> MergeParams:
        """The merge parameters of these settings: every MergeParams setting (only ``keys``: the others at
        MergeParams's defaults), ``given`` ones replaced."""
        names = [f.name for f in fields(MergeParams)] if keys is None else keys
        return MergeParams(**{**{k: getattr(self, k) for k in names}, **given})

    def as_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def cycle_period_for(self, strategy: str, settled: bool = False) -> float:
        """``cycle_period_s`` for a merger running ``strategy`` (a resolved name: its table's period when
        the setting is null, :meth:`merger.team.online.Strategy.period`, by whether the robot's last cycle
        placed its whole team, ``settled``; 0 for a merger of no strategy in the table)."""
        if self.cycle_period_s is not None:
            return float(self.cycle_period_s)
        s = STRATEGIES_BY_NAME.get(strategy)
        return s.period(settled) if s is not None else 0.0


@dataclass(frozen=True)
class Scenario:
    """A validated scenario; build it with :func:`load_scenario` or :func:`scenario_from_dict`."""

    name: str
    description: str
    seed: int
    duration_s: float
    dt_s: float
    world: WorldSpec
    robots: RobotsSpec
    laser: LaserConfig
    slam: SlamConfig
    center_error: CenterErrorSpec
    network: NetworkConfig
    merger: MergerSettings
    output: OutputSpec
    source: str = field(default="<dict>", compare=False)
    raw: dict = field(default_factory=dict, compare=False, repr=False)

    def with_overrides(self, assignments) -> Scenario:
        """A copy with ``key.path=value`` assignments applied (values parsed as YAML) and re-validated."""
        return _overridden(self.raw, assignments, self.source)


def _overridden(raw: dict, assignments, source: str) -> Scenario:
    """The scenario of the data ``raw`` with ``key.path=value`` assignments applied, then validated once
    (so an override can make a file valid: a circle too big for its ``slam.size_m`` and ``--set
    slam.size_m=20``); an error names the assignments it concerns."""
    data = copy.deepcopy(raw)
    pairs = []
    for a in assignments:
        key, sep, text = a.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ScenarioError(f"{source}: --set {a!r}: expected key.path=value")
        try:
            value = load_yaml(text)
        except (yaml.YAMLError, ValueError, TypeError, RecursionError):
            raise ScenarioError(f"{source}: --set {a}: value is not valid YAML") from None
        key = resolve_alias(key, value)
        _assign(data, key.split("."), value, f"{source}: --set {a}")
        pairs.append((key, a))
    try:
        return _build(data, source)
    except Invalid as e:
        culprits = [a for k, a in pairs
                    if e.path == k or e.path.startswith(k + ".") or k.startswith(e.path + ".")]
        label = " ".join(f"--set {a}" for a in (culprits or [a for _, a in pairs]))
        raise ScenarioError(f"{source} ({label}): {e.text}") from None


# DESIGN.md and the issues spell some keys without their unit; the scenario keys carry it. `--set` and
# `circsim sweep --grid` accept both (an alias of a section, `center_error`, only with a plain value).
ALIASES = {"center_error": "center_error.magnitude_m", "network.latency": "network.latency_s",
           "network.jitter": "network.jitter_s", "network.period": "network.period_s",
           "latency": "network.latency_s"}


def resolve_alias(key: str, value=None) -> str:
    """The scenario key an alias stands for (``center_error`` → ``center_error.magnitude_m``); a mapping
    assigned to ``center_error`` sets the section itself."""
    if key in ALIASES and not isinstance(value, dict):
        return ALIASES[key]
    return key


def load_scenario(path, overrides=()) -> Scenario:
    """Read and validate a scenario file; ``overrides`` (``key.path=value``, as ``--set``) are applied to
    the file's data before it is validated, once."""
    path = Path(path)
    label = path.name
    try:
        data = load_yaml(read_input(path, MAX_YAML_BYTES, "scenario file").decode("utf-8"))
    except OSError as e:
        raise ScenarioError(f"{label}: cannot read file ({e.strerror or e})") from None
    except InputLimitError as e:
        raise ScenarioError(str(e)) from None
    except UnicodeDecodeError:
        raise ScenarioError(f"{label}: not a text file (expected a YAML scenario)") from None
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        problem = str(getattr(e, "problem", None) or e).splitlines()[0]
        raise ScenarioError(f"{label}: invalid YAML{where}: {problem}") from None
    except (ValueError, TypeError, RecursionError) as e:  # e.g. a date 2001-13-01, nesting too deep
        raise ScenarioError(f"{label}: invalid YAML: {type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}") \
            from None
    if data is None:  # an empty or comment-only file would silently run the default scene
        raise ScenarioError(f"{label}: empty scenario (expected a mapping of scenario sections: "
                            f"{', '.join(TOP_KEYS)})")
    _absolute_map_path(data, path.parent)
    if overrides and isinstance(data, dict):
        return _overridden({"name": path.stem, **data}, list(overrides), label)
    return scenario_from_dict(data, source=label, default_name=path.stem)


def _absolute_map_path(data, folder: Path) -> None:
    """A file's ``world.map`` is relative to the file's folder: made absolute in ``data`` (so overrides,
    sweeps and ``scenario_to_dict`` carry a path that works from anywhere)."""
    world = data.get("world") if isinstance(data, dict) else None
    m = world.get("map") if isinstance(world, dict) else None
    if isinstance(m, str) and m and not Path(m).is_absolute():
        data["world"] = {**world, "map": str((folder / m).resolve())}


def scenario_from_dict(data, source: str = "<dict>", default_name: str = "scenario") -> Scenario:
    """Validate a plain mapping (as parsed from YAML) into a :class:`Scenario`."""
    if isinstance(data, dict) and "name" not in data:
        data = {"name": default_name, **data}
    try:
        return _build(data, source)
    except Invalid as e:
        raise ScenarioError(f"{source}: {e.text}") from None


def scenario_to_dict(sc: Scenario) -> dict[str, Any]:
    """The fully resolved scenario as plain JSON-able data (valid input to :func:`scenario_from_dict`)."""
    return plain_value(sc)


def bundled_scenarios() -> dict[str, Path]:
    """The scenarios shipped with circsim, by name (file stem)."""
    return {p.stem: p for p in sorted(SCENARIO_DIR.glob("*.yaml"))}


# --- validation: the merger section and what spans sections -----------------------------------------
# The merger section's keys are MergerSettings's fields: MergeParams's, each checked by its one rule
# (merger.team.params.RULES, the rule's words in the reference; roi_m the ROI's rule with the inputs' limits,
# merger.limits), then the bench's own. window_m against roi_m is checked by constructing the settings
# (MergeParams's __post_init__, _merger_section), the ROI in cells of slam.resolution_m below (_build).
MERGER_CHECKS = {
    **{name: ruled(rule) for name, rule in RULES.items()},
    "roi_m": ruled(lambda v, key: check_roi(v, key=key, limits=True), f"a number in (0, {MAX_ROI_M:g}]"),
    "correct_tol_deg": POSITIVE, "correct_tol_m": POSITIVE, "min_maps": optional(integer(ge=2)),
    "cycle_period_s": optional(NON_NEGATIVE),
    "strategy": choice(*STRATEGIES), "algorithm": choice(*ALGORITHMS), "share_hypotheses": boolean}
if set(MERGER_CHECKS) != {f.name for f in fields(MergerSettings)}:  # a bench key added needs its check
    raise ImportError(f"merger section: checks for {sorted(MERGER_CHECKS)}, settings "
                      f"{sorted(f.name for f in fields(MergerSettings))}")
MERGER_SCHEMA = section(MergerSettings, MERGER_CHECKS)


def _merger_section(v, path: str = "merger") -> MergerSettings:
    """The merger section checked key by key (MERGER_SCHEMA), then as a whole by MergeParams's rules
    (a refusal names its key: ``merger.window_m``)."""
    try:
        return MERGER_SCHEMA(v, path)
    except ValueError as e:
        raise refused(e, join(path, e.key) if getattr(e, "key", None) else path) from None


TOP_KEYS = ("name", "description", "seed", "duration_s", "dt_s", "world", "robots", "laser", "slam",
        "center_error", "network", "merger", "output")


def _build(data, source: str) -> Scenario:
    if not isinstance(data, dict):
        raise bad("(top level)", "a mapping of scenario sections", data)
    for k in data:
        if k not in TOP_KEYS:
            raise Invalid(str(k), f"unknown key; expected one of {', '.join(TOP_KEYS)}")
    robots = robots_section(data.get("robots"))
    laser = LASER_SCHEMA(data.get("laser"), "laser")
    if laser.range_min_m >= laser.range_max_m:
        raise bad("laser.range_min_m", f"a number < laser.range_max_m ({laser.range_max_m:g})",
                  laser.range_min_m)
    slam = SLAM_SCHEMA(data.get("slam"), "slam")
    if slam.free_thresh >= slam.occupied_thresh:
        raise bad("slam.free_thresh", f"a number < slam.occupied_thresh ({slam.occupied_thresh:g})",
                  slam.free_thresh)
    if slam.size_m <= 4 * robots.radius_m:  # the map is centred on the start pose, on the circle
        raise bad("slam.size_m", f"a number > 4 * robots.radius_m ({4 * robots.radius_m:g}) so that the "
                  "robot's circle fits in its map", slam.size_m)
    cells = slam.size_m / slam.resolution_m
    if cells > MAX_GRID_CELLS:
        raise bad("slam.size_m", f"a grid of at most {MAX_GRID_CELLS} cells a side (slam.size_m / "
                  f"slam.resolution_m = {cells:.0f})", slam.size_m)
    merger = _merger_section(data.get("merger"))  # window_m within a quarter of roi_m: MergeParams's rule
    try:
        check_roi(merger.roi_m, slam.resolution_m, "merger.roi_m", limits=True, cells_of="slam.resolution_m")
    except ValueError as e:
        raise refused(e, "merger.roi_m") from None
    one_tour = math.ceil(2 * math.pi * robots.radius_m / robots.speed_mps)
    duration_s = POSITIVE(data.get("duration_s", one_tour), "duration_s")
    dt_s = DT_S(data.get("dt_s", 0.1), "dt_s")
    if dt_s > duration_s:
        raise bad("dt_s", f"a number <= duration_s ({duration_s:g} s): at least one tick", dt_s)
    if duration_s / dt_s > MAX_TICKS:
        raise bad("duration_s", f"at most {MAX_TICKS} ticks of dt_s ({dt_s:g} s): a number <= "
                  f"{MAX_TICKS * dt_s:g}", duration_s)
    world = world_section(data.get("world"))
    if world.map is not None:
        world = load_world_map(world)
    elif world.generate is not None:
        world = generate_world(world, robots)
    check_geometry(world, robots)
    return Scenario(
        name=string(data.get("name", "scenario"), "name"),
        description=string(data.get("description", ""), "description"),
        seed=integer(ge=0)(data.get("seed", 0), "seed"),
        duration_s=duration_s, dt_s=dt_s, world=world, robots=robots, laser=laser, slam=slam,
        center_error=center_error_section(data.get("center_error"), robots.names, merger.roi_m),
        network=NETWORK_SCHEMA(data.get("network"), "network"), merger=merger,
        output=OUTPUT_SCHEMA(data.get("output"), "output"), source=source, raw=copy.deepcopy(data))


def _assign(data: dict, keys: list[str], value, label: str) -> None:
    node = data
    for i, k in enumerate(keys[:-1]):
        nxt = node.get(k) if isinstance(node, dict) else None
        if nxt is None:
            nxt = node[k] = {}
        if not isinstance(nxt, dict):
            raise ScenarioError(f"{label}: {'.'.join(keys[:i + 1])}: expected a mapping to set keys in, "
                                f"got {nxt!r}")
        node = nxt
    node[keys[-1]] = value


def plain_value(v):
    if is_dataclass(v):
        out = {"type": v.type} if hasattr(type(v), "type") else {}
        for f in fields(v):
            if f.compare:
                out[f.name] = plain_value(getattr(v, f.name))
        if isinstance(v, Room):
            keep = ("walls",) if v.size_m is None else ("size_m", "center")
            out = {k: out[k] for k in keep}
        if isinstance(v, WorldSpec):  # a room world's keys as before maps existed; a map world has no room
            drop = ("map", "map_resolution_m") if v.map is None else \
                ("room",) + (("map_resolution_m",) if v.map_resolution_m is None else ())
            drop += ("generate",) if v.generate is None else ("room",)
            out = {k: x for k, x in out.items() if k not in drop}
        return out
    if isinstance(v, tuple | list):
        return [plain_value(x) for x in v]
    if isinstance(v, dict):
        return {str(k): plain_value(x) for k, x in v.items()}
    return v
