"""Trajectories on the circle: online counter-clockwise motion and the offline ±φ schedule."""

from __future__ import annotations

import math

import numpy as np
import pytest

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.world.motion import (
    CircleTrajectory,
    OfflineStep,
    Pose,
    offline_schedule,
    offline_steps,
    trajectories,
)

C = (0.5, -0.25)


def polar_deg(p: Pose, center=C) -> float:
    return math.degrees(math.atan2(p.y - center[1], p.x - center[0])) % 360.0


def wrap_deg(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


def test_start_pose_on_circle_facing_center():
    tr = CircleTrajectory(center=C, radius_m=1.6, start_angle_deg=210.0)
    p = tr.start_pose()
    assert math.hypot(p.x - C[0], p.y - C[1]) == pytest.approx(1.6)
    assert polar_deg(p) == pytest.approx(210.0)
    to_center = math.degrees(math.atan2(C[1] - p.y, C[0] - p.x))
    assert wrap_deg(math.degrees(p.yaw) - to_center) == pytest.approx(0.0, abs=1e-9)


def test_online_motion_is_counter_clockwise_at_speed():
    tr = CircleTrajectory(center=C, radius_m=2.0, start_angle_deg=90.0, speed_mps=0.25)
    assert tr.arc_travelled_deg(8.0) == pytest.approx(math.degrees(0.25 * 8.0 / 2.0))
    prev = tr.pose_at(0.0)
    for t in np.arange(0.1, 10.0, 0.1):
        p = tr.pose_at(t)
        step = math.hypot(p.x - prev.x, p.y - prev.y)
        assert step == pytest.approx(0.025, rel=1e-3)  # chord ≈ arc at this step
        assert wrap_deg(polar_deg(p) - polar_deg(prev)) > 0  # counter-clockwise
        assert math.hypot(p.x - C[0], p.y - C[1]) == pytest.approx(2.0)
        prev = p
    end = tr.pose_at(tr.tour_s())
    assert tuple(end) == pytest.approx(tuple(tr.start_pose()), abs=1e-9)


def test_tangent_heading_and_yaw_offset():
    tr = CircleTrajectory(center=C, radius_m=1.0, start_angle_deg=0.0, heading="tangent", yaw_offset_deg=10.0)
    assert math.degrees(tr.pose_at_displacement(30.0).yaw) == pytest.approx(30.0 + 90.0 + 10.0)
    with pytest.raises(ValueError):
        CircleTrajectory(center=C, radius_m=1.0, start_angle_deg=0.0, heading="outward")


def test_offline_schedule_alternates_sides():
    assert offline_schedule(3.0, 1.0) == [0.0, 1.0, -1.0, 2.0, -2.0, 3.0, -3.0]
    assert offline_schedule(1.0, 0.4) == pytest.approx([0.0, 0.4, -0.4, 0.8, -0.8])
    with pytest.raises(ValueError):
        offline_schedule(10.0, 0.0)


def test_offline_steps_mark_completed_arcs():
    tr = CircleTrajectory(center=C, radius_m=1.5, start_angle_deg=330.0)
    steps = list(offline_steps(tr, 2.0, 1.0))
    assert all(isinstance(s, OfflineStep) for s in steps)
    assert [(s.displacement_deg, s.completes) for s in steps] == [
        (0.0, True), (1.0, False), (-1.0, True), (2.0, False), (-2.0, True)]
    assert [s.phi_deg for s in steps if s.completes] == [0.0, 1.0, 2.0]
    for s in steps:
        assert wrap_deg(polar_deg(s.pose) - 330.0 - s.displacement_deg) == pytest.approx(0.0, abs=1e-9)


def test_scenario_trajectories_are_about_120_degrees_apart():
    sc = load_scenario(bundled_scenarios()["scene1"])
    trs = trajectories(sc)
    assert list(trs) == ["Lyon", "Auckland", "Nevers"]
    angles = [polar_deg(t.start_pose(), sc.world.center) for t in trs.values()]
    assert angles == pytest.approx([90.0, 210.0, 330.0])
    yaws = [math.degrees(t.start_pose().yaw) for t in trs.values()]
    assert wrap_deg(yaws[1] - yaws[0]) == pytest.approx(120.0)  # ground truth θ* between map frames
