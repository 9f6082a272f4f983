"""A sweep's folder: the row store (``runs.jsonl``), the folder lock and the sweep's identity.

The contract: rows are appended to ``runs.jsonl`` as each run finishes (:func:`read_rows` ignores a line
torn by a kill and refuses one that is not a run's row); one sweep at a time writes a folder
(:func:`lock_out`); ``sweep.json`` records what the sweep is (:func:`write_sweep_identity`), so
``--resume`` continues only the same sweep and names what differs (:func:`prepare_out`). See
docs/sweeps.md.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from .plan import (
    ERRORS_JSONL,
    RUNS_CSV,
    RUNS_JSONL,
    RUNS_PARQUET,
    SUMMARY_CSV,
    RunTask,
    SweepError,
    base_digest,
)


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
