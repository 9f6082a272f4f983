"""merger.algorithms.hough (Carpin's Hough spectrum): the spectrum turns with the map, the spectra's
cross-correlation peaks at the known turn, the projections' correlation recovers a known whole-cell
shift, a known placement of a generated room is found, and refusals say why."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from merger.algorithms.hough import AI_MIN, HYPOTHESES, align, rotation_hypotheses, spectrum, translation
from merger.grid import FREE_S, OCCUPIED_S, OccupancyGrid
from merger.search import angle_diff_deg
from merger.synthetic import arc_viewpoints, partial_view, room_scene
from merger.team.orders import MapInput, MergeParams


def _cloud(seed, n=60):
    """Random points (metres) anywhere: ρ/res falls on a rounding tie (x.5) with probability 0."""
    return np.random.default_rng(seed).uniform(-2.0, 2.0, size=(n, 2))


@pytest.mark.parametrize("seed", range(3))
def test_the_spectrum_is_normalized_and_a_quarter_turn_shifts_it_by_90(seed):
    """Turning the points by 90° ((x, y) → (−y, x), exact in floats) gives ρ(θ) of the turned points =
    ρ(θ − 90°) of the original: the spectrum circularly shifted by 90 cells."""
    pts = _cloud(seed)
    hs = spectrum(pts, 0.05)
    assert hs.shape == (360,) and hs.max() == 1.0 and hs.min() >= 0.0
    turned = np.stack([-pts[:, 1], pts[:, 0]], axis=1)
    assert np.allclose(spectrum(turned, 0.05), np.roll(hs, 90), atol=1e-9)
    # and a half turn: the same spectrum shifted by 180 (ρ changes sign, the squares do not)
    assert np.allclose(spectrum(-pts, 0.05), np.roll(hs, 180), atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(shift=st.integers(0, 359), seed=st.integers(0, 10**6))
def test_the_first_hypothesis_is_the_known_turn(shift, seed):
    """HS_ref(θ) = HS_mov(θ − α): the cross-correlation's highest peak is α (Cauchy–Schwarz; a random
    spectrum has no other shift equal to itself), listed first with α ± 1°."""
    hs_mov = np.random.default_rng(seed).random(360)
    hyps = rotation_hypotheses(np.roll(hs_mov, shift), hs_mov)
    assert len(hyps) == 3 * HYPOTHESES
    assert hyps[:3] == [float(shift), float((shift + 1) % 360), float((shift - 1) % 360)]
    assert all(0.0 <= h < 360.0 for h in hyps)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6), dx=st.integers(-30, 30), dy=st.integers(-30, 30))
def test_the_projections_recover_a_whole_cell_shift(seed, dx, dy):
    pts = np.random.default_rng(seed).integers(-40, 40, size=(80, 2)) * 0.05 + 0.025  # cell centres
    moved = pts - np.array([dx, dy]) * 0.05
    sx, sy = translation(pts, moved, 0.05)
    assert sx == pytest.approx(dx * 0.05, abs=1e-9) and sy == pytest.approx(dy * 0.05, abs=1e-9)


@pytest.fixture(scope="module")
def room():
    scene = room_scene(np.random.default_rng(5))
    vps = arc_viewpoints(60.0, 60.0, 1.8, k=5)
    return scene, vps


@pytest.mark.parametrize("turn", [90.0, 180.0, 270.0])
def test_a_known_placement_of_a_generated_room_is_found(room, turn):
    """One room mapped from the same viewpoints in two frames at the same place turned by a quarter turn
    multiple (the rasters are the same cells turned): θ = ``turn``, and both centers are the scene's center,
    so t = 0."""
    scene, vps = room
    g, c = partial_view(scene, (0.0, 0.0, 0.0), vps, size_m=10.0)
    h, ch = partial_view(scene, (0.0, 0.0, math.radians(turn)), vps, size_m=10.0)
    a = align(MapInput("ref", g, c), MapInput("mov", h, ch), MergeParams())
    assert a.accepted, a.reason
    assert abs(angle_diff_deg(a.theta_deg, turn)) <= 1.0
    assert math.hypot(*a.translation_m) <= 0.1
    assert a.score == a.evidence["acceptance_index"] >= AI_MIN
    tried = dict((th, ai) for th, ai in a.evidence["hypotheses"])
    assert len(a.evidence["hypotheses"]) == 3 * HYPOTHESES and tried[a.theta_deg] == max(tried.values())


def test_too_few_occupied_cells_are_refused():
    st_ = np.full((50, 50), FREE_S, np.uint8)
    st_[10, 10] = OCCUPIED_S
    one = OccupancyGrid(st_, 0.05, (0.0, 0.0))
    a = align(MapInput("a", one, (1.0, 1.0)), MapInput("b", one, (1.0, 1.0)), MergeParams())
    assert not a.accepted and a.theta_deg is None and a.reason == "hough: too few occupied cells (1 and 1)"


def test_a_support_floor_above_the_overlap_refuses_a_good_fit(room):
    scene, vps = room
    g, c = partial_view(scene, (0.0, 0.0, 0.0), vps, size_m=10.0)
    ok = align(MapInput("a", g, c), MapInput("b", g, c), MergeParams())
    assert ok.accepted and ok.theta_deg == 0.0 and ok.score == 1.0  # a map on itself
    floor = ok.evidence["support"] + 1
    a = align(MapInput("a", g, c), MapInput("b", g, c), MergeParams(min_support=floor))
    assert not a.accepted and a.theta_deg == 0.0
    assert a.reason == f"hough: ω rests on {ok.evidence['support']} occupied cells < {floor}"


def test_unrelated_maps_are_refused_for_a_low_acceptance_index():
    rng = np.random.default_rng(8)
    a_ = OccupancyGrid(rng.choice(3, size=(80, 80), p=[0.3, 0.5, 0.2]).astype(np.uint8), 0.05, (0.0, 0.0))
    b_ = OccupancyGrid(rng.choice(3, size=(80, 80), p=[0.3, 0.5, 0.2]).astype(np.uint8), 0.05, (0.0, 0.0))
    a = align(MapInput("a", a_, (2.0, 2.0)), MapInput("b", b_, (2.0, 2.0)), MergeParams())
    ai = a.evidence["acceptance_index"]
    assert not a.accepted and ai < AI_MIN and a.reason == f"hough: acceptance index ω {ai:.3f} < {AI_MIN:g}"
    assert a.theta_deg is not None  # the best refused hypothesis is kept


@pytest.mark.parametrize("turn, p", [(90.0, (0.5, -0.25)), (180.0, (-0.3, 0.6)), (270.0, (0.0, 0.45))])
def test_the_placement_about_any_two_centers(room, turn, p):
    """The moving frame at (p, turn) in the reference's, whole cells and quarter turns (the same cells):
    with centers that are not one point, x_ref = c_ref + t + R(θ)(x_mov − c_mov) gives
    t* = R(turn)·c_mov + p − c_ref."""
    scene, vps = room
    g, _ = partial_view(scene, (0.0, 0.0, 0.0), vps, size_m=10.0)
    h, _ = partial_view(scene, (p[0], p[1], math.radians(turn)), vps, size_m=10.0)
    c_ref, c_mov = (0.3, 0.2), (-0.5, 0.4)
    a = align(MapInput("ref", g, c_ref), MapInput("mov", h, c_mov), MergeParams())
    assert a.accepted, a.reason
    r = math.radians(turn)
    want = (math.cos(r) * c_mov[0] - math.sin(r) * c_mov[1] + p[0] - c_ref[0],
            math.sin(r) * c_mov[0] + math.cos(r) * c_mov[1] + p[1] - c_ref[1])
    assert abs(angle_diff_deg(a.theta_deg, turn)) <= 1.0
    # the translation is the peak of the projections' correlation, not refined by ω: views rasterized in
    # two frames differ in ~1 % of their cells, which can move that peak by a cell (at 180° here, where ω
    # itself prefers the truth); within two cells, as the real-map test allows
    assert math.dist(a.translation_m, want) <= 0.1
