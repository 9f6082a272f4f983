"""The offline experiment's displaced robots and their maps (circsim.experiments.offline_bench)."""

import math

import numpy as np
import pytest

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.experiments.offline_bench import ArcDriftSlam, OfflineBench
from circsim.world.motion import offline_schedule


def scene(name, *sets):
    return load_scenario(bundled_scenarios()[name]).with_overrides(list(sets))


def test_maps_grow_with_phi_and_truth_is_the_start_headings():
    sc = scene("scene1", "center_error.magnitude_m=0")
    bench = OfflineBench(sc, scans_per_pose=2)
    assert [round(v, 6) % 360 for v in bench.truth_deg.values()] == [0.0, 120.0, 240.0]
    known = []
    phis = []
    for phi, grids in bench.maps(4.0, 1.0):
        phis.append(phi)
        known.append(sum(int(np.count_nonzero(g.states)) for g in grids.values()))
    assert phis == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert known == sorted(known) and known[-1] > known[0]
    for n in sc.robots.names:  # an exact center: the given center is the true center in M_i
        c = bench.slams[n].true_to_map(np.array(sc.world.center))
        assert np.allclose(bench.centers[n], c)


def test_center_error_has_the_simulations_magnitude():
    sc = scene("scene2", "center_error.magnitude_m=0.2")
    bench = OfflineBench(sc)
    for n in sc.robots.names:
        c = bench.slams[n].true_to_map(np.array(sc.world.center))
        assert math.hypot(*(np.array(bench.centers[n]) - c)) == pytest.approx(0.2)


def test_arc_drift_depends_on_the_place_not_the_path():
    sc = scene("scene1", "slam.drift.yaw_deg_per_m=2", "slam.drift.xy_m_per_m=0.05")
    bench = OfflineBench(sc, scans_per_pose=1, drift="arc")
    slam = bench.slams["Lyon"]
    assert isinstance(slam, ArcDriftSlam)
    seen = {}
    for d in offline_schedule(3.0, 1.0) + [2.0, -1.0]:  # revisit +2 and −1 at the end
        bench._scan_all(d)
        est = slam.estimated_pose()
        true = slam.true_pose_in_map(bench.trajs["Lyon"].pose_at_displacement(d))
        err = (est.x - true.x, est.y - true.y, est.yaw - true.yaw)
        if d in seen:
            assert np.allclose(err, seen[d])
        seen[d] = err
    assert seen[0.0] == (0.0, 0.0, 0.0) and any(abs(e[2]) > 0 for e in seen.values())
