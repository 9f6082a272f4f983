"""The scenario reference (``docs/scenario-reference.md``), generated from the loader's own checks.

Every key, its default and what the loader expects come from the validators and defaults of
:mod:`circsim.config.scenario` and :mod:`circsim.config.schema`, so the page cannot drift from the code:
``circsim scenarios --reference`` prints it and ``tests/circsim/config/test_reference_doc.py`` checks
that the file in docs/ is current (regenerate it with
``circsim scenarios --reference > docs/scenario-reference.md``).
"""

from __future__ import annotations

import json

from . import scenario as S
from . import schema as K
from .validate import describe, integer, string

HEADER = """# Scenario reference

Generated from the scenario loader's checks (`circsim scenarios --reference > docs/scenario-reference.md`;
a test keeps it current). Every key is optional; a missing key takes the default shown (the default
scenario: `circsim scenarios --show FILE` prints any scenario with every key resolved). Unknown keys,
wrong types and out-of-range values are one-line errors naming the file, the key path and what was
expected. `--set` and `circsim sweep --grid` take the same key paths, and these aliases:
{aliases}.
"""

CONSTRAINTS = """
## Constraints between keys (checked by the loader)

- `laser.range_min_m` < `laser.range_max_m`; `slam.free_thresh` < `slam.occupied_thresh`.
- `slam.size_m` > 4 × `robots.radius_m` (the circle fits in each robot's map, centred on its start);
  `slam.size_m` / `slam.resolution_m` ≤ {cells} cells a side.
- `merger.window_m` ≤ `merger.roi_m` / 4; `merger.roi_m` ≤ {roi:g} m.
- `duration_s` / `dt_s` ≤ {ticks} ticks (an hour at 10 Hz; how long that takes: docs/limits.md); `dt_s` ≤
  `duration_s`; `duration_s` defaults to one tour of the circle (2π·`robots.radius_m` / `robots.speed_mps`,
  rounded up).
- `robots.names`: unique, at least two; `robots.start_angles_deg` and `robots.yaw_offsets_deg`: one per robot
  (with names other than three and no start angles: spread evenly from 90°); {body:g} m ≤
  `robots.body_radius_m` < `robots.radius_m`; `robots.speed_mps` ≤ {speed:g}; the robots' bodies do not
  overlap at their starts.
- With a rectangular `world.room`: `world.center`, the robots' circle plus their bodies, every pillar and
  object lie inside the room. No pillar or object stands on a robot's start, nor on the robots' path: the
  circle (as wide as their bodies) for online robots, which drive it without avoiding obstacles; each
  robot's arc ±`robots.offline.max_deg` for offline ones. `world.room` is either `size_m` (and `center`:
  the room is centred on `world.center` unless given) or `walls`, not both.
- With a `world.map` (a map world, instead of `world.room`): the map is read as `merger` reads map_server
  files (`mode`, thresholds, `negate`, `origin`); its occupied and unknown cells are solid, and beyond its
  edge is solid. `world.center` lies in a free cell; every robot's start and every point of its path (the
  circle online, its arc offline) is at least `robots.body_radius_m` from every solid cell (exact
  distances to the cells' squares); pillars and objects lie wholly in free space. A refusal names the
  first blocking point in map coordinates, what the map has there, and the largest circle about
  `world.center` that is clear. A missing or malformed map file is the map loader's one-line error.
- With a `world.generate` (instead of `world.room` or `world.map`): the building is drawn from
  `world.generate.seed` (the same seed, the same cells) and then checked as a map world. Its outer walls'
  centre lines run from (0, 0) to `size_m`; a spine corridor runs along the long side (`corridors: 2`: and
  one across it), one room, the hall, is sized for the robots' circle, and no furniture comes within
  `robots.radius_m` + `robots.body_radius_m` + 0.3 m of the common center: `world.center` when given
  (checked as any map world's), else a point of the hall the generator chooses (`circsim scenarios --show`
  and `circsim run` print it). `rooms` counts the hall: at least 3 (5 with two corridors), and at most what
  the building holds with rooms at least 2 m wide inside (a refusal names that number); the building is at
  least as deep as the hall, a corridor and a room; `wall_m` ≥ `resolution_m`; at most 2000 cells a side.
- `center_error.magnitude_m` and each `center_error.per_robot` error at most `merger.roi_m` / 2;
  `center_error.per_robot`: keys are robot names, values `[dx, dy]` in metres (they replace
  `magnitude_m` for those robots).
- A scenario file is a regular file of at most 1 MiB whose YAML aliases expand to at most 2 Mi nodes and
  characters (see docs/limits.md).
"""


