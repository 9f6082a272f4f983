"""circsim.experiments.plan: a sweep's plan is every combination × every seed (seed = base + i), each
combination's scenario built and validated before any run; --grid values parse as --set's (YAML 1.2);
a bad grid is one SweepError line naming the key and value; the run key tells runs apart exactly when
they differ (scenario, base scenario, grid values as numbers, seed)."""

import itertools
import json

import pytest

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.experiments.plan import SweepError, base_digest, parse_grid, plan, run_key, value_text


@pytest.fixture(scope="module")
def base():
    return load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=5", "seed=7"])


def test_grid_values_parse_as_yaml_12_and_aliases_resolve():
    axes = parse_grid(["center_error=0,1e-1,0.2", "merger.measure=similarity,ncc", "latency=0,1"])
    assert [a.key for a in axes] == ["center_error.magnitude_m", "merger.measure", "network.latency_s"]
    assert axes[0].values == (0.0, 0.1, 0.2) and axes[0].texts == ("0", "1e-1", "0.2")
    assert axes[1].values == ("similarity", "ncc") and axes[2].values == (0.0, 1.0)


@pytest.mark.parametrize("spec, words", [
    ("center_error", "expected KEY.PATH=V1,V2,..."),
    ("=1,2", "expected KEY.PATH=V1,V2,..."),
    ("seed=1,2", "seeds are not a grid axis"),
    ("center_error=0,,1", "empty value"),
    ("center_error=0,0.0", "repeated value"),  # 0 and 0.0 are one value
    ("center_error=[1", "is not valid YAML"),
])
def test_a_bad_grid_is_one_line_naming_it(spec, words):
    with pytest.raises(SweepError) as e:
        parse_grid([spec])
    assert words in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(SweepError, match="given twice"):
        parse_grid(["center_error=0", "center_error.magnitude_m=1"])


def test_the_plan_is_every_combination_times_every_seed(base):
    axes = parse_grid(["center_error=0,0.2", "merger.window_m=0,0.5,1"])
    tasks = plan(base, axes, 3)
    combos = list(itertools.product([0.0, 0.2], [0.0, 0.5, 1.0]))
    assert [(tuple(v for _, v in t.grid), t.seed) for t in tasks] == [(c, 7 + i) for c in combos for i in range(3)]
    assert len({t.key for t in tasks}) == len(tasks) == 18
    sc = tasks[4].scenario()  # (0, 0.5), seed 8: the scenario the worker runs
    assert (sc.seed, sc.merger.window_m, sc.center_error.magnitude_m, sc.duration_s) == (8, 0.5, 0.0, 5)
    assert tasks[4].assignments() == ["center_error.magnitude_m=0", "merger.window_m=0.5", "seed=8"]
    assert plan(base, [], 2)[1].grid == () and [t.seed for t in plan(base, [], 2)] == [7, 8]


def test_a_value_the_scenario_refuses_is_named_before_any_run(base):
    with pytest.raises(SweepError) as e:
        plan(base, parse_grid(["merger.window_m=0,-1"]), 1)
    assert "--grid merger.window_m=-1" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(SweepError, match="--seeds: expected an integer >= 1, got 0"):
        plan(base, [], 0)


def test_run_keys_and_digests():
    k = run_key("scene1", [("center_error.magnitude_m", 0)], 3, "abc")
    assert k == run_key("scene1", [("center_error.magnitude_m", 0.0)], 3, "abc")  # 0 and 0.0: one run
    assert json.loads(k) == {"scenario": "scene1", "base": "abc", "grid": {"center_error.magnitude_m": 0.0}, "seed": 3}
    assert k != run_key("scene1", [("center_error.magnitude_m", 0)], 4, "abc")
    assert k != run_key("scene1", [("center_error.magnitude_m", 0)], 3, "abd")
    assert base_digest({"a": 1, "seed": 1}) == base_digest({"seed": 2, "a": 1}) != base_digest({"a": 2})
    assert [value_text(v) for v in (3.0, 0.25, "ncc", True, 2.0 ** 60)] == ["3", "0.25", '"ncc"', "true",
                                                                             "1.152921504606847e+18"]
