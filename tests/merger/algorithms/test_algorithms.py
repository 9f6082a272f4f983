"""Merging methods as registered algorithms (issue 35): ``features`` (m-explore map_merge's pipeline) and
``hough`` (Carpin's Hough spectrum) find a known placement of a real map onto itself, refuse unrelated maps
with a reason, and a team is chained along the strongest accepted pairs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from merger.algorithms import ALGORITHMS, align_pair, merge, merge_every_map
from merger.algorithms.base import PairAnswer
from merger.algorithms.online import AlgorithmMerger, make_merger
from merger.algorithms.team import merge_pairwise
from merger.grid import OccupancyGrid
from merger.io.mapio import load_map
from merger.search import angle_diff_deg
from merger.team.online import MapMessage, TeamMerger
from merger.team.orders import MapInput, MergeParams
from merger.transform import sample_nearest
from tests.paths import REAL_MAP


def moved(g: OccupancyGrid, yaw_deg: float, p) -> OccupancyGrid:
    """``g`` seen from a frame whose pose in g's frame is (yaw, p): x_g = R(yaw) x_new + p (nearest cells)."""
    a = math.radians(yaw_deg)
    c, s = math.cos(a), math.sin(a)
    corners = np.array([[g.origin[0] + dx * g.width * g.resolution, g.origin[1] + dy * g.height * g.resolution]
                        for dx in (0, 1) for dy in (0, 1)]) - p
    local = corners @ np.array([[c, -s], [s, c]])  # R(−yaw)(x − p)
    lo, hi = local.min(0), local.max(0)
    res = g.resolution
    w, h = int(math.ceil((hi[0] - lo[0]) / res)), int(math.ceil((hi[1] - lo[1]) / res))
    yy, xx = np.mgrid[0:h, 0:w]
    q = np.stack([lo[0] + (xx + 0.5) * res, lo[1] + (yy + 0.5) * res], axis=-1).reshape(-1, 2)
    xg = q @ np.array([[c, s], [-s, c]]) + p  # R(yaw) q + p
    return OccupancyGrid(sample_nearest(g, xg).reshape(h, w), res, (float(lo[0]), float(lo[1])))


@pytest.fixture(scope="module")
def office():
    g = load_map(str(REAL_MAP))
    yaw, p = 37.0, np.array([0.8, -0.5])
    mov = moved(g, yaw, p)
    c_ref = (float(g.origin[0] + 0.5 * g.width * g.resolution), float(g.origin[1] + 0.5 * g.height * g.resolution))
    a = math.radians(yaw)
    d = np.asarray(c_ref) - p
    c_mov = (math.cos(a) * d[0] + math.sin(a) * d[1], -math.sin(a) * d[0] + math.cos(a) * d[1])  # the same point
    return MapInput("ref", g, c_ref), MapInput("mov", mov, c_mov), yaw


@pytest.mark.parametrize("algorithm", ["features", "hough"])
def test_finds_a_known_placement_of_a_real_map(office, algorithm):
    ref, mov, yaw = office
    a = align_pair(algorithm, ref, mov, MergeParams())
    assert a.accepted, a.reason
    assert abs(angle_diff_deg(a.theta_deg, yaw)) <= 1.0
    assert math.hypot(*a.translation_m) <= 0.1  # the centers are the same point: t* = 0
    assert a.evidence  # what it measured comes with the answer


@pytest.mark.parametrize("algorithm", ["features", "hough"])
def test_refuses_unrelated_maps_with_a_reason(office, algorithm):
    ref, _, _ = office
    rng = np.random.default_rng(3)
    noise = OccupancyGrid(rng.choice(3, size=(120, 120), p=[0.6, 0.3, 0.1]).astype(np.uint8), 0.05, (0.0, 0.0))
    a = align_pair(algorithm, ref, MapInput("noise", noise, (3.0, 3.0)), MergeParams())
    assert not a.accepted and a.reason.startswith(algorithm)


def test_inverse_reads_the_placement_the_other_way():
    a = PairAnswer(True, 30.0, (0.4, -0.2), 1.0)
    b = a.inverse()
    back = b.inverse()
    assert back.theta_deg == pytest.approx(30.0) and back.translation_m == pytest.approx((0.4, -0.2))
    # x_i = c_i + t + R(θ)(x_j − c_j) and its inverse compose to the identity at any point
    th = math.radians(a.theta_deg)
    x_j = np.array([1.3, 0.7])
    x_i = np.array(a.translation_m) + np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]]) @ x_j
    tb = math.radians(b.theta_deg)
    x_j2 = np.array(b.translation_m) + np.array([[math.cos(tb), -math.sin(tb)], [math.sin(tb), math.cos(tb)]]) @ x_i
    assert x_j2 == pytest.approx(x_j)


def _maps(n=3):
    g = OccupancyGrid(np.ones((10, 10), np.uint8), 0.05, (0.0, 0.0))
    return [MapInput(f"m{k}", g, (0.25, 0.25), version=1) for k in range(n)]


