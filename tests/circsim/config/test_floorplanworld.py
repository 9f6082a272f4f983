"""circsim.config.floorplanworld, called directly: ``world.generate``'s keys checked, the world's cells the
generator's plan for the robots' keep-clear disc, the center chosen only when not given, a plan the
building cannot hold refused at its key in one line, and the one-line description."""

from __future__ import annotations

import pytest

from circsim.config.floorplanworld import GENERATE, KEEP_MARGIN_M, MAX_PLAN_CELLS, describe, generate_world
from circsim.config.types import FloorplanSpec, RobotsSpec, Room, WorldSpec
from circsim.config.validate import Invalid
from circsim.world.floorplan import generate

ROBOTS = RobotsSpec()
KEEP = ROBOTS.radius_m + ROBOTS.body_radius_m + KEEP_MARGIN_M


def _world(center=None, **plan):
    return WorldSpec(center, Room(None, None, ()), generate=FloorplanSpec(**plan))


def test_the_generate_keys():
    assert GENERATE({"kind": "floorplan"}, "world.generate") == FloorplanSpec()
    assert GENERATE({"kind": "floorplan", "seed": 3, "size_m": [30, 20]}, "world.generate") == \
        FloorplanSpec(seed=3, size_m=(30.0, 20.0))
    with pytest.raises(Invalid, match=r"^world.generate.kind: missing required key$"):
        GENERATE({"seed": 1}, "world.generate")
    with pytest.raises(Invalid, match=r"^world.generate.kind: expected one of 'floorplan', got 'castle'$"):
        GENERATE({"kind": "castle"}, "world.generate")
    with pytest.raises(Invalid, match=r"^world.generate.rooms: expected an integer in \[3, 200\], got 2$"):
        GENERATE({"kind": "floorplan", "rooms": 2}, "world.generate")


def test_the_world_is_the_generators_plan_and_its_chosen_center():
    w = generate_world(_world(seed=3), ROBOTS)
    plan = generate(3, (24.0, 16.0), 8, 1, 1.6, 0.9, 0.15, 3.0, 0.05, keep_clear_m=KEEP)
    assert (w.map_grid.states == plan.states).all() and w.map_grid.origin == plan.origin
    assert w.map_grid.resolution == 0.05 and w.center == plan.center
    assert generate_world(_world(seed=3), ROBOTS).center == w.center  # one seed, one building


def test_a_given_center_is_kept():
    chosen = generate_world(_world(seed=5), ROBOTS).center
    given = (chosen[0] + 0.1, chosen[1] - 0.1)
    w = generate_world(_world(given, seed=5), ROBOTS)
    assert w.center == pytest.approx(given)


@pytest.mark.parametrize("plan, key, words", [
    (dict(wall_m=0.05, resolution_m=0.1), "world.generate.wall_m",
     "expected at least a cell (world.generate.resolution_m 0.1 m), got 0.05"),
    (dict(size_m=(100.0, 60.0), resolution_m=0.02), "world.generate.size_m",
     f"expected a plan of at most {MAX_PLAN_CELLS} cells a side (size_m / resolution_m = 5000)"),
    (dict(size_m=(16.0, 12.0), rooms=60), "world.generate.rooms", "got 60"),
])
def test_a_plan_the_building_cannot_hold_is_refused_at_its_key(plan, key, words):
    with pytest.raises(Invalid) as e:
        generate_world(_world(**plan), ROBOTS)
    assert e.value.path == key and words in e.value.text and "\n" not in e.value.text


def test_the_description_names_the_plan_and_the_center():
    w = generate_world(_world(seed=2, corridors=2, size_m=(30.0, 20.0), rooms=10), ROBOTS)
    x, y = w.center
    assert describe(w) == (f"world: floor plan seed 2, 30 x 20 m, 10 rooms, 2 corridors; common center "
                           f"({x:g}, {y:g})")
    one = generate_world(_world(seed=2), ROBOTS)
    assert "8 rooms, 1 corridor;" in describe(one)
