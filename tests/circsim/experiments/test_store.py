"""circsim.experiments.store: a sweep folder's rows read back with a torn last line ignored and a foreign line
refused by file and line; one sweep at a time per folder; --resume continues only the same sweep (its
remaining runs), refusing another base scenario with the differences named; --overwrite starts afresh."""

from __future__ import annotations

import json
import os

import pytest

from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.experiments.plan import ERRORS_JSONL, RUNS_JSONL, SweepError, parse_grid, plan
from circsim.experiments.store import (
    SWEEP_JSON,
    check_sweep_outputs,
    lock_out,
    prepare_out,
    read_rows,
    write_sweep_identity,
)
from merger.io.mapread import MapFileError


def _tasks(duration="5"):
    base = load_scenario(bundled_scenarios()["scene1"]).with_overrides([f"duration_s={duration}"])
    return plan(base, parse_grid(["center_error=0,0.1"]), 2)


def _row(task):
    return json.dumps({"run_key": task.key, "seed": task.seed}) + "\n"


def test_rows_are_read_back_and_a_torn_line_is_ignored(tmp_path):
    p = tmp_path / RUNS_JSONL
    assert read_rows(p) == []
    p.write_text('{"run_key": "a", "x": 1}\n{"run_key": "b"}\n{"run_key": "c", "x"')  # killed mid-line
    assert read_rows(p) == [{"run_key": "a", "x": 1}, {"run_key": "b"}]


@pytest.mark.parametrize("line", ['[1, 2]', '{"x": 1}', '{"run_key": 7}', '"text"'])
def test_a_line_that_is_not_a_run_is_refused_by_file_and_line(tmp_path, line):
    p = tmp_path / RUNS_JSONL
    p.write_text('{"run_key": "a"}\n' + line + "\n")
    with pytest.raises(SweepError) as e:
        read_rows(p)
    assert str(e.value).startswith(f"{p}: line 2: expected a run's row") and "--overwrite" in str(e.value)


def test_one_sweep_at_a_time_per_folder(tmp_path):
    lock = lock_out(tmp_path)
    with pytest.raises(SweepError, match=r"another sweep is writing there"):
        lock_out(tmp_path)
    lock.close()
    with lock_out(tmp_path):  # released: the folder can be taken again
        pass
    assert os.listdir(tmp_path) == []  # no lock file left behind


def test_a_fifo_where_a_sweep_writes_is_refused(tmp_path):
    os.mkfifo(tmp_path / RUNS_JSONL)
    with pytest.raises(MapFileError, match=r"runs.jsonl: is not a regular file"):
        check_sweep_outputs(tmp_path)


def test_resume_runs_what_is_left_of_the_same_sweep(tmp_path):
    tasks = _tasks()
    assert len(tasks) == 4
    todo, done = prepare_out(tmp_path / "s", tasks, resume=False, overwrite=False)
    assert todo == tasks and done == 0  # a fresh folder, made
    out = tmp_path / "s"
    write_sweep_identity(out, tasks)
    (out / RUNS_JSONL).write_text(_row(tasks[0]) + _row(tasks[2]))
    with pytest.raises(SweepError, match=r"already holds 2 runs; pass --resume .* or --overwrite"):
        prepare_out(out, tasks, resume=False, overwrite=False)
    todo, done = prepare_out(out, tasks, resume=True, overwrite=False)
    assert todo == [tasks[1], tasks[3]] and done == 2


def test_resume_refuses_another_base_scenario_naming_the_difference(tmp_path):
    tasks = _tasks("5")
    write_sweep_identity(tmp_path, tasks)
    (tmp_path / RUNS_JSONL).write_text(_row(tasks[0]))
    with pytest.raises(SweepError) as e:
        prepare_out(tmp_path, _tasks("6"), resume=True, overwrite=False)
    assert "holds a sweep of another scenario or --set values (duration_s: 5" in str(e.value)
    assert "6 now)" in str(e.value)
    # a folder from before sweep.json: the run keys carry the base scenario's digest
    (tmp_path / SWEEP_JSON).unlink()
    with pytest.raises(SweepError, match=r"are of another scenario or --set values"):
        prepare_out(tmp_path, _tasks("6"), resume=True, overwrite=False)
    assert prepare_out(tmp_path, tasks, resume=True, overwrite=False)[1] == 1


def test_overwrite_starts_afresh(tmp_path):
    tasks = _tasks()
    write_sweep_identity(tmp_path, tasks)
    (tmp_path / RUNS_JSONL).write_text(_row(tasks[0]) + _row(tasks[1]))
    (tmp_path / ERRORS_JSONL).write_text("{}\n")
    todo, done = prepare_out(tmp_path, _tasks("6"), resume=False, overwrite=True)
    assert len(todo) == 4 and done == 0
    assert (tmp_path / RUNS_JSONL).read_text() == ""
    assert not (tmp_path / ERRORS_JSONL).exists() and not (tmp_path / SWEEP_JSON).exists()
