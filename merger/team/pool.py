"""The merge cycle's thread pool: a cycle's independent searches (merge orders, tree pairs) side by side.

The search kernels release the GIL (numba ``nogil=True``), so threads use every core. Results come back
in input order and each task is a pure function of its inputs, so a cycle's result is the same whatever
the scheduling and the number of threads (``MERGER_THREADS``, default: the machine's cores; 1: none).
A task that itself asks for the pool runs its work in its own thread (no nested waits on the pool).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor

_LOCK = threading.Lock()
_POOL: ThreadPoolExecutor | None = None
_INSIDE = threading.local()


def max_threads() -> int:
    """The most threads ``MERGER_THREADS`` may ask for: 4 × the machine's cores, at least 8 (more only
    thrash: every search is compute-bound)."""
    return max(8, 4 * (os.cpu_count() or 1))


def threads() -> int:
    """The pool's size: ``MERGER_THREADS`` if set (plain decimal digits, 1 to :func:`max_threads`), else
    the machine's cores. Anything else set (``abc``, ``0``, ``-2``, ``2_0``, ``99999999999999999999``)
    raises ValueError: both command lines check it before any work."""
    text = os.environ.get("MERGER_THREADS", "").strip()
    if not text:
        return os.cpu_count() or 1
    cap = max_threads()
    # int() also takes '2_0' (20), '+3', '٣' (Arabic-Indic 3) and any number of digits: only 0-9, and short
    n = int(text) if text.isascii() and text.isdigit() and len(text) <= 6 else 0
    if not 1 <= n <= cap:
        raise ValueError(f"MERGER_THREADS={text[:40]!r}: expected an integer >= 1 and <= {cap} (4 x the "
                         "machine's cores, at least 8; decimal digits only) (threads per merge cycle; unset: "
                         "one per core)")
    return n


def _pool() -> ThreadPoolExecutor:
    global _POOL
    with _LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=threads(), thread_name_prefix="merger")
        return _POOL


def _run(fn, item):
    _INSIDE.active = True
    try:
        return fn(item)
    finally:
        _INSIDE.active = False


def parallel_map(fn: Callable, items: Iterable) -> list:
    """``[fn(x) for x in items]``, computed on the pool (in order; exceptions re-raised in order)."""
    items = list(items)
    if len(items) < 2 or threads() < 2 or getattr(_INSIDE, "active", False):
        return [fn(x) for x in items]
    futures = [_pool().submit(_run, fn, x) for x in items]
    return [f.result() for f in futures]
