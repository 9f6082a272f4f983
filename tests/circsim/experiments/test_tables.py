"""circsim.experiments.tables: a sweep's rows grouped per grid combination with their medians and quartiles
(checked against statistics), totals of false merges, the rows in plan order, the CSV columns as the
union of keys read back by csv, the parquet table the same rows, and the printed table aligned."""

from __future__ import annotations

import csv
import json
import statistics

import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from circsim.experiments.plan import RUNS_JSONL, Axis, RunTask
from circsim.experiments.tables import counted, format_summary, summarize, sweep_rows, write_csv, write_tables

AXES = [Axis("center_error.magnitude_m", (0.0, 0.1))]


def _row(ce, seed, first, false=0, merged=True, **kw):
    return {"run_key": f"{ce}/{seed}", "center_error.magnitude_m": ce, "seed": seed, "all_merged": merged,
            "first_merge_s.mean": first, "false_merges": false, **kw}


def test_counted():
    assert [counted(1, "seed"), counted(2, "seed"), counted(0, "run"), counted(3, "cross", "crosses")] == \
        ["1 seed", "2 seeds", "0 runs", "3 crosses"]


@settings(max_examples=40, deadline=None)
@given(firsts=st.lists(st.one_of(st.none(), st.floats(0, 100)), min_size=1, max_size=9),
       falses=st.data())
def test_each_combination_gets_its_quartiles_and_totals(firsts, falses):
    f = falses.draw(st.lists(st.integers(0, 3), min_size=len(firsts), max_size=len(firsts)))
    rows = [_row(0.1, k, x, fm, merged=x is not None) for k, (x, fm) in enumerate(zip(firsts, f, strict=True))]
    rows += [_row(0.0, 0, 2.0)]
    s = {r["center_error.magnitude_m"]: r for r in summarize(rows, AXES)}
    assert set(s) == {0.0, 0.1}
    a = s[0.1]
    assert a["runs"] == len(firsts) and a["false_merges.total"] == sum(f)
    assert a["runs_with_false_merge"] == sum(x > 0 for x in f)
    assert a["all_merged_frac"] == pytest.approx(sum(x is not None for x in firsts) / len(firsts))
    xs = sorted(x for x in firsts if x is not None)
    if not xs:
        assert a["first_merge_s.mean.median"] is None and a["first_merge_s.mean.q1"] is None
    else:
        assert a["first_merge_s.mean.median"] == statistics.median(xs)
        if len(xs) > 1:
            q1, _, q3 = statistics.quantiles(xs, n=4, method="inclusive")
            assert (a["first_merge_s.mean.q1"], a["first_merge_s.mean.q3"]) == (q1, q3)
            assert a["first_merge_s.mean.q1"] <= a["first_merge_s.mean.median"] <= a["first_merge_s.mean.q3"]
    assert s[0.0]["runs"] == 1 and s[0.0]["first_merge_s.mean.median"] == 2.0


def test_the_rows_of_this_sweep_in_plan_order(tmp_path):
    tasks = [RunTask({}, "s", (), seed, f"k{seed}") for seed in (3, 1, 2)]
    (tmp_path / RUNS_JSONL).write_text("".join(json.dumps({"run_key": k, "v": k}) + "\n"
                                               for k in ("k2", "other", "k3")))
    assert [r["run_key"] for r in sweep_rows(tmp_path, tasks)] == ["k3", "k2"]  # k1 not run; other not this sweep's


def test_csv_columns_are_the_union_of_keys_and_values_read_back(tmp_path):
    rows = [{"a": 1, "b": 0.1 + 0.2}, {"b": None, "c": [1, 2], "d": {"x": 1}}]
    p = tmp_path / "t.csv"
    write_csv(rows, p)
    with open(p, newline="") as f:
        back = list(csv.DictReader(f))
    assert list(back[0]) == ["a", "b", "c", "d"]
    assert back[0] == {"a": "1", "b": "0.3", "c": "", "d": ""}  # 12 significant digits: 0.3, not 0.30000000000000004
    assert back[1] == {"a": "", "b": "", "c": "[1, 2]", "d": '{"x": 1}'}
    write_csv([], p)
    assert p.read_text() == ""


def test_write_tables_writes_runs_summary_and_parquet(tmp_path):
    rows = [_row(0.0, 0, 1.5), _row(0.1, 0, None, 2, merged=False)]
    summary = summarize(rows, AXES)
    paths = write_tables(rows, summary, tmp_path)
    assert [p.name for p in paths] == ["runs.csv", "summary.csv", "runs.parquet"]
    table = pq.read_table(tmp_path / "runs.parquet").to_pylist()
    assert table == rows
    with open(tmp_path / "summary.csv", newline="") as f:
        assert [r["false_merges.total"] for r in csv.DictReader(f)] == ["0", "2"]


def test_the_printed_summary_is_aligned_and_shows_missing_values():
    rows = [_row(0.0, 0, 1.5, top_error_deg={"median": 0.3}), _row(0.1, 0, None, 1, merged=False)]
    text = format_summary(summarize(rows, AXES), AXES)
    lines = text.splitlines()
    assert len(lines) == 3 and len({len(ln) for ln in lines}) == 1  # every row as wide: columns aligned
    head = lines[0].split()
    assert head[0] == "center_error.magnitude_m" and "runs" in head
    assert "1.5 [1.5–1.5]" in lines[1] and "100%" in lines[1]  # one run: its value is every quartile
    assert "— [—–—]" in lines[2] and " 0%" in lines[2]  # nobody merged
    assert lines[2].split()[0] == "0.1"
