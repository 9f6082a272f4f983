"""Parameter sweeps: every combination of grid values × every seed is one run; one tidy row per run.

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
cycles), ``merge_cycle_ms.median``, ``merge_cycle_ms.p95``, ``realtime_factor``, ``sim_s``,
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

import csv
import hashlib
import itertools
import json
import math
import os
import statistics
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import merger.caches
from merger.limits import load_yaml

from ..config.scenario import ALIASES, Scenario, ScenarioError, scenario_from_dict
from ..events import Observer
from ..record import jsonout

RUNS_JSONL, RUNS_CSV, RUNS_PARQUET, SUMMARY_CSV = "runs.jsonl", "runs.csv", "runs.parquet", "summary.csv"
ERRORS_JSONL = "errors.jsonl"


class SweepError(ValueError):
    """A user error in a sweep's grid or output directory (one line)."""


@dataclass(frozen=True)
class Axis:
    key: str  # canonical scenario key path
    values: tuple
    texts: tuple = ()  # the values as the user wrote them (for messages)


@dataclass(frozen=True)
class RunTask:
    """Everything a worker needs to run one (combination, seed): plain data, picklable."""

    raw: dict  # the base scenario as data (with --set applied)
    source: str
    grid: tuple[tuple[str, object], ...]  # (key, value) per axis
    seed: int
    key: str

    def assignments(self) -> list[str]:
        return [f"{k}={json.dumps(v)}" for k, v in self.grid] + [f"seed={self.seed}"]

    def scenario(self) -> Scenario:
        return scenario_from_dict(self.raw, source=self.source).with_overrides(self.assignments())


def _norm(v):
    """Numbers as floats so that 0 and 0.0 are the same grid value (and the same run key)."""
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else v


def parse_grid(specs: Iterable[str]) -> list[Axis]:
    """``["center_error=0,0.1", "network.latency_s=0,1"]`` → axes (key aliases resolved)."""
    import yaml

    axes: list[Axis] = []
    for spec in specs:
        key, sep, text = spec.partition("=")
        key = key.strip()
        if not sep or not key or not text.strip():
            raise SweepError(f"--grid {spec!r}: expected KEY.PATH=V1,V2,... (e.g. center_error=0,0.1,0.2)")
        key = ALIASES.get(key, key)
        if key == "seed":
            raise SweepError(f"--grid {spec!r}: seeds are not a grid axis; use --seed BASE and --seeds N")
        values, texts = [], []
        for item in text.split(","):
            texts.append(item.strip())
            try:
                v = load_yaml(item)  # as --set parses values (YAML 1.2 numbers: 1e-1 is a number)
            except (yaml.YAMLError, ValueError, TypeError, RecursionError):
                raise SweepError(f"--grid {key}: value {item!r} is not valid YAML") from None
            if v is None:
                raise SweepError(f"--grid {key}: empty value in {text!r}; expected V1,V2,...")
            values.append(_norm(v))
        if len(set(map(json.dumps, values))) != len(values):
            raise SweepError(f"--grid {key}: repeated value in {text!r}")
        if any(a.key == key for a in axes):
            raise SweepError(f"--grid {key}: given twice; put all its values in one --grid")
        axes.append(Axis(key, tuple(values), tuple(texts)))
    return axes


def _check(base: Scenario, combo, label: str) -> None:
    try:
        base.with_overrides([f"{k}={json.dumps(v)}" for k, v in combo])
    except ScenarioError as e:
        msg = str(e).split("): ", 1)[-1]  # "<file> (--set k=v): path: expectation" → "path: expectation"
        raise SweepError(f"{base.source}: {label}: {msg}") from None


def base_digest(raw: dict) -> str:
    """A short digest of the base scenario (after ``--set``), its seed left out (runs carry their own)."""
    data = {k: v for k, v in raw.items() if k != "seed"}
    return hashlib.sha1(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:12]


def run_key(scenario: str, grid, seed: int, base: str = "") -> str:
    """What identifies a run for ``--resume``: scenario name, base scenario digest (so a changed ``--set``
    or scenario file is not mistaken for a finished run), grid values and seed."""
    return json.dumps({"scenario": scenario, "base": base, "grid": {k: _norm(v) for k, v in grid},
                       "seed": int(seed)}, sort_keys=True)


