"""The comparison of merging methods (issue 35): sweep rows and real-map verdicts summarized per method."""

from __future__ import annotations

import pytest

from circsim.experiments.compare import plot, real_summary, real_table, sim_summary, sim_table


def _row(alg, err, merged, first, false, ms=10.0, scene="scene1"):
    return {"scenario": scene, "merger.algorithm": f'"{alg}"', "center_error.magnitude_m": err,
            "robots_merged": merged, "first_merge_s.mean": first, "false_merges": false,
            "merge_cycle_ms.median": ms, "interrupted": False}


ROWS = [_row("thesis", 0.0, 3, 2.0, 0), _row("thesis", 0.0, 3, 4.0, 0, 30.0), _row("hough", 0.0, 2, 3.0, 5),
        _row("hough", 0.0, 0, None, 1), _row("features", 0.1, 0, None, 0),
        {**_row("thesis", 0.1, 3, 1.0, 9), "interrupted": True}]


def test_sim_summary_per_algorithm_and_error():
    s = {(x["algorithm"], x["center_error_m"]): x for x in sim_summary(ROWS, {"scene1": 3})}
    assert set(s) == {("thesis", 0.0), ("hough", 0.0), ("features", 0.1)}  # the interrupted run is left out
    assert s[("thesis", 0.0)]["merged_fraction"] == 1.0 and s[("thesis", 0.0)]["first_merge_s"] == 3.0
    assert s[("thesis", 0.0)]["cycle_ms"] == 20.0
    h = s[("hough", 0.0)]
    assert h["merged_fraction"] == pytest.approx(1 / 3) and h["first_merge_s"] == 3.0 and h["false_merges"] == 3.0
    assert s[("features", 0.1)]["first_merge_s"] is None
    table = sim_table(sim_summary(ROWS, {"scene1": 3}), ["thesis", "features", "hough"])
    assert "| scene1 | 0 m | 100% / 3.0 s / 0.0 (20 ms) | — | 33% / 3.0 s / 3.0 (10 ms) |" in table


def test_real_summary_counts_correct_false_refused(tmp_path):
    v = [{"set": "A", "algorithm": "hough", "accepted": True, "correct": True, "ms": 1.0},
         {"set": "A", "algorithm": "hough", "accepted": True, "correct": False, "ms": 3.0},
         {"set": "A", "algorithm": "hough", "accepted": False, "correct": True, "ms": 5.0}]
    (r,) = real_summary(v)
    assert (r["pairs"], r["correct"], r["false"], r["refused"], r["ms"]) == (3, 1, 1, 1, 3.0)
    assert "| A | 3 | — | 1 / 1 / 1 (3 ms) |" in real_table([r], ["thesis", "hough"])
    out = plot(sim_summary(ROWS, {"scene1": 3}), [r], ["thesis", "features", "hough"], tmp_path / "c.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
