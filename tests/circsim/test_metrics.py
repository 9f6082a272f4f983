"""The run's metrics (circsim.metrics): the estimated-frame truth and the kinds of false merges (issue 22)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.events import MergeCycle, Observer
from circsim.metrics import (
    MetricsObserver,
    RobotMetrics,
    RunResult,
    false_merge_kind,
    false_merge_lines,
)
from circsim.sim import Simulation, estimated_truth, truth_translation


# --- the estimated-frame truth and the false merges' kinds (issue 22) -------------------------------------
def _to_frame(frame, p):
    c, s = math.cos(frame[2]), math.sin(frame[2])
    dx, dy = p[0] - frame[0], p[1] - frame[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy])


def test_estimated_truth_places_every_world_point_of_the_maps_as_built():
    """Whatever the two map frames (as the SLAMs built them) and the given centers, the estimated-frame
    truth maps a world point's coordinates in map j onto its coordinates in map i."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        fi, fj = rng.uniform(-3, 3, 3), rng.uniform(-3, 3, 3)
        ci, cj = rng.uniform(-2, 2, 2), rng.uniform(-2, 2, 2)
        theta, t = estimated_truth(fi, fj, ci, cj)
        assert 0.0 <= theta < 360.0
        a = math.radians(theta)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        for x in rng.uniform(-5, 5, (5, 2)):
            xi, xj = _to_frame(fi, x), _to_frame(fj, x)
            np.testing.assert_allclose(ci + np.array(t) + rot @ (xj - cj), xi, atol=1e-9)


def test_estimated_truth_with_exact_slam_is_the_start_frame_truth():
    """With the map frames at the start poses, (θ̂, t̂) is (θ*, t*) for the given (erroneous) centers."""
    si, sj = (0.15, 1.5, -math.pi / 2), (-1.2, -0.9, math.pi / 6)
    true_center = (0.15, -0.1)
    ei, ej = (0.03, -0.02), (-0.05, 0.04)
    ci, cj = _to_frame(si, true_center) + ei, _to_frame(sj, true_center) + ej
    theta, t = estimated_truth(si, sj, ci, cj)
    star = math.degrees(sj[2] - si[2]) % 360.0
    assert theta == pytest.approx(star, abs=1e-9)
    assert t == pytest.approx(truth_translation(star, ei, ej), abs=1e-9)


def _cycle(t, errors, t_errors, est_correct, accepted=True):
    res = SimpleNamespace(accepted=accepted, cost_ms=1.0, chosen=None)
    return MergeCycle(t, "Lyon", "Nevers", res, {}, False, errors, False, accepted, translation_error_m=t_errors,
                      est_angle_error_deg={k: 0.3 for k in errors}, est_translation_error_m={k: 0.01 for k in errors},
                      est_correct=est_correct)


def test_false_merges_are_told_apart_and_logged():
    res = RunResult("s", 1, {}, {"Lyon": RobotMetrics(), "Nevers": RobotMetrics()})
    obs = MetricsObserver(res, lambda r, t: 0.0, tol_deg=2.0, tol_m=0.1)
    obs.on_merge_cycle(_cycle(10.0, {"Lyon": 0.0, "Nevers": 2.3}, {"Lyon": 0.0, "Nevers": 0.0}, True))
    obs.on_merge_cycle(_cycle(12.0, {"Lyon": 0.0, "Nevers": 179.0}, {"Lyon": 0.0, "Nevers": 0.0}, False))
    obs.on_merge_cycle(_cycle(13.0, {"Lyon": 0.0, "Nevers": 1.0}, {"Lyon": 0.0, "Nevers": 0.7}, False))
    obs.on_merge_cycle(_cycle(14.0, {"Lyon": 0.0, "Nevers": 3.0}, {"Lyon": 0.0, "Nevers": 0.0}, False))
    d = res.to_dict()
    assert (d["false_merges"], d["gross_merges"], d["drift_limited_merges"]) == (4, 2, 1)
    log = d["false_merge_log"]
    assert [(e["t"], e["kind"]) for e in log] == [(10.0, "drift_limited"), (12.0, "gross"), (13.0, "gross"),
                                                  (14.0, "other")]
    assert all(list(e["maps"]) == ["Nevers"] and e["robot"] == "Lyon" for e in log)  # only the misplaced map
    assert log[2]["maps"]["Nevers"]["translation_error_m"] == 0.7
    assert log[0]["maps"]["Nevers"]["est_angle_error_deg"] == 0.3
    lines = false_merge_lines(d, limit=2)
    assert "4 (2 gross" in lines[0] and "1 drift-limited" in lines[0]
    assert "10.0 s  Lyon: drift_limited: Nevers off 2.30°" in lines[1] and lines[-1].startswith("  … 2 more")
    assert d["robots"]["Lyon"]["accepted_error_max"]["start"]["deg"] == 179.0
    assert false_merge_kind(_cycle(0.0, {"N": 1.0}, {"N": 0.5}, False)) == "other"  # 0.5 m is not > 0.5 m


class _Cycles(Observer):
    def __init__(self):
        self.cycles = []

    def on_merge_cycle(self, cycle):
        self.cycles.append(cycle)


@pytest.mark.slow
def test_with_exact_odometry_the_estimated_frame_errors_are_the_start_frame_errors():
    sc = load_scenario(bundled_scenarios()["scene1"]).with_overrides(
        ["duration_s=8", "slam.model=odometry_only", "slam.drift.xy_m_per_m=0", "slam.drift.yaw_deg_per_m=0",
         "merger.window_m=0.3", "center_error.magnitude_m=0.1"])
    obs = _Cycles()
    res = Simulation(sc, [obs]).run()
    accepted = [c for c in obs.cycles if c.result.accepted]
    assert accepted and res.false_merges == 0
    for c in accepted:
        assert c.est_angle_error_deg == pytest.approx(c.angle_error_deg, abs=1e-9)
        assert c.est_translation_error_m == pytest.approx(c.translation_error_m, abs=1e-9)
        assert c.est_correct
    for m in res.robots.values():  # exact SLAM: no pose error, sampled every whole second
        assert m.slam_pose_error_max == {"m": pytest.approx(0.0, abs=1e-9), "deg": pytest.approx(0.0, abs=1e-9)}
        assert [round(t, 6) for t, _, _ in m.slam_pose_error] == [float(k) for k in range(9)]


@pytest.mark.slow
def test_a_drifting_slam_makes_drift_limited_false_merges_and_they_are_logged():
    """The random-walk stress model with a strong yaw drift: the merger places the drifted maps as they
    were built (small estimated-frame errors) and the strict count calls that false."""
    sc = load_scenario(bundled_scenarios()["scene2"]).with_overrides(
        ["duration_s=40", "slam.model=odometry_only", "slam.drift.yaw_deg_per_m=1.0"])
    res = Simulation(sc).run()
    d = res.to_dict()
    assert d["false_merges"] > 0 and len(d["false_merge_log"]) == d["false_merges"]
    assert d["drift_limited_merges"] >= d["false_merges"] // 2
    assert d["gross_merges"] + d["drift_limited_merges"] <= d["false_merges"]
    for e in d["false_merge_log"]:
        assert e["maps"] and all(v["angle_error_deg"] > 2.0 or v["translation_error_m"] > 0.1
                                 for v in e["maps"].values())
    worst = max(m["slam_pose_error_max"]["deg"] for m in d["robots"].values())
    assert worst > 1.0
