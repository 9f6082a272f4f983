"""The scenario sections' checks (circsim.config.schema): the physical ranges, their sources and their extremes."""

import pytest

from circsim.config.scenario import ScenarioError, bundled_scenarios, load_scenario


# issue 37, items 2 and 3: values inside the old ranges that hung or meant nothing physical
@pytest.mark.parametrize("sets, needle", [
    (["laser.noise_std_m=1e6"], "laser.noise_std_m: expected a number in [0, 0.2], got 1000000.0"),  # 19 false merges
    ([f"slam.odometry.alpha{k}=1e6" for k in range(1, 6)], "slam.odometry.alpha1: expected a number in [0, 0.2]"),
    (["laser.range_max_m=1e-9"], "laser.range_max_m: expected a number in [1, 100]"),  # the robots mapped nothing
    (["laser.dropout=0.99"], "laser.dropout: expected a number in [0, 0.5]"),
    (["laser.noise_rel=0.9"], "laser.noise_rel: expected a number in [0, 0.1]"),
    (["slam.resolution_m=1e-6"], "slam.resolution_m: expected a number in [0.01, 0.5]"),
    (["slam.drift.yaw_deg_per_m=90"], "slam.drift.yaw_deg_per_m: expected a number in [0, 5.7]"),
    # the hang: 5 s of scan matching with these windows had not finished after 180 s
    (["slam.matcher.linear_window_m=100"], "slam.matcher.linear_window_m: expected a number in [0, 0.5]"),
    (["slam.matcher.angular_window_deg=180"], "slam.matcher.angular_window_deg: expected a number in [0, 45]"),
    # 10⁶ ticks of 1 µs (the old cap) had not finished after 540 s
    (["duration_s=1", "dt_s=1e-6"], "dt_s: expected a number in [0.01, 1], got 1e-06"),
])
def test_settings_no_real_robot_has_are_refused(sets, needle):
    sc = load_scenario(bundled_scenarios()["scene1"])
    with pytest.raises(ScenarioError) as e:
        sc.with_overrides(["slam.model=scan_matching", *sets])
    assert needle in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_the_physical_ranges_cite_their_source_in_the_reference():
    from circsim.config.reference_doc import scenario_reference

    rows = {ln.split("|")[1].strip(" `"): ln for ln in scenario_reference().splitlines() if ln.startswith("| `")}
    for key in ("dt_s", "laser.range_max_m", "laser.range_min_m", "laser.noise_std_m", "laser.noise_rel",
                "laser.dropout", "slam.resolution_m", "slam.odometry.alpha1", "slam.odometry.alpha5",
                "slam.matcher.linear_window_m", "slam.matcher.angular_window_deg", "slam.drift.xy_m_per_m"):
        assert " — " in rows[key], rows[key]


def test_the_extremes_of_the_ranges_run():
    """The worst allowed SLAM work (every alpha, both matcher windows and the tick at their caps, the fastest
    robots) runs and stays a SLAM: 2 simulated seconds, the pose errors bounded by the caps' meaning."""
    from circsim.sim import Simulation

    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(
        ["slam.model=scan_matching", "duration_s=2", "dt_s=1", "robots.speed_mps=2",
         *[f"slam.odometry.alpha{k}=0.2" for k in range(1, 6)],
         "slam.matcher.linear_window_m=0.5", "slam.matcher.angular_window_deg=45", "laser.noise_std_m=0.2"])
    res = Simulation(sc).run()
    assert res.sim_s == 2.0 and set(res.robots) == {"Lyon", "Auckland", "Nevers"}
