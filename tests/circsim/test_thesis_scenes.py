"""Bench fidelity (issue 13): gmapping's scan-integration rule, the URG-04LX's range noise, and the
thesis-conditions scenes scene1-thesis / scene2-thesis against the thesis's online figures."""

from __future__ import annotations

import math

import numpy as np
import pytest

from circsim.config.scenario import MergerSettings, bundled_scenarios, load_scenario
from circsim.config.types import DriftConfig, LaserConfig, SlamConfig
from circsim.sim import Simulation, merge_params
from circsim.slam.models import Slam
from circsim.world.laser import LaserScan, apply_sensor_model

GMAPPING = SlamConfig(model="odometry_only", drift=DriftConfig(0.0, 0.0), linear_update_m=1.0,
                      angular_update_rad=0.5)


def a_scan():
    return LaserScan(-0.1, 0.1, 0.1, 0.02, 5.6, np.full(3, 2.0))


def test_every_scan_is_integrated_by_default():
    slam = Slam(SlamConfig(model="odometry_only", drift=DriftConfig(0.0, 0.0)), (0.0, 0.0, 0.0),
                np.random.default_rng(0))
    for k in range(5):
        slam.update((0.01 * k, 0.0, 0.0), a_scan())
    assert slam.updates == 5


def test_gmapping_rule_integrates_after_a_metre_of_path_or_half_a_radian_of_turns():
    slam = Slam(GMAPPING, (0.0, 0.0, 0.0), np.random.default_rng(0))
    slam.update((0.0, 0.0, 0.0), a_scan())
    assert slam.updates == 1  # the first scan, always
    for x in np.arange(0.1, 1.0, 0.1):  # 0.1 … 0.9 m: not yet
        slam.update((float(x), 0.0, 0.0), a_scan())
    assert slam.updates == 1
    slam.update((1.0, 0.0, 0.0), a_scan())
    assert slam.updates == 2  # 1.0 m travelled since the last integrated scan
    slam.update((1.0, 0.0, 0.49), a_scan())
    assert slam.updates == 2
    slam.update((1.0, 0.0, 0.5), a_scan())
    assert slam.updates == 3  # 0.5 rad turned since the last integrated scan
    slam.update((1.0, 0.0, 0.2), a_scan())
    slam.update((1.0, 0.0, 0.5), a_scan())
    assert slam.updates == 4  # turns are summed: back and forth makes 0.6 rad
    for x in (1.3, 1.0, 1.3, 1.0):  # the path is summed too: 1.2 m there and back
        slam.update((x, 0.0, 0.5), a_scan())
    assert slam.updates == 5
    # the pose estimate follows every scan, integrated or not
    slam.update((1.3, 0.0, 0.5), a_scan())
    assert slam.updates == 5 and math.isclose(slam.estimated_pose().x, 1.3)


def test_relative_range_noise_follows_the_datasheet_shape():
    cfg = LaserConfig(noise_std_m=0.015, noise_rel=0.015, range_max_m=5.6)
    rng = np.random.default_rng(3)
    for r, sigma in ((0.5, 0.015), (4.0, 0.06)):
        readings = apply_sensor_model(np.full(200_000, r), cfg, rng)
        assert abs(np.std(readings - r) / sigma - 1.0) < 0.02, (r, np.std(readings - r))


@pytest.mark.parametrize("name", ["scene1-thesis", "scene2-thesis"])
def test_thesis_scenes_are_the_scenes_under_gmapping_and_urg_settings(name):
    thesis = load_scenario(bundled_scenarios()[name])
    base = load_scenario(bundled_scenarios()[name.removesuffix("-thesis")])
    assert (thesis.slam.linear_update_m, thesis.slam.angular_update_rad, thesis.slam.publish_period_s) == (1.0, 0.5, 5.0)
    assert (thesis.laser.noise_std_m, thesis.laser.noise_rel) == (0.015, 0.015)
    assert thesis.world == base.world and thesis.robots == base.robots and thesis.merger == base.merger
    assert thesis.network == base.network


@pytest.mark.parametrize("name", ["scene1", "scene2", "scene1-thesis", "scene2-thesis"])
def test_thesis_scenes_pin_the_thesis_rule_while_the_default_is_auto(name):
    """The thesis scenes verify by the thesis's rule (ω̃ ≥ ν_min) and merge at the search's placement;
    every other scenario takes the defaults: verification auto, the placement refined on the whole maps."""
    m = load_scenario(bundled_scenarios()[name]).merger
    assert m.verification == "whole_map" and not m.refine_whole
    assert merge_params(load_scenario(bundled_scenarios()[name])).verification == "whole_map"
    d = MergerSettings()
    assert d.verification == "auto" and d.refine_whole
    hall = load_scenario(bundled_scenarios()["hall4"])
    assert merge_params(hall).verification == "auto" and merge_params(hall).refine_whole


# The thesis's online experiment: first correct merges after 20–30 s, under a quarter circle; the issue's
# band is a factor 1.5 either way (13.3–45 s, arc under 135°).
@pytest.mark.slow
@pytest.mark.parametrize("name", ["scene1-thesis", "scene2-thesis"])
def test_thesis_scenes_first_merges_inside_the_thesis_band(name):
    sc = load_scenario(bundled_scenarios()[name]).with_overrides(["duration_s=40"])
    res = Simulation(sc).run()
    assert res.false_merges == 0
    for robot, m in res.robots.items():
        assert m.first_merge_s is not None, robot
        assert 20.0 / 1.5 <= m.first_merge_s <= 30.0 * 1.5, (robot, m.first_merge_s)
        assert m.first_merge_arc_deg <= 90.0 * 1.5, (robot, m.first_merge_arc_deg)


@pytest.mark.slow
def test_agreeing_orders_combined_remove_the_sparse_maps_two_degree_false_merges():
    """scene2-thesis, seed 11: with the thesis's rule (the highest Σν order) Lyon at 15.9 s and 19.0 s and
    Nevers at 17.1 s accepted an order that put one sparse map 2.05° off (Σν 2.9051 vs the correct
    order's 2.9050); the mean of the agreeing accepted orders places every map within the tolerance."""
    sc = load_scenario(bundled_scenarios()["scene2-thesis"]).with_overrides(["duration_s=20", "seed=11"])
    res = Simulation(sc).run()
    assert res.false_merges == 0
    assert all(m.first_merge_s is not None for m in res.robots.values())