def plan(base: Scenario, axes: list[Axis], seeds: int) -> list[RunTask]:
    """Every (combination, seed) as a task; builds every combination's scenario first (validation)."""
    if seeds < 1:
        raise SweepError(f"--seeds: expected an integer >= 1, got {seeds}")
    for a in axes:  # one key at a time first: the message names the culprit key and value
        for v, text in zip(a.values, a.texts, strict=True):
            _check(base, [(a.key, v)], f"--grid {a.key}={text}")
    combos = list(itertools.product(*[[(a.key, v) for v in a.values] for a in axes]))
    for combo in combos:  # then every combination (keys that constrain each other)
        _check(base, combo, "--grid " + " ".join(f"{k}={json.dumps(v)}" for k, v in combo))
    base_seed, digest = int(base.seed), base_digest(base.raw)
    return [RunTask(base.raw, base.source, combo, base_seed + i,
                    run_key(base.name, combo, base_seed + i, digest))
            for combo in combos for i in range(seeds)]


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
    row.update(false_merges=rec["false_merges"], rejected_correct=rec["rejected_correct"], cycles=cycles,
               rejected_correct_rate=rec["rejected_correct"] / cycles if cycles else None)
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


# --- the row store ---------------------------------------------------------------------------------
def read_rows(path: Path) -> list[dict]:
    """Rows of a runs.jsonl; a torn line (a sweep killed while writing it) is ignored. A line that is JSON
    but not a run's row (an object with its ``run_key``) is refused: SweepError naming the file and line."""
    rows = []
    if path.exists():
        for i, raw in enumerate(path.read_bytes().splitlines(), 1):
            try:
                row = json.loads(raw)
            except (json.JSONDecodeError, UnicodeDecodeError):
                continue
            if not (isinstance(row, dict) and isinstance(row.get("run_key"), str)):
                text = raw.decode("utf-8", "replace")
                raise SweepError(f"{path}: line {i}: expected a run's row (a JSON object with its run_key), got "
                                 f"{text[:60]!r}{'...' if len(text) > 60 else ''}; remove the line, or start "
                                 "again with --overwrite")
            rows.append(row)
    return rows


