"""A generated world (``world.generate: {kind: floorplan, seed: S, ...}``): its keys checked and its plan
made, then handed to the map world's path.

The contract: :data:`GENERATE_SCHEMA` checks the keys of ``world.generate`` (the reference prints it);
:func:`generate_world` draws the plan (:func:`circsim.world.floorplan.generate`, deterministic from
``world.generate.seed``) and returns the world with its cells in ``map_grid``, exactly as
:func:`circsim.config.mapworld.load_world_map` returns a map file's: from there the scene checks
(:func:`circsim.config.mapworld.check_map_world`), the laser's walls (:mod:`circsim.world.mapgeometry`)
and the recording are the map world's, nothing repeated. The plan keeps a disc of the robots' circle
plus their bodies and :data:`KEEP_MARGIN_M` free of furniture about the center: ``world.center`` when
the scenario gives it (then checked as any map world's center), else a point of the plan's hall that the
generator chooses and the resolved scenario states (``circsim scenarios --show``; ``circsim run`` prints
it). A plan the building cannot hold is :class:`~circsim.config.validate.Invalid` at its key
(``world.generate.rooms``, ``world.generate.size_m`` ...), one line.
"""

from __future__ import annotations

from dataclasses import replace

from .types import FloorplanSpec, MapGrid, RobotsSpec, WorldSpec
from .validate import Invalid, choice, integer, number, section, vec2

KEEP_MARGIN_M = 0.3  # beyond the robots' bodies, no furniture this close to their circle
MAX_PLAN_CELLS = 2000  # cells on a side of a generated plan (100 m at 5 cm; a plan is made in ~0.1 s)

GENERATE_SCHEMA = {
    "kind": choice("floorplan"),
    "seed": integer(ge=0),
    "size_m": vec2(ge=6, le=100),
    "rooms": integer(ge=3, le=200),
    "corridors": integer(ge=1, le=2),
    "corridor_m": number(ge=0.8, le=4, why="corridors of offices and labs: 1.2–2.4 m inside"),
    "door_m": number(ge=0.6, le=1.8, why="a door: 0.8–1 m; double doors 1.6–1.8 m"),
    "wall_m": number(ge=0.05, le=0.5, why="interior walls 0.1–0.25 m; at least a cell of resolution_m"),
    "furniture": number(ge=0, le=10, why="pieces per room on average (cabinets, desks, tables with chairs)"),
    "resolution_m": number(ge=0.02, le=0.1, why="the cell of a SLAM map: gmapping and Cartographer save 5 cm"),
}
GENERATE = section(FloorplanSpec, GENERATE_SCHEMA, required=("kind",))
GENERATE.expected = ("a mapping {kind: floorplan, seed, size_m, rooms, ...}: a building generated from the "
                     "seed (not with world.room or world.map)")


def describe(world: WorldSpec) -> str:
    """One line on a generated world: the plan and where the common center is (given or chosen)."""
    g, (x, y) = world.generate, world.center
    return (f"world: floor plan seed {g.seed}, {g.size_m[0]:g} x {g.size_m[1]:g} m, {g.rooms} rooms, "
            f"{g.corridors} corridor{'s' if g.corridors > 1 else ''}; common center ({x:g}, {y:g})")


def generate_world(world: WorldSpec, robots: RobotsSpec) -> WorldSpec:
    """``world`` with its generated plan's cells in ``map_grid`` and, when ``world.center`` is None (not
    given), the center the generator chose."""
    from ..world.floorplan import FloorplanError, generate

    g = world.generate
    if g.wall_m < g.resolution_m:
        raise Invalid("world.generate.wall_m", f"expected at least a cell (world.generate.resolution_m "
                      f"{g.resolution_m:g} m), got {g.wall_m:g}")
    cells = max(g.size_m) / g.resolution_m
    if cells > MAX_PLAN_CELLS:
        raise Invalid("world.generate.size_m", f"expected a plan of at most {MAX_PLAN_CELLS} cells a side "
                      f"(size_m / resolution_m = {cells:.0f})")
    keep = robots.radius_m + robots.body_radius_m + KEEP_MARGIN_M
    try:
        plan = generate(g.seed, g.size_m, g.rooms, g.corridors, g.corridor_m, g.door_m, g.wall_m, g.furniture,
                        g.resolution_m, keep_clear_m=keep, center=world.center)
    except FloorplanError as e:
        raise Invalid(f"world.generate.{e.key}", e.message) from None
    return replace(world, center=plan.center, map_grid=MapGrid(plan.states, plan.resolution, plan.origin))