RESEARCH = """
## When pairs are searched again (`merger.research`)

- `on_change` (the default): a pair of maps (the `tree` strategy) or the team's hypothesis (`orders`) that
  holds an accepted answer is *re-verified* at each new map version: an exact local search about the
  answer (±3° and ±3 cells, the same measure, 0.1° step and sub-cell refinement; `merger.search.local`) and
  the whole-map verification. A global search runs when (a) that fails, or its ν falls more than
  `research_drop` ({drop:g}) below the last global search's; (b) either map's region of interest changed
  by more than `research_change` ({change:g}: that fraction of its known cells changed state; the cells on
  the team's ring, where the teammates drive, do not count) since the last global search; (c) `research_period_s` ({period:g} s) passed since it (three times
  that for a pair whose two maps the team's accepted placement links); (d) a global answer that
  disagreed awaits a second one (a different answer replaces the tracked one only when two global searches
  find it and it verifies with a higher ν: hysteresis; each switch is an event in the run's log), or the
  team's assembly found the pair inconsistent. The first merge of a pair is always a global search's
  answer. A pair that never verified is searched again when a map's ROI changed by a quarter of
  `research_change`, or, when the held team placement already links its two maps, locally from that
  relative pose (globally at the staleness bound); with the `tree`, once two global searches found it one
  answer that had too little support (fewer than `min_support` cells), it is re-verified there by the
  local search and searched globally again only once that answer's support reaches three quarters of
  `min_support`
  (`waited` in the tracking summary). With the `tree`, a verified pair's answer holds for new
  versions while neither map's ROI changed by more than a quarter of `research_change` since the versions
  it was computed on (the maps' frames do not move; the tree's edges are verified on the current maps at
  every cycle).
- `every_version`: every map version is searched globally — the thesis's behaviour; `scene1`, `scene2`
  and their `-thesis` variants pin it.

Anchors: Cartographer (`pose_graph.lua`, `constraint_builder_2d.cc`) searches globally only for
trajectories not connected within `global_constraint_search_after_n_seconds` = 10 s and otherwise matches
locally from the current relative pose (our `research_period_s`; for connected pairs we keep a bound three times
it); its global matches need
`global_localization_min_score` 0.6 against `min_score` 0.55 for local ones (the tree's stricter ν for an
edge that no loop confirms). m-explore's `map_merge` re-estimates at 0.5 Hz and overwrites its estimate
with every new one; its users report merged maps that jump (hrnr/m-explore #22): hence the hysteresis.
Swarm-SLAM retries a failed candidate only when its maps grow (the change rule for pairs never verified).
What tracking costs in quality is measured by `benchmarks/bench_tracking.py` (docs/performance-history.md).
"""


# Defaults that follow another key: the table says which (the default scenario's value would mislead).
DERIVED_DEFAULTS = {"world.room.center": "(`world.center`)", "world.map": "(none: the world is `world.room`)",
                    "world.map_resolution_m": "(none: a map's YAML states its own)"}


def _default(defaults, path: list[str]):
    node = defaults
    for k in path:
        if not isinstance(node, dict) or k not in node:
            return "—"
        node = node[k]
    return json.dumps(node, ensure_ascii=False)


def item_defaults(check) -> dict:
    """Defaults of a list item's keys (a pillar, an object): its dataclass's, "required" for the others."""
    import dataclasses

    out = {k: "(required)" for k in getattr(check, "required", ())}
    for f in dataclasses.fields(check.cls) if dataclasses.is_dataclass(getattr(check, "cls", None)) else ():
        if f.default is not dataclasses.MISSING:
            out.setdefault(f.name, S.plain_value(f.default))
    return out


