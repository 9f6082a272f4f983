"""Progress of long work (a run, a sweep, the offline experiment), on stderr, off with ``--quiet``.

On a terminal it is tqdm's bar, redrawn in place. Otherwise (stderr piped, redirected to a log, a CI job)
a bar's redraws would fill the log with carriage returns and tqdm prints nothing useful; there it is a
plain line at most every :data:`PLAIN_EVERY_S` seconds of wall time — ``circsim: scene1 12.3/60 sim s
(20%), 9 s elapsed`` — and one last line at the end of work that printed any. Work shorter than that
prints nothing. :func:`progress_bar` chooses; both kinds answer tqdm's calls that circsim uses (``n``,
``update``, ``refresh``, ``set_postfix_str``, ``write``, ``close``, ``with``).
"""

from __future__ import annotations

import sys
import time

PLAIN_EVERY_S = 5.0  # at most one plain progress line this often


class PlainProgress:
    """tqdm's interface as plain lines on ``file`` (default stderr), at most one every ``every_s``."""

    def __init__(self, total: float, unit: str, desc: str, *, every_s: float | None = None, file=None,
                 clock=time.monotonic) -> None:
        self.total, self.unit, self.desc = total, unit, desc
        self.every_s = PLAIN_EVERY_S if every_s is None else every_s
        self.file, self.clock = file, clock
        self.n: float = 0
        self.postfix = ""
        self.t0 = self.last = clock()
        self.printed = False

    def _line(self) -> str:
        pct = f" ({100 * self.n / self.total:.0f}%)" if self.total else ""
        post = f", {self.postfix}" if self.postfix else ""
        return (f"circsim: {self.desc} {self.n:g}/{self.total:g} {self.unit}{pct}, "
                f"{self.clock() - self.t0:.0f} s elapsed{post}")

    def refresh(self) -> None:
        now = self.clock()
        if now - self.last >= self.every_s:
            self.last = now
            self.write(self._line())
            self.printed = True

    def update(self, k: float = 1) -> None:
        self.n += k
        self.refresh()

    def set_postfix_str(self, s: str) -> None:
        self.postfix = s

    def write(self, msg: str, file=None) -> None:
        print(msg, file=file or self.file or sys.stderr, flush=True)

    def close(self) -> None:
        if self.printed:  # the end of work that showed progress
            self.write(self._line())
            self.printed = False

    def __enter__(self) -> PlainProgress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def progress_bar(total: float, unit: str, desc: str, *, quiet: bool, **tqdm_kw):
    """A tqdm bar on a terminal, :class:`PlainProgress` lines otherwise, a silent tqdm with ``quiet``."""
    from tqdm import tqdm

    if quiet:
        return tqdm(total=total, disable=True)
    if sys.stderr.isatty():
        return tqdm(total=total, unit=unit, desc=desc, **tqdm_kw)
    return PlainProgress(total, unit, desc)
