"""merger.algorithms.features (m-explore map_merge's ORB pipeline): the grid as the pipeline's image, the
two-way ratio-test matches, a known placement of a real map found (a turn other than the module test's),
deterministic, its confidence as Brown and Lowe's formula, and refusals that say why."""

from __future__ import annotations

import math

import numpy as np
import pytest

from merger.algorithms.features import CONFIDENCE_MIN, MIN_SIDE, align, image, matches
from merger.grid import FREE_S, OCCUPIED_S, UNKNOWN_S, OccupancyGrid
from merger.io.mapio import load_map
from merger.search import angle_diff_deg
from merger.team.orders import MapInput
from merger.transform import sample_nearest
from tests.paths import REAL_MAP


def moved(g: OccupancyGrid, yaw_deg: float, p) -> OccupancyGrid:
    """``g`` seen from a frame whose pose in g's frame is (yaw, p): x_g = R(yaw) x_new + p (nearest cells)."""
    a = math.radians(yaw_deg)
    c, s = math.cos(a), math.sin(a)
    corners = np.array([[g.origin[0] + dx * g.width * g.resolution, g.origin[1] + dy * g.height * g.resolution]
                        for dx in (0, 1) for dy in (0, 1)]) - p
    local = corners @ np.array([[c, -s], [s, c]])
    lo, hi = local.min(0), local.max(0)
    res = g.resolution
    w, h = int(math.ceil((hi[0] - lo[0]) / res)), int(math.ceil((hi[1] - lo[1]) / res))
    yy, xx = np.mgrid[0:h, 0:w]
    q = np.stack([lo[0] + (xx + 0.5) * res, lo[1] + (yy + 0.5) * res], axis=-1).reshape(-1, 2)
    xg = q @ np.array([[c, s], [-s, c]]) + p
    return OccupancyGrid(sample_nearest(g, xg).reshape(h, w), res, (float(lo[0]), float(lo[1])))


YAW, P = 200.0, (-0.4, 0.6)  # the moving frame's pose in the map's frame


@pytest.fixture(scope="module")
def office():
    """The real office map and itself seen from a frame turned 200° and moved (−0.4, 0.6) m; both centers
    are the map's middle (the same world point): the truth is θ = 200°, t = 0."""
    g = load_map(str(REAL_MAP))
    yaw, p = YAW, np.array(P)
    c_ref = (float(g.origin[0] + 0.5 * g.width * g.resolution), float(g.origin[1] + 0.5 * g.height * g.resolution))
    a = math.radians(yaw)
    d = np.asarray(c_ref) - p
    c_mov = (math.cos(a) * d[0] + math.sin(a) * d[1], -math.sin(a) * d[0] + math.cos(a) * d[1])
    return MapInput("ref", g, c_ref), MapInput("mov", moved(g, yaw, p), c_mov), yaw


def test_the_image_is_the_pipelines_bytes():
    g = OccupancyGrid(np.array([[UNKNOWN_S, FREE_S], [OCCUPIED_S, FREE_S]], np.uint8), 0.05, (0.0, 0.0))
    img = image(g)
    assert img.dtype == np.uint8 and img.tolist() == [[255, 0], [100, 0]]


def test_matches_are_the_two_way_ratio_test_each_pair_once():
    """Distinct random descriptors and the same set permuted: every descriptor matches its copy (distance
    0 against a second nearest > 0), found both ways but listed once; a descriptor with no copy and two
    equally near ones fails the ratio test."""
    rng = np.random.default_rng(0)
    d_ref = rng.integers(0, 256, size=(40, 32), dtype=np.uint8)
    perm = rng.permutation(40)
    d_mov = d_ref[perm]
    got = matches(d_mov, d_ref)
    assert sorted(got) == sorted((m, int(perm[m])) for m in range(40))
    assert len(got) == len(set(got)) == 40
    twin = np.vstack([d_ref[:1], d_ref[:1]])  # two identical reference descriptors: no unique nearest
    assert matches(d_ref[:1], twin) == []


