"""Ground-truth judgement of an alignment (circsim.judge)."""

import math

from circsim.judge import judge


def test_judge_wraps_angles_and_applies_the_tolerance_per_map():
    errors, ok = judge({"A": 0.0, "B": 359.5, "C": 121.9}, {"A": 0.0, "B": 0.5, "C": 120.0}, 2.0)
    assert errors["A"] == 0.0
    assert abs(errors["B"] - 1.0) < 1e-12  # 359.5° vs 0.5°: 1° apart across the wrap
    assert abs(errors["C"] - 1.9) < 1e-9
    assert ok
    errors, ok = judge({"A": 0.0, "B": 182.0}, {"A": 0.0, "B": 0.0}, 2.0)
    assert errors["B"] == 178.0 and not ok


def test_judge_an_error_of_exactly_the_tolerance_counts_as_correct_despite_float_noise():
    # the sim's truth θ* = degrees(yaw_j − yaw_i) for robots at 330° and 210° is 119.99999999999997
    truth = math.degrees(math.radians(330) - math.radians(210)) % 360
    errors, ok = judge({"B": 122.0}, {"B": truth}, 2.0)
    assert errors["B"] > 2.0 and ok  # 2.0000000000000284: exactly 2° on the 0.1° lattice
    errors, ok = judge({"B": 122.01}, {"B": truth}, 2.0)
    assert not ok

