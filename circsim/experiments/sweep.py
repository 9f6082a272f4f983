"""Parameter sweeps: every combination of grid values × every seed is one run; one tidy row per run.

The sweep is four modules: :mod:`.plan` (the grid and the tasks), this one (running them: :func:`run_one`,
:func:`execute`, the row of a run), :mod:`.store` (the folder: rows, lock, identity) and :mod:`.tables`.

A sweep is planned first (:func:`plan`): the grid (``--grid key=v1,v2,...``, values parsed as YAML) is
expanded, every combination's scenario is built and validated before anything runs, so a bad key or
value is one line naming it. Runs are independent and deterministic per seed (seed = base seed + i);
each is a plain picklable :class:`RunTask` executed by :func:`run_one` — in a local process pool
(:func:`execute`, default all cores) or on an existing dask.distributed cluster. Rows are appended to
``runs.jsonl`` as each run finishes, so an interrupted sweep keeps every finished row, and a resumed
sweep skips the runs whose key (scenario, grid values, seed) is already there. At the end the rows are
written as ``runs.csv`` (and ``runs.parquet`` with pyarrow), ``summary.csv`` and plots.

Row columns (DESIGN.md metric names, flattened): ``scenario``, ``seed``, every grid key, the
scenario's ``center_error.magnitude_m`` and ``network.latency_s``, every run parameter as
``param.<key>`` (:func:`circsim.sim.run_params`, e.g. ``param.merger.nu_min``: a ``--set`` shows here),
``first_merge_s.<robot>``,
``first_merge_arc_deg.<robot>``, ``first_merge_s.mean`` / ``first_merge_arc_deg.mean`` (over the
robots that merged; ``robots_merged`` says how many), ``first_merge_s.max``, ``all_merged``,
``false_merges``, ``rejected_correct``, ``cycles``, ``rejected_correct_rate`` (= rejected_correct /
cycles; null when no cycle's best hypothesis was correct), ``merge_cycle_ms.median``,
``merge_cycle_ms.p95``, ``realtime_factor``, ``sim_s``,
``wall_s``, ``duration_s``, ``near_180_proposed``, ``near_180_accepted``, ``top_error_deg.median``,
``top_translation_error_m.median`` (see :class:`HypothesisStats`), ``final_angle_error_deg.<robot>`` /
``final_translation_error_m.<robot>`` (the largest error over that robot's teammates, of the alignment it
held at the end; empty if it never accepted one), ``final_angle_error_deg.max`` /
``final_translation_error_m.max`` (the largest over the robots), ``first_merge_translation_error_m.<robot>``
(the largest translation error of its first correct merge), ``consensus_s`` / ``consensus_final`` (the
first time every robot held the same global alignment, whether they still did at the end, and for how
many seconds in all they did; see
:mod:`circsim.metrics`), ``hypotheses_adopted`` (shared hypotheses adopted, all robots), ``run_key``.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import merger.caches

from ..config.scenario import Scenario
from ..events import Observer
from ..record import jsonout
from .plan import ERRORS_JSONL, RUNS_JSONL, RunTask, SweepError
from .store import write_sweep_identity


# --- one run ---------------------------------------------------------------------------------------
def run_one(task: RunTask) -> dict:
    """Run one task and return its flat row (called in a worker process or a dask worker)."""
    from ..sim import run_scenario

    sc = task.scenario()
    merger.caches.clear_all()  # a worker runs many tasks: its memory at its floor between runs (no answer changes)
    hyp = HypothesisStats()
    row = flatten(run_scenario(sc, [hyp]).to_dict(), task, sc)
    row.update(hyp.columns())
    return row


class HypothesisStats(Observer):
    """What the merge cycles proposed, beyond the DESIGN metrics.

    ``near_180_proposed`` / ``near_180_accepted`` / ``near_180_chosen``: order hypotheses with a ~180° error
    (|err − 180°| ≤ 10° for some map), how many of them passed whole-map verification, and how many were
    the cycle's accepted choice (each of those is also a false merge). ``top_error_deg.median``: median over the cycles
    of the largest angle error of the cycle's best hypothesis (how far from ground truth the merger's
    answer is, accepted or not); ``top_translation_error_m.median``: the same for its translation error
    |t − t*| in metres.
    """

    def __init__(self, tol_deg: float = 10.0) -> None:
        self.tol_deg, self.proposed, self.accepted, self.chosen = tol_deg, 0, 0, 0
        self.top_errors: list[float] = []
        self.top_t_errors: list[float] = []

    def on_merge_cycle(self, c) -> None:
        from merger.search import angle_diff_deg

        for o in c.result.orders:
            if any(abs(abs(angle_diff_deg(o.theta_deg[k], c.truth_deg[k])) - 180.0) <= self.tol_deg
                   for k in o.theta_deg):
                self.proposed += 1
                self.accepted += o.accepted
                self.chosen += o is c.result.chosen
        self.top_errors.append(max(c.angle_error_deg.values(), default=0.0))
        self.top_t_errors.append(max(c.translation_error_m.values(), default=0.0))

    def columns(self) -> dict:
        return {"near_180_proposed": self.proposed, "near_180_accepted": self.accepted,
                "near_180_chosen": self.chosen,
                "top_error_deg.median": statistics.median(self.top_errors) if self.top_errors else None,
                "top_translation_error_m.median":
                    statistics.median(self.top_t_errors) if self.top_t_errors else None}


def _flat_params(d: dict, prefix: str) -> dict:
    """Nested run parameters as ``prefix.key.sub`` columns; lists as JSON text."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat_params(v, f"{prefix}{k}.") if v else {f"{prefix}{k}": "{}"})
        else:
            out[f"{prefix}{k}"] = json.dumps(v) if isinstance(v, list | tuple) else v
    return out