def test_a_known_placement_of_a_real_map_is_found_and_is_deterministic(office):
    ref, mov, yaw = office
    a = align(ref, mov)
    assert a.accepted, a.reason
    assert abs(angle_diff_deg(a.theta_deg, yaw)) <= 1.0
    assert math.hypot(*a.translation_m) <= 0.1
    ev = a.evidence
    assert ev["confidence"] == pytest.approx(ev["inliers"] / (8 + 0.3 * ev["matches"]))
    assert a.score == ev["confidence"] >= CONFIDENCE_MIN
    assert ev["scale"] == pytest.approx(1.0, abs=0.02)  # two maps of one resolution
    assert align(ref, mov) == a  # RANSAC seeded: the same answer every time


def test_a_map_too_small_for_orb_is_refused_naming_its_size(office):
    ref, _, _ = office
    tiny = OccupancyGrid(np.full((MIN_SIDE - 1, 200), FREE_S, np.uint8), 0.05, (0.0, 0.0))
    a = align(ref, MapInput("tiny", tiny, (1.0, 1.0)))
    assert not a.accepted and a.theta_deg is None
    assert a.reason.startswith("features: tiny is 62 × 200 cells") and str(MIN_SIDE) in a.reason


def test_a_featureless_map_is_refused(office):
    ref, _, _ = office
    blank = OccupancyGrid(np.full((100, 100), FREE_S, np.uint8), 0.05, (0.0, 0.0))
    a = align(ref, MapInput("blank", blank, (2.5, 2.5)))
    assert not a.accepted and a.theta_deg is None and "too few ORB features (0 and" in a.reason


def test_unrelated_maps_are_refused_for_too_few_matches(office):
    ref, _, _ = office
    rng = np.random.default_rng(3)
    noise = OccupancyGrid(rng.choice(3, size=(120, 120), p=[0.6, 0.3, 0.1]).astype(np.uint8), 0.05, (0.0, 0.0))
    a = align(ref, MapInput("noise", noise, (3.0, 3.0)))
    n = a.evidence["matches"]
    assert not a.accepted and a.theta_deg is None and n < 6
    assert a.reason == f"features: {n} matches, fewer than 6"


def test_a_mirrored_map_has_no_rigid_placement_and_is_refused_with_its_figures(office):
    """The map mirrored left to right: features match (ORB is not mirror-invariant, but corners and
    their neighbourhoods often are near enough), yet no rotation and translation lays a mirror image on
    the original; the fit's confidence is below the floor and the reason spells out the formula."""
    ref, _, _ = office
    g = ref.grid
    mirror = MapInput("mirror", OccupancyGrid(g.states[:, ::-1].copy(), g.resolution, g.origin), ref.center)
    a = align(ref, mirror)
    ev = a.evidence
    assert not a.accepted and ev["matches"] >= 6
    assert ev["confidence"] == pytest.approx(ev["inliers"] / (8 + 0.3 * ev["matches"]))
    assert ev["confidence"] < CONFIDENCE_MIN
    assert f"{ev['inliers']} inliers / (8 + 0.3 × {ev['matches']} matches) < 1" in a.reason


def test_the_placement_about_two_distinct_centers(office):
    """The same fit read about centers that are not one point: x_ref = R(yaw) x_mov + p gives
    t* = R(yaw)·c_mov + p − c_ref."""
    ref, mov, yaw = office
    c_ref, c_mov = (ref.center[0] + 1.0, ref.center[1] - 0.5), (0.2, -0.7)
    a = align(MapInput("ref", ref.grid, c_ref), MapInput("mov", mov.grid, c_mov))
    assert a.accepted, a.reason
    r, p = math.radians(yaw), P
    want = (math.cos(r) * c_mov[0] - math.sin(r) * c_mov[1] + p[0] - c_ref[0],
            math.sin(r) * c_mov[0] + math.cos(r) * c_mov[1] + p[1] - c_ref[1])
    assert abs(angle_diff_deg(a.theta_deg, yaw)) <= 1.0
    assert math.dist(a.translation_m, want) <= 0.1
