"""circsim.experiments.api.run_sweep: a sweep from Python is the command's sweep (same plan, folder, rows)."""

from __future__ import annotations

import pytest

from circsim.cli import main
from circsim.experiments.api import run_sweep
from circsim.experiments.plan import SweepError
from circsim.experiments.store import read_rows

VOLATILE = ("wall_s", "realtime_factor", "merge_cycle_ms.median", "merge_cycle_ms.p95")


def stable(rows):
    return [{k: v for k, v in r.items() if k not in VOLATILE and not k.startswith("param.")} for r in rows]


@pytest.mark.slow
def test_run_sweep_gives_the_rows_of_circsim_sweep(tmp_path, capsys):
    args = dict(grid={"center_error": [0, 0.2]}, seeds=1, sets=["duration_s=2"], workers=1, plots=False)
    res = run_sweep("scene1", out=tmp_path / "py", **args)
    assert res.planned == 2 and res.failed == 0 and res.keys == ["center_error.magnitude_m"]
    assert [r["center_error.magnitude_m"] for r in res.rows] == [0, 0.2]
    assert read_rows(tmp_path / "py" / "runs.jsonl") == res.rows and len(res.summary) == 2
    assert main(["sweep", "scene1", "--grid", "center_error=0,0.2", "--seeds", "1", "--set", "duration_s=2",
                 "--workers", "1", "--no-plots", "--quiet", "--out", str(tmp_path / "cli")]) == 0
    assert stable(read_rows(tmp_path / "cli" / "runs.jsonl")) == stable(res.rows)
    again = run_sweep("scene1", out=tmp_path / "py", resume=True, **args)  # nothing left to run
    assert again.skipped == 2 and stable(again.rows) == stable(res.rows)


def test_bad_input_is_one_sweep_error_before_any_run(tmp_path):
    with pytest.raises(SweepError, match="merger.windw_m"):
        run_sweep("scene1", grid={"merger.windw_m": [0, 0.5]}, out=tmp_path / "o")
    with pytest.raises(SweepError, match=r"workers: expected an integer >= 1, got 0"):
        run_sweep("scene1", workers=0, out=tmp_path / "o")
    assert not (tmp_path / "o").exists()
