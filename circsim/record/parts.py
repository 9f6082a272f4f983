"""The temporary file a recording is written to, and the ones a killed run left behind.

A recording goes to ``.NAME.XXXX.part.rrd`` beside its target and is renamed into place when complete
(:mod:`circsim.record.rerun`). A run killed outright (SIGKILL, a power cut) cannot delete its part, so the
next run of the same output removes the parts nobody writes any more: a writer holds an exclusive
``flock`` on its part for as long as it runs, which the kernel releases when the process ends however it
ends; a part whose lock can be taken has no writer (a part of a run still writing is left alone).
"""

from __future__ import annotations

import fcntl
import glob
import os
import tempfile
from pathlib import Path

SUFFIX = ".part.rrd"


def remove_stale_parts(target) -> list[Path]:
    """Delete the parts of ``target`` whose writer has ended; returns them."""
    target = Path(target)
    gone = []
    for p in glob.glob(os.path.join(glob.escape(str(target.parent)), f".{glob.escape(target.name)}.*{SUFFIX}")):
        try:
            fd = os.open(p, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0))
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # held: a run is writing it
            os.close(fd)
            continue
        try:
            os.unlink(p)
            gone.append(Path(p))
        except OSError:
            pass
        finally:
            os.close(fd)
    return gone


def claim_part(target) -> tuple[str, int]:
    """A new part beside ``target`` (stale ones removed first), locked while the returned descriptor is
    open: close it (:func:`release`) once the part is renamed or deleted."""
    target = Path(target)
    remove_stale_parts(target)
    fd, path = tempfile.mkstemp(prefix=f".{target.name}.", suffix=SUFFIX, dir=target.parent)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # a fresh file: nobody else holds it
    return path, fd


def release(fd: int | None) -> None:
    """Close a part's descriptor (its lock goes with it)."""
    if fd is not None:
        try:
            os.close(fd)
        except OSError:
            pass
