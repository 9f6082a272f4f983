"""The scenario's merger section is merger.MergeParams plus the bench's own keys (issue 38, item 3): the same
defaults, and a bad value is refused by the merger's own rule, in one line naming the file and the key."""

from __future__ import annotations

import dataclasses

import pytest

from circsim.config.scenario import (
    MergerSettings,
    ScenarioError,
    bundled_scenarios,
    load_scenario,
    scenario_from_dict,
)
from circsim.sim import merge_params
from merger.search.problem import DEFAULT_ROI_M, DEFAULT_WINDOW_M
from merger.team import params


def test_merger_settings_are_merge_params_plus_the_bench_keys():
    names = {f.name for f in dataclasses.fields(params.MergeParams)}
    own = {f.name for f in dataclasses.fields(MergerSettings)} - names
    assert (MergerSettings().roi_m, MergerSettings().window_m) == (DEFAULT_ROI_M, DEFAULT_WINDOW_M)
    assert own == {"correct_tol_deg", "correct_tol_m", "min_maps", "strategy", "algorithm", "share_hypotheses"}
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
    ({"score_min": 2}, "s.yaml: merger: score_min must be a finite number in [-1, 1]"),
])
def test_scenario_refusals_are_the_merger_rules_in_one_line(merger_section, needle):
    with pytest.raises(ScenarioError) as e:
        scenario_from_dict({"merger": merger_section}, source="s.yaml")
    assert str(e.value).startswith(needle) and "\n" not in str(e.value), str(e.value)
