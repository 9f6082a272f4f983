"""A sweep from Python: :func:`run_sweep`, what ``circsim sweep`` runs — the same plan (:mod:`.plan`), the
same folder of rows (:mod:`.store`: ``runs.jsonl``, resumable, locked while written), the same local
process pool or dask.distributed cluster (:func:`.sweep.execute`) and the same tables and plot.

::

    from circsim.experiments.api import run_sweep

    res = run_sweep("scene1", grid={"center_error": [0, 0.2]}, seeds=2, sets=["duration_s=10"],
                    out="runs/sweep")
    res.rows        # one dict per run (the columns of docs/sweeps.md), in plan order
    res.summary     # one dict per grid combination (medians and IQRs over the seeds)

A bad scenario, key or value is a :class:`~circsim.experiments.plan.SweepError` (one line, before any
run); a run that raises is counted in ``failed`` and its traceback kept in ``errors.jsonl``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .plan import SweepError


@dataclass(frozen=True)
class SweepResult:
    """What :func:`run_sweep` answers: the rows of every finished run of the plan (earlier ones of a
    resumed sweep included), the summary per combination, the files written and the runs that failed."""

    rows: list[dict]
    summary: list[dict]
    paths: list[Path]
    failed: int
    planned: int
    skipped: int = 0  # runs already in the folder (resume)
    keys: list[str] = field(default_factory=list)  # the grid's keys, in order


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during the runs: the finished rows are kept and their tables written; ``result`` holds them
    (``--resume`` / ``resume=True`` continues)."""

    def __init__(self, result: SweepResult) -> None:
        super().__init__()
        self.result = result


def _grid_specs(grid) -> list[str]:
    """``{"key": [v1, v2]}`` (or ``--grid`` strings) as ``key=v1,v2`` specs (values in YAML/JSON form)."""
    import json

    if isinstance(grid, dict):
        specs = []
        for key, values in grid.items():
            values = list(values) if isinstance(values, (list, tuple)) else [values]
            specs.append(f"{key}=" + ",".join(json.dumps(v) if not isinstance(v, str) else v for v in values))
        return specs
    return [str(g) for g in grid]


def run_sweep(scenario: str | Path, *, grid=(), seeds: int = 1, sets=(), seed: int | None = None,
              out: str | Path, workers: int | None = None, dask: str | None = None, resume: bool = False,
              overwrite: bool = False, plots: bool = True, progress: bool = False,
              on_start=None, out_key: str = "out") -> SweepResult:
    """Run every combination of ``grid`` × ``seeds`` seeds of ``scenario`` into the folder ``out``.

    Parameters
    ----------
    scenario : a scenario file or a bundled scenario's name (``circsim scenarios``).
    grid : ``{"key.path": [v1, v2, ...]}`` or ``["key.path=v1,v2", ...]`` (``--grid``); keys as in
        docs/scenario-reference.md.
    seeds : seeds per combination (seed = base seed + i).
    sets, seed : ``--set`` assignments and ``--seed``, applied to the scenario first.
    out : the sweep's folder (``runs.jsonl``, ``runs.csv``, ``summary.csv``, ``sweep.png``).
    workers : local processes (default every core); ``dask``: a dask.distributed scheduler's address
        (``tcp://host:8786``) instead — its workers need this package installed (docs/sweeps.md).
    resume, overwrite : continue a sweep in ``out`` (only the runs not there), or start it again.
    plots : write ``sweep.png``. ``progress``: a progress bar on stderr.
    out_key : how an error names ``out`` (the command line: ``--out``).
    on_start : called as ``on_start(base, axes, tasks, done, todo)`` before the first run (the CLI's line).

    Raises
    ------
    SweepError
        A bad input (:class:`~circsim.experiments.plan.SweepError`), before any run.
    SweepInterrupted
        Ctrl-C: the finished rows are written and its ``result`` holds them.
    """
    from merger.io.mapio import ensure_output_dir

    from ..commands import load_with_overrides
    from .plan import parse_grid, plan
    from .store import check_sweep_outputs, lock_out, prepare_out
    from .sweep import check_dask, execute
    from .tables import summarize, sweep_rows, write_tables

    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise SweepError(f"workers: expected an integer >= 1, got {workers!r}")
    if dask:
        check_dask()
    base = load_with_overrides(str(scenario), seed, list(sets))
    axes = parse_grid(_grid_specs(grid))
    tasks = plan(base, axes, seeds)
    out = Path(out)
    ensure_output_dir(out, out_key)
    with lock_out(out):  # one sweep writes a folder at a time
        check_sweep_outputs(out)
        todo, done = prepare_out(out, tasks, resume=resume, overwrite=overwrite)
        if on_start is not None:
            on_start(base, axes, tasks, done, todo)
        interrupted, failed = False, 0
        try:
            failed = execute(todo, out, workers=workers, dask_address=dask, progress=progress).failed
        except KeyboardInterrupt:
            interrupted = True
        rows = sweep_rows(out, tasks)
        summary = summarize(rows, axes)
        paths = []
        if rows:
            paths = write_tables(rows, summary, out)
            if plots:
                from .plots import choose_axes, plot_sweep

                x_key, line_keys = choose_axes([a.key for a in axes])
                paths.append(plot_sweep(rows, line_keys, out / "sweep.png", title=f"sweep {base.name}", x_key=x_key))
    result = SweepResult(rows, summary, paths, failed, len(tasks), done, [a.key for a in axes])
    if interrupted:
        raise SweepInterrupted(result)
    return result
