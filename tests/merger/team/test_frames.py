"""merger.team.frames: placements composed onto another map's frame place every point as the two
placements do; a translated placement's source center makes the canvas's rotation about c_f land x_k where
x_f = c_f + t + R(θ)(x_k − c_k) puts it; and the maps placed on map 0's frame read, cell by cell, the map cell
that formula sends each canvas cell centre to (rotations of 90° with centers on cell centres: exact)."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from merger.grid import OccupancyGrid
from merger.team.frames import Warps, _source_center, compose, fused_layers, place_on_frame0, shifted
from merger.team.params import MapInput
from merger.transform import rotation

coord = st.floats(-20, 20, allow_nan=False)
angle = st.floats(0, 360, allow_nan=False, exclude_max=True)


def place(theta, t, c_to, c_from, x):
    """x_to = c_to + t + R(θ)(x − c_from)."""
    return np.asarray(c_to) + np.asarray(t) + rotation(theta) @ (np.asarray(x) - np.asarray(c_from))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(angle, coord, coord, coord, coord), min_size=2, max_size=5), st.data())
def test_compose_places_points_as_the_two_placements(rows, data):
    onto_first = {k: (th, (tx, ty)) for k, (th, tx, ty, _, _) in enumerate(rows)}
    onto_first[0] = (0.0, (0.0, 0.0))
    centers = [(cx, cy) for (_, _, _, cx, cy) in rows]
    base = data.draw(st.integers(0, len(rows) - 1))
    out = compose(onto_first, 0, base)
    assert out[base] == (0.0, (0.0, 0.0))
    x = np.array([1.3, -0.7])
    th_b, t_b = onto_first[base]
    for k, (th, t) in onto_first.items():
        x_first = place(th, t, centers[0], centers[k], x)
        # back from the first map's frame to base's: x_b = c_b + R(−θ_b)(x_f − c_f − t_b)
        want = np.asarray(centers[base]) + rotation(-th_b) @ (x_first - np.asarray(centers[0]) - np.asarray(t_b))
        np.testing.assert_allclose(place(*out[k], centers[base], centers[k], x), want, atol=1e-9)
        assert 0 <= out[k][0] < 360


@settings(max_examples=150, deadline=None)
@given(angle, coord, coord, coord, coord, coord, coord)
def test_the_source_center_moves_the_placement_by_t(theta, tx, ty, cx, cy, fx, fy):
    s = _source_center((cx, cy), theta, (tx, ty))
    x = np.array([0.4, 2.5])
    np.testing.assert_allclose(place(theta, (0.0, 0.0), (fx, fy), s, x), place(theta, (tx, ty), (fx, fy), (cx, cy), x),
                               atol=1e-9)
    assert shifted((cx, cy), (tx, ty)) == (cx + tx, cy + ty) and shifted((cx, cy), (0.0, 0.0)) == (cx, cy)


def cell_state(g: OccupancyGrid, p) -> int:
    c = math.floor((p[0] - g.origin[0]) / g.resolution)
    r = math.floor((p[1] - g.origin[1]) / g.resolution)
    return int(g.states[r, c]) if 0 <= r < g.height and 0 <= c < g.width else 0


def test_maps_placed_on_frame0_read_the_cell_the_placement_sends_each_cell_centre_to():
    rng = np.random.default_rng(11)
    res = 0.05
    g0 = OccupancyGrid(rng.integers(0, 3, (30, 24)).astype(np.uint8), res, (-0.6, -0.3))
    g1 = OccupancyGrid(rng.integers(0, 3, (18, 26)).astype(np.uint8), res, (1.0, 2.0))
    g2 = OccupancyGrid(rng.integers(0, 3, (20, 20)).astype(np.uint8), res, (0.0, 0.0))
    c0 = (g0.origin[0] + 12.5 * res, g0.origin[1] + 15.5 * res)  # centers on cell centres
    c1 = (g1.origin[0] + 13.5 * res, g1.origin[1] + 9.5 * res)
    c2 = (g2.origin[0] + 10.5 * res, g2.origin[1] + 10.5 * res)
    maps = [MapInput("a", g0, c0), MapInput("b", g1, c1), MapInput("c", g2, c2)]
    place0 = {0: (0.0, (0.0, 0.0)), 1: (90.0, (2 * res, -res)), 2: (270.0, (0.0, 3 * res))}
    layers = place_on_frame0(maps, place0)
    assert len({(g.shape, g.origin) for g in layers}) == 1  # one canvas
    canvas = layers[0]
    rows, cols = np.indices(canvas.shape)
    centres = np.stack([canvas.origin[0] + (cols + 0.5) * res, canvas.origin[1] + (rows + 0.5) * res], axis=-1)
    for k, layer in enumerate(layers):
        th, t = place0[k]
        want = np.empty(canvas.shape, np.uint8)
        for r in range(canvas.height):
            for c in range(canvas.width):
                x_k = np.asarray(maps[k].center) + rotation(-th) @ (centres[r, c] - np.asarray(c0) - np.asarray(t))
                want[r, c] = cell_state(maps[k].grid, x_k)
        np.testing.assert_array_equal(layer.states, want)
        assert (layer.states != 0).sum() == (maps[k].grid.states != 0).sum()  # every known cell placed once
    by_name = fused_layers(maps, {"a": 0.0, "b": 90.0, "c": 270.0}, {"b": (2 * res, -res), "c": (0.0, 3 * res)})
    for a, b in zip(by_name, layers, strict=True):
        np.testing.assert_array_equal(a.states, b.states)
    w = Warps(maps)
    assert w.get(0, 1, 90.0, (2 * res, -res)) is w.get(0, 1, 90.0, (2 * res, -res))  # computed once
    assert w.get(0, 0, 0.0) is g0
