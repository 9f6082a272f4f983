"""merger.cli.report: what the commands print and write. The text's poses are the MergeResult's (to the
printed millimetre and hundredth of a degree), the JSON carries them exactly, the written map is the merged
map cell for cell; an order's mark never says "accepted" for what the cycle refuses; the overlay's title is
ASCII."""

import json
import re
from types import SimpleNamespace as NS

import numpy as np
import pytest

import merger
from merger.cli.report import (
    ascii_text,
    merge_files,
    order_mark,
    overlay_path,
    pose_lines,
    report_merge,
    verdict_line,
    write_merge,
)
from merger.io.mapio import load_map
from tests.strategies import three_views


@pytest.fixture(scope="module")
def merged():
    _, names, maps, _ = three_views(2)
    return merger.merge([g for g, _ in maps[:2]], centers=[c for _, c in maps[:2]], names=names[:2])


def test_the_text_prints_the_results_poses(merged, capsys):
    assert merged.accepted
    report_merge(merged, as_json=False)
    lines = capsys.readouterr().out.splitlines()
    assert lines[-1] == pose_lines(merged)[0] and lines[-2].endswith(verdict_line(merged))
    assert verdict_line(merged) == f"chosen: Lyon→Auckland (accepted by {merged.rule}: {merged.reason})"
    m = re.fullmatch(r"pose: Auckland in Lyon's frame: x (\S+) m, y (\S+) m, yaw (\S+)°", lines[-1])
    p = merged.poses["Auckland"]
    assert abs(float(m[1]) - p.x) <= 5e-4 and abs(float(m[2]) - p.y) <= 5e-4 and abs(float(m[3]) - p.yaw_deg) <= 5e-3
    assert lines[0].startswith("* order Lyon→Auckland") and lines[0].endswith("[accepted]")


def test_the_json_carries_the_poses_exactly(merged, capsys):
    report_merge(merged, as_json=True, extra={"resampled": []})
    out = json.loads(capsys.readouterr().out)
    assert out["poses"] == {k: p.to_dict() for k, p in merged.poses.items()}
    assert out["decided_by"] == merged.rule and out["resampled"] == [] and out["accepted"] is True


def test_the_written_map_is_the_merged_map(merged, tmp_path):
    files = merge_files(merged.team, list(merged.maps), tmp_path / "m.v1", force=False)
    assert sorted(p.name for p in files) == ["m.v1.pgm", "m.v1.yaml", "m.v1_overlay.png"]
    written = write_merge(merged.team, list(merged.maps), tmp_path / "m.v1", force=False)
    assert sorted(written) == sorted(files)
    back = load_map(tmp_path / "m.v1.yaml")
    np.testing.assert_array_equal(back.states, merged.merged.states)
    assert back.resolution == merged.merged.resolution
    np.testing.assert_allclose(back.origin, merged.merged.origin, atol=1e-9)
    refused = NS(accepted=False)
    assert merge_files(refused, list(merged.maps), tmp_path / "x", force=False) == {}  # nothing without --force


def test_an_orders_mark_follows_the_cycle():
    chosen = NS(order=("a", "b", "c"), combined=(("a", "c", "b"),))
    other = NS(order=("a", "c", "b"), accepted=True)
    assert order_mark(chosen, NS(chosen=chosen)) == "accepted"
    assert order_mark(other, NS(chosen=chosen)) == "verified, not chosen (averaged into the chosen)"
    assert order_mark(NS(order=("b", "a", "c"), accepted=True), NS(chosen=chosen)) == "verified, not chosen"
    assert order_mark(NS(accepted=False, reason="ν 0.2 < 0.4"), NS(chosen=None)) == "rejected: ν 0.2 < 0.4"
    assert order_mark(other, NS(chosen=None, rule="ambiguity")) == (
        "verified, but the cycle is rejected by the ambiguity rule (below)")
    assert verdict_line(NS(accepted=False, rule="the ambiguity rule", reason="x")) == "REJECTED by the ambiguity rule: x"


def test_the_overlay_title_is_ascii_and_sits_beside_the_yaml(tmp_path):
    assert ascii_text("θ 12.5° ν ≥ 0.4 → ±1 m — ω̃ ∞") == "theta 12.5 deg nu >= 0.4 > +-1 m - omega ?"
    assert overlay_path(tmp_path / "merged.v2.yaml") == tmp_path / "merged.v2_overlay.png"