class FolderLock:
    """An exclusive ``flock`` on the folder itself (no lock file is left behind), held until :meth:`close`
    or the process ends. A context manager."""

    def __init__(self, fd: int) -> None:
        self.fd = fd

    def close(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing the descriptor releases the lock
            self.fd = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def check_sweep_outputs(out: Path) -> None:
    """The files a sweep writes in ``out`` must be regular files or absent (not a FIFO, whose read would
    block, a device or a link): MapFileError naming the file."""
    from merger.io.mapio import check_outputs

    check_outputs({out / n: "--out" for n in (RUNS_JSONL, RUNS_CSV, RUNS_PARQUET, SUMMARY_CSV, SWEEP_JSON,
                                               ERRORS_JSONL, "sweep.png")})


def lock_out(out: Path) -> FolderLock:
    """Lock the sweep folder ``out`` against a second sweep writing into it (its rows would interleave
    with this one's: two sweeps gave 12 rows for 6 runs). SweepError if another sweep holds it."""
    import fcntl

    fd = os.open(out, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_CLOEXEC", 0))
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise SweepError(f"--out {out}: another sweep is writing there; wait for it to finish, or use another "
                         "--out") from None
    return FolderLock(fd)


SWEEP_JSON = "sweep.json"


def _leaves(d, prefix: str = "") -> dict:
    """Nested data as ``{"a.b": value}`` (lists as JSON text) for naming differences."""
    if not isinstance(d, dict):
        return {prefix: json.dumps(d, sort_keys=True, default=str)}
    out = {}
    for k, v in d.items():
        out.update(_leaves(v, f"{prefix}.{k}" if prefix else str(k)))
    return out


def _differences(was: dict, now: dict, most: int = 3) -> str:
    a, b = _leaves(was), _leaves(now)
    keys = [k for k in dict.fromkeys([*a, *b]) if a.get(k) != b.get(k)]
    parts = [f"{k}: {a.get(k, '(unset)')} then, {b.get(k, '(unset)')} now" for k in keys[:most]]
    return "; ".join(parts) + (f"; and {len(keys) - most} more" if len(keys) > most else "")


def _sweep_identity(tasks: list[RunTask]) -> dict:
    """What makes rows of one experiment: the base scenario after ``--set`` (seed left out)."""
    raw = tasks[0].raw
    return {"scenario": tasks[0].source, "base": {k: v for k, v in raw.items() if k != "seed"},
            "digest": base_digest(raw)}


def prepare_out(out: Path, tasks: list[RunTask], *, resume: bool, overwrite: bool) -> tuple[list[RunTask], int]:
    """The tasks still to run, and how many were already done (``--resume``).

    The folder's ``sweep.json`` records the base scenario (with ``--set`` applied) of the sweep its rows
    belong to; resuming with another (a different ``--set`` or scenario file) would mix two experiments in
    runs.jsonl, so it is refused with the differences named."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / RUNS_JSONL
    rows = read_rows(path)
    done = {r.get("run_key") for r in rows}
    if done and not resume and not overwrite:
        raise SweepError(f"{path} already holds {len(done)} runs; pass --resume to continue that sweep "
                         "or --overwrite to start again")
    ident = _sweep_identity(tasks)
    if resume and done:
        _check_same_sweep(out, rows, ident)
    if overwrite and not resume:
        path.write_text("")
        (out / ERRORS_JSONL).unlink(missing_ok=True)  # the old sweep's failures are not this one's
        (out / SWEEP_JSON).unlink(missing_ok=True)
        done = set()
    todo = [t for t in tasks if t.key not in done]
    return todo, len(tasks) - len(todo)


def write_sweep_identity(out: Path, tasks: list[RunTask]) -> None:
    """``sweep.json``: the base scenario the rows of ``out`` belong to (written with the first row)."""
    from merger.io.mapio import write_files

    ident = _sweep_identity(tasks)
    write_files({out / SWEEP_JSON: json.dumps(ident, indent=1, sort_keys=True, default=str).encode()})


def _check_same_sweep(out: Path, rows: list[dict], ident: dict) -> None:
    """``--resume`` continues the sweep in ``out`` only: refuse other base scenarios, naming what differs."""
    try:
        was = json.loads((out / SWEEP_JSON).read_text())
    except (OSError, ValueError):
        was = None
    if isinstance(was, dict) and "digest" in was:
        if was["digest"] != ident["digest"]:
            raise SweepError(f"--resume: {out} holds a sweep of another scenario or --set values "
                             f"({_differences(was.get('base', {}), ident['base'])}); resume it with the same "
                             "scenario and --set, or use another --out (or --overwrite)")
        return
    digests = set()  # a folder from before sweep.json: the run keys carry the base digest
    for r in rows:
        try:
            digests.add(json.loads(r["run_key"]).get("base"))
        except (KeyError, TypeError, ValueError, AttributeError):
            continue
    if digests and ident["digest"] not in digests:
        raise SweepError(f"--resume: the runs in {out / RUNS_JSONL} are of another scenario or --set values; "
                         "resume with the same scenario and --set, or use another --out (or --overwrite)")


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


def _init_worker(parent_pid: int | None = None) -> None:
    import signal

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


def _local(tasks: list[RunTask], workers: int):
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed

    ctx = multiprocessing.get_context("spawn")  # no fork of a parent holding threads (tqdm, OpenCV)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker,
                               initargs=(os.getpid(),))
    futures = {pool.submit(run_one, t): t for t in tasks}
    try:
        for f in as_completed(futures):
            yield _outcome(futures[f], f)
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
    from tqdm import tqdm

    if not tasks:
        return Executed(0, 0)
    workers = workers or os.cpu_count() or 1
    _end_line(out / RUNS_JSONL)
    outcomes = _dask(tasks, dask_address) if dask_address else _local(tasks, min(workers, len(tasks)))
    written = failed = 0
    f = None  # runs.jsonl is opened with the first row: a sweep that cannot start writes nothing
    try:
        with tqdm(total=len(tasks), unit="run", desc="sweep", disable=not progress, smoothing=0.1) as bar:
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


# --- tables ----------------------------------------------------------------------------------------
def sweep_rows(out: Path, tasks: list[RunTask]) -> list[dict]:
    """The rows of this sweep's tasks from the JSONL, in plan order (grid order, then seed)."""
    by_key = {r["run_key"]: r for r in read_rows(out / RUNS_JSONL) if "run_key" in r}
    return [by_key[t.key] for t in tasks if t.key in by_key]


def _quantiles(xs: list[float]) -> tuple[float, float, float] | tuple[None, None, None]:
    xs = sorted(x for x in xs if x is not None)
    if not xs:
        return None, None, None
    if len(xs) == 1:
        return xs[0], xs[0], xs[0]
    q = statistics.quantiles(xs, n=4, method="inclusive")
    return q[0], statistics.median(xs), q[2]


def summarize(rows: list[dict], axes: list[Axis]) -> list[dict]:
    """One line per grid combination: medians and IQRs over seeds."""
    keys = [a.key for a in axes]
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault(tuple(json.dumps(r.get(k)) for k in keys), []).append(r)
    out = []
    for g, rs in groups.items():
        s = {k: json.loads(v) for k, v in zip(keys, g, strict=True)}
        s["runs"] = len(rs)
        s["all_merged_frac"] = sum(bool(r["all_merged"]) for r in rs) / len(rs)
        for m in ("first_merge_s.mean", "first_merge_arc_deg.mean", "rejected_correct_rate",
                  "merge_cycle_ms.median", "realtime_factor", "top_error_deg.median",
                  "top_translation_error_m.median", "final_translation_error_m.max", "consensus_s",
                  "consensus_held_s"):
            q1, med, q3 = _quantiles([r.get(m) for r in rs])
            s[f"{m}.median"], s[f"{m}.q1"], s[f"{m}.q3"] = med, q1, q3
        s["false_merges.total"] = sum(r["false_merges"] for r in rs)
        s["runs_with_false_merge"] = sum(r["false_merges"] > 0 for r in rs)
        s["near_180_proposed.total"] = sum(r.get("near_180_proposed") or 0 for r in rs)
        s["near_180_accepted.total"] = sum(r.get("near_180_accepted") or 0 for r in rs)
        s["near_180_chosen.total"] = sum(r.get("near_180_chosen") or 0 for r in rs)
        s["consensus_frac"] = sum(r.get("consensus_s") is not None for r in rs) / len(rs)
        out.append(s)
    return out


def _columns(rows: list[dict]) -> list[str]:
    cols: dict[str, None] = {}
    for r in rows:
        cols.update(dict.fromkeys(r))
    return list(cols)


def write_csv(rows: list[dict], path: Path) -> None:
    """Rows as CSV: columns are the union of their keys in first-seen order; None is empty, lists and
    dicts are JSON; no rows, an empty file. Written atomically (temporary file, then rename)."""
    import io

    from merger.io.mapio import write_files

    f = io.StringIO(newline="")
    if rows:
        w = csv.DictWriter(f, fieldnames=_columns(rows), restval="")
        w.writeheader()
        for r in jsonout.rounded(rows):
            w.writerow({k: ("" if v is None else json.dumps(v) if isinstance(v, list | dict) else v)
                        for k, v in r.items()})
    write_files({path: f.getvalue().encode()})  # atomic: a reader never sees half a table


def write_tables(rows: list[dict], summary: list[dict], out: Path) -> list[Path]:
    """runs.csv and summary.csv (one row per run / per combination); runs.parquet when pyarrow is
    installed (the ``sweep`` extra). Columns are the union of all rows' keys, in first-seen order."""
    paths = [out / RUNS_CSV, out / SUMMARY_CSV]
    write_csv(rows, paths[0])
    write_csv(summary, paths[1])
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return paths
    cols = _columns(rows)
    table = pa.Table.from_pylist([{c: r.get(c) for c in cols} for r in rows])
    tmp = out / f".{RUNS_PARQUET}.part"
    pq.write_table(table, tmp)
    os.replace(tmp, out / RUNS_PARQUET)
    paths.append(out / RUNS_PARQUET)
    return paths


def _cm(v):
    return None if v is None else 100.0 * v


def format_summary(summary: list[dict], axes: list[Axis]) -> str:
    """The summary as a text table: one row per grid combination, every column under its header
    (right-aligned, as wide as its widest cell). Medians over seeds with [q1–q3]; "—" where no run
    had a value (e.g. no robot merged)."""
    def f(v, fmt="{:.1f}"):
        return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else fmt.format(v)

    def iqr(s, m, fmt="{:.1f}"):
        return f"{f(s[m + '.median'], fmt)} [{f(s[m + '.q1'], fmt)}–{f(s[m + '.q3'], fmt)}]"

    columns = [(a.key, lambda s, k=a.key: json.dumps(s[k])) for a in axes] + [
        ("runs", lambda s: str(s["runs"])),
        ("all merged", lambda s: f"{s['all_merged_frac']:.0%}"),
        ("first merge s", lambda s: iqr(s, "first_merge_s.mean")),
        ("arc deg", lambda s: iqr(s, "first_merge_arc_deg.mean")),
        ("false merges", lambda s: str(s["false_merges.total"])),
        ("rej.-correct rate", lambda s: iqr(s, "rejected_correct_rate", "{:.2f}")),
        ("top err deg", lambda s: f(s["top_error_deg.median.median"])),
        ("top err cm", lambda s: f(_cm(s.get("top_translation_error_m.median.median")))),
        ("180° prop/acc", lambda s: f"{s['near_180_proposed.total']}/{s['near_180_accepted.total']}"),
        ("cycle ms", lambda s: f(s["merge_cycle_ms.median.median"], "{:.0f}")),
        ("consensus s", lambda s: iqr(s, "consensus_s")),
        ("consensus runs", lambda s: f"{s['consensus_frac']:.0%}"),
    ]
    cells = [[fmt(s) for _, fmt in columns] for s in summary]
    widths = [max([len(head)] + [len(row[i]) for row in cells]) for i, (head, _) in enumerate(columns)]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True))
                     for row in [[head for head, _ in columns], *cells])
