"""Generated floor plans (circsim.world.floorplan, world.generate): deterministic from their seed, closed and
connected, the robots' circle and starts in free space with clearance, the plan through the map world's
path (checks, laser, a run), and bad keys refused in one line with exit 2."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from circsim.cli import main
from circsim.config.floorplanworld import KEEP_MARGIN_M
from circsim.config.mapworld import clearance
from circsim.config.scenario import (
    ScenarioError,
    bundled_scenarios,
    load_scenario,
    scenario_from_dict,
    scenario_to_dict,
)
from circsim.config.types import LaserConfig
from circsim.experiments.plan import parse_grid, plan
from circsim.world import laser
from circsim.world.floorplan import FREE, UNKNOWN, FloorplanError, generate
from circsim.world.motion import trajectories
from circsim.world.world import World
from merger.grid import OccupancyGrid
from merger.synthetic import grid_ray_cast

KEEP = 1.75 + 0.18 + KEEP_MARGIN_M  # the default circle, body and margin
LAYOUTS = [dict(size_m=(24, 16), rooms=8), dict(size_m=(14, 26), rooms=7),  # landscape, portrait
           dict(size_m=(36, 20), rooms=16, corridors=2, furniture=5.0), dict(size_m=(12, 10), rooms=3)]


def world_scenario(generate_keys: str, robots: str = "{names: [A, B, C, D]}", world_extra: str = ""):
    import yaml

    return yaml.safe_load(f"world: {{generate: {generate_keys}{world_extra}}}\nrobots: {robots}\nduration_s: 3\n")


def test_one_seed_is_one_plan_and_seeds_differ():
    a, b = generate(7, (24, 16), 8, keep_clear_m=KEEP), generate(7, (24, 16), 8, keep_clear_m=KEEP)
    assert np.array_equal(a.states, b.states) and a.center == b.center and a.origin == b.origin
    plans = [generate(s, (24, 16), 8, keep_clear_m=KEEP) for s in range(6)]
    for i in range(6):
        for j in range(i):
            assert not np.array_equal(plans[i].states, plans[j].states), (i, j)
    assert len({p.center for p in plans}) == 6
    sc = scenario_from_dict(world_scenario("{kind: floorplan, seed: 7}"))  # the loader's plan is the generator's
    assert np.array_equal(sc.world.map_grid.states, a.states) and sc.world.center == a.center


@pytest.mark.parametrize("layout", LAYOUTS, ids=lambda d: "x".join(map(str, d["size_m"])))
def test_plans_are_closed_and_connected(layout):
    """Over 15 seeds: no free cell on the map's edge or beside an unknown one (4-neighbours), every free
    cell in the center's 4-connected component, the building's rooms, doors and furniture as asked."""
    for seed in range(15):
        p = generate(seed, keep_clear_m=KEEP, **layout)
        s = p.states
        free = s == FREE
        assert not (free[0].any() or free[-1].any() or free[:, 0].any() or free[:, -1].any())
        unknown = s == UNKNOWN
        assert not ((free[1:] & unknown[:-1]).any() or (free[:-1] & unknown[1:]).any()
                    or (free[:, 1:] & unknown[:, :-1]).any() or (free[:, :-1] & unknown[:, 1:]).any())
        n, labels = cv2.connectedComponents(free.astype(np.uint8), connectivity=4)
        col, row = (int((c - o) / p.resolution) for c, o in zip(p.center, p.origin, strict=True))
        assert n == 2 and labels[row, col] == 1, (seed, n)
        assert p.rooms == layout["rooms"] and p.doors >= p.rooms  # a door per room at least (spanning tree)
        h, w = s.shape
        assert (w > h) == (layout["size_m"][0] > layout["size_m"][1])
        if layout.get("furniture", 3.0) >= 3:
            assert p.furniture >= p.rooms // 2, (seed, p.furniture)


@pytest.mark.parametrize("seed", range(8))
def test_the_circle_and_the_starts_lie_in_free_space_with_clearance(seed):
    sc = scenario_from_dict(world_scenario(f"{{kind: floorplan, seed: {seed}, corridors: {1 + seed % 2}, "
                                           f"rooms: {6 + seed}}}"))
    g, (cx, cy), r = sc.world.map_grid, sc.world.center, sc.robots.radius_m
    a = np.linspace(0, 2 * math.pi, 720, endpoint=False)
    circle = np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=1)
    assert clearance(g, circle, 1.0).min() >= sc.robots.body_radius_m + KEEP_MARGIN_M - 2 * g.resolution
    starts = [t.start_pose()[:2] for t in trajectories(sc).values()]
    assert clearance(g, starts, 1.0).min() >= sc.robots.body_radius_m
    x0, y0, x1, y1 = generate(seed, (24, 16), 6 + seed, 1 + seed % 2, keep_clear_m=KEEP).hall
    assert x0 + KEEP - 1e-6 <= cx <= x1 - KEEP + 1e-6 and y0 + KEEP - 1e-6 <= cy <= y1 - KEEP + 1e-6
    # no furniture on the robots' disc: only walls may be nearer than KEEP to the center
    assert clearance(g, [(cx, cy)], KEEP)[0] >= KEEP - g.resolution


def test_a_given_center_is_used_and_checked_and_the_chosen_one_round_trips(tmp_path, capsys):
    sc = scenario_from_dict(world_scenario("{kind: floorplan, seed: 4}"))
    d = scenario_to_dict(sc)  # the chosen center, now given
    assert d["world"]["generate"]["seed"] == 4 and "room" not in d["world"] and "map" not in d["world"]
    again = scenario_from_dict(d)
    assert again == sc and np.array_equal(again.world.map_grid.states, sc.world.map_grid.states)
    x0, y0, x1, y1 = generate(4, (24, 16), 8, keep_clear_m=KEEP).hall
    moved = scenario_from_dict(world_scenario("{kind: floorplan, seed: 4}",
                                              world_extra=f", center: [{x0 + 2.2}, {y0 + 2.3}]"))
    assert moved.world.center == pytest.approx((x0 + 2.2, y0 + 2.3))
    p = tmp_path / "wall.yaml"  # the outer wall's centre line: a center in a wall, refused
    p.write_text("world: {generate: {kind: floorplan, seed: 4}, center: [0.0, 5.0]}\n")
    with pytest.raises(ScenarioError, match=r"world.center: expected a point in the free space of the map "
                                            r"generated by world.generate \(seed 4\)"):
        load_scenario(p)
    assert main(["run", str(p), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_a_sweep_over_the_plan_seed_gives_other_buildings():
    base = load_scenario(bundled_scenarios()["floorplan"])
    tasks = plan(base, parse_grid(["world.generate.seed=0,1,2"]), 1)
    scs = [t.scenario() for t in tasks]
    assert [s.world.generate.seed for s in scs] == [0, 1, 2]
    assert len({s.world.center for s in scs}) == 3
    assert not np.array_equal(scs[0].world.map_grid.states, scs[1].world.map_grid.states)


def test_the_laser_sees_the_plans_walls():
    """From the robots' starts, every return lies on a solid cell of the plan and a ray marched through
    the plan never stops before it (the map world's walls are the plan's cells, nothing else)."""
    sc = load_scenario(bundled_scenarios()["floorplan"])
    g = sc.world.map_grid
    grid = OccupancyGrid(g.states, g.resolution, g.origin)
    w, cfg = World.from_scenario(sc), LaserConfig()
    for i, (name, t) in enumerate(trajectories(sc).items()):
        x, y, yaw = t.start_pose()
        for k, other in enumerate(w.robot_names):
            w.set_robot_pose(other, 1e3 + 10 * k + 100 * i, 1e3, 0.0)
        ranges = laser.cast(w, name, (x, y, yaw), cfg)
        angles = yaw + cfg.angle_min + np.arange(cfg.beams) * cfg.angle_increment
        march, _ = grid_ray_cast(grid, (x, y), angles, cfg.range_max_m)
        hit = np.isfinite(ranges)
        assert hit.mean() > 0.3 and np.all(march >= ranges - 1e-9)  # a hall: some beams reach nothing
        px = x + (ranges[hit] + 1e-7) * np.cos(angles[hit])
        py = y + (ranges[hit] + 1e-7) * np.sin(angles[hit])
        col = np.floor((px - g.origin[0]) / g.resolution).astype(int)
        row = np.floor((py - g.origin[1]) / g.resolution).astype(int)
        assert np.all(g.states[row, col] != FREE)


@pytest.mark.slow
def test_a_generated_world_runs_end_to_end(tmp_path, capsys):
    """A small building, three robots, 4 s: the run says where the center is, every robot merges, no
    gross false merge."""
    p = tmp_path / "small.yaml"
    p.write_text("world: {generate: {kind: floorplan, seed: 2, size_m: [16, 12], rooms: 4}}\n"
                 "robots: {radius_m: 1.2}\nduration_s: 4\ncenter_error: {magnitude_m: 0.1}\n")
    out = tmp_path / "run.json"
    assert main(["run", str(p), "--quiet", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    cx, cy = load_scenario(p).world.center
    assert f"world: floor plan seed 2, 16 x 12 m, 4 rooms, 1 corridor; common center ({cx:g}, {cy:g})" in text
    import json

    d = json.loads(out.read_text())
    assert d["gross_merges"] == 0
    assert all(r["first_merge_s"] is not None for r in d["robots"].values()), d["robots"]


@pytest.mark.parametrize("generate_keys, needle", [
    ("{seed: 1}", "world.generate.kind: missing required key"),
    ("{kind: house}", "world.generate.kind: expected one of 'floorplan', got 'house'"),
    ("{kind: floorplan, rooms: 2}", "world.generate.rooms: expected an integer in [3, 200], got 2"),
    ("{kind: floorplan, rooms: 4, corridors: 2, size_m: [30, 20]}",
     "world.generate.rooms: expected at least 5 rooms with 2 corridors"),
    ("{kind: floorplan, rooms: 120}", "world.generate.rooms: expected at most"),
    ("{kind: floorplan, size_m: [10, 8]}", "world.generate.size_m: expected a building at least"),
    ("{kind: floorplan, wall_m: 0.06, resolution_m: 0.1}", "world.generate.wall_m: expected at least a cell"),
    ("{kind: floorplan, size_m: [100, 60], resolution_m: 0.02}",
     "world.generate.size_m: expected a plan of at most 2000 cells a side"),
    ("{kind: floorplan, seed: -1}", "world.generate.seed: expected an integer >= 0, got -1"),
    ("{kind: floorplan, doors: 3}", "world.generate.doors: unknown key; expected one of kind, seed"),
    ("{kind: floorplan}, room: {size_m: [4, 4]}", "world.room: expected either world.generate or world.room"),
    ("{kind: floorplan}, map: x.yaml", "world.map: expected either world.generate or world.map"),
    ("3", "world.generate: expected a mapping with keys kind, seed"),
])
def test_bad_generate_keys_are_one_line_errors_with_exit_2(tmp_path, capsys, generate_keys, needle):
    p = tmp_path / "bad.yaml"
    p.write_text(f"world: {{generate: {generate_keys}}}\n")
    with pytest.raises(ScenarioError) as e:
        load_scenario(p)
    assert str(e.value).startswith("bad.yaml: ") and needle in str(e.value), str(e.value)
    assert main(["run", str(p), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and needle in err


def test_a_plan_too_full_for_its_rooms_names_the_number_it_holds():
    with pytest.raises(FloorplanError) as e:
        generate(0, (16, 12), 60, keep_clear_m=KEEP)
    assert e.value.key == "rooms" and "expected at most" in e.value.message and "got 60" in e.value.message
