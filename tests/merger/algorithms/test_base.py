"""merger.algorithms.base: the one answer every pairwise algorithm gives — its inverse undoes it at every
point, a refusal carries no placement, and :func:`center_form` reads a known rigid placement about the
centers back out of the affine map of cell indices that any image-based algorithm estimates."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from merger.algorithms.base import PairAnswer, center_form, refused
from merger.grid import OccupancyGrid
from merger.search import angle_diff_deg
from merger.team.orders import MapInput

angles = st.floats(0.0, 359.999, allow_nan=False)
coords = st.floats(-5.0, 5.0, allow_nan=False)


def _rot(deg):
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def _place(ans: PairAnswer, x):
    """x_ref − c_ref = t + R(θ)(x_mov − c_mov): the answer applied to a point relative to the centers."""
    return np.asarray(ans.translation_m) + _rot(ans.theta_deg) @ np.asarray(x)


@settings(max_examples=50, deadline=None)
@given(theta=angles, tx=coords, ty=coords, px=coords, py=coords)
def test_the_inverse_undoes_the_placement_at_every_point(theta, tx, ty, px, py):
    a = PairAnswer(True, theta, (tx, ty), 0.7, {"k": 1}, "why")
    b = a.inverse()
    assert 0.0 <= b.theta_deg < 360.0
    assert np.allclose(_place(b, _place(a, (px, py))), (px, py), atol=1e-9)
    assert np.allclose(_place(a, _place(b, (px, py))), (px, py), atol=1e-9)
    assert (b.accepted, b.score, b.evidence, b.reason) == (True, 0.7, {"k": 1}, "why")
    assert abs(angle_diff_deg(b.theta_deg, -theta)) < 1e-9


def test_a_refusal_has_no_placement_and_its_inverse_is_itself():
    r = refused("hough: too few", cells=3, maps=["a", "b"])
    assert not r.accepted and r.theta_deg is None and r.translation_m == (0.0, 0.0) and r.score == 0.0
    assert r.reason == "hough: too few" and r.evidence == {"cells": 3, "maps": ["a", "b"]}
    assert r.inverse() is r


def _map(name, origin, res, center, shape=(40, 30)):
    return MapInput(name, OccupancyGrid(np.zeros(shape, np.uint8), res, origin), center)


@settings(max_examples=50, deadline=None)
@given(theta=angles, t=st.tuples(st.floats(-2, 2), st.floats(-2, 2)),
       o_ref=st.tuples(coords, coords), o_mov=st.tuples(coords, coords),
       c_ref=st.tuples(coords, coords), c_mov=st.tuples(coords, coords),
       res=st.sampled_from([0.05, 0.1]))
def test_center_form_reads_a_known_placement_off_the_affine_map_of_cell_indices(theta, t, o_ref, o_mov, c_ref,
                                                                                  c_mov, res):
    """The placement x_ref = c_ref + t + R(θ)(x_mov − c_mov) written as the affine map of the moving
    map's cell indices (a cell's centre at its index: x = origin + (index + ½)·res) onto the reference's;
    center_form gives back (θ, t)."""
    ref, mov = _map("r", o_ref, res, c_ref), _map("m", o_mov, res, c_mov)
    R = _rot(theta)
    # index_ref = (x_ref − o_ref)/res − ½ with x_ref = c_ref + t + R(x_mov − c_mov), x_mov = o_mov + (i + ½)res
    lin = R
    off = (np.asarray(c_ref) + t + R @ (np.asarray(o_mov) + 0.5 * res - np.asarray(c_mov)) - np.asarray(o_ref)) / res - 0.5
    affine = np.hstack([lin, off[:, None]])
    th, tt = center_form(affine, ref, mov)
    assert abs(angle_diff_deg(th, theta)) < 1e-7 and 0.0 <= th < 360.0
    assert tt == pytest.approx(t, abs=1e-9)


def test_center_form_of_the_identity_between_one_map_is_no_placement():
    m = _map("a", (-1.0, 2.0), 0.05, (0.3, 2.4))
    th, t = center_form(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), m, m)
    assert th == 0.0 and t == pytest.approx((0.0, 0.0), abs=1e-12)
    # a shift of three columns and one row: the moving center lands 3 cells right and 1 up
    th, t = center_form(np.array([[1.0, 0.0, 3.0], [0.0, 1.0, 1.0]]), m, m)
    assert th == 0.0 and t == pytest.approx((0.15, 0.05), abs=1e-12)


def test_the_inverse_of_a_tiny_angle_stays_in_0_360():
    assert PairAnswer(True, 1e-300, (0.0, 0.0)).inverse().theta_deg < 360.0


def test_center_form_of_a_tiny_negative_turn_stays_in_0_360():
    m = _map("a", (0.0, 0.0), 0.05, (0.5, 0.5))
    th, _ = center_form(np.array([[1.0, 0.0, 0.0], [-1e-300, 1.0, 0.0]]), m, m)
    assert th < 360.0
