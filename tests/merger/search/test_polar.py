"""merger.search.polar: the rotation-only bounds of every whole degree at once (Lemma 6) — never below
the exact value at any angle, tight enough to rule out angles far from a map's own rotation; the polar
tables of uniform maps; and the angle shift of :func:`angle_bounds` (a point in bin f reads bin f − θ)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid
from merger.search import RotationProblem, reference_search, searcher_for
from merger.search.polar import angle_bounds, polar_tables
from merger.search.prepared import Prepared
from merger.synthetic import arc_viewpoints, partial_view, room_scene
from tests.strategies import adversarial_problem

COARSE = np.arange(360.0)


@settings(max_examples=15, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10**6), measure=st.sampled_from(["similarity", "birk_carpin", "ncc"]))
def test_the_polar_bounds_are_never_below_the_exact_value(seed, measure):
    p = adversarial_problem(seed, measure, False)
    s = searcher_for(p)
    bounds = s.polar_bounds()
    exact = np.array([s.values(float(th), [(0, 0)])[0] for th in COARSE])
    assert bounds.shape == (360,)
    assert np.all(bounds >= exact - 1e-12), np.flatnonzero(bounds < exact - 1e-12)


@pytest.mark.parametrize("turn", [0.0, 70.0, 213.0])
def test_the_bounds_rule_out_angles_far_from_a_maps_rotation(turn):
    """A room's view against the same room seen in a frame turned by ``turn``: the bound holds at the
    truth (the search finds it) and is below the answer at most angles far from it, which is what lets
    the branch and bound skip them."""
    scene = room_scene(np.random.default_rng(11))
    vps = arc_viewpoints(100.0, 40.0, 1.8, k=3)
    g, c = partial_view(scene, (0.0, 0.0, 0.0), vps, size_m=8.0)
    h, ch = partial_view(scene, (0.0, 0.0, math.radians(turn)), vps, size_m=8.0)
    p = RotationProblem(g, h, c, ch, 4.0, "similarity", 0.0)
    bounds = searcher_for(p).polar_bounds()
    ans = reference_search(p)
    assert abs((ans.theta_deg - turn + 180) % 360 - 180) <= 1.0
    assert bounds[int(round(ans.theta_grid_deg)) % 360] >= ans.profile.max() - 1e-12
    far = np.abs((COARSE - turn + 180) % 360 - 180) > 20
    assert np.mean(bounds[far] < ans.score) > 0.5


def _tables(states, roi_m=2.0):
    g = OccupancyGrid(states, 0.05, (-2.0, -2.0))  # 4 m square, the center (0, 0) in its middle
    return Prepared(RotationProblem(g, g, (0.0, 0.0), (0.0, 0.0), roi_m, "similarity", 0.0)).tables


def test_polar_tables_of_uniform_maps():
    """ring width one cell: all occupied → every polar cell may hold an occupied cell out to the grid;
    all free → every polar cell well inside the ROI's square (half 1 m) is surely free, none beyond it;
    all unknown → neither, anywhere."""
    n_rings, ring_w = 60, 0.05
    inner = int(1.0 / math.sqrt(2) / ring_w) - 2  # rings wholly inside the 1 m half-side square
    occ, not_free = polar_tables(_tables(np.full((80, 80), OCCUPIED_S, np.uint8)), ring_w, n_rings)
    assert occ.shape == not_free.shape == (n_rings, 360)
    assert occ[:40].all() and not_free.all()  # out to 2 m (the grid's half side) every cell is occupied
    occ, not_free = polar_tables(_tables(np.full((80, 80), FREE_S, np.uint8)), ring_w, n_rings)
    assert not occ.any()
    assert not not_free[:inner].any()
    # the ROI is a square of half side 1 m: past it a lookup is unknown. Rings beyond its corners
    # (√2 m) are nowhere surely free; a ring at 1.05–1.10 m is past the square along the axes but inside
    # it on the diagonals
    assert not_free[int(math.sqrt(2) / ring_w) + 1:].all()
    assert not_free[21, [0, 90, 180, 270]].all() and not not_free[21, [44, 135, 225, 315]].any()
    occ, not_free = polar_tables(_tables(np.full((80, 80), UNKNOWN_S, np.uint8)), ring_w, n_rings)
    assert not occ.any() and not_free.all()


def test_angle_bounds_shift_a_point_by_the_angle():
    """A point at radius 0.125 (ring 2 of 5 cm) and bearing 37.5° (bin 37): under θ it reads bin
    37 − θ (mod 360). may_occ marks one polar cell (ring 2, bin 300) and sure-free another (ring 2,
    bin 10): agr̃ ≤ 1 exactly at θ = 37 − 300 mod 360 = 97, dis ≥ 1 exactly at θ = 27."""
    may = np.zeros((6, 360), np.uint8)
    not_free = np.ones((6, 360), np.uint8)
    may[2, 300] = 1
    not_free[2, 10] = 0
    r, phi = 0.125, math.radians(37.5)
    agr, dis = angle_bounds(np.array([r * math.cos(phi)]), np.array([r * math.sin(phi)]), may, not_free, 0.05)
    assert np.flatnonzero(agr).tolist() == [97] and agr[97] == 1
    assert np.flatnonzero(dis).tolist() == [27] and dis[27] == 1
    # two points add up; a point beyond the last ring counts nowhere (outside: unknown)
    agr2, dis2 = angle_bounds(np.array([r * math.cos(phi)] * 2 + [1.0]), np.array([r * math.sin(phi)] * 2 + [0.0]),
                              may, not_free, 0.05)
    assert agr2.sum() == 2 and agr2[97] == 2 and dis2[27] == 2 and dis2.sum() == 2


def test_a_point_on_a_bin_edge_counts_in_both_bins():
    """Bearing exactly 0° lies on the edge of bins 359 and 0: the bound ORs the occupied marks of both
    and needs both surely free."""
    may = np.zeros((4, 360), np.uint8)
    may[1, 359] = 1  # under θ the point reads bins −θ and −1 − θ: 359 at θ = 0 (bin −1) and θ = 1 (bin 0 − 1)
    agr, _ = angle_bounds(np.array([0.075]), np.array([0.0]), may, np.ones((4, 360), np.uint8), 0.05)
    assert np.flatnonzero(agr).tolist() == [0, 1]
    not_free = np.ones((4, 360), np.uint8)
    not_free[1, 0] = 0  # only one of the two bins surely free: no disagreement is sure
    _, dis = angle_bounds(np.array([0.075]), np.array([0.0]), np.zeros((4, 360), np.uint8), not_free, 0.05)
    assert not dis.any()
    not_free[1, 359] = 0
    _, dis = angle_bounds(np.array([0.075]), np.array([0.0]), np.zeros((4, 360), np.uint8), not_free, 0.05)
    assert np.flatnonzero(dis).tolist() == [0]  # bins 0 and 359 both free only under θ = 0
