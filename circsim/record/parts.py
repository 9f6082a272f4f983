"""The temporary files a recording or a bag is written to, and the ones a killed run left behind.

A recording goes to ``.NAME.XXXX.part.rrd`` beside its target and is renamed into place when complete
(:mod:`circsim.record.rerun`); a bag (a folder) is written inside ``.NAME.XXXX.part.bag/`` beside its
target and renamed out of it when complete (:mod:`circsim.record.bag`). A run killed outright (SIGKILL, a
power cut) cannot delete its part, so the next run of the same output removes the parts nobody writes
any more: a writer holds an exclusive ``flock`` on its part (the file, or the folder) for as long as it
runs, which the kernel releases when the process ends however it ends; a part whose lock can be taken
has no writer (a part of a run still writing is left alone).
"""

from __future__ import annotations

import fcntl
import glob
import os
import shutil
import stat
import tempfile
from pathlib import Path

SUFFIX = ".part.rrd"
BAG_SUFFIX = ".part.bag"
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)


def _stale(target, suffix: str, folder: bool) -> list[Path]:
    """Delete the parts of ``target`` ending in ``suffix`` (files, or folders) whose writer has ended."""
    target = Path(target)
    gone = []
    for p in glob.glob(os.path.join(glob.escape(str(target.parent)), f".{glob.escape(target.name)}.*{suffix}")):
        try:
            if stat.S_ISDIR(os.lstat(p).st_mode) != folder:
                continue
            fd = os.open(p, os.O_RDONLY | _NOFOLLOW | (getattr(os, "O_DIRECTORY", 0) if folder else 0))
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:  # held: a run is writing it
            os.close(fd)
            continue
        try:
            if folder:
                shutil.rmtree(p)
            else:
                os.unlink(p)
            gone.append(Path(p))
        except OSError:
            pass
        finally:
            os.close(fd)
    return gone


def remove_stale_parts(target) -> list[Path]:
    """Delete the recording parts of ``target`` whose writer has ended; returns them."""
    return _stale(target, SUFFIX, folder=False)


def remove_stale_bag_parts(target) -> list[Path]:
    """Delete the bag parts (folders) of ``target`` whose writer has ended; returns them."""
    return _stale(target, BAG_SUFFIX, folder=True)


def claim_part(target) -> tuple[str, int]:
    """A new part beside ``target`` (stale ones removed first), locked while the returned descriptor is
    open: close it (:func:`release`) once the part is renamed or deleted."""
    target = Path(target)
    remove_stale_parts(target)
    fd, path = tempfile.mkstemp(prefix=f".{target.name}.", suffix=SUFFIX, dir=target.parent)
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # a fresh file: nobody else holds it
    return path, fd


def claim_bag_part(target) -> tuple[Path, int]:
    """A new, empty part folder beside the bag ``target`` (stale ones removed first), locked while the
    returned descriptor is open (:func:`release`)."""
    target = Path(target)
    remove_stale_bag_parts(target)
    path = tempfile.mkdtemp(prefix=f".{target.name}.", suffix=BAG_SUFFIX, dir=target.parent)
    try:
        fd = os.open(path, os.O_RDONLY | _NOFOLLOW | getattr(os, "O_DIRECTORY", 0))
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # a fresh folder: nobody else holds it
    except OSError:
        shutil.rmtree(path, ignore_errors=True)
        raise
    return Path(path), fd


def release(fd: int | None) -> None:
    """Close a part's descriptor (its lock goes with it)."""
    if fd is not None:
        try:
            os.close(fd)
        except OSError:
            pass
