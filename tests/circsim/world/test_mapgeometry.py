"""A map world's walls (circsim.world.mapgeometry) and what the laser sees of them: the cell edges between
free and solid cells, checked against the map itself (merger.synthetic.grid_ray_cast)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.config.types import LaserConfig
from circsim.world import laser
from circsim.world.mapgeometry import boundary_segments
from circsim.world.motion import trajectories
from circsim.world.world import World
from merger.grid import Cell, OccupancyGrid
from merger.io.mapio import load_map
from merger.synthetic import grid_ray_cast
from tests.paths import REAL_MAP


def test_a_free_block_is_bounded_by_four_merged_edges_and_solid_blocks_draw_no_inside():
    solid = np.ones((6, 7), bool)
    solid[1:4, 2:6] = False  # free cells: rows 1..3, columns 2..5
    seg = boundary_segments(solid, 0.5, (-1.0, 2.0))
    expect = {(0.0, 2.5, 2.0, 2.5), (0.0, 4.0, 2.0, 4.0),  # bottom and top: y = 2 + 0.5 * (1, 4)
              (0.0, 2.5, 0.0, 4.0), (2.0, 2.5, 2.0, 4.0)}  # left and right: x = -1 + 0.5 * (2, 6)
    assert {tuple(map(float, s)) for s in seg} == expect


def test_free_cells_on_the_map_edge_are_closed_by_the_edge_and_a_solid_cell_inside_gets_its_square():
    solid = np.zeros((3, 3), bool)
    solid[1, 1] = True
    seg = boundary_segments(solid, 1.0, (0.0, 0.0))
    # the map's outline (beyond it is solid) and the inner cell's four sides
    assert len(seg) == 8
    lengths = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    assert sorted(lengths.tolist()) == [1.0] * 4 + [3.0] * 4


def office_world():
    sc = load_scenario(bundled_scenarios()["office"])
    return sc, World.from_scenario(sc)


def test_office_world_is_its_map_walls():
    sc, w = office_world()
    grid = load_map(REAL_MAP)
    seg = w.geometry().segments
    assert len(seg) == len(boundary_segments(grid.states != Cell.FREE, grid.resolution, grid.origin))
    # every wall lies on a cell edge of the map
    for k in range(4):
        q = (seg[:, k] - grid.origin[k % 2]) / grid.resolution
        assert np.allclose(q, np.rint(q), atol=1e-9)


@pytest.mark.parametrize("method", ["numpy", "pymunk"])
def test_the_laser_sees_the_maps_walls_where_the_map_has_them(method):
    """From every robot's start and from points of the office scenario's circle, each beam's range against
    a ray marched through the map itself: the march never stops before the laser's return (no free cell
    is seen through), the point just past the laser's return is in a solid cell of the map (the laser
    stops at a wall the map has), and the march, which samples every quarter cell, stops within a sample
    of it on all but the beams that only graze a cell's corner."""
    sc, w = office_world()
    grid = load_map(REAL_MAP)
    cfg = LaserConfig()
    step = 0.25 * grid.resolution
    poses = [t.start_pose() for t in trajectories(sc).values()]
    cx, cy = sc.world.center
    poses += [(cx + 0.9 * math.cos(a), cy + 0.9 * math.sin(a), a) for a in np.radians([10, 100, 200, 290])]
    close = total = 0
    for i, (x, y, yaw) in enumerate(poses):
        name = w.robot_names[0]
        w.set_robot_pose(name, 1e3, 1e3, 0.0)  # the laser's own body is excluded; the others are parked away
        for other in w.robot_names[1:]:
            w.set_robot_pose(other, 2e3 + 10 * i, 2e3, 0.0)
        ranges = laser.cast(w, name, (x, y, yaw), cfg, method=method)
        angles = yaw + cfg.angle_min + np.arange(cfg.beams) * cfg.angle_increment
        march, _ = grid_ray_cast(grid, (x, y), angles, cfg.range_max_m)
        assert np.all(march >= ranges - 1e-9)
        hit = np.isfinite(ranges)
        assert hit.mean() > 0.5  # an office: most beams meet a wall within 5.6 m
        past = np.stack([x + (ranges[hit] + 1e-7) * np.cos(angles[hit]),
                         y + (ranges[hit] + 1e-7) * np.sin(angles[hit])], axis=1)
        col = np.floor((past[:, 0] - grid.origin[0]) / grid.resolution).astype(int)
        row = np.floor((past[:, 1] - grid.origin[1]) / grid.resolution).astype(int)
        assert np.all(grid.states[row, col] != Cell.FREE)
        close += int(np.sum(march[hit] - ranges[hit] <= step + 1e-9)) + int(np.sum(~hit & np.isinf(march)))
        total += cfg.beams
    assert close / total > 0.97, close / total


