"""What every circsim command shares: user errors, the scenario argument, progress bars, and how the
process answers Ctrl-C and SIGTERM.

The contract: a command raises :class:`UsageError` (or ``ValueError``) with one line for a user's
mistake; ``circsim.cli.main`` prints it and exits with 2. :func:`load_with_overrides` is the one way a
command reads its scenario argument (a file or a bundled name, ``--set``, ``--seed``). A command's
``main`` calls :func:`start` first and :func:`finish` last; a command calls :func:`begin_work` when its
work begins — before, a signal is one line and exit; from then on Ctrl-C and SIGTERM stop the work and
keep what it produced, and :func:`interrupted_code` is the exit code (130, or 143 after SIGTERM).

The top-level command line (:mod:`circsim.cli`) and the experiment commands
(:mod:`circsim.experiments.cli`) both use this module, so neither imports the other's state: the state
of the signals lives here, once, whatever module runs as ``__main__``.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from pathlib import Path


class UsageError(Exception):
    pass


def resolve_scenario(arg: str) -> Path:
    """A scenario file path, or the name of a bundled scenario (``scene1``)."""
    from .config.scenario import bundled_scenarios

    p = Path(arg)
    if p.exists():
        return p
    bundled = bundled_scenarios()
    if arg in bundled:
        return bundled[arg]
    raise UsageError(f"{arg}: no such scenario file (bundled scenarios: {', '.join(bundled)})")


def load_with_overrides(arg: str, seed: int | None, sets: list[str]):
    """The scenario ``arg`` (file or bundled name) with ``--set`` assignments and ``--seed`` applied."""
    from .config.scenario import load_scenario

    assignments = list(sets or [])
    if seed is not None:
        assignments.append(f"seed={seed}")
    return load_scenario(resolve_scenario(arg), assignments)  # overrides first, then one validation


def add_scenario_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="scenario YAML file or bundled scenario name (see `circsim scenarios`)")
    p.add_argument("--seed", type=int, help="override the scenario's seed")
    p.add_argument("--set", action="append", default=[], metavar="KEY.PATH=VALUE",
                   help="override a scenario value, e.g. --set center_error.magnitude_m=0.1 (repeatable)")


def progress_observer(sc, quiet: bool):
    """The run's progress on stderr (:func:`circsim.progress.progress_bar`: a bar on a terminal, a plain
    line every few seconds otherwise), none with --quiet."""
    from .events import Observer
    from .progress import progress_bar

    if quiet:
        return None

    class Progress(Observer):
        def __init__(self):
            self.bar = progress_bar(round(sc.duration_s, 1), "sim s", sc.name, quiet=False, leave=False)

        def on_tick(self, t, step, ticks):
            self.bar.n = round(t, 1)
            if step % 10 == 0:
                self.bar.refresh()

        def on_end(self, result):
            self.bar.close()

    return Progress()


_TERMINATED = []  # a SIGTERM arrived (the exit code is then 143, 128 + SIGTERM)
_STATE = {"starting": False, "sigint_ignored_at_start": False, "own_sigint": False}


def _stop_starting(signum, frame) -> None:
    """A signal while circsim starts (modules loading, scenario checked; nothing written yet): one line and
    out at once. Raising KeyboardInterrupt here could land in an import's cleanup callback, where Python
    prints a traceback and swallows it."""
    term = signum == signal.SIGTERM
    sys.stderr.write("circsim: terminated\n" if term else "circsim: interrupted\n")
    sys.stderr.flush()
    os._exit(143 if term else 130)


def _sigterm_as_ctrl_c(signum, frame) -> None:
    """SIGTERM does what Ctrl-C does at this moment: the run's handler (stop at the end of the tick; a
    second one interrupts at once), or KeyboardInterrupt. While SIGINT is ignored for a moment (the
    recorder writing the .rrd footer) it is ignored too; the run is ending anyway."""
    if _STATE["starting"]:
        _stop_starting(signum, frame)
    _TERMINATED.append(signum)
    h = signal.getsignal(signal.SIGINT)
    if h is signal.SIG_IGN and not _STATE["sigint_ignored_at_start"]:
        return
    if callable(h) and h is not signal.default_int_handler:
        h(signal.SIGINT, frame)
        return
    raise KeyboardInterrupt


def begin_work() -> None:
    """Called by a command when its work begins (the run, the sweep's pool): from here Ctrl-C and SIGTERM
    stop the work and keep what it produced (KeyboardInterrupt, or the run's tick-boundary handler)."""
    _STATE["starting"] = False
    if _STATE["own_sigint"] and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.default_int_handler)
        _STATE["own_sigint"] = False


def start() -> dict:
    """Called by a command line's ``main`` first: SIGTERM is handled as Ctrl-C, and a signal while the
    command starts is one line and exit (:func:`begin_work` ends that phase). Returns what
    :func:`finish` restores."""
    saved = {}
    _TERMINATED.clear()
    if threading.current_thread() is threading.main_thread():
        _STATE["sigint_ignored_at_start"] = signal.getsignal(signal.SIGINT) is signal.SIG_IGN
        saved[signal.SIGTERM] = signal.signal(signal.SIGTERM, _sigterm_as_ctrl_c)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            saved[signal.SIGINT] = signal.signal(signal.SIGINT, _stop_starting)
            _STATE["own_sigint"] = True
        _STATE["starting"] = True
    return saved


def finish(saved: dict) -> None:
    """Called by a command line's ``main`` last: the signal handlers :func:`start` replaced are back."""
    _STATE.update(starting=False, own_sigint=False)
    for sig, h in saved.items():
        signal.signal(sig, h)


def terminated() -> bool:
    """Whether a SIGTERM arrived (the exit code is then 143)."""
    return bool(_TERMINATED)


def interrupted_code() -> int:
    """Exit code of a command stopped early: 143 after SIGTERM, 130 after Ctrl-C."""
    return 143 if _TERMINATED else 130
