"""The scenario's merger section is merger.MergeParams plus the bench's own keys (issue 38, item 3): the same
defaults, and a bad value is refused by the merger's own rule, in one line naming the file and the key."""

from __future__ import annotations

import dataclasses

import pytest

from circsim.config.scenario import (
    MERGER_CHECKS,
    MergerSettings,
    ScenarioError,
    bundled_scenarios,
    load_scenario,
    scenario_from_dict,
)
from circsim.sim import merge_params
from merger.settings import DEFAULT_ROI_M, DEFAULT_WINDOW_M, SettingError
from merger.team import online, params


def test_merger_settings_are_merge_params_plus_the_bench_keys():
    names = {f.name for f in dataclasses.fields(params.MergeParams)}
    own = {f.name for f in dataclasses.fields(MergerSettings)} - names
    assert (MergerSettings().roi_m, MergerSettings().window_m) == (DEFAULT_ROI_M, DEFAULT_WINDOW_M)
    assert own == {"correct_tol_deg", "correct_tol_m", "min_maps", "cycle_period_s", "strategy", "algorithm",
                   "share_hypotheses"}
    for name, path in bundled_scenarios().items():  # the scenario's values reach MergeParams unchanged
        sc = load_scenario(path)
        p = merge_params(sc)
        assert type(p) is params.MergeParams and all(getattr(p, k) == getattr(sc.merger, k) for k in names), name


@pytest.mark.parametrize("merger_section, needle", [
    ({"window_m": 3.0}, "s.yaml: merger.window_m = 3 m is more than a quarter of the ROI side (8 m): expected at "
                        "most 2 m"),
    ({"window_m": -1}, "s.yaml: merger.window_m must be a finite number >= 0, got -1"),
    ({"window_m": True}, "s.yaml: merger.window_m must be a number of metres, got True"),
    ({"roi_m": 1.9}, "s.yaml: merger.window_m = 0.5 m is more than a quarter of the ROI side (1.9 m)"),
    ({"roi_m": 0.1, "window_m": 0}, "s.yaml: merger.roi_m: expected a side of 10 to 4000 cells of "
                                    "slam.resolution_m at 0.05 m per cell"),
    ({"score_min": 2}, "s.yaml: merger.score_min must be a number in [-1, 1], got 2"),
    ({"nu_min": -0.5}, "s.yaml: merger.nu_min must be a number in [0, 1], got -0.5"),
    ({"research_period_s": 0}, "s.yaml: merger.research_period_s must be a number in (0, 1e+06], got 0"),
    ({"roi_min_support": -1}, "s.yaml: merger.roi_min_support must be a whole number of cells >= 0"),
    ({"refine": 1}, "s.yaml: merger.refine must be true or false, got 1"),
    ({"strategy": "star"}, "s.yaml: merger.strategy: expected one of 'auto', 'orders', 'tree', got 'star'"),
])
def test_scenario_refusals_are_the_merger_rules_in_one_line(merger_section, needle):
    with pytest.raises(ScenarioError) as e:
        scenario_from_dict({"merger": merger_section}, source="s.yaml")
    assert str(e.value).startswith(needle) and "\n" not in str(e.value), str(e.value)


def test_the_merger_defaults_are_merge_params_and_the_online_merger():
    """Every MergeParams setting's default is MergeParams's (one default), the strategy's the online merger's."""
    d, sc = params.MergeParams(), scenario_from_dict({})
    assert all(getattr(sc.merger, f.name) == getattr(d, f.name) for f in dataclasses.fields(params.MergeParams))
    assert sc.merger.strategy == online.TeamMerger.strategy == "auto"


# a value each rule refuses: the scenario's refusal is that rule's words with the scenario's key
REFUSED = {"roi_m": -1.0, "measure": "sad", "method": "slow", "verification": "maybe", "nu_min": 1.5,
           "min_support": -1, "score_min": -2.0, "window_m": -1.0, "refine": "yes", "ambiguity_margin": 2.0,
           "combine_orders": 0, "roi_min_support": 2 ** 40, "tolerance_m": 0.0, "contrast_min": -1.0,
           "refine_whole": None, "research": "sometimes", "research_period_s": 0.0, "research_change": 1.5,
           "research_drop": 3.0, "teammate_radius_m": -0.2, "teammate_shift_m": 1.5}


@pytest.mark.parametrize("name", list(params.RULES))
def test_each_merger_setting_is_checked_by_its_one_rule(name):
    assert set(REFUSED) == set(params.RULES)
    with pytest.raises(SettingError) as rule:
        params.RULES[name](REFUSED[name], f"merger.{name}")
    with pytest.raises(ScenarioError) as e:
        scenario_from_dict({"merger": {name: REFUSED[name]}}, source="s.yaml")
    if name == "roi_m":  # the scenario adds the inputs' limits to the ROI's rule: its own words
        assert str(e.value).startswith("s.yaml: merger.roi_m: expected a number in (0, 100]"), str(e.value)
        return
    assert str(e.value) == f"s.yaml: {rule.value}", (str(e.value), str(rule.value))
    assert MERGER_CHECKS[name].expected == params.RULES[name].expected  # the reference prints the rule's words


def test_strategies_are_the_online_mergers():
    assert MERGER_CHECKS["strategy"].expected == "one of " + ", ".join(map(repr, online.STRATEGIES))
