"""Two pillars point-symmetric about the center: the ROI search sees two equal peaks 180° apart, and
whole-map verification rejects the wrong one because the (off-center) walls disagree."""

import math

import numpy as np
import pytest

import merger
from merger.search import angle_diff_deg
from merger.synthetic import arc_viewpoints, partial_view, room_scene
from merger.team.verify import verify
from merger.transform import canvas, paste, warp_grid


@pytest.fixture(scope="module")
def pillar_views():
    scene = room_scene(np.random.default_rng(0), n_boxes=0, room_center=(0.9, 0.5))
    theta = 63.0
    fa = (0.2, -0.1, 0.3)
    fb = (-0.4, 0.3, 0.3 + math.radians(theta))
    ga, ca = partial_view(scene, fa, arc_viewpoints(90, 180, 1.8, k=8))
    gb, cb = partial_view(scene, fb, arc_viewpoints(90, 180, 1.8, k=8))
    return ga, ca, gb, cb, theta


def whole_map_nu(ga, ca, gb, cb, th):
    cv = canvas(ga, [(gb, th, cb)], ca)
    return verify(paste(ga, cv).states, warp_grid(gb, th, cb, ca, cv).states, nu_min=0.4, min_support=150)


def test_pillars_give_a_180_degree_runner_up(pillar_views):
    ga, ca, gb, cb, theta = pillar_views
    al = merger.search_pair(ga, gb, center_ref=ca, center_moving=cb, roi_m=4.0, method="reference")
    peaks = sorted([al.theta_deg, al.runner_up_deg])
    assert abs(angle_diff_deg(peaks[1] - peaks[0], 180.0)) <= 2.0
    # one of the two peaks is the truth, and the two are nearly as good
    assert min(abs(angle_diff_deg(p, theta)) for p in peaks) <= 1.5  # the runner-up is on the 1° grid
    assert al.runner_up_score >= 0.6 * al.profile.max()  # both on the coarse 1° grid


def test_whole_map_verification_rejects_180(pillar_views):
    ga, ca, gb, cb, theta = pillar_views
    good = whole_map_nu(ga, ca, gb, cb, theta)
    flipped = whole_map_nu(ga, ca, gb, cb, theta + 180.0)
    assert good.passed, good.reason
    assert not flipped.passed and "ν" in flipped.reason
    assert flipped.nu < 0.5 * good.nu