def test_a_hand_made_map_world_gives_the_ranges_of_its_cells():
    """A 4 x 3 m free room in a 5 cm map, one occupied cell block inside: the analytic ranges."""
    states = np.full((80, 100), Cell.UNKNOWN, np.uint8)
    states[10:70, 10:90] = Cell.FREE  # x in [0.5, 4.5), y in [0.5, 3.5) with origin (0, 0)
    states[30:40, 60:70] = Cell.OCCUPIED  # a block at x [3, 3.5), y [1.5, 2)
    grid = OccupancyGrid(states, 0.05, (0.0, 0.0))
    w = World()
    w.add_walls(boundary_segments(grid.states != Cell.FREE, grid.resolution, grid.origin))
    w.add_robot("r", 0.1, (2.0, 1.75, 0.0))
    cfg = LaserConfig(fov_deg=360, beams=4)
    r = laser.cast(w, "r", (2.0, 1.75, 0.0), cfg)
    angles = cfg.angle_min + np.arange(4) * cfg.angle_increment
    expect = {0.0: 1.0, 90.0: 1.75, 180.0: 1.5, 270.0: 1.25}  # east hits the block at x = 3
    for a, got in zip(np.degrees(angles) % 360, r, strict=True):
        assert got == pytest.approx(expect[round(a) % 360], abs=1e-9)


def test_the_compiled_path_for_many_walls_gives_the_numpy_paths_bits(monkeypatch):
    """Above laser._MANY segments the walls within reach go through one compiled loop
    (circsim.world.raykernel); it must give exactly the ranges of the numpy pairs it replaces, also with
    a laser that wraps past 2π, and segments out of reach change nothing."""
    sc, w = office_world()
    seg = w.geometry().segments
    circ = w.geometry().circles
    rng = np.random.default_rng(4)
    cx, cy = sc.world.center
    cases = [((cx + 0.8 * math.cos(a), cy + 0.8 * math.sin(a)), float(rng.uniform(-7, 7)), n, fov)
             for a, n, fov in zip(rng.uniform(0, 2 * math.pi, 12), [667, 360, 1081] * 4,
                                  [240, 360, 270] * 4, strict=True)]
    for origin, start, beams, fov in cases:
        inc = math.radians(fov) / (beams - (fov < 360))
        args = (origin, start, inc, beams, 5.6, seg, circ)
        fast = laser.raycast(*args)
        monkeypatch.setattr(laser, "_MANY", 10**9)
        slow = laser.raycast(*args)
        monkeypatch.undo()
        assert np.array_equal(fast, slow) and np.isfinite(fast).sum() > beams // 2


def test_numpy_and_pymunk_agree_in_a_map_world():
    """The two casters over the office's 3,032 walls (the compiled path against pymunk's own queries)."""
    sc, w = office_world()
    for name, traj in trajectories(sc).items():
        pose = traj.start_pose()
        a = laser.cast(w, name, pose, sc.laser, method="numpy")
        b = laser.cast(w, name, pose, sc.laser, method="pymunk")
        assert np.array_equal(np.isfinite(a), np.isfinite(b))
        assert np.allclose(a[np.isfinite(a)], b[np.isfinite(b)], rtol=0, atol=1e-9)
