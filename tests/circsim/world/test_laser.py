"""circsim.world.laser, on plain geometry (no pymunk world): rays hit a wall and a pillar at their
analytic distances and equal an independent ray caster on random segments and circles; a start inside a
circle reads 0 (Chipmunk); the sensor model (range_min → −inf, noise, clipping, dropout → NaN, one stream
whatever the settings); a scan's angles and points."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from circsim.config.types import LaserConfig
from circsim.world.laser import LaserScan, apply_sensor_model, raycast
from merger.synthetic import Scene, ray_cast


def test_a_wall_and_a_pillar_at_their_analytic_distances():
    wall = np.array([[3.0, -10.0, 3.0, 10.0]])  # x = 3
    pillar = np.array([[0.0, 2.0, 0.5]])  # centre (0, 2), radius 0.5
    r = raycast((0.0, 0.0), 0.0, math.pi / 4, 8, 10.0, wall, pillar)  # beams at 0°, 45°, 90°, ...
    assert r[0] == pytest.approx(3.0, abs=1e-12)  # straight at the wall
    assert r[1] == pytest.approx(3.0 * math.sqrt(2), abs=1e-12)  # 45° to the wall
    assert r[2] == pytest.approx(1.5, abs=1e-12)  # the pillar's near side at y = 2 − 0.5
    assert np.isinf(r[4])  # behind: nothing within 10 m
    assert r.shape == (8,)
    short = raycast((0.0, 0.0), 0.0, math.pi / 4, 8, 2.0, wall, pillar)
    assert np.isinf(short[0]) and short[2] == pytest.approx(1.5, abs=1e-12)  # beyond range_max: no return


def test_a_start_inside_a_circle_reads_zero_everywhere():
    r = raycast((0.1, 0.0), 0.0, 0.1, 20, 5.0, np.zeros((0, 4)), np.array([[0.0, 0.0, 0.3]]))
    assert (r == 0.0).all()


def test_beams_wrapping_past_the_first_one_still_see_the_wall():
    """Beam 0 points at 170°, a full turn of 36 beams: the wall at x = 2 is seen by the beams near 360°
    (an angular window that wraps past the first beam)."""
    inc = 2 * math.pi / 36
    r = raycast((0.0, 0.0), math.radians(170.0), inc, 36, 10.0, np.array([[2.0, -5.0, 2.0, 5.0]]), np.zeros((0, 3)))
    a = math.radians(170.0) + inc * np.arange(36)
    facing = np.cos(a) > 0.45  # within ±63° of +x: the wall's 5 m half length is reached
    assert np.allclose(r[facing], 2.0 / np.cos(a[facing]), atol=1e-9)
    assert np.isinf(r[np.cos(a) < 0]).all()


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), n_seg=st.integers(0, 12), n_circ=st.integers(0, 4),
       start=st.floats(-math.pi, math.pi), beams=st.integers(3, 200))
def test_raycast_equals_an_independent_caster(seed, n_seg, n_circ, start, beams):
    """Random segments and circles around a laser outside every circle: the ranges equal merger.synthetic's
    ray caster (another formula: ray–segment by Cramer's rule, ray–circle by the quadratic) to 1e-9 m."""
    rng = np.random.default_rng(seed)
    seg = rng.uniform(-4, 4, (n_seg, 4))
    circ = np.column_stack([rng.uniform(-4, 4, (n_circ, 2)), rng.uniform(0.05, 0.4, n_circ)])
    circ = circ[np.hypot(circ[:, 0], circ[:, 1]) > circ[:, 2] + 0.05]
    inc = 2 * math.pi / beams
    got = raycast((0.0, 0.0), start, inc, beams, 6.0, seg, circ)
    want = ray_cast(Scene(seg.reshape(-1, 2, 2), circ), (0.0, 0.0), start + inc * np.arange(beams), 6.0)
    both = np.isfinite(got) & np.isfinite(want)
    assert (np.isfinite(got) == np.isfinite(want)).mean() >= 0.98  # grazing hits may differ at the ends
    assert np.allclose(got[both], want[both], atol=1e-9)


def test_many_segments_give_the_same_ranges_as_few():
    """Over 64 segments the compiled loop takes them (those out of reach left out): a wall cut into 200
    pieces reads as the whole wall."""
    ys = np.linspace(-5.0, 5.0, 201)
    pieces = np.column_stack([np.full(200, 3.0), ys[:-1], np.full(200, 3.0), ys[1:]])
    far = np.array([[50.0, -1.0, 50.0, 1.0]] * 10)  # out of reach
    whole = raycast((0.0, 0.0), -1.0, 0.01, 200, 8.0, np.array([[3.0, -5.0, 3.0, 5.0]]), np.zeros((0, 3)))
    cut = raycast((0.0, 0.0), -1.0, 0.01, 200, 8.0, np.vstack([pieces, far]), np.zeros((0, 3)))
    assert np.allclose(cut, whole, atol=1e-12, equal_nan=False)
    assert np.isfinite(whole).all()


def test_the_sensor_model():
    cfg = LaserConfig(range_max_m=5.0, range_min_m=0.1, noise_std_m=0.02, dropout=0.1)
    ideal = np.concatenate([np.full(5000, 2.0), np.full(100, 0.05), np.full(100, np.inf), np.full(100, 4.999)])
    r = apply_sensor_model(ideal, cfg, np.random.default_rng(0))
    drop = np.isnan(r)
    assert 0.08 < drop.mean() < 0.12
    ok = ~drop
    assert (r[5000:5100][ok[5000:5100]] == -np.inf).all()  # closer than range_min
    assert (r[5100:5200][ok[5100:5200]] == np.inf).all()  # no return stays no return
    near_max = r[5200:][ok[5200:]]
    assert (near_max <= 5.0).all() and (near_max == 5.0).any()  # clipped at range_max
    two = r[:5000][ok[:5000]]
    assert abs(two.mean() - 2.0) < 0.002 and two.std() == pytest.approx(0.02, rel=0.08)
    rel = apply_sensor_model(np.full(5000, 4.0), LaserConfig(noise_std_m=0.01, noise_rel=0.03),
                             np.random.default_rng(1))
    assert rel.std() == pytest.approx(0.12, rel=0.08)  # σ = max(0.01, 3 % of 4 m)


def test_the_stream_advances_alike_whatever_the_settings():
    a, b = np.random.default_rng(5), np.random.default_rng(5)
    apply_sensor_model(np.full(50, 1.0), LaserConfig(noise_std_m=0.0, dropout=0.0), a)
    apply_sensor_model(np.full(50, 1.0), LaserConfig(noise_std_m=0.1, dropout=0.5, noise_rel=0.1), b)
    assert a.random() == b.random()


def test_a_scans_angles_and_points():
    s = LaserScan(-math.pi / 2, math.pi / 2, math.pi / 2, 0.1, 5.0, np.array([1.0, np.inf, 2.0]))
    assert s.angles() == pytest.approx([-math.pi / 2, 0.0, math.pi / 2])
    assert s.points() == pytest.approx(np.array([[0.0, -1.0], [0.0, 2.0]]), abs=1e-12)
    cfg = LaserConfig(fov_deg=360.0, beams=8)
    assert cfg.angle_increment == pytest.approx(math.pi / 4)  # a full turn: no duplicate beam
    assert LaserConfig(fov_deg=90.0, beams=3).angle_increment == pytest.approx(math.pi / 4)
