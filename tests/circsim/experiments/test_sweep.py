"""Sweeps: grid parsing and validation, process pool vs dask, resume, tidy rows (circsim.experiments.plan, sweep,
store, tables)."""

import json

import pytest

from circsim.cli import main
from circsim.config.scenario import bundled_scenarios, load_scenario
from circsim.experiments.offline import default_search_method
from circsim.experiments.plan import RUNS_JSONL, SweepError, parse_grid, plan
from circsim.experiments.store import prepare_out, read_rows
from circsim.experiments.sweep import execute
from circsim.experiments.tables import sweep_rows

# short runs with a small ROI: the machinery is under test here, not the merger
SETS = [f"merger.method={default_search_method()}", "merger.roi_m=3", "duration_s=3"]
TIMING = ("wall_s", "realtime_factor", "merge_cycle_ms.median", "merge_cycle_ms.p95")


def base():
    return load_scenario(bundled_scenarios()["scene1"]).with_overrides(SETS)


def stable(rows):
    return sorted(json.dumps({k: v for k, v in r.items() if k not in TIMING}, sort_keys=True) for r in rows)


def test_grid_aliases_values_and_plan():
    axes = parse_grid(["center_error=0,0.05", "network.latency=0,1"])
    assert [a.key for a in axes] == ["center_error.magnitude_m", "network.latency_s"]
    assert axes[0].values == (0.0, 0.05) and axes[1].values == (0.0, 1.0)  # 0 and 0.0 are one value
    tasks = plan(base(), axes, seeds=3)
    assert len(tasks) == 2 * 2 * 3 and len({t.key for t in tasks}) == 12
    assert sorted({t.seed for t in tasks}) == [1, 2, 3]  # base seed + i
    sc = tasks[-1].scenario()
    assert (sc.center_error.magnitude_m, sc.network.latency_s, sc.seed) == (0.05, 1.0, 3)