def flatten(rec: dict, task: RunTask, sc: Scenario) -> dict:
    """The tidy row of one run record (:meth:`circsim.metrics.RunResult.to_dict`)."""
    row = {"scenario": rec["scenario"], "seed": rec["seed"]}
    row.update({k: v for k, v in task.grid})
    row["center_error.magnitude_m"] = sc.center_error.magnitude_m
    row["network.latency_s"] = sc.network.latency_s
    row.update(_flat_params(rec["params"], "param."))
    robots = rec["robots"]
    for name, r in robots.items():
        row[f"first_merge_s.{name}"] = r["first_merge_s"]
        row[f"first_merge_arc_deg.{name}"] = r["first_merge_arc_deg"]
        row[f"first_pair_merge_s.{name}"] = r.get("first_pair_merge_s")
        row[f"teammates_placed_final.{name}"] = r.get("teammates_placed_final")
    merged = [r for r in robots.values() if r["first_merge_s"] is not None]
    row["robots_merged"] = len(merged)
    row["first_merge_s.mean"] = statistics.fmean(r["first_merge_s"] for r in merged) if merged else None
    row["first_merge_arc_deg.mean"] = (statistics.fmean(r["first_merge_arc_deg"] for r in merged)
                                       if merged else None)
    row["first_merge_s.max"] = max(r["first_merge_s"] for r in merged) if len(merged) == len(robots) else None
    row["all_merged"] = rec["all_merged"]
    for key in ("final_angle_error_deg", "final_translation_error_m"):
        worst = {name: _worst_teammate(r.get(key), name) for name, r in robots.items()}
        row.update({f"{key}.{name}": v for name, v in worst.items()})
        known = [v for v in worst.values() if v is not None]
        row[f"{key}.max"] = max(known) if known else None
    for name, r in robots.items():
        row[f"first_merge_translation_error_m.{name}"] = r.get("first_merge_translation_error_m")
    cycles = sum(r["cycles"] for r in robots.values())
    # a rate of refusing correct hypotheses needs one: no cycle's best hypothesis correct (none accepted
    # correctly, none refused) is no data, not a rate of 0
    correct = rec["rejected_correct"] + sum(r["accepted"] for r in robots.values()) - rec["false_merges"]
    row.update(gross_merges=rec.get("gross_merges"), drift_limited_merges=rec.get("drift_limited_merges"))
    if sc.world.generate is not None:  # a generated building: where its generator put the common center
        row["world.center.x"], row["world.center.y"] = sc.world.center
    row.update(false_merges=rec["false_merges"], rejected_correct=rec["rejected_correct"], cycles=cycles,
               rejected_correct_rate=rec["rejected_correct"] / cycles if cycles and correct > 0 else None)
    row["consensus_s"] = rec.get("consensus_s")
    row["consensus_final"] = rec.get("consensus_final")
    row["consensus_held_s"] = rec.get("consensus_held_s")
    row["hypotheses_adopted"] = sum(r.get("hypotheses_adopted", 0) for r in robots.values())
    row["merge_cycle_ms.median"] = rec["merge_cycle_ms"]["median"]
    row["merge_cycle_ms.p95"] = rec["merge_cycle_ms"]["p95"]
    row.update(realtime_factor=rec["realtime_factor"], sim_s=rec["sim_s"], wall_s=rec["wall_s"],
               duration_s=sc.duration_s, interrupted=rec["interrupted"], run_key=task.key)
    return row


