"""The offline displacement experiment (circsim.experiments.offline) and its CLI."""

import json

import numpy as np
import pytest

from circsim.cli import main
from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.experiments.offline import (
    THESIS_PHI_DEG,
    OfflineSettings,
    calibrated_threshold,
    default_search_method,
    judge_cycle,
    method_params,
    run_offline,
    summarize,
)
from merger.measures import Counts
from merger.search import Alignment
from merger.team.orders import OrderResult, TeamMergeResult
from merger.team.verify import Verification

FAST = default_search_method()


def scene(name, *sets):
    return load_scenario(bundled_scenarios()[name]).with_overrides(list(sets))


def _order(theta, accepted, names=("Lyon", "Auckland", "Nevers")):
    al = Alignment(0.0, 0.5, Counts(1, 1), "ncc", "reference", 8.0, np.zeros(360), (180.0, 0.2))
    checks = {"x": Verification(0.5, Counts(1, 1), accepted, "" if accepted else "too low")}
    return OrderResult(names, dict(zip(names, theta, strict=True)), (("Auckland", al), ("Nevers", al)),
                       checks, accepted, "" if accepted else "too low")


def test_judge_counts_180_degree_hypotheses_and_their_rejection():
    truth = {"Lyon": 0.0, "Auckland": 120.0, "Nevers": 240.0}
    right = _order((0.0, 120.5, 239.0), True)
    flipped = _order((0.0, 300.0, 240.0), False)  # Auckland 180° off, rejected
    near = _order((0.0, 115.0, 240.0), False)  # 5° off: wrong but not a 180° error
    res = TeamMergeResult("Lyon", (right, flipped, near), right, None, {})
    rec = judge_cycle(res, truth, 2.0, scene="s", seed=0, method="ncc", phi_deg=3.0)
    assert rec.accepted and rec.correct and not rec.false_merge
    assert (rec.proposed_180, rec.rejected_180) == (1, 1)
    res2 = TeamMergeResult("Lyon", (flipped, _order((0.0, 300.0, 60.0), True)), None, None, {})
    res2 = TeamMergeResult("Lyon", res2.orders, res2.orders[1], None, {})
    rec2 = judge_cycle(res2, truth, 2.0, scene="s", seed=0, method="ncc", phi_deg=3.0)
    assert rec2.false_merge and not rec2.correct and (rec2.proposed_180, rec2.rejected_180) == (2, 1)


def test_method_params_follow_the_scenario():
    sc = scene("scene1", "merger.nu_min=0.55", "merger.min_support=123", "merger.roi_m=6")
    s = OfflineSettings(ncc_score_min=0.42, search_method="reference")
    ncc, sim = method_params(sc, "ncc", s), method_params(sc, "similarity", s)
    assert (ncc.measure, ncc.verification, ncc.score_min, ncc.roi_m) == ("ncc", "roi_score", 0.42, 6)
    assert (sim.measure, sim.verification, sim.nu_min, sim.min_support) == ("similarity", "whole_map", 0.55, 123)
    with pytest.raises(ValueError, match="--methods"):
        OfflineSettings(methods=("ncc", "sift"))


def test_calibrated_threshold_lies_above_every_wrong_rotation():
    rows = [{"score": 0.5, "correct": True, "wrong_angle_score": 0.31},
            {"score": 0.28, "correct": False, "wrong_angle_score": 0.28},
            {"score": 0.6, "correct": True, "wrong_angle_score": None}]
    cal = calibrated_threshold(rows)
    assert cal["threshold"] == pytest.approx(0.35) and cal["correct_at_or_above"] == 2


def test_run_stops_each_method_at_its_first_valid_correct_merge():
    sc = scene("scene2", "merger.roi_m=4")
    s = OfflineSettings(max_deg=6, scans_per_pose=2, search_method=FAST)
    results, records = run_offline(sc, s)
    for m, r in results.items():
        assert r.cycles == len([x for x in records if x.method == m])
        if r.first_correct_phi_deg is not None:
            assert r.last_phi_deg == r.first_correct_phi_deg  # stopped there
            assert r.first_merge is not None and r.first_merge.accepted
    rows = summarize(list(results.values()))
    assert {row["method"] for row in rows} == {"ncc", "similarity"}
    assert rows[0]["thesis_phi"] == THESIS_PHI_DEG[("scene2", rows[0]["method"])]


def test_cli_offline_writes_csv_json_and_prints_the_thesis_column(tmp_path, capsys):
    out = tmp_path / "off"
    rc = main(["offline", "scene1", "--max-deg", "3", "--out", str(out), "--quiet", "--scans-per-pose", "2",
               "--search-method", FAST, "--set", "merger.roi_m=4", "--save-maps", "--full"])
    text = capsys.readouterr().out
    assert rc == 0
    assert "thesis" in text and "±28°" in text and "±17°" in text
    data = json.loads((out / "offline.json").read_text())
    assert {r["method"] for r in data["summary"]} == {"ncc", "similarity"}
    assert (out / "offline.csv").read_text().startswith("scene,method,")
    assert len((out / "offline_records.jsonl").read_text().splitlines()) == 2 * 4  # both methods, φ = 0..3
    assert (out / "maps" / "scene1" / "seed1" / "phi3" / "Lyon.yaml").exists()


def test_cli_offline_and_sweep_unwritable_out_is_exit_2_before_any_run(tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("")
    for args in (["offline", "scene1", "--out", str(afile / "x")],
                 ["offline", "scene1", "--calibrate", "--out", str(afile / "x")],
                 ["sweep", "scene1", "--grid", "center_error=0,0.1", "--out", str(afile)]):
        assert main(args + ["--quiet"]) == 2, args
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "--out" in err and "cannot write" in err, err


def test_cli_offline_bad_method_is_exit_2(capsys):
    assert main(["offline", "scene1", "--methods", "ncc,sift"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--methods" in err
