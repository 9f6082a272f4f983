"""The bench under ``merger.research: on_change`` (issue 33): the same first merges as searching every map
version, no more false merges, and the tracker's work and the latency in the metrics."""

from __future__ import annotations

import pytest

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.sim import Simulation


def _run(name, *sets):
    sc = load_scenario(bundled_scenarios()[name]).with_overrides(list(sets))
    return Simulation(sc).run().to_dict()


@pytest.mark.slow
def test_tracking_merges_as_early_as_searching_every_version_with_no_more_false_merges():
    sets = ("duration_s=12", "merger.window_m=0.5", "center_error=0.15")
    old = _run("hall4", *sets, "merger.research=every_version")
    new = _run("hall4", *sets, "merger.research=on_change")
    period = new["params"]["network"]["period_s"]
    for n, r in old["robots"].items():
        assert r["first_merge_s"] is not None
        t = new["robots"][n]["first_merge_s"]
        assert t is not None and t <= r["first_merge_s"] + period, (n, t, r["first_merge_s"])
    assert new["false_merges"] <= old["false_merges"]
    tr = new["tracking"]
    assert tr["local_checks"] > 0 and tr["global_searches"] > 0
    assert old["tracking"]["per_robot"] == {}  # every_version: no tracker
    assert new["latency_s"]["count"] > 0 and new["latency_s"]["p95"] <= period + 1.0
    assert new["placement_jump"]["count"] > 0


def test_the_thesis_scenes_search_every_version():
    for name in ("scene1", "scene2", "scene1-thesis", "scene2-thesis"):
        sc = load_scenario(bundled_scenarios()[name])
        assert sc.merger.research == "every_version", name
    assert load_scenario(bundled_scenarios()["hall8"]).merger.research == "on_change"


@pytest.mark.slow
def test_a_tracked_pair_does_not_walk_along_a_bare_halls_flat_ridge():
    """Generated floor plan 28 (a bare 6 x 11 m hall), centers 0.15 m off: the local re-verifications walked
    Auckland's placement of Lyon along the hall, 3 cells a version, to 0.53 m off at 3.6 s and 0.70 m at
    5.0 s (gross false merges, angle right). A local answer that leaves its hypothesis's neighbourhood is
    now searched globally: no gross merge, and every robot's first correct merge by 5 s (4.6 s); with the
    teammates' faces centred (``teammate_shift_m``, the default since issue 43's seventh pass) by 6 s (5.6 s).
    The faces left as seen is checked at the merge rate its bound was measured at (0.5 s throughout): there the
    robots first accept complete placements that are off (non-gross), and at the default rate a robot so
    placed merges once per 2 s, which moved its first correct merge to 5.7 s (docs/experiments.md, twelfth pass)."""
    d = _run("floorplan", "world.generate.seed=28", "center_error.magnitude_m=0.15", "duration_s=7")
    assert d["gross_merges"] == 0
    assert all(r["first_merge_s"] is not None and r["first_merge_s"] <= 6.0 for r in d["robots"].values())
    off = _run("floorplan", "world.generate.seed=28", "center_error.magnitude_m=0.15", "duration_s=6",
               "merger.teammate_shift_m=0", "merger.cycle_period_s=0.5")
    assert off["gross_merges"] == 0
    assert all(r["first_merge_s"] is not None and r["first_merge_s"] <= 5.0 for r in off["robots"].values())
