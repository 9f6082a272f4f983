"""`merger.algorithm` on the bench (issue 35): every merging method runs online, is judged by the same truth
and metrics, and a bad name is a one-line scenario error."""

from __future__ import annotations

import pytest

from circsim.cli import main
from circsim.config.scenario import ScenarioError, bundled_scenarios, load_scenario
from circsim.sim import Simulation
from merger.algorithms.online import AlgorithmMerger


def _scene1(*sets):
    return load_scenario(bundled_scenarios()["scene1"]).with_overrides(["duration_s=6", *sets])


@pytest.mark.slow
def test_hough_merges_scene1_online_and_is_judged():
    sim = Simulation(_scene1("merger.algorithm=hough"))
    assert all(isinstance(r.merger, AlgorithmMerger) for r in sim.robots.values())
    res = sim.run()
    assert all(r.cycles > 0 for r in res.robots.values())
    assert any(r.first_merge_s is not None for r in res.robots.values())  # scene 1: hough merges in seconds
    for r in res.robots.values():  # every accepted merge was judged: correct or counted false
        assert r.accepted >= r.false_merges


def test_features_runs_and_refuses_with_its_rule():
    res = Simulation(_scene1("merger.algorithm=features")).run()
    assert sum(r.cycles for r in res.robots.values()) > 0
    assert res.params["merger"]["algorithm"] == "features"


def test_the_thesis_is_the_default():
    assert _scene1().merger.algorithm == "thesis"
    assert type(Simulation(_scene1()).robots["Lyon"].merger).__name__ == "TeamMerger"


def test_a_bad_algorithm_is_one_line(capsys):
    with pytest.raises(ScenarioError, match=r"merger.algorithm.*'thesis', 'features', 'hough'"):
        _scene1("merger.algorithm=orb")
    assert main(["run", "scene1", "--set", "merger.algorithm=orb", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "merger.algorithm" in err[0]