def test_team_is_chained_along_the_strongest_accepted_pairs():
    # m1 onto m0: refused; m2 onto m0: 90°, t (1, 0), score 2; m1 onto m2: 90°, t (0, 1), score 3
    answers = {("m0", "m1"): PairAnswer(False, 10.0, (0.0, 0.0), 5.0, reason="x: no"),
               ("m0", "m2"): PairAnswer(True, 90.0, (1.0, 0.0), 2.0),
               ("m1", "m2"): PairAnswer(True, 270.0, (-1.0, 0.0), 3.0)}  # m2 onto m1; so m1 onto m2 is 90°, (0, 1)
    calls = []

    def align(ref, mov, params):
        calls.append((ref.name, mov.name))
        return answers[(ref.name, mov.name)]

    res = merge_pairwise(align, _maps(), MergeParams())
    ch = res.chosen
    assert ch.order == ("m0", "m2", "m1")
    assert ch.theta_deg["m2"] == pytest.approx(90.0) and ch.translation("m2") == pytest.approx((1.0, 0.0))
    # m1 onto m0 = (m2 onto m0) ∘ (m1 onto m2): θ 180°, t = (1, 0) + R(90°)(0, 1) = (0, 0)
    assert ch.theta_deg["m1"] == pytest.approx(180.0) and ch.translation("m1") == pytest.approx((0.0, 0.0), abs=1e-12)
    cache: dict = {}
    merge_pairwise(align, _maps(), MergeParams(), cache=cache)
    merge_pairwise(align, _maps(), MergeParams(), cache=cache)
    assert len(calls) == 3 + 3  # the second cached run aligned nothing


def test_nothing_accepted_keeps_the_best_hypothesis_and_every_reason():
    def align(ref, mov, params):
        return PairAnswer(False, 45.0, (0.0, 0.0), 0.5, reason=f"hough: no {mov.name}")

    res = merge_pairwise(align, _maps(), MergeParams())
    assert res.chosen is None and set(res.top.theta_deg) == {"m0", "m1", "m2"}
    assert "hough: no m1" in res.reason and "hough: no m2" in res.reason


def test_a_file_merge_needs_every_map_placed(office):
    """Online, a partial team's merge is kept; merging files, a map left out refuses the merge."""
    ref, mov, _ = office
    rng = np.random.default_rng(3)
    noise = OccupancyGrid(rng.choice(3, size=(120, 120), p=[0.6, 0.3, 0.1]).astype(np.uint8), 0.05, (0.0, 0.0))
    maps = [ref, mov, MapInput("noise", noise, (3.0, 3.0))]
    assert merge("hough", maps).accepted
    res = merge_every_map("hough", maps)
    assert not res.accepted and res.reason.startswith("noise not placed")


def test_registry_and_online_merger(office):
    ref, mov, _ = office
    assert ALGORITHMS == ("thesis", "features", "hough")
    assert type(make_merger("thesis", "a", ("a", "b"))) is TeamMerger
    m = make_merger("hough", "a", ("a", "b"))
    assert isinstance(m, AlgorithmMerger)
    m.receive(MapMessage("a", 1.0, ref.grid, ref.center))
    m.receive(MapMessage("b", 1.0, mov.grid, mov.center))
    res = m.cycle(now=1.0)
    assert res.accepted and m.current is res and len(m._answers) == 1
    with pytest.raises(ValueError, match="algorithm must be one of"):
        merge("orb", [ref, mov])


def test_the_algorithms_are_one_table_of_objects():
    """Issue 45: an algorithm per name (its pair function, whether it merges pair by pair), one table."""
    from merger.algorithms import ALGORITHMS_BY_NAME, algorithm_of, pair_function
    from merger.algorithms.features import align as features_align
    from merger.algorithms.hough import align as hough_align

    assert ALGORITHMS == tuple(ALGORITHMS_BY_NAME)
    assert {n: a.pairwise for n, a in ALGORITHMS_BY_NAME.items()} == {"thesis": False, "features": True,
                                                                       "hough": True}
    assert algorithm_of("features").align is features_align is pair_function("features")
    assert algorithm_of("hough").align is hough_align and algorithm_of("thesis").name == "thesis"
    with pytest.raises(ValueError, match="merger algorithm must be one of thesis, features, hough, got 'orb'"):
        algorithm_of("orb")
    with pytest.raises(ValueError, match="AlgorithmMerger: algorithm must be one of features, hough, got 'thesis'"):
        AlgorithmMerger("a", ("a", "b"), algorithm="thesis")


def test_merger_merge_algorithm_option(office, tmp_path, capsys):
    from merger.cli import main
    from merger.io.mapio import map_files, write_files

    ref, mov, yaw = office
    write_files({**map_files(ref.grid, tmp_path / "ref.yaml"), **map_files(mov.grid, tmp_path / "mov.yaml")})
    centers = [f"{ref.center[0]:.6f},{ref.center[1]:.6f}", f"{mov.center[0]:.6f},{mov.center[1]:.6f}"]
    args = [str(tmp_path / "ref.yaml"), str(tmp_path / "mov.yaml"), "--center", centers[0], "--center", centers[1]]
    assert main(["merge", *args, "--algorithm", "hough", "-o", str(tmp_path / "h")]) == 0
    assert (tmp_path / "h.yaml").exists()
    assert "accepted by the algorithm's own rule (merger.algorithms))" in capsys.readouterr().out
    rng = np.random.default_rng(3)
    noise = OccupancyGrid(rng.choice(3, size=(120, 120), p=[0.6, 0.3, 0.1]).astype(np.uint8), 0.05, (0.0, 0.0))
    write_files(map_files(noise, tmp_path / "noise.yaml"))
    assert main(["merge", str(tmp_path / "ref.yaml"), str(tmp_path / "noise.yaml"), "--center", centers[0],
                 "--center", "3,3", "--algorithm", "features", "-o", str(tmp_path / "f")]) == 1
    out = capsys.readouterr().out
    assert "features:" in out and not (tmp_path / "f.yaml").exists()