def _rows(schema: dict, prefix: list[str], defaults, out: list) -> None:
    for key, check in schema.items():
        if key == "type":
            continue
        path = [*prefix, key]
        sub = getattr(check, "schema", None)
        item = getattr(check, "item", None)
        if sub is not None and getattr(check, "expected", "") == "a mapping":
            _rows(sub, path, defaults, out)
        elif item is not None and getattr(item, "schema", None) is not None:
            out.append((".".join(path), _default(defaults, path), describe(check)))
            _rows(item.schema, [path[-1] + "[]"], item_defaults(item), out)
            out[-len(item.schema):] = [(".".join(prefix) + "." + k, d, e) for k, d, e in out[-len(item.schema):]]
        else:
            d = defaults.get(key) if isinstance(defaults, dict) and prefix and prefix[-1].endswith("[]") else None
            out.append((".".join(path), json.dumps(d, ensure_ascii=False) if d is not None
                        else _default(defaults, path), describe(check)))


def _sections():
    """(section title, key prefix, schema) in the order of a scenario file."""
    world = {k: v for k, v in K.WORLD_SCHEMA.items() if k not in ("room", "generate")}
    return [
        ("Top level", [], {"name": string, "description": string, "seed": integer(ge=0),
                           "duration_s": K.POSITIVE, "dt_s": K.DT_S}),
        ("world", ["world"], world),
        ("world.room", ["world", "room"], K.ROOM_SCHEMA),
        ("world.generate (a generated floor plan)", ["world", "generate"], K.GENERATE.schema),
        *[(f"world.objects[] with type: {kind}", ["world", "objects[]"], check)
          for kind, check in K.OBJECT_SCHEMAS.items()],
        ("robots", ["robots"], K.ROBOTS_SCHEMA),
        ("laser", ["laser"], K.LASER_SCHEMA.schema),
        ("slam", ["slam"], K.SLAM_SCHEMA.schema),
        ("center_error", ["center_error"], {"magnitude_m": K.NON_NEGATIVE}),
        ("network", ["network"], K.NETWORK_SCHEMA.schema),
        ("merger", ["merger"], S.MERGER_SCHEMA.schema),
        ("output", ["output"], K.OUTPUT_SCHEMA.schema),
    ]


def _cell(d: str) -> str:
    """A default as code, or a note in words: ``"(required)"`` → (required)."""
    if d.startswith('"(') and d.endswith(')"'):
        return d[1:-1]
    return "—" if d == "—" else f"`{d}`"


def scenario_reference() -> str:
    """The reference page as Markdown."""
    sc = S.scenario_from_dict({}, default_name="FILE_STEM")
    defaults = {**S.scenario_to_dict(sc), "name": "(the file name without .yaml)", "description": "",
                "seed": sc.seed, "duration_s": "(one tour of the circle)", "dt_s": sc.dt_s}
    defaults["world"]["generate"] = item_defaults(K.GENERATE)  # a room world has none: the plan's own
    aliases = ", ".join(f"`{a}` → `{k}`" for a, k in S.ALIASES.items())
    parts = [HEADER.format(aliases=aliases)]
    for title, prefix, schema in _sections():
        rows: list = []
        if callable(schema):  # an object type: its keys with the object's own defaults
            _rows(schema.schema, prefix, item_defaults(schema), rows)
        else:
            _rows(schema, prefix, defaults, rows)
        parts.append(f"\n## {title}\n\n| key | default | expected |\n|---|---|---|\n")
        parts.append("".join(f"| `{k}` | {DERIVED_DEFAULTS.get(k) or _cell(d)} | {e} |\n" for k, d, e in rows))
    parts.append(CONSTRAINTS.format(cells=S.MAX_GRID_CELLS, roi=S.MAX_ROI_M, ticks=S.MAX_TICKS,
                                    body=K.MIN_BODY_RADIUS_M, speed=K.MAX_SPEED_MPS))
    d = S.MergerSettings()  # the merger's defaults (merger.team.params.MergeParams)
    parts.append(RESEARCH.format(drop=d.research_drop, change=d.research_change, period=d.research_period_s))
    return "".join(parts)
