"""The one way our kernels are compiled: numba's ``njit`` with an on-disk cache that can neither break
nor stop a run.

``@njit(cache=True, nogil=True)`` from here is numba's ``njit`` (no fastmath) whose cache is guarded:

* a cache file that cannot be read back — an ``.nbc`` cut short by a full disk or a killed first
  compile, a garbled ``.nbi`` index (numba raises ``UnpicklingError`` on every later call, and a run
  never recovers until the folder is deleted) — is discarded: the function's index and data files are
  removed, the kernel is compiled again in memory and its cache rewritten;
* a cache that cannot be written (a full disk, a read-only folder) costs only the next process's
  compile: the compiled kernel is used;
* a ``NUMBA_CACHE_DIR`` that cannot be used (a file, a read-only mount, a folder that cannot be made):
  numba silently caches beside the sources instead (``__pycache__``); that is said once, with where the
  kernels are cached;
* no place to cache at all (numba's locators: ``NUMBA_CACHE_DIR``, then the source's ``__pycache__``,
  then the user's cache folder; none writable raises ``cannot cache function …: no locator available``
  at import) compiles in memory;
* a cache compiled from other sources — any of merger's or circsim's SLAM files changed since — is not
  used (numba alone checks only the kernel's own file, and a kernel holds the code of the kernels it
  calls: a stale one gave wrong answers after an edit of one of those).

Each case is reported once per process as one line on the ``merger.jit`` logger (without logging
configured, Python prints warnings to stderr as the bare line). Answers never depend on the cache: a
cached kernel is the same machine code as a freshly compiled one. Kernel modules import ``njit`` from
here, never from numba (``tests/merger/test_jit.py`` checks every kernel of merger and circsim).
"""

from __future__ import annotations

import glob
import logging
import os

import numba
from numba.core.caching import FunctionCache

log = logging.getLogger(__name__)
_told: set[str] = set()  # the kinds of warning already given in this process


def warn_once(kind: str, message: str) -> None:
    """Log ``message`` as a warning unless a warning of this ``kind`` was already given here."""
    if kind not in _told:
        _told.add(kind)
        log.warning("warning: %s", message)


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return type(exc).__name__ + (f": {text[0]}" if text else "")


def sources_stamp(paths) -> tuple:
    """(path, mtime, size) of every file in ``paths`` that exists, sorted: a stamp that changes when one does."""
    out = []
    for path in sorted(map(str, paths)):
        try:
            st = os.stat(path)
        except OSError:
            continue
        out.append((os.path.basename(path), st.st_mtime_ns, st.st_size))
    return tuple(out)


_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# the sources a kernel can be compiled from: numba's own stamp is the kernel's file alone, and a cached
# kernel holds the machine code of every kernel it calls and of the globals it read (numba: "cache
# invalidation fails to recognize changes in symbols defined in another file"), so after an edit — a
# ``git pull`` on an editable install — a kernel whose own file did not change would run stale code
KERNEL_SOURCES = sorted(glob.glob(os.path.join(_ROOT, "merger", "**", "*.py"), recursive=True)
                        + glob.glob(os.path.join(_ROOT, "circsim", "slam", "*.py")))
_STAMP = sources_stamp(KERNEL_SOURCES)
_FOLDER_STAMPS: dict[str, tuple] = {}


def _check_cache_dir(used: str) -> None:
    """Say once when ``NUMBA_CACHE_DIR`` is set but numba caches elsewhere (``used``): it could not use it."""
    wanted = numba.config.CACHE_DIR
    if not wanted:
        return
    root = os.path.abspath(wanted)
    if os.path.abspath(used).startswith(root.rstrip(os.sep) + os.sep):
        return
    why = ("it is not a folder" if os.path.lexists(root) and not os.path.isdir(root) else
           "it is not writable: a read-only mount or folder" if os.path.isdir(root) else
           "it cannot be made")
    warn_once("cachedir", f"NUMBA_CACHE_DIR={wanted}: cannot be used to cache compiled kernels ({why}); "
              f"they are cached beside their sources instead (__pycache__: {used}, ...)")


class GuardedCache(FunctionCache):
    """numba's per-function cache, whose unreadable files are discarded and whose write errors are not
    fatal (a cache is an optimisation: a failure of it only costs a compile), and which is fresh only
    while no source a kernel can be compiled from changed (:data:`KERNEL_SOURCES`)."""

    def __init__(self, py_func):
        super().__init__(py_func)
        _check_cache_dir(self.cache_path)
        cf = self._cache_file
        folder = os.path.dirname(os.path.abspath(py_func.__code__.co_filename))
        if folder not in _FOLDER_STAMPS:  # the kernel's own folder too (a kernel outside merger and circsim)
            _FOLDER_STAMPS[folder] = sources_stamp(glob.glob(os.path.join(glob.escape(folder), "*.py")))
        cf._source_stamp = (cf._source_stamp, _STAMP, _FOLDER_STAMPS[folder])

    def load_overload(self, sig, target_context):
        try:
            return super().load_overload(sig, target_context)
        except Exception as exc:  # any failure to read back is a bad file: pickle, EOF, a bad payload
            self._discard()
            warn_once("corrupt", f"numba's compile cache in {self.cache_path} could not be read "
                      f"({_reason(exc)}): discarded, the kernels are compiled again (about 30 s) and re-cached")
            return None

    def save_overload(self, sig, data):
        try:
            super().save_overload(sig, data)
        except Exception as exc:  # a full disk, a read-only or vanished folder, an index garbled meanwhile
            warn_once("unsaved", f"numba's compile cache in {self.cache_path} could not be written "
                      f"({_reason(exc)}): the kernels run compiled in memory, the next run compiles them again")

    def _discard(self) -> None:
        base = os.path.join(self.cache_path, glob.escape(self._impl.filename_base))
        for path in glob.glob(base + ".nbi") + glob.glob(base + ".*.nbc"):
            try:
                os.unlink(path)
            except OSError:  # already gone (another process discarded it) or read-only: saving will say
                pass


def njit(*, cache: bool = True, nogil: bool = True, inline: bool = False):
    """``numba.njit(cache=cache, nogil=nogil)`` with the cache guarded (module docstring). ``inline``: the
    function is inlined where a kernel calls it (numba's ``inline="always"``): small helpers in hot loops
    cost no call (a call passes every field of its arguments; measured +36% on the coarse search)."""

    def wrap(func):
        disp = numba.njit(nogil=nogil, inline="always" if inline else "never")(func)
        if cache and hasattr(disp, "enable_caching"):  # (NUMBA_DISABLE_JIT=1 gives the function itself)
            try:
                disp._cache = GuardedCache(func)  # what numba's Dispatcher.enable_caching() does
            except RuntimeError as exc:  # numba: "cannot cache function …: no locator available …"
                warn_once("nowhere", f"numba finds no writable folder to cache compiled kernels in ({exc}): "
                          "they are compiled in memory on every run (about 30 s); set NUMBA_CACHE_DIR to a "
                          "writable folder")
        return disp

    return wrap