@pytest.mark.parametrize("grid, words", [
    ("center_error=0,abc", ["center_error.magnitude_m=abc", "expected a number"]),
    ("nosuch.key=1", ["nosuch", "unknown key"]),
    ("network.latency_s=-1", ["network.latency_s", ">= 0"]),
    ("center_error", ["KEY.PATH=V1,V2"]),
    ("center_error=0,0", ["repeated value"]),
    ("seed=1,2", ["--seeds"]),
])
def test_bad_grid_is_one_line_exit_2_and_runs_nothing(tmp_path, capsys, grid, words):
    rc = main(["sweep", "scene1", "--grid", grid, "--out", str(tmp_path / "o"), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and err.startswith("circsim: error:")
    assert all(w in err for w in words), err
    assert not (tmp_path / "o" / RUNS_JSONL).exists()


@pytest.mark.slow
def test_pool_and_dask_give_the_same_rows(tmp_path):
    distributed = pytest.importorskip("distributed")
    tasks = plan(base(), parse_grid(["center_error=0,0.2"]), seeds=2)
    pool_out, dask_out = tmp_path / "pool", tmp_path / "dask"
    for out in (pool_out, dask_out):
        prepare_out(out, tasks, resume=False, overwrite=False)
    assert execute(tasks, pool_out, workers=2, progress=False).written == 4
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        assert execute(tasks, dask_out, dask_address=cluster.scheduler_address, progress=False).written == 4
    a, b = sweep_rows(pool_out, tasks), sweep_rows(dask_out, tasks)
    assert len(a) == 4 and stable(a) == stable(b)
    row = a[0]
    for k in ("scenario", "seed", "center_error.magnitude_m", "network.latency_s", "first_merge_s.Lyon",
              "first_merge_arc_deg.Nevers", "first_merge_s.mean", "false_merges", "rejected_correct",
              "rejected_correct_rate", "merge_cycle_ms.median", "merge_cycle_ms.p95", "realtime_factor",
              "all_merged", "run_key", "final_translation_error_m.Lyon", "final_translation_error_m.max",
              "final_angle_error_deg.max", "first_merge_translation_error_m.Nevers",
              "top_translation_error_m.median", "param.merger.window_m", "param.merger.correct_tol_m"):
        assert k in row, k


@pytest.mark.slow
def test_cli_sweep_writes_tables_and_resume_skips_finished_rows(tmp_path, capsys):
    out = tmp_path / "sw"
    args = ["sweep", "scene1", "--grid", "center_error=0,0.1", "--seeds", "2", "--out", str(out), "--quiet",
            "--workers", "2", *[x for s in SETS for x in ("--set", s)]]
    assert main(args) == 0
    for f in ("runs.jsonl", "runs.csv", "summary.csv", "sweep.png"):
        assert (out / f).stat().st_size > 0, f
    rows = read_rows(out / RUNS_JSONL)
    assert len(rows) == 4
    # every run parameter is a column, --set overrides included, in the CSV too
    header = (out / "runs.csv").read_text().splitlines()[0].split(",")
    for r in rows:
        assert r["param.duration_s"] == 3.0 and r["param.merger.roi_m"] == 3.0  # from --set
        assert r["param.center_error.magnitude_m"] == r["center_error.magnitude_m"]
    assert {"param.duration_s", "param.merger.nu_min", "param.network.jitter_s", "param.drift.xy_m_per_m"} <= set(header)
    # an interrupted sweep: drop two finished rows and tear the last line, as a kill would
    lines = (out / RUNS_JSONL).read_text().splitlines()
    (out / RUNS_JSONL).write_text("\n".join(lines[:2]) + "\n" + lines[2][:40])
    capsys.readouterr()
    assert main(args) == 2  # refuses to mix with an existing sweep without --resume
    assert "--resume" in capsys.readouterr().err
    assert main([*args, "--resume"]) == 0
    err = capsys.readouterr().err
    assert "2 already done, 2 to run" in err
    again = read_rows(out / RUNS_JSONL)
    assert stable(again) == stable(rows)
    assert main([*args, "--resume"]) == 0  # nothing left to run
    assert "4 already done, 0 to run" in capsys.readouterr().err
    assert len(read_rows(out / RUNS_JSONL)) == 4


def test_same_task_same_row():
    t = plan(base(), parse_grid(["network.latency_s=0.5"]), seeds=1)[0]
    from circsim.experiments.sweep import run_one

    assert stable([run_one(t)]) == stable([run_one(t)])


def test_sweep_error_is_a_value_error():
    with pytest.raises(SweepError):
        plan(base(), [], seeds=0)


@pytest.mark.slow
def test_a_failing_run_is_recorded_and_the_sweep_goes_on(tmp_path):
    from circsim.experiments.plan import ERRORS_JSONL, RunTask

    good = plan(base(), [], seeds=1)[0]
    bad = RunTask({"name": "broken", "robots": {"speed_mps": -1}}, "broken.yaml", (), 0, "broken-key")
    prepare_out(tmp_path, [good, bad], resume=False, overwrite=False)
    done = execute([good, bad], tmp_path, workers=2, progress=False)
    assert (done.written, done.failed) == (1, 1)
    err = json.loads((tmp_path / ERRORS_JSONL).read_text())
    assert err["run_key"] == "broken-key" and "speed_mps" in err["error"]
    assert [r["run_key"] for r in read_rows(tmp_path / RUNS_JSONL)] == [good.key]


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:9", "notaurl"])
def test_cli_sweep_unreachable_dask_scheduler_is_a_one_line_error(tmp_path, capsys, monkeypatch, address):
    pytest.importorskip("distributed")
    import circsim.experiments.sweep as sweep

    monkeypatch.setattr(sweep, "DASK_CONNECT_TIMEOUT_S", 1)
    args = ["sweep", "scene1", "--grid", "center_error=0", "--seeds", "1", "--out", str(tmp_path / "sw"),
            "--quiet", "--dask", address, *[x for s in SETS for x in ("--set", s)]]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("circsim: error: --dask ") and address in err and "scheduler" in err
    assert list((tmp_path / "sw").iterdir()) == []  # a sweep that cannot start writes nothing


def test_a_changed_base_scenario_is_not_resumed_as_finished():
    """--resume must not take rows of a sweep run with other --set values (or another scenario file)."""
    base = load_scenario(bundled_scenarios()["scene1"])
    axes = parse_grid(["center_error=0,0.1"])
    keys = [t.key for t in plan(base, axes, 2)]
    assert keys == [t.key for t in plan(base, axes, 2)]  # deterministic
    changed = [t.key for t in plan(base.with_overrides(["merger.nu_min=0.9"]), axes, 2)]
    assert not set(keys) & set(changed)
    reseeded = plan(base.with_overrides(["seed=5"]), axes, 2)
    digest = {json.loads(k)["base"] for k in keys}
    assert len(digest) == 1 and {json.loads(t.key)["base"] for t in reseeded} == digest  # seeds are per run
    assert sorted({t.seed for t in reseeded}) == [5, 6]


# --- issue 12: resume of another sweep, the dask extra, workers outliving their parent, SIGTERM ---------
@pytest.mark.slow
def test_resume_with_other_set_values_is_refused_naming_the_difference(tmp_path, capsys):
    out = tmp_path / "sw"
    args = ["sweep", "scene1", "--seeds", "1", "--out", str(out), "--quiet", "--workers", "1", "--no-plots",
            *[x for s in SETS for x in ("--set", s)]]
    assert main(args) == 0
    rows_before = (out / RUNS_JSONL).read_text()
    csv_before = (out / "runs.csv").read_text()
    capsys.readouterr()
    assert main([*args, "--set", "merger.nu_min=0.7", "--resume"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--resume" in err and "merger.nu_min: 0.5 then, 0.7 now" in err, err
    assert (out / RUNS_JSONL).read_text() == rows_before and (out / "runs.csv").read_text() == csv_before
    # a folder from before sweep.json: the run keys' digests still tell
    (out / "sweep.json").unlink()
    assert main([*args, "--set", "merger.nu_min=0.7", "--resume"]) == 2
    assert "another scenario or --set values" in capsys.readouterr().err
    assert main([*args, "--resume"]) == 0  # the same sweep resumes
    assert "1 already done, 0 to run" in capsys.readouterr().err


def test_dask_without_the_sweep_extra_names_it(tmp_path, capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed → ImportError
    args = ["sweep", "scene1", "--seeds", "1", "--out", str(tmp_path / "sw"), "--quiet", "--dask", "tcp://x:1",
            *[x for s in SETS for x in ("--set", s)]]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pip install 'circsim[sweep]'" in err and "--dask" in err
    assert not (tmp_path / "sw").exists()


def _children(pid: int) -> set[int]:
    import os

    out = set()
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    if int(f.read().rsplit(")", 1)[1].split()[1]) == pid:
                        out.add(int(d))
            except (OSError, IndexError, ValueError):
                continue
    return out


def _alive(pid: int) -> bool:

    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not __import__("os").path.isdir("/proc"), reason="reads /proc")
@pytest.mark.parametrize("how", ["SIGKILL", "SIGTERM"])
def test_pool_workers_exit_when_the_sweep_parent_dies(tmp_path, how):
    """Killing the sweep's parent leaves no worker running orphaned runs (SIGKILL: the workers notice
    their parent is gone; SIGTERM: handled as Ctrl-C, the pool is stopped and the tables written)."""
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "sw"
    cmd = [sys.executable, "-m", "circsim.cli", "sweep", "scene1", "--seeds", "4", "--out", str(out), "--quiet",
           "--workers", "2", "--no-plots", "--set", f"merger.method={default_search_method()}",
           "--set", "duration_s=120"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        t0 = time.monotonic()
        workers: set[int] = set()
        while len(workers) < 2 and time.monotonic() - t0 < 120 and proc.poll() is None:
            time.sleep(0.2)  # the two pool workers (and multiprocessing's resource tracker)
            workers = {p for p in _children(proc.pid) if "spawn_main" in open(f"/proc/{p}/cmdline").read()}
        assert len(workers) == 2, proc.communicate()
        time.sleep(1.0)
        os.kill(proc.pid, getattr(signal, how))
        proc.communicate(timeout=60)
        t1 = time.monotonic()
        while any(_alive(p) for p in workers) and time.monotonic() - t1 < 15:
            time.sleep(0.1)
        assert not any(_alive(p) for p in workers), "pool workers outlived their parent"
        if how == "SIGTERM":
            assert proc.returncode == 143  # 128 + SIGTERM
    finally:
        if proc.poll() is None:
            proc.kill()
        for p in _children(proc.pid):
            try:
                os.kill(p, signal.SIGKILL)
            except OSError:
                pass


def test_sweep_plot_x_axis_is_the_swept_key(tmp_path):
    """Issue 12: sweep.png plots against center error when it is swept, else against the first --grid key
    (numbers at their value, names in order), ticks at the swept values."""
    from circsim.experiments.plots import choose_axes, plot_sweep, x_position

    assert choose_axes(["network.latency_s", "center_error.magnitude_m"]) == ("center_error.magnitude_m",
                                                                              ["network.latency_s"])
    assert choose_axes(["network.latency_s", "merger.window_m"]) == ("network.latency_s", ["merger.window_m"])
    assert choose_axes([]) == ("center_error.magnitude_m", [])
    xmap, ticks, labels = x_position([3.0, 0.0, 1.0, 0.0])
    assert ticks == [0.0, 1.0, 3.0] and labels == ["0", "1", "3"] and xmap["3.0"] == 3.0
    xmap, ticks, labels = x_position(["reference", "fast", "fast"])
    assert ticks == [0.0, 1.0] and labels == ["fast", "reference"]
    row = {"seed": 1, "center_error.magnitude_m": 0.0, "first_merge_s.mean": 3.0, "first_merge_arc_deg.mean": 9.0,
           "all_merged": True, "false_merges": 0, "rejected_correct_rate": 0.1, "top_error_deg.median": 0.2}
    rows = [{**row, "merger.method": m, "network.latency_s": lat, "seed": s}
            for m in ("fast", "reference") for lat in (0.0, 1.0) for s in (1, 2)]
    for x_key, lines in (("merger.method", ["network.latency_s"]), ("network.latency_s", ["merger.method"])):
        p = plot_sweep(rows, lines, tmp_path / f"{x_key}.png", title="t", x_key=x_key)
        assert p.read_bytes()[:4] == b"\x89PNG"


def _die_in(task):
    """A run for test_a_killed_worker_...: the tasks named in ``task.die`` kill their own worker process
    (as the OOM killer would) on every attempt, or on the first only (``task.once``, a marker file)."""
    import os
    import signal
    import time
    from pathlib import Path

    time.sleep(0.05 * task.n)
    if task.key in task.die:
        marker = Path(task.marker_dir) / task.key
        if not (task.once and marker.exists()):
            marker.touch()
            os.kill(os.getpid(), signal.SIGKILL)
    return {"key": task.key}


@pytest.mark.slow
@pytest.mark.parametrize("once", [True, False])
def test_a_killed_worker_fails_only_its_own_run(tmp_path, once):
    """One SIGKILLed worker broke the whole process pool: every run still queued in it failed (issue 37).
    Now the runs it took down go to a new pool; a run that kills its worker every time is failed alone."""
    from types import SimpleNamespace

    from circsim.experiments.sweep import _local

    tasks = [SimpleNamespace(key=f"r{n}", n=n, die={"r2"}, once=once, marker_dir=str(tmp_path)) for n in range(8)]
    outcomes = {t.key: (row, err) for t, row, err in _local(tasks, 2, fn=_die_in)}
    assert sorted(outcomes) == [t.key for t in tasks]
    for key, (row, err) in outcomes.items():
        if key == "r2" and not once:
            assert row is None and "worker process died" in err
        else:
            assert row == {"key": key} and err is None, (key, err)
