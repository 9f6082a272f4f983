"""circsim.record.entities: frames convert both ways, the fast overlay is the overlay it tabulates, maps are
cropped to their known cells and logged upside down with their corner's position, the scene's geometry
split into walls, pillars and the other objects, and the default blueprint builds for any robot names."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rerun.blueprint as rrb
from hypothesis import given, settings
from hypothesis import strategies as st

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.record.entities import (
    CROP_MARGIN_CELLS,
    circle_points,
    default_blueprint,
    dim_colour,
    entity_part,
    from_frame,
    json_block,
    known_window,
    overlay_fast,
    rr_grid_map,
    split_geometry,
    to_frame,
)
from circsim.world.world import World
from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid
from merger.io.overlay import overlay_rgb

coord = st.floats(-50, 50)


@settings(max_examples=60, deadline=None)
@given(x=coord, y=coord, px=coord, py=coord, yaw=st.floats(-7, 7))
def test_to_frame_and_from_frame_are_inverse(x, y, px, py, yaw):
    pose = (px, py, yaw)
    back = from_frame(to_frame((x, y), pose), pose)
    assert back == pytest.approx((x, y), abs=1e-9)


def test_a_point_in_a_turned_frame():
    # a frame at (1, 2) facing +y: the world point (1, 3) is 1 m straight ahead, (0, 2) 1 m to its left
    pose = (1.0, 2.0, math.pi / 2)
    assert to_frame((1.0, 3.0), pose) == pytest.approx((1.0, 0.0), abs=1e-12)
    assert to_frame((0.0, 2.0), pose) == pytest.approx((0.0, 1.0), abs=1e-12)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 6])
def test_the_fast_overlay_is_the_overlay(n):
    rng = np.random.default_rng(n)
    layers = [rng.integers(0, 3, (17, 23)).astype(np.uint8) for _ in range(n)]
    names = [f"r{k}" for k in range(n)]
    assert np.array_equal(overlay_fast(layers, names), overlay_rgb(layers, names))


def test_entity_parts_and_colours():
    assert entity_part("Lyon") == "Lyon" and entity_part("a b/c.d") == "a_b_c_d" and entity_part(3) == "3"
    assert dim_colour((0, 100, 255)) == (127, 177, 255)  # halfway to white


def test_the_known_window_is_the_known_cells_plus_a_margin():
    a = np.zeros((200, 300), np.uint8)
    a[50:60, 100:120] = FREE_S
    b = np.zeros_like(a)
    b[150, 10] = OCCUPIED_S
    rs, cs = known_window([a, b])
    m = CROP_MARGIN_CELLS
    assert (rs, cs) == (slice(50 - m, 151 + m), slice(0, 120 + m))  # the far corner clipped at the grid
    assert known_window([np.zeros((4, 5), np.uint8)]) == (slice(0, 4), slice(0, 5))
    assert known_window([a], margin=0) == (slice(50, 60), slice(100, 120))


def test_a_grid_map_is_cropped_flipped_and_placed_at_its_window():
    st_ = np.zeros((100, 80), np.uint8)
    st_[40, 30] = OCCUPIED_S  # one occupied cell: the window is it ± the margin
    st_[41, 30] = FREE_S
    g = OccupancyGrid(st_, 0.05, (-2.0, -1.0))
    gm = rr_grid_map(g, 0.1)
    m = CROP_MARGIN_CELLS
    rows, cols = slice(40 - m, 42 + m), slice(30 - m, 31 + m)
    want = np.flipud(g.to_ros()[rows, cols])
    data = np.frombuffer(bytes(gm.data.as_arrow_array()[0].values.to_numpy()), np.uint8)
    assert np.array_equal(data.view(np.int8).reshape(want.shape), want)
    assert gm.translation.as_arrow_array().to_pylist()[0] == pytest.approx(
        [-2.0 + (30 - m) * 0.05, -1.0 + (40 - m) * 0.05, 0.1])
    assert gm.cell_size.as_arrow_array().to_pylist()[0] == pytest.approx(0.05)


def test_circle_points_close_on_the_circle():
    p = circle_points(1.0, -2.0, 0.5, 12)
    assert p.shape == (13, 3) and np.allclose(p[0], p[-1]) and not p[:, 2].any()
    assert np.allclose(np.hypot(p[:, 0] - 1.0, p[:, 1] + 2.0), 0.5)


def test_the_scenes_geometry_is_split_into_walls_pillars_and_objects():
    sc = load_scenario(bundled_scenarios()["scene1"])
    geo = World.from_scenario(sc).geometry()
    walls, pillars, objects = split_geometry(sc, geo)
    assert len(walls) == len(sc.world.room.wall_segments()) and len(pillars) == len(sc.world.pillars)
    # every segment and circle of the world is drawn once: as a wall, a pillar or an object
    assert len(walls) + len(pillars) + len(objects) == len(geo.segments) + len(geo.circles)
    for w in walls:
        assert (*w[0, :2], *w[1, :2]) in {tuple(s) for s in sc.world.room.wall_segments()}


def test_a_json_block_writes_floats_as_the_run_json():
    assert json_block({"t": 0.1 + 0.2}) == '```json\n{\n  "t": 0.3\n}\n```\n'


def test_the_default_blueprint_builds_for_any_names():
    bp = default_blueprint(["Lyon", "a b/c"], (0.5, 0.3), {"Lyon": (0.0, 0.0), "a b/c": (1.0, 2.0)})
    assert isinstance(bp, rrb.Blueprint)