def _worst_teammate(errors: dict | None, robot: str) -> float | None:
    """The largest of a robot's per-map errors over its teammates (None: it never accepted a merge)."""
    if not errors:
        return None
    return max((v for k, v in errors.items() if k != robot), default=0.0)



# --- execution -------------------------------------------------------------------------------------
PARENT_POLL_S = 0.5


def _exit_with_parent(parent_pid: int, poll_s: float = PARENT_POLL_S) -> None:
    """In a worker: a daemon thread that ends the process once its parent is gone (killed with SIGKILL,
    or a SIGTERM that did not reach the pool), instead of running orphaned runs to the end. The parent
    is gone when this process is re-parented (``os.getppid()`` changes)."""
    import threading
    import time

    def watch():
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


_STARTED = None  # in a worker: the queue on which it says which run it starts (see _local)


def _init_worker(parent_pid: int | None = None, started=None) -> None:
    import signal

    global _STARTED
    _STARTED = started
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle (it stops the pool)
    if parent_pid is not None:
        _exit_with_parent(parent_pid)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    try:
        import cv2

        cv2.setNumThreads(1)  # one run per core: no nested thread pools
    except Exception:  # pragma: no cover - OpenCV is a dependency, but threads are an optimisation
        pass


def _outcome(task: RunTask, fut):
    """(task, row, None) for a finished run, (task, None, traceback text) for a failed one."""
    import traceback

    try:
        return task, fut.result(), None
    except Exception as e:  # a run that raised: record it, keep the sweep going
        return task, None, "".join(traceback.format_exception(e)).strip()


WORKER_DEATHS_PER_RUN = 2  # a run this often in a worker that died is then run alone (which tells if it is the cause)


def _run_reporting(fn, task):
    """In a worker: say that ``task`` starts, then run it."""
    if _STARTED is not None:
        _STARTED.put(task.key)
    return fn(task)


