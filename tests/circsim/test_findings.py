"""The thesis's qualitative findings (section 3.3), measured on our bench.

Each test asserts what holds on the bench. Where the thesis's finding does not hold, the test says
so and asserts the measured behaviour instead (numbers and conditions in docs/experiments.md).
"""

import math

import pytest

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.experiments.offline import OfflineSettings, default_search_method, run_offline
from circsim.experiments.sweep import HypothesisStats
from circsim.sim import Simulation

pytestmark = pytest.mark.slow  # every test runs the bundled scenes end to end (online or offline)

FAST = default_search_method()  # "fast": the exact branch and bound, quick enough for online runs in CI
SCENES = ["scene1", "scene2"]


def scene(name, *sets):
    return load_scenario(bundled_scenarios()[name]).with_overrides([f"merger.method={FAST}", *sets])


@pytest.mark.parametrize("name", SCENES)
@pytest.mark.parametrize("seed_offset", [0, 1])
def test_exact_center_first_correct_merge_within_a_quarter_circle_and_no_false_merge(name, seed_offset):
    """Holds: every robot's first correct merge comes before 90° of travel; nothing false is accepted."""
    base = scene(name)
    quarter_s = 0.25 * 2 * math.pi * base.robots.radius_m / base.robots.speed_mps
    sc = base.with_overrides(["center_error.magnitude_m=0", f"duration_s={quarter_s + 1.0:.1f}",
                              f"seed={base.seed + seed_offset}"])
    hyp = HypothesisStats()
    res = Simulation(sc, [hyp]).run().to_dict()
    assert res["false_merges"] == 0
    assert hyp.accepted == 0
    for robot, r in res["robots"].items():
        assert r["first_merge_arc_deg"] is not None, f"{robot} never merged within a quarter circle"
        assert r["first_merge_arc_deg"] < 90.0, robot


@pytest.mark.parametrize("name", SCENES)
def test_180_degree_hypotheses_occur_with_an_imprecise_center_and_verification_rejects_them(name):
    """Holds online once the center is off by 0.2 m: the point-symmetric pillars (and the nearly
    symmetric room) make orders propose ~180° rotations; the whole-map verification rejects every one.
    With an exact center no 180° hypothesis arises at all on our bench (see docs/experiments.md)."""
    sc = scene(name, "center_error.magnitude_m=0.2", "duration_s=10")
    hyp = HypothesisStats()
    res = Simulation(sc, [hyp]).run().to_dict()
    assert hyp.proposed > 0
    assert hyp.accepted == 0 and res["false_merges"] == 0


@pytest.fixture(scope="module")
def offline_results():
    """The offline experiment with the default settings, first seed of each scene, stopped at first merges."""
    return {name: run_offline(scene(name), OfflineSettings(search_method=FAST))[0] for name in SCENES}


@pytest.mark.parametrize("name", SCENES)
def test_offline_every_method_finds_a_valid_correct_merge_without_false_merges(offline_results, name):
    for method, r in offline_results[name].items():
        assert r.first_correct_phi_deg is not None, method
        assert r.false_merges == 0, method
        assert r.proposed_180 == r.rejected_180, method


@pytest.mark.parametrize("name", SCENES)
def test_offline_similarity_does_not_need_less_displacement_than_ncc_on_our_bench(offline_results, name):
    """The thesis's finding (similarity ±17°/±11° < NCC ±28°/±40°) does NOT hold on our bench.

    From its start pose every robot already sees most of the room (240° laser, 5.6 m, robots facing the
    center), so NCC — with a threshold calibrated above every wrong rotation's score — accepts a correct
    merge at φ = 0; the similarity method waits for the whole-map support (min_support) and needs
    ±1° (scene1) and ±5° (scene2). We assert what holds: NCC needs no more displacement than similarity.
    """
    r = offline_results[name]
    assert r["ncc"].first_correct_phi_deg <= r["similarity"].first_correct_phi_deg


# NCC threshold for a 3 m ROI, calibrated like circsim.experiments.offline.NCC_SCORE_MIN (above every wrong rotation's
# score on seeds 100–102 of both scenes): `circsim offline scene1 scene2 --seed 100 --seeds 3 --calibrate
# --set merger.roi_m=3` → highest wrong-rotation score 0.467 → 0.5.
NCC_SCORE_MIN_ROI3 = 0.5


@pytest.mark.parametrize("name", SCENES)
def test_offline_with_the_roi_on_the_scene_similarity_needs_less_displacement_than_ncc(name):
    """Holds when the ROI covers the scene rather than the whole room (3 m instead of the bundled 8 m):
    the room's walls no longer make every view alike, and the thesis's ordering appears
    (ours: similarity ±6°/±5°, NCC ±44°/±50° on scene1/scene2; thesis ±17°/±11° and ±28°/±40°)."""
    sc = scene(name, "merger.roi_m=3")
    res, _ = run_offline(sc, OfflineSettings(search_method=FAST, ncc_score_min=NCC_SCORE_MIN_ROI3))
    ncc, sim = res["ncc"], res["similarity"]
    assert sim.first_correct_phi_deg is not None and ncc.first_correct_phi_deg is not None
    assert sim.first_correct_phi_deg < ncc.first_correct_phi_deg
    assert sim.false_merges == 0 and ncc.false_merges == 0
    assert ncc.proposed_180 > 0 and ncc.rejected_180 == ncc.proposed_180  # 180° flips occur, all rejected