def _local(tasks: list[RunTask], workers: int, fn=run_one):
    """Outcomes of ``fn`` over ``tasks`` on a pool of processes. A worker killed outright (SIGKILL, the OOM
    killer) breaks the whole pool: every run not yet finished fails with BrokenProcessPool, without saying
    which one was in the dead worker. Workers say which run they start, so the runs that had not started go
    to a new pool as they were; those that were running (one of them in the dead worker) too, and one that
    was running in :data:`WORKER_DEATHS_PER_RUN` dying pools is then run alone: only a run whose own pool
    (of one) breaks is recorded as failed. The other runs of the sweep finish."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    ctx = multiprocessing.get_context("spawn")  # no fork of a parent holding threads (tqdm, OpenCV)
    deaths: dict[str, int] = {}
    todo, alone = list(tasks), []
    while todo or alone:
        batch, todo = (todo, []) if todo else ([alone.pop(0)], [])
        started = ctx.SimpleQueue()
        pool = ProcessPoolExecutor(max_workers=min(workers, len(batch)), mp_context=ctx,
                                   initializer=_init_worker, initargs=(os.getpid(), started))
        futures = {pool.submit(_run_reporting, fn, t): t for t in batch}
        running: set[str] = set()
        done: set[str] = set()
        try:
            for f in as_completed(futures):
                task = futures[f]
                if not isinstance(f.exception(), BrokenProcessPool):
                    done.add(task.key)
                    yield _outcome(task, f)
                    continue
                while not started.empty():
                    running.add(started.get())
                if len(batch) == 1:  # alone in its pool: its own worker died
                    yield task, None, "its worker process died while it ran (killed: out of memory?)"
                    continue
                if task.key in running or not running - done:  # (a worker that died starting: all suspect)
                    deaths[task.key] = deaths.get(task.key, 0) + 1
                (todo if deaths.get(task.key, 0) < WORKER_DEATHS_PER_RUN else alone).append(task)
        except BaseException:  # Ctrl-C: stop now, the finished rows are already written
            procs = list((getattr(pool, "_processes", None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for p in procs:
                p.terminate()
            raise
        pool.shutdown()


DASK_CONNECT_TIMEOUT_S = 15


def check_dask() -> None:
    """``--dask`` needs dask.distributed (the ``sweep`` extra): a one-line error naming it otherwise."""
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise SweepError("--dask: dask.distributed is not installed; install the sweep extra: "
                         "pip install 'circsim[sweep]'") from None


def _dask(tasks: list[RunTask], address: str):
    check_dask()
    from distributed import Client, as_completed

    try:
        client = Client(address, timeout=DASK_CONNECT_TIMEOUT_S)
    except (OSError, ValueError) as e:  # unreachable, refused, timed out, malformed address
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise SweepError(f"--dask {address}: cannot reach a dask scheduler there ({msg})") from None
    with client:
        futures = {client.submit(run_one, t, pure=False): t for t in tasks}
        try:
            for f in as_completed(list(futures)):
                yield _outcome(futures[f], f)
        except BaseException:
            client.cancel(list(futures))
            raise


@dataclass(frozen=True)
class Executed:
    written: int  # rows appended to runs.jsonl
    failed: int  # runs that raised (details in errors.jsonl; --resume retries them)


def execute(tasks: list[RunTask], out: Path, *, workers: int | None = None, dask_address: str | None = None,
            progress: bool = True, on_row: Callable[[dict], None] | None = None) -> Executed:
    """Run ``tasks``, appending each finished row to ``out/runs.jsonl`` as it arrives.

    A run that raises is appended to ``out/errors.jsonl`` (key and traceback) and the sweep goes on;
    an interrupted run (Ctrl-C reached it) is not written. ``--resume`` runs both again.
    """
    from ..progress import progress_bar

    if not tasks:
        return Executed(0, 0)
    workers = workers or os.cpu_count() or 1
    _end_line(out / RUNS_JSONL)
    outcomes = _dask(tasks, dask_address) if dask_address else _local(tasks, min(workers, len(tasks)))
    written = failed = 0
    f = None  # runs.jsonl is opened with the first row: a sweep that cannot start writes nothing
    try:
        with progress_bar(len(tasks), "run", "sweep", quiet=not progress, smoothing=0.1) as bar:
            for task, row, error in outcomes:
                if error is not None:
                    failed += 1
                    with open(out / ERRORS_JSONL, "a") as e:
                        e.write(json.dumps({"run_key": task.key, "grid": dict(task.grid), "seed": task.seed,
                                            "error": error}) + "\n")
                    bar.write(f"circsim: run {dict(task.grid)} seed {task.seed} failed: "
                              f"{error.splitlines()[-1]}", file=sys.stderr)
                elif not row.get("interrupted"):
                    try:
                        if f is None:
                            write_sweep_identity(out, tasks)
                            f = open(out / RUNS_JSONL, "a")  # noqa: SIM115 - closed below, after the last row
                        f.write(jsonout.dumps(row) + "\n")  # floats to 12 significant digits
                        f.flush()
                    except OSError as e:  # a full disk: the rows already written stay; --resume continues
                        raise SweepError(f"{out / RUNS_JSONL}: cannot write a run's row ({e.strerror or e}); "
                                         f"{written} rows of this sweep were written before") from None
                    written += 1
                    if on_row:
                        on_row(row)
                bar.update(1)
    finally:
        if f is not None:
            f.close()
    return Executed(written, failed)


def _end_line(path: Path) -> None:
    """Terminate a torn last line (a sweep killed while writing) so that new rows start on their own."""
    if path.exists() and path.stat().st_size:
        with open(path, "rb+") as f:
            f.seek(-1, os.SEEK_END)
            if f.read(1) != b"\n":
                f.write(b"\n")
